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
"""

from __future__ import annotations

import numpy as np

from ..catalog import MANOEUVRES
from .data import PILOT, PilotParams

#: Number of uniform draws per run (fixed, whatever the manoeuvre).
N_DRAWS = 8


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


def inputs_for_runs(manoeuvres, t: np.ndarray, gens, params: PilotParams = PILOT):
    """Stacked pilot inputs of a batch, three (n, T) arrays; ``gens`` the runs' manoeuvre
    generators (each advanced by :data:`N_DRAWS` uniforms)."""
    out = [pilot_inputs(str(m), t, g.uniform(size=N_DRAWS), params) for m, g in zip(manoeuvres, gens)]
    return tuple(np.array([o[j] for o in out]) for j in range(3))
