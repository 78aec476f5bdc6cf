"""The six ADDSAFE manoeuvres as pilot inputs flown through the laws (docs/physics.md §7 phase 2).

Sidestick: a load-factor order n_zc [g] (pitch) and a roll-rate order p_c [rad/s] (roll);
pedals: a sideslip order β_c [rad]. Each input rises and falls with a smooth step of
``smooth_s`` (cubic smoothstep). Per run, 8 uniform numbers are drawn from the run's
manoeuvre stream first, whatever the manoeuvre, so the draws never depend on the batch.

- ``cruise``: no input (the laws fly the turbulence);
- ``nose_up``: a pull of n_zc held for ``nose_up_hold_s``;
- ``aoa_protection``: a slow pull (ramp ``aoa_ramp_s``) held, then released;
- ``pitch_protection``: a pull then a push of ``pitch_g``, each held ``pitch_hold_s``;
- ``yaw_angle_mode``: a pedal sideslip order held ``yaw_hold_s``;
- ``turn_coordination``: a roll-in at ``turn_rate_deg_s`` to the bank angle, a turn, a
  roll-out, each edge smoothed over ``turn_smooth_s``.

Manoeuvre sets (:data:`scenarios.catalog.MANOEUVRE_SETS`, docs/physics.md §7): ``normal``
flies :data:`~scenarios.aircraft.data.PILOT` (turn roll-in at 7.5 °/s over 1.5-s edges);
``stress`` flies :data:`PILOT_STRESS` (roll-in at the normal law's full-stick 15 °/s over the
0.5-s edges of the other inputs, to a 33° bank; every load-factor and sideslip range at its
high end, the shortest AoA ramp).
"""

from __future__ import annotations

import numpy as np

import dataclasses
import types

from ..catalog import MANOEUVRE_SETS, MANOEUVRES, check_name
from .data import PILOT, PilotParams

#: Number of uniform draws per run (fixed, whatever the manoeuvre).
N_DRAWS = 8

#: The ``stress`` manoeuvre set at the aircraft level (docs/physics.md §7): the turn at the
#: Airbus normal law's full-stick roll-rate demand, 15 °/s (Airbus FCOM DSC-27-20-10-30),
#: with the 0.5-s edges of the other stick inputs, to the 33° of the bank protection; every
#: other range at its aggressive end. Holds and the start time are those of the normal set.
PILOT_STRESS = dataclasses.replace(
    PILOT,
    nose_up_g=(PILOT.nose_up_g[1],) * 2,
    aoa_g=(PILOT.aoa_g[1],) * 2,
    aoa_ramp_s=(PILOT.aoa_ramp_s[0],) * 2,
    pitch_g=(PILOT.pitch_g[1],) * 2,
    yaw_beta_deg=(PILOT.yaw_beta_deg[1],) * 2,
    turn_rate_deg_s=15.0,
    turn_bank_deg=(PILOT.turn_bank_deg[1],) * 2,
    turn_smooth_s=PILOT.smooth_s,
)

#: Pilot-input table of each manoeuvre set.
PILOT_SETS = types.MappingProxyType({"normal": PILOT, "stress": PILOT_STRESS})


def set_params(manoeuvre_set: str) -> PilotParams:
    """The pilot-input table of manoeuvre set *manoeuvre_set* (``normal`` or ``stress``); an
    unknown name raises ``ValueError`` naming the allowed ones."""
    check_name("manoeuvre set", manoeuvre_set, MANOEUVRE_SETS)
    return PILOT_SETS[manoeuvre_set]


def _smooth(t, t0, rise):
    """Smooth step from 0 (t ≤ t0) to 1 (t ≥ t0 + rise) [-] (cubic smoothstep)."""
    s = np.clip((t - t0) / rise, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _lerp(bounds, u):
    return bounds[0] + (bounds[1] - bounds[0]) * u


def pilot_inputs(manoeuvre: str, t: np.ndarray, u: np.ndarray, params: PilotParams = PILOT):
    """(n_zc [g], p_c [rad/s], β_c [rad]) of one run, each shaped like ``t`` [s].

    ``u``: the run's :data:`N_DRAWS` uniform numbers in [0, 1).
    """
    if manoeuvre not in MANOEUVRES:
        raise ValueError(f"unknown manoeuvre {manoeuvre!r}; allowed: {', '.join(MANOEUVRES)}")
    zero = np.zeros_like(t)
    nz, p, beta = zero.copy(), zero.copy(), zero.copy()
    r = params.smooth_s
    t0 = _lerp(params.start_s, u[0])
    if manoeuvre == "nose_up":
        hold = _lerp(params.nose_up_hold_s, u[2])
        nz = _lerp(params.nose_up_g, u[1]) * (_smooth(t, t0, r) - _smooth(t, t0 + r + hold, r))
    elif manoeuvre == "aoa_protection":
        ramp, hold = _lerp(params.aoa_ramp_s, u[2]), _lerp(params.aoa_hold_s, u[3])
        nz = _lerp(params.aoa_g, u[1]) * (_smooth(t, t0, ramp) - _smooth(t, t0 + ramp + hold, ramp))
    elif manoeuvre == "pitch_protection":
        hold = _lerp(params.pitch_hold_s, u[2])
        t1 = t0 + 2 * r + hold + params.pitch_gap_s
        nz = (_lerp(params.pitch_g, u[1]) * (_smooth(t, t0, r) - _smooth(t, t0 + r + hold, r))
              - _lerp(params.pitch_g, u[3]) * (_smooth(t, t1, r) - _smooth(t, t1 + r + hold, r)))
    elif manoeuvre == "yaw_angle_mode":
        hold = _lerp(params.yaw_hold_s, u[2])
        sign = 1.0 if u[4] < 0.5 else -1.0
        beta = sign * np.radians(_lerp(params.yaw_beta_deg, u[1])) * (
            _smooth(t, t0, r) - _smooth(t, t0 + r + hold, r))
    elif manoeuvre == "turn_coordination":
        rate = np.radians(params.turn_rate_deg_s)
        t_roll = np.radians(_lerp(params.turn_bank_deg, u[1])) / rate
        hold = _lerp(params.turn_hold_s, u[2])
        sign = 1.0 if u[4] < 0.5 else -1.0
        t1 = t0 + t_roll + hold
        rt = params.turn_smooth_s
        # a rate pulse of width t_roll (smoothed edges keep its area: rate·t_roll)
        p = sign * rate * ((_smooth(t, t0, rt) - _smooth(t, t0 + t_roll, rt))
                           - (_smooth(t, t1, rt) - _smooth(t, t1 + t_roll, rt)))
    return nz, p, beta


def inputs_for_runs(manoeuvres, t: np.ndarray, gens, params: PilotParams | list = PILOT):
    """Stacked pilot inputs of a batch, three (n, T) arrays; ``gens`` the runs' manoeuvre
    generators (each advanced by :data:`N_DRAWS` uniforms); ``params`` one table for every
    run or one per run (e.g. each run's manoeuvre set, :func:`set_params`)."""
    manoeuvres = list(manoeuvres)
    per_run = [params] * len(manoeuvres) if isinstance(params, PilotParams) else list(params)
    if len(per_run) != len(manoeuvres):
        raise ValueError(f"params must be one PilotParams or one per run ({len(manoeuvres)}), "
                         f"got {len(per_run)}")
    out = [pilot_inputs(str(m), t, g.uniform(size=N_DRAWS), p)
           for m, g, p in zip(manoeuvres, gens, per_run)]
    return tuple(np.array([o[j] for o in out]) for j in range(3))
