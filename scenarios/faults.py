"""Fault injection (docs/physics.md §5): how each fault type enters the servo-loop.

A fault acts from its onset step k0 = round(onset/Ts) on (faults act at step boundaries).
This module turns the per-run fault description (type, onset, magnitude, frequency) into
arrays the vectorised loop applies with masks, so runs with different faults share one
batch without any per-run branching:

========================  ===================================================================
fault                     mechanism (and the unit of ``magnitude``)
========================  ===================================================================
``runaway``               the order seen by the loop is corrupted by a ramp ṙ·(t − t0)
                          ([COMB] D_V1, [VANEK]); magnitude = signed ṙ [deg/s]
``hardover``              the servo-valve current is replaced by ±i_max; magnitude = ±1
``liquid_jam``            a bias f is added to the COM rod acquisition the loop closes on
                          ([CHEN] eq. 4, [VANEK] "bias on the rod sensor"); magnitude = f [mm]
``solid_jam``             rod and surface seized ([CHEN] eq. 4), in one of two variants
                          chosen by ``magnitude``: NaN — *seized where it stands* at t0;
                          finite — *offset*: at t0 the rod jumps by the signed ``magnitude``
                          [mm] (its last uncommanded motion, [CHEN] §6.2: 1.8 % of the
                          deflection range) and is seized there; the rod sensors read it
``disconnection``         rod–surface link broken at t0: the rod is unloaded, the surface
                          floats ([CHEN] eq. 5)
``ofc_liquid``            a sinusoid A·sin(2πf(t − t0)) added to the current; magnitude = A
                          [mA], ``freq_hz`` = f
``ofc_solid``             the COM rod acquisition replaced by its value at t0 plus
                          A·sin(2πf(t − t0)); magnitude = A [mm]
========================  ===================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import ActuatorParams, param

#: Never-reached onset step for runs without a given fault.
NEVER = np.iinfo(np.int64).max // 2


@dataclass(frozen=True)
class FaultDefaults:
    """Default magnitudes of a single run (``fdd-campaign simulate``); campaigns sample their
    own from the campaign file (docs/physics.md §5)."""

    runaway_rate_deg_s: float = param("deg/s", "[COMB] D_V1, [VANEK]", "runaway ramp rate")
    liquid_jam_pct_range: float = param("%", "[CHEN] §6.2 (1.3 % of the range)",
                                        "liquid-jam bias as a share of the deflection range")
    ofc_liquid_amp_mA: float = param("mA", "est.", "liquid OFC current amplitude")
    ofc_solid_amp_mm: float = param("mm", "est.", "solid OFC rod-measurement amplitude")
    ofc_freq_hz: float = param("Hz", "est.", "OFC frequency")
    runaway_margin_deg: float = param("deg", "est.",
                                      "a runaway order is clipped this far beyond the stops")
    jam_pressure_gain_mA: float = param("mA", "est. (servo-valve pressure gain)",
                                        "current that drives full ΔP across a blocked piston")
    solid_jam_offset_pct_range: float = param(
        "%", "[CHEN] §6.2 (1.8 % of the range)",
        "offset of a solid jam (variant \"offset\") as a share of the deflection range")


FAULT_DEFAULTS = FaultDefaults(
    runaway_rate_deg_s=5.0,
    liquid_jam_pct_range=1.3,
    ofc_liquid_amp_mA=1.0,
    ofc_solid_amp_mm=1.0,
    ofc_freq_hz=1.0,
    runaway_margin_deg=5.0,
    jam_pressure_gain_mA=0.5,
    solid_jam_offset_pct_range=1.8,
)

#: Variants of ``solid_jam`` (docs/physics.md §5): ``"seized"`` (run-table magnitude NaN) —
#: rod and surface seized where they stand at onset; ``"offset"`` (finite magnitude [mm]) —
#: seized at a position offset from the current one, [CHEN] eq. 4 and §6.2.
SOLID_JAM_VARIANTS: tuple[str, ...] = ("seized", "offset")


def liquid_jam_bias_mm(act: ActuatorParams, pct_of_range: float) -> float:
    """Rod-signal bias [mm] equivalent to *pct_of_range* % of the deflection range."""
    return float(act.deg_to_mm(pct_of_range / 100.0 * act.deflection_range_deg))


def solid_jam_offset_mm(act: ActuatorParams, pct_of_range: float) -> float:
    """Rod offset [mm] of an ``"offset"`` solid jam of *pct_of_range* % of the deflection
    range: r·sin(p·Δδ), the rod travel of that share of the range from neutral (the same
    conversion as :func:`liquid_jam_bias_mm`; [CHEN] §6.2 gives 1.8 %)."""
    return liquid_jam_bias_mm(act, pct_of_range)


def solid_jam_variant(magnitude: float) -> str:
    """Variant of a ``solid_jam`` run of run-table *magnitude*: ``"seized"`` when NaN,
    ``"offset"`` when finite (:data:`SOLID_JAM_VARIANTS`)."""
    return "offset" if np.isfinite(magnitude) else "seized"


def estimation_range_mm(act: ActuatorParams) -> float:
    """Normaliser [mm] of a rod-measurement fault estimate: the rod travel r·Δδ of the whole
    deflection range (Δδ in rad, small-angle), so that a fault of p % of the range reads
    ≈ p/100 (the normalisation in which [CHEN] §6.2 states its jams, 1.3 % and 1.8 %)."""
    return float(act.r_mm * np.radians(act.deflection_range_deg))


def default_magnitude(fault: str, act: ActuatorParams) -> float:
    """Magnitude of a single run of *fault* with the defaults of :data:`FAULT_DEFAULTS`."""
    d = FAULT_DEFAULTS
    return {
        "none": np.nan,
        "runaway": d.runaway_rate_deg_s,
        "hardover": 1.0,
        "liquid_jam": liquid_jam_bias_mm(act, d.liquid_jam_pct_range),
        "solid_jam": np.nan,
        "disconnection": np.nan,
        "ofc_liquid": d.ofc_liquid_amp_mA,
        "ofc_solid": d.ofc_solid_amp_mm,
    }[fault]


@dataclass(frozen=True)
class FaultArrays:
    """Per-run fault injection data for the loop (shapes (n,) or (n, n_steps))."""

    u_loop: np.ndarray        # order seen by the loop [mm] (runaway-corrupted)
    com_add: np.ndarray       # added to the COM acquisition [mm] (liquid jam) or None
    cur_add: np.ndarray       # added to the current [mA] (liquid OFC) or None
    cur_force: np.ndarray     # replaces the current where finite [mA] (hardover) or None
    com_osc: np.ndarray       # replacement oscillation of the COM acquisition [mm] or None
    k_osc: np.ndarray         # onset step of the COM replacement (ofc_solid) (n,)
    k_jam: np.ndarray         # onset step of a solid jam (n,)
    k_disc: np.ndarray        # onset step of a disconnection (n,)
    jam_offset: np.ndarray    # jump of an "offset" solid jam at onset [mm] (n,); 0: seized


def onset_steps(onset_s, ts: float) -> np.ndarray:
    """Onset step k0 = round(onset/Ts); NEVER where the onset is NaN."""
    onset = np.asarray(onset_s, dtype=float)
    k = np.full(onset.shape, NEVER, dtype=np.int64)
    ok = np.isfinite(onset)
    k[ok] = np.rint(onset[ok] / ts).astype(np.int64)
    return k


def fault_arrays(fault, onset_s, magnitude, freq_hz, order_deg, act: ActuatorParams,
                 ts: float, i_max, *, command_mm=None) -> FaultArrays:
    """Build the injection arrays of a batch.

    fault (n,) str; onset_s, magnitude, freq_hz (n,) float; order_deg (n, T) the fault-free
    surface order [deg]; i_max (n,) the true current saturation [mA]. *command_mm* (n, T),
    when given, is ``act.r_mm * sin(radians(order_deg))`` (the fault-free rod order, already
    computed by the caller): the order seen by the loop of a run it equals bit for bit (no
    runaway, no zero order whose sign the ramp's + 0 would flip, inside the stops) is then
    copied from it instead of computed again. Every array is computed row by row for the
    runs of its fault type only; the values are those of the whole-batch formulas.
    """
    fault = np.asarray(fault).astype(str)
    n, T = order_deg.shape
    t = np.arange(T) * ts
    k0 = onset_steps(onset_s, ts)
    mag = np.asarray(magnitude, dtype=float)
    freq = np.asarray(freq_hz, dtype=float)

    def timing(rows):
        """(active, time since onset) of *rows*, each (len(rows), T)."""
        active = np.arange(T)[None, :] >= k0[rows, None]
        return active, np.where(active, t[None, :] - (k0[rows] * ts)[:, None], 0.0)

    # runaway: the order seen by the loop ramps away from t0 (clipped beyond the stops)
    m = FAULT_DEFAULTS.runaway_margin_deg
    lo, hi = act.stop_min_deg - m, act.stop_max_deg + m
    runaway = fault == "runaway"
    if command_mm is None:
        redo = np.ones(n, dtype=bool)
        u_loop = np.empty((n, T))
    else:
        u_loop = np.array(command_mm, dtype=float)
        redo = runaway | ((order_deg == 0.0) | (order_deg < lo) | (order_deg > hi)).any(axis=1)
    rows = np.flatnonzero(redo)
    if rows.size:
        active, dt_on = timing(rows)
        ramp = np.where(runaway[rows, None] & active, np.nan_to_num(mag[rows])[:, None] * dt_on,
                        0.0)
        order_loop = np.clip(order_deg[rows] + ramp, lo, hi)
        u_loop[rows] = act.deg_to_mm(order_loop)

    def injected(name, fill, values):
        """(n, T) array: *fill*, and ``values(rows, active, dt_on)`` after the onset of the
        runs of fault *name* (None when the batch has none)."""
        rows = np.flatnonzero(fault == name)
        if rows.size == 0:
            return None
        out = np.full((n, T), fill)
        active, dt_on = timing(rows)
        out[rows] = np.where(active, values(rows, dt_on), fill)
        return out

    def oscillation(rows, dt_on):
        return (np.nan_to_num(mag[rows])[:, None]
                * np.sin(2 * np.pi * np.nan_to_num(freq[rows])[:, None] * dt_on))

    def hardover(rows, dt_on):
        direction = np.sign(np.nan_to_num(mag[rows], nan=1.0))
        direction[direction == 0] = 1.0
        return (direction * np.asarray(i_max)[rows])[:, None]

    com_add = injected("liquid_jam", 0.0, lambda rows, _: np.nan_to_num(mag[rows])[:, None])
    cur_add = injected("ofc_liquid", 0.0, oscillation)
    cur_force = injected("hardover", np.nan, hardover)
    com_osc = injected("ofc_solid", np.nan, oscillation)

    def k_of(name):
        return np.where(fault == name, k0, NEVER)

    jam_offset = np.where((fault == "solid_jam") & np.isfinite(mag), np.nan_to_num(mag), 0.0)
    return FaultArrays(
        u_loop=u_loop, com_add=com_add, cur_add=cur_add, cur_force=cur_force,
        com_osc=com_osc, k_osc=k_of("ofc_solid"), k_jam=k_of("solid_jam"),
        k_disc=k_of("disconnection"), jam_offset=jam_offset,
    )


def jam_onset_position(x, k: int, fa: FaultArrays, x_min, x_max):
    """Rod positions [mm] at the start of step *k*, an ``"offset"`` solid jam applied: the
    runs whose jam starts at *k* jump by their ``jam_offset`` (inside the stops), the others
    are *x* unchanged (NumPy reference of the engines, docs/physics.md §5)."""
    jump = (fa.k_jam == k) & (fa.jam_offset != 0.0)
    if not jump.any():
        return x
    return np.where(jump, np.clip(x + fa.jam_offset, x_min, x_max), x)


def required_magnitude(fault: str) -> bool:
    """Whether a fault type needs a finite magnitude in the run table."""
    return fault in ("runaway", "hardover", "liquid_jam", "ofc_liquid", "ofc_solid")



#: Fault types whose additive effect on the rod measurement is defined ([CHEN] eq. 4).
ROD_MEASUREMENT_FAULTS: tuple[str, ...] = ("liquid_jam", "solid_jam")
