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
``solid_jam``             rod and surface seized at their position at t0 ([CHEN] eq. 4)
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


FAULT_DEFAULTS = FaultDefaults(
    runaway_rate_deg_s=5.0,
    liquid_jam_pct_range=1.3,
    ofc_liquid_amp_mA=1.0,
    ofc_solid_amp_mm=1.0,
    ofc_freq_hz=1.0,
    runaway_margin_deg=5.0,
    jam_pressure_gain_mA=0.5,
)


def liquid_jam_bias_mm(act: ActuatorParams, pct_of_range: float) -> float:
    """Rod-signal bias [mm] equivalent to *pct_of_range* % of the deflection range."""
    return float(act.r_mm * np.sin(np.radians(pct_of_range / 100.0 * act.deflection_range_deg)))


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


def onset_steps(onset_s, ts: float) -> np.ndarray:
    """Onset step k0 = round(onset/Ts); NEVER where the onset is NaN."""
    onset = np.asarray(onset_s, dtype=float)
    k = np.full(onset.shape, NEVER, dtype=np.int64)
    ok = np.isfinite(onset)
    k[ok] = np.rint(onset[ok] / ts).astype(np.int64)
    return k


def fault_arrays(fault, onset_s, magnitude, freq_hz, order_deg, act: ActuatorParams,
                 ts: float, i_max) -> FaultArrays:
    """Build the injection arrays of a batch.

    fault (n,) str; onset_s, magnitude, freq_hz (n,) float; order_deg (n, T) the fault-free
    surface order [deg]; i_max (n,) the true current saturation [mA].
    """
    fault = np.asarray(fault).astype(str)
    n, T = order_deg.shape
    t = np.arange(T) * ts
    k0 = onset_steps(onset_s, ts)
    mag = np.asarray(magnitude, dtype=float)
    freq = np.asarray(freq_hz, dtype=float)
    active = np.arange(T)[None, :] >= k0[:, None]                 # (n, T)
    dt_on = np.where(active, t[None, :] - (k0 * ts)[:, None], 0.0)  # time since onset

    def only(name):
        return (fault == name)[:, None] & active

    # runaway: the order seen by the loop ramps away from t0 (clipped beyond the stops)
    m = FAULT_DEFAULTS.runaway_margin_deg
    ramp = np.where(only("runaway"), np.nan_to_num(mag)[:, None] * dt_on, 0.0)
    order_loop = np.clip(order_deg + ramp, act.stop_min_deg - m, act.stop_max_deg + m)
    u_loop = act.r_mm * np.sin(np.radians(order_loop))

    com_add = cur_add = cur_force = com_osc = None
    if (fault == "liquid_jam").any():
        com_add = np.where(only("liquid_jam"), np.nan_to_num(mag)[:, None], 0.0)
    if (fault == "ofc_liquid").any():
        osc = np.nan_to_num(mag)[:, None] * np.sin(2 * np.pi * np.nan_to_num(freq)[:, None] * dt_on)
        cur_add = np.where(only("ofc_liquid"), osc, 0.0)
    if (fault == "hardover").any():
        direction = np.sign(np.nan_to_num(mag, nan=1.0))
        direction[direction == 0] = 1.0
        cur_force = np.where(only("hardover"), (direction * np.asarray(i_max))[:, None], np.nan)
    if (fault == "ofc_solid").any():
        osc = np.nan_to_num(mag)[:, None] * np.sin(2 * np.pi * np.nan_to_num(freq)[:, None] * dt_on)
        com_osc = np.where(only("ofc_solid"), osc, np.nan)

    def k_of(name):
        return np.where(fault == name, k0, NEVER)

    return FaultArrays(
        u_loop=u_loop, com_add=com_add, cur_add=cur_add, cur_force=cur_force,
        com_osc=com_osc, k_osc=k_of("ofc_solid"), k_jam=k_of("solid_jam"),
        k_disc=k_of("disconnection"),
    )


def required_magnitude(fault: str) -> bool:
    """Whether a fault type needs a finite magnitude in the run table."""
    return fault in ("runaway", "hardover", "liquid_jam", "ofc_liquid", "ofc_solid")

