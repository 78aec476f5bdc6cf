"""Surface-deflection orders of the six ADDSAFE fault-free manoeuvres (docs/physics.md §7, phase 1).

The order of one run [deg] is

    δ_order(t) = clip( δ_trim + Σ_i ΔA_i·s((t − t_i)/D_i) + δ_gust(t),  δ_min, δ_max )

* δ_trim: elevator trim at the flight point (:func:`elevator_trim_deg`), 0 for the aileron.
* the manoeuvre: a sum of smooth transitions s(x) = ½·(1 − cos(π·x)) for 0 ≤ x ≤ 1 (0 before,
  1 after) of size ΔA_i and duration D_i. Peak rate π·|ΔA|/(2·D); every D is at least the
  one giving ``manoeuvre_rate_deg_s`` and at least ``transition_min_s``, and the transitions
  of one surface never overlap, so the manoeuvre is rate-limited by construction.
* amplitudes: the docs/physics.md §7 values hold at the reference dynamic pressure q_ref and scale
  as f = clip(q_ref/q̄, scale_min, scale_max) (:func:`amplitude_scale`): a smaller q̄ needs a
  larger deflection for the same hinge/aircraft moment. They are then limited to the
  authority left between the trim and the electrical limit in that direction.
* δ_gust: the control law's reaction to Dryden turbulence (:mod:`.turbulence`): a gain
  times the gust angle — angle of attack w_g/V for the elevator, sideslip v_g/V for the
  aileron — through a first-order lag of the closed-loop bandwidth. Its flight-point
  dependence comes from σ(altitude) and V: the moment ratio Cmα/Cmδ (Clβ/Clδ) it stands
  for does not depend on q̄, so it carries no q̄ factor. At the reference flight point its
  std is ≈ 0.15° and a 60-s run spans ≈ ±0.35° (docs/physics.md §7: cruise ±0.2–0.5°).
* the final clip keeps the order within the electrical limits of ``actuator``; clipping
  cannot increase the rate. Order rate bound: ``rate_max_deg_s`` = manoeuvre transitions
  (``manoeuvre_rate_deg_s``) + the gust reaction (≈ 0.7 °/s RMS at the slowest, most
  turbulent grid corner: the 5 °/s margin is 7 RMS), checked by the tests.

Shapes (names of :data:`scenarios.catalog.MANOEUVRES`; amplitudes at q_ref, est.):

* ``cruise`` — elevator: trim + gust reaction; aileron: gust reaction
* ``nose_up`` — elevator: step to −(2…5)° held 5–10 s (width at half amplitude); aileron: gust
  reaction (wings level)
* ``aoa_protection`` — elevator: slow excursion to −(5…15)°: 2–4 s ramps, held 2–5 s; aileron: gust
  reaction
* ``pitch_protection`` — elevator: transient to 85–100 % of the nose-up authority (to the limit),
  held 0.5–1.5 s; 2–4 s later the same towards the nose-down limit; aileron: gust reaction
* ``yaw_angle_mode`` — elevator: gust reaction (a steady sideslip needs no pitch input to first
  order); aileron: ±(2…5)° held 5–10 s
* ``turn_coordination`` — elevator: small pull −k_g·(1/cos φ − 1) held through the turn (load factor
  of the bank φ); aileron: ±(5…10)° roll-in pulse lasting φ/p (roll-in rate p: 7.5 °/s in the normal
  set), turn held 4–7 s, opposite roll-out pulse

Manoeuvre sets (:data:`scenarios.catalog.MANOEUVRE_SETS`, :func:`set_params`): the list
above is the ``normal`` set (:data:`MANOEUVRE_PARAMS`); the ``stress`` set
(:data:`STRESS_MANOEUVRE_PARAMS`) rolls into the turn at the normal law's full-stick 15 °/s,
to a 33° bank, with every amplitude range at its high end (docs/physics.md §7).

Timing: a manoeuvre starts at lead_s + U(0, min(start_spread_s, room)) where room is what is
left so that it ends ``tail_s`` before the end of the record. The longest manoeuvre is the
normal set's turn at the lowest q̄ (two roll pulses of 33°/(7.5 °/s) = 4.4 s, a 7-s turn and
the elevator's ramp: ≤ 17.7 s), so records of at least 23 s contain the whole manoeuvre; in a
20–23 s record (``min_duration_s`` = 20 s) the longest turns start at lead_s and their
roll-out is cut by the end of the record. A fixed start time ``start_s`` (the run-table column
``manoeuvre_start_s``, e.g. to place a transient at a given time as in [COMB] §4 D_V2) replaces the
sampled one; the start uniform is still drawn, so the rest of the run's draws do not change.

Random numbers come from the run's generator in a fixed order, whatever the manoeuvre,
surface or duration: first :data:`N_SHAPE_DRAWS` uniforms (start time, then the shape
parameters listed in :func:`_transitions`), then the turbulence (:func:`.turbulence.lagged_gust`).
"""

from __future__ import annotations

import dataclasses
import math
import types
from dataclasses import dataclass, fields
from typing import Mapping, Sequence

import numpy as np

from .catalog import MANOEUVRE_SETS, MANOEUVRES, SURFACES, check_name
from .params import ActuatorParams, param
from .turbulence import MODERATE, DrydenParams, lagged_gust

#: Number of uniforms drawn per run for timing and shape, before the turbulence.
N_SHAPE_DRAWS: int = 6

#: Keys of the flight mapping, with their units.
FLIGHT_KEYS: dict[str, str] = {
    "qbar_pa": "Pa",       # dynamic pressure q̄
    "tas_ms": "m/s",       # true airspeed V
    "alt_ft": "ft",        # pressure altitude
    "alpha_deg": "deg",    # trimmed angle of attack
    "cg_pct": "% MAC",     # centre of gravity
    "mach": "-",           # Mach number (validated; the phase-1 profiles do not use it)
}


@dataclass(frozen=True)
class ManoeuvreParams:
    """Manoeuvre shapes, flight-point scaling, trim and gust-reaction laws (docs/physics.md §7).

    Ranges ``(lo, hi)`` are sampled uniformly per run. Amplitudes are magnitudes at the
    reference dynamic pressure; signs are in the shape table of the module docstring.
    """

    # ---- flight-point scaling ------------------------------------------------------
    qbar_ref_pa: float = param("Pa", "est.: ISA, M 0.82 at FL370, q̄ = (γ/2)·p·M²",
                               "reference dynamic pressure of the docs/physics.md §7 amplitudes")
    scale_min: float = param("-", "est. (grid q̄ ≈ 3.4–18 kPa → q_ref/q̄ ≈ 0.56–3.0)",
                             "lower clip of the amplitude factor q_ref/q̄")
    scale_max: float = param("-", "est. (see scale_min)",
                             "upper clip of the amplitude factor q_ref/q̄")
    # ---- smoothness -----------------------------------------------------------------
    rate_max_deg_s: float = param("deg/s",
                                  "est. (below the 48/57 °/s no-load rates, docs/physics.md §3)",
                                  "bound on the order rate, manoeuvre + gust reaction")
    manoeuvre_rate_deg_s: float = param("deg/s",
                                        "est. (rate_max minus a margin for the gust reaction)",
                                        "peak rate of a manoeuvre transition")
    transition_min_s: float = param("s", "est.", "shortest transition (bounds the acceleration)")
    # ---- timing -----------------------------------------------------------------------
    lead_s: float = param("s", "est.", "earliest start of a manoeuvre")
    start_spread_s: float = param("s", "est.", "start = lead + U(0, min(spread, room))")
    tail_s: float = param("s", "est.", "a manoeuvre is over this long before the record ends")
    min_duration_s: float = param("s", "est. (fits the longest manoeuvre)",
                                  "shortest record accepted")
    # ---- elevator trim: δ_trim = k0 + kα·α + kcg·(cg − cg_ref) -------------------------
    trim_k0_deg: float = param("deg", "est.",
                               "trim k0 (the trimmable stabiliser takes most of the trim)")
    trim_k_alpha: float = param("deg/deg", "est. (sign of −Cmα/Cmδ; share left to the elevator)",
                                "trim kα: more angle of attack, more nose-up (negative) elevator")
    trim_k_cg_deg_per_pct: float = param("deg/%MAC", "est.",
                                         "trim kcg: an aft CG needs less nose-up elevator")
    cg_ref_pct: float = param("% MAC", "docs/physics.md §6 (middle of the CG grid)",
                              "reference CG of the trim law")
    trim_min_deg: float = param("deg", "est.",
                                "lower bound of the trim (then the electrical limit)")
    trim_max_deg: float = param("deg", "est.",
                                "upper bound of the trim (then the electrical limit)")
    # ---- gust reaction: δ = k·(gust/V) through 1/(1 + τ·s) ----------------------------
    gust_gain_elevator: float = param("deg/deg", "est. (≈ ½·Cmα/Cmδ of a transport)",
                                      "elevator order per degree of gust angle of attack w_g/V")
    gust_gain_aileron: float = param("deg/deg", "est. (≈ ½·Clβ/Clδa of a transport)",
                                     "aileron order per degree of gust sideslip v_g/V")
    gust_lag_s: float = param("s", "est. (closed-loop pitch/roll bandwidth ≈ 2 rad/s)",
                              "time constant τ of the gust reaction")
    # ---- shapes (docs/physics.md §7 suggested shapes; all est.) --------------------------------
    nose_up_amp_deg: tuple[float, float] = param("deg", "docs/physics.md §7 (est.)",
                                                 "nose-up step magnitude")
    nose_up_hold_s: tuple[float, float] = param("s", "docs/physics.md §7 (est.)",
                                                "step width at half amplitude")
    aoa_amp_deg: tuple[float, float] = param("deg", "docs/physics.md §7 (est.)",
                                             "AoA-protection excursion magnitude")
    aoa_ramp_s: tuple[float, float] = param("s", "est. ('slow', docs/physics.md §7)",
                                            "ramp duration into and out of it")
    aoa_hold_s: tuple[float, float] = param("s", "est.", "time held at the excursion")
    pitch_authority_frac: tuple[float, float] = param(
        "-", "docs/physics.md §7 'transients to the limits' (est.)",
        "peak as a fraction of the authority to the limit")
    pitch_hold_s: tuple[float, float] = param("s", "est.",
                                              "time held at each pitch-protection peak")
    pitch_gap_s: tuple[float, float] = param("s", "est.",
                                             "pause between the nose-up and nose-down transients")
    yaw_amp_deg: tuple[float, float] = param("deg", "docs/physics.md §7 (est.)",
                                             "aileron held in yaw-angle mode")
    yaw_hold_s: tuple[float, float] = param("s", "est.", "hold width at half amplitude")
    turn_amp_deg: tuple[float, float] = param("deg", "docs/physics.md §7 (est.)",
                                              "aileron roll-in/roll-out pulse")
    turn_roll_rate_deg_s: float = param(
        "deg/s", "docs/physics.md §7: normal set 7.5 °/s (est.: half the 15 °/s full-stick "
        "roll-rate demand of the Airbus normal law, Airbus FCOM DSC-27-20-10-30; flight-guidance "
        "roll-rate limits are 3.5–5 °/s); stress set 15 °/s (full stick)",
        "aircraft roll rate of the roll-in: pulse width = bank/rate")
    turn_bank_deg: tuple[float, float] = param("deg", "est.", "bank angle φ of the turn")
    turn_hold_s: tuple[float, float] = param("s", "est.", "time in the steady turn")
    turn_elevator_deg_per_g: float = param(
        "deg/g", "est. (Δα = C_L/C_Lα per g, times Cmα/Cmδ, at q_ref)",
        "elevator per g of load factor: turn pull = k_g·(1/cos φ − 1)")

    def __post_init__(self):
        problems = []
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
                problems.append(f"{f.name} must be finite, got {value!r}")
            elif isinstance(value, tuple) and (len(value) != 2 or value[0] > value[1]):
                problems.append(f"{f.name} must be a range (lo, hi) with lo ≤ hi, got {value!r}")
        if problems:
            raise ValueError("invalid ManoeuvreParams: " + "; ".join(problems))
        for name in ("qbar_ref_pa", "scale_min", "rate_max_deg_s", "manoeuvre_rate_deg_s",
                     "transition_min_s", "turn_roll_rate_deg_s", "gust_lag_s"):
            if not getattr(self, name) > 0:
                problems.append(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.scale_min > self.scale_max:
            problems.append("scale_min must be ≤ scale_max")
        if self.trim_min_deg > self.trim_max_deg:
            problems.append("trim_min_deg must be ≤ trim_max_deg")
        if self.manoeuvre_rate_deg_s > self.rate_max_deg_s:
            problems.append("manoeuvre_rate_deg_s must be ≤ rate_max_deg_s")
        if problems:
            raise ValueError("invalid ManoeuvreParams: " + "; ".join(problems))


MANOEUVRE_PARAMS = ManoeuvreParams(
    qbar_ref_pa=10_200.0,
    scale_min=0.5,
    scale_max=3.0,
    rate_max_deg_s=30.0,
    manoeuvre_rate_deg_s=25.0,
    transition_min_s=0.3,
    lead_s=3.0,
    start_spread_s=10.0,
    tail_s=2.0,
    min_duration_s=20.0,
    trim_k0_deg=0.5,
    trim_k_alpha=-0.4,
    trim_k_cg_deg_per_pct=0.05,
    cg_ref_pct=30.0,
    trim_min_deg=-10.0,
    trim_max_deg=5.0,
    gust_gain_elevator=0.5,
    gust_gain_aileron=0.5,
    gust_lag_s=0.5,
    nose_up_amp_deg=(2.0, 5.0),
    nose_up_hold_s=(5.0, 10.0),
    aoa_amp_deg=(5.0, 15.0),
    aoa_ramp_s=(2.0, 4.0),
    aoa_hold_s=(2.0, 5.0),
    pitch_authority_frac=(0.85, 1.0),
    pitch_hold_s=(0.5, 1.5),
    pitch_gap_s=(2.0, 4.0),
    yaw_amp_deg=(2.0, 5.0),
    yaw_hold_s=(5.0, 10.0),
    turn_amp_deg=(5.0, 10.0),
    turn_roll_rate_deg_s=7.5,
    turn_bank_deg=(25.0, 33.0),
    turn_hold_s=(4.0, 7.0),
    turn_elevator_deg_per_g=4.0,
)

#: The ``stress`` manoeuvre set (docs/physics.md §7): the turn rolls in at the normal law's
#: full-stick 15 °/s (Airbus FCOM DSC-27-20-10-30) and its bank is the 33° of the bank
#: protection; every amplitude range is at its high end and the AoA-protection ramps are the
#: shortest. Holds, gaps and the rate bounds are those of the normal set.
STRESS_MANOEUVRE_PARAMS = dataclasses.replace(
    MANOEUVRE_PARAMS,
    nose_up_amp_deg=(MANOEUVRE_PARAMS.nose_up_amp_deg[1],) * 2,
    aoa_amp_deg=(MANOEUVRE_PARAMS.aoa_amp_deg[1],) * 2,
    aoa_ramp_s=(MANOEUVRE_PARAMS.aoa_ramp_s[0],) * 2,
    pitch_authority_frac=(MANOEUVRE_PARAMS.pitch_authority_frac[1],) * 2,
    yaw_amp_deg=(MANOEUVRE_PARAMS.yaw_amp_deg[1],) * 2,
    turn_amp_deg=(MANOEUVRE_PARAMS.turn_amp_deg[1],) * 2,
    turn_roll_rate_deg_s=15.0,
    turn_bank_deg=(MANOEUVRE_PARAMS.turn_bank_deg[1],) * 2,
)

#: Actuator-level shape table of each manoeuvre set (:data:`scenarios.catalog.MANOEUVRE_SETS`).
MANOEUVRE_SET_PARAMS: Mapping[str, ManoeuvreParams] = types.MappingProxyType({
    "normal": MANOEUVRE_PARAMS,
    "stress": STRESS_MANOEUVRE_PARAMS,
})


def set_params(manoeuvre_set: str) -> ManoeuvreParams:
    """The actuator-level shape table of manoeuvre set *manoeuvre_set* (``normal`` or
    ``stress``, docs/physics.md §7); an unknown name raises ``ValueError`` naming the allowed
    ones."""
    check_name("manoeuvre set", manoeuvre_set, MANOEUVRE_SETS)
    return MANOEUVRE_SET_PARAMS[manoeuvre_set]


#: The reference flight point of the amplitudes (ISA, M 0.82 at FL370, mid CG; est. α).
REFERENCE_FLIGHT: Mapping[str, float] = types.MappingProxyType({
    "qbar_pa": MANOEUVRE_PARAMS.qbar_ref_pa,
    "tas_ms": 242.0,
    "alt_ft": 37_000.0,
    "alpha_deg": 2.5,
    "cg_pct": MANOEUVRE_PARAMS.cg_ref_pct,
    "mach": 0.82,
})


# ---- flight-point laws -------------------------------------------------------------------
def amplitude_scale(qbar_pa: float, params: ManoeuvreParams = MANOEUVRE_PARAMS) -> float:
    """Amplitude factor f = clip(q_ref/q̄, scale_min, scale_max) [-] (docs/physics.md §7)."""
    return min(max(params.qbar_ref_pa / qbar_pa, params.scale_min), params.scale_max)


def elevator_trim_deg(alpha_deg: float, cg_pct: float, actuator: ActuatorParams,
                      params: ManoeuvreParams = MANOEUVRE_PARAMS) -> float:
    """Elevator trim δ_trim = k0 + kα·α + kcg·(cg − cg_ref) [deg] (est. law, see ManoeuvreParams).

    Clipped to [trim_min, trim_max] and to the electrical limits of ``actuator``.
    """
    trim = (params.trim_k0_deg + params.trim_k_alpha * alpha_deg
            + params.trim_k_cg_deg_per_pct * (cg_pct - params.cg_ref_pct))
    lo = max(params.trim_min_deg, actuator.delta_min_deg)
    hi = min(params.trim_max_deg, actuator.delta_max_deg)
    return min(max(trim, lo), hi)


# ---- validation --------------------------------------------------------------------------
def _check_flight(flight: Mapping, where: str = "") -> dict[str, float]:
    values = {}
    for key in FLIGHT_KEYS:
        if key not in flight:
            raise ValueError(f"{where}flight is missing {key!r} [{FLIGHT_KEYS[key]}]; "
                             f"required keys: {', '.join(FLIGHT_KEYS)}")
        try:
            value = float(flight[key])
        except (TypeError, ValueError):
            raise ValueError(f"{where}flight[{key!r}] must be a number, got "
                             f"{flight[key]!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"{where}flight[{key!r}] must be finite, got {value!r}")
        values[key] = value
    for key in ("qbar_pa", "tas_ms"):
        if values[key] <= 0:
            raise ValueError(f"{where}flight[{key!r}] must be > 0 [{FLIGHT_KEYS[key]}], got "
                             f"{values[key]!r}")
    if values["mach"] < 0:
        raise ValueError(f"{where}flight['mach'] must be ≥ 0, got {values['mach']!r}")
    return values


def _check_time(t, params: ManoeuvreParams) -> tuple[np.ndarray, float]:
    """Times relative to t[0] and the step ts; t must be uniform and long enough."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"t must be a 1-D array of at least 2 times [s], got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t must be finite")
    ts = float(t[1] - t[0])
    if not ts > 0 or not np.allclose(np.diff(t), ts, rtol=1e-6, atol=1e-9):
        raise ValueError("t must be uniform and increasing (constant step ts)")
    duration = t.size * ts
    if duration < params.min_duration_s - 1e-9:
        raise ValueError(f"t covers {duration:g} s; manoeuvres need at least "
                         f"{params.min_duration_s:g} s (ManoeuvreParams.min_duration_s)")
    return t - t[0], ts


def _check_actuator(surface: str, actuator) -> None:
    if not isinstance(actuator, ActuatorParams):
        raise TypeError(f"actuator must be an ActuatorParams, got {type(actuator).__name__}")
    if actuator.surface != surface:
        raise ValueError(f"actuator is for surface {actuator.surface!r} but surface={surface!r}")


def _check_start(start_s, where: str = "") -> float | None:
    """A fixed manoeuvre start [s] (None/NaN: sampled); must be ≥ 0."""
    if start_s is None:
        return None
    try:
        value = float(start_s)
    except (TypeError, ValueError):
        raise ValueError(f"{where}start_s must be a number of seconds, got {start_s!r}") from None
    if math.isnan(value):
        return None
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{where}start_s must be a finite time ≥ 0 s, got {start_s!r}")
    return value


# ---- the profiles ------------------------------------------------------------------------
def _lerp(bounds: tuple[float, float], u: float) -> float:
    """Map a uniform draw u ∈ [0, 1) to U(lo, hi)."""
    return bounds[0] + (bounds[1] - bounds[0]) * u


def _transitions(manoeuvre: str, surface: str, u: Sequence[float], scale: float, trim: float,
                 actuator: ActuatorParams, p: ManoeuvreParams) -> list[tuple[float, float, float]]:
    """(start [s] from the manoeuvre start, size ΔA [deg], duration D [s]) of each transition.

    ``u``: the run's uniforms; u[0] is the start time (used by the caller), u[1:] the shape
    parameters in the order of the ranges used below.
    """
    down_room = trim - actuator.delta_min_deg   # authority towards the lower (nose-up) limit
    up_room = actuator.delta_max_deg - trim

    def duration(size: float, nominal: float = 0.0) -> float:
        # raised cosine: peak rate π·|ΔA|/(2·D) ≤ manoeuvre_rate
        return max(nominal, p.transition_min_s,
                   math.pi * abs(size) / (2.0 * p.manoeuvre_rate_deg_s))

    def signed(size: float, positive: bool) -> float:
        return min(size, up_room) if positive else -min(size, down_room)

    if manoeuvre == "nose_up" and surface == "elevator":
        a = signed(scale * _lerp(p.nose_up_amp_deg, u[1]), positive=False)
        d = duration(a)
        width = max(_lerp(p.nose_up_hold_s, u[2]), d)
        return [(0.0, a, d), (width, -a, d)]
    if manoeuvre == "aoa_protection" and surface == "elevator":
        a = signed(scale * _lerp(p.aoa_amp_deg, u[1]), positive=False)
        ramp = duration(a, _lerp(p.aoa_ramp_s, u[2]))
        hold = _lerp(p.aoa_hold_s, u[3])
        return [(0.0, a, ramp), (ramp + hold, -a, ramp)]
    if manoeuvre == "pitch_protection" and surface == "elevator":
        a1 = -down_room * min(1.0, scale * _lerp(p.pitch_authority_frac, u[1]))
        d1 = duration(a1)
        hold1 = _lerp(p.pitch_hold_s, u[2])
        second = 2.0 * d1 + hold1 + _lerp(p.pitch_gap_s, u[3])
        a2 = up_room * min(1.0, scale * _lerp(p.pitch_authority_frac, u[4]))
        d2 = duration(a2)
        hold2 = _lerp(p.pitch_hold_s, u[5])
        return [(0.0, a1, d1), (d1 + hold1, -a1, d1),
                (second, a2, d2), (second + d2 + hold2, -a2, d2)]
    if manoeuvre == "yaw_angle_mode" and surface == "aileron":
        a = signed(scale * _lerp(p.yaw_amp_deg, u[1]), positive=u[3] < 0.5)
        d = duration(a)
        width = max(_lerp(p.yaw_hold_s, u[2]), d)
        return [(0.0, a, d), (width, -a, d)]
    if manoeuvre == "turn_coordination":
        bank = _lerp(p.turn_bank_deg, u[2])
        turn = _lerp(p.turn_hold_s, u[3])
        amp = scale * _lerp(p.turn_amp_deg, u[1])
        d_free = duration(amp)
        # roll-in/out pulse width at half amplitude: bank/roll rate, and at least the
        # transition, so the pulse reaches its plateau; the same timing on both surfaces
        roll = max(bank / p.turn_roll_rate_deg_s, d_free)
        if surface == "aileron":
            a = signed(amp, positive=u[4] < 0.5)
            d = duration(a)
            return [(0.0, a, d), (roll, -a, d), (roll + turn, -a, d), (2.0 * roll + turn, a, d)]
        load = 1.0 / math.cos(math.radians(bank)) - 1.0   # extra load factor of the turn [g]
        pull = signed(scale * p.turn_elevator_deg_per_g * load, positive=False)
        ramp = duration(pull, roll + d_free)              # over the roll-in / roll-out
        return [(0.0, pull, ramp), (roll + turn, -pull, ramp)]
    return []   # cruise, and the manoeuvres of the other axis: trim + gust reaction only


def _sequential(steps: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
    """The transitions in time order, each starting no earlier than the previous one ends."""
    out, end = [], 0.0
    for start, size, dur in sorted(steps):
        start = max(start, end)
        out.append((start, size, dur))
        end = start + dur
    return out


def _order(manoeuvre: str, surface: str, t_rel: np.ndarray, ts: float, flight: dict[str, float],
           rng: np.random.Generator, actuator: ActuatorParams, p: ManoeuvreParams,
           turbulence: DrydenParams, start_s: float | None = None,
           engine: str | None = None) -> np.ndarray:
    """One run's order from validated inputs (see :func:`surface_order_deg`); *engine* of
    the gust's draws and filter (:func:`scenarios.turbulence.lagged_gust`)."""
    u = rng.random(N_SHAPE_DRAWS).tolist()
    scale = amplitude_scale(flight["qbar_pa"], p)
    trim = (elevator_trim_deg(flight["alpha_deg"], flight["cg_pct"], actuator, p)
            if surface == "elevator" else 0.0)
    steps = _sequential(_transitions(manoeuvre, surface, u, scale, trim, actuator, p))

    # Control-law reaction to turbulence: gain·(gust/V) [deg] through 1/(1 + τ·s).
    component, gain = (("w", p.gust_gain_elevator) if surface == "elevator"
                       else ("v", p.gust_gain_aileron))
    order = lagged_gust(t_rel.size, ts, flight["tas_ms"], flight["alt_ft"], rng,
                        component=component, lag_s=p.gust_lag_s, params=turbulence,
                        engine=engine)
    order *= math.degrees(gain / flight["tas_ms"])

    # Trim + manoeuvre, one pass: constant levels between the raised-cosine transitions.
    level, done = 0.0, 0     # manoeuvre level: its transitions add up to exactly 0 at the end
    if steps:
        length = steps[-1][0] + steps[-1][2]
        room = t_rel.size * ts - p.tail_s - p.lead_s - length
        t0 = p.lead_s + u[0] * min(p.start_spread_s, max(room, 0.0))
        if start_s is not None and math.isfinite(start_s):
            t0 = float(start_s)
        for start, size, dur in steps:
            i0, i1 = np.searchsorted(t_rel, (t0 + start, t0 + start + dur)).tolist()
            order[done:i0] += trim + level
            order[i0:i1] += trim + level + size * 0.5 * (
                1.0 - np.cos((np.pi / dur) * (t_rel[i0:i1] - (t0 + start))))
            level += size
            done = i1
    order[done:] += trim + level
    return np.clip(order, actuator.delta_min_deg, actuator.delta_max_deg, out=order)


# ---- public API --------------------------------------------------------------------------
def surface_order_deg(manoeuvre: str, surface: str, t, flight: Mapping[str, float],
                      rng: np.random.Generator, actuator: ActuatorParams, *,
                      params: ManoeuvreParams = MANOEUVRE_PARAMS,
                      turbulence: DrydenParams = MODERATE,
                      start_s: float | None = None) -> np.ndarray:
    """One run's surface-deflection order [deg] at the times ``t``, shape (n_steps,).

    Parameters
    ----------
    manoeuvre : str
        One of :data:`scenarios.catalog.MANOEUVRES`.
    surface : str
        One of :data:`scenarios.catalog.SURFACES`; must match ``actuator.surface``.
    t : array (n_steps,) [s]
        Uniform sample times (step ts), covering at least ``params.min_duration_s``.
    flight : mapping
        The true flight point: :data:`FLIGHT_KEYS` (q̄ [Pa], V [m/s], altitude [ft],
        α [deg], CG [% MAC], Mach [-]); other keys are ignored.
    rng : numpy.random.Generator
        The run's stream: timing, shape and turbulence, drawn in a fixed order.
    actuator : ActuatorParams
        Gives the electrical deflection limits.
    params, turbulence : keyword-only
        Manoeuvre and turbulence tables.
    start_s : float, keyword-only
        Fixed start of the manoeuvre [s] from t[0] (≥ 0); None or NaN: sampled.
    """
    check_name("manoeuvre", manoeuvre, MANOEUVRES)
    check_name("surface", surface, SURFACES)
    _check_actuator(surface, actuator)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    t_rel, ts = _check_time(t, params)
    return _order(manoeuvre, surface, t_rel, ts, _check_flight(flight), rng, actuator, params,
                  turbulence, _check_start(start_s))


def orders_for_runs(manoeuvres: Sequence[str], surface: str, t, flight: Mapping,
                    rngs: Sequence[np.random.Generator], actuator: ActuatorParams, *,
                    params: ManoeuvreParams | Sequence[ManoeuvreParams] = MANOEUVRE_PARAMS,
                    turbulence: DrydenParams = MODERATE,
                    start_s: Sequence[float] | None = None,
                    engine: str | None = None) -> np.ndarray:
    """Orders [deg] of a batch of runs, shape (n_runs, n_steps).

    Run i is exactly ``surface_order_deg(manoeuvres[i], surface, t, {k: flight[k][i]},
    rngs[i], actuator, params=params_i)``: it never depends on the other runs of the batch.
    ``flight`` maps each of :data:`FLIGHT_KEYS` to an array of shape (n_runs,). ``params``
    is one shape table for every run or one per run (e.g. the table of each run's manoeuvre
    set, :func:`set_params`). ``start_s`` (n_runs,), when given, fixes each run's manoeuvre
    start [s] (NaN: sampled). ``engine``: how the gusts are drawn and filtered
    (:func:`scenarios.turbulence.lagged_gust`; the same values with either).
    """
    if isinstance(manoeuvres, str):
        raise ValueError("manoeuvres must be a sequence of names, one per run, not a single string")
    n_runs = len(rngs)
    if len(manoeuvres) != n_runs:
        raise ValueError(f"{len(manoeuvres)} manoeuvres for {n_runs} rngs: need one per run")
    check_name("surface", surface, SURFACES)
    _check_actuator(surface, actuator)
    per_run = [params] * n_runs if isinstance(params, ManoeuvreParams) else list(params)
    if len(per_run) != n_runs or not all(isinstance(p, ManoeuvreParams) for p in per_run):
        raise ValueError(f"params must be one ManoeuvreParams or one per run ({n_runs}), "
                         f"got {params!r:.80}")
    t_rel, ts = _check_time(t, max(per_run, key=lambda p: p.min_duration_s) if per_run
                            else MANOEUVRE_PARAMS)
    columns = {}
    for key in FLIGHT_KEYS:
        if key not in flight:
            raise ValueError(f"flight is missing {key!r} [{FLIGHT_KEYS[key]}]; "
                             f"required keys: {', '.join(FLIGHT_KEYS)}")
        columns[key] = np.asarray(flight[key])
        if columns[key].shape != (n_runs,):
            raise ValueError(f"flight[{key!r}] must have shape ({n_runs},), got "
                             f"{columns[key].shape}")
    orders = np.empty((n_runs, t_rel.size))
    for i in range(n_runs):
        where = f"run {i}: "
        try:
            check_name("manoeuvre", manoeuvres[i], MANOEUVRES)
        except ValueError as exc:
            raise ValueError(where + str(exc)) from None
        if not isinstance(rngs[i], np.random.Generator):
            raise TypeError(f"{where}rng must be a numpy.random.Generator, got "
                            f"{type(rngs[i]).__name__}")
        run_flight = _check_flight({k: c[i] for k, c in columns.items()}, where)
        start = None if start_s is None else _check_start(start_s[i], where)
        orders[i] = _order(manoeuvres[i], surface, t_rel, ts, run_flight, rngs[i], actuator,
                           per_run[i], turbulence, start, engine)
    return orders
