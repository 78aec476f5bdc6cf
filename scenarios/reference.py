"""Straightforward per-run reference simulation: a Python loop over runs and periods with
``scipy.integrate.solve_ivp`` at tight tolerance inside each FCC period.

It shares the open-loop preparation (orders, noise, fault arrays) and the sensor models with
:mod:`scenarios.simulate` and differs only in how the plant is integrated, so it serves two
purposes: the accuracy reference of the fixed-step scheme (PHYSICS §2: RMS error far below
the sensor noise) and the speed baseline of ``fdd-campaign bench``.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from .faults import NEVER
from .params import SENSORS, SensorParams
from .servo import PlantArrays, float_rate, rod_rate
from .simulate import Prepared, Trajectory, acquire_com, applied_current


def _take(pl: PlantArrays, j: int) -> PlantArrays:
    return PlantArrays(**{k: np.asarray(v)[j:j + 1] for k, v in vars(pl).items()})


def _select(p: Prepared, j: int) -> Prepared:
    """The single run *j* of a prepared batch (arrays keep a leading axis of length 1)."""
    from dataclasses import replace

    from .faults import FaultArrays

    fa = p.faults
    fa1 = FaultArrays(**{k: (None if v is None else np.asarray(v)[j:j + 1])
                         for k, v in vars(fa).items()})
    fields = {k: np.asarray(v)[j:j + 1] for k, v in vars(p).items()
              if isinstance(v, np.ndarray)}
    return replace(p, plant=_take(p.plant, j), faults=fa1, **fields)


def integrate_reference(p: Prepared, sensors: SensorParams = SENSORS, *, rtol: float = 1e-9,
                        atol: float = 1e-10) -> Trajectory:
    """Same closed loop as :func:`scenarios.simulate.integrate`, one run at a time, with
    ``solve_ivp`` (RK45, *rtol*/*atol*) over each period instead of one RK4 step."""
    n, T = p.u.shape
    out = {k: np.empty((n, T)) for k in ("x", "delta", "i_cmd", "i_app", "y_com")}
    act, ts = p.act, p.ts
    d_min, d_max = np.radians(act.stop_min_deg), np.radians(act.stop_max_deg)
    for j in range(n):
        q = _select(p, j)
        pl, fa = q.plant, q.faults
        x = np.clip(q.u[:, 0].copy(), pl.x_min, pl.x_max)
        delta = np.arcsin(x / pl.r_mm)
        i_prev = np.zeros(1)
        y_hold = np.zeros(1)
        for k in range(T):
            y, y_hold = acquire_com(x, k, q, sensors, y_hold)
            i_new = np.clip(pl.K * (fa.u_loop[:, k] - y), -pl.i_max, pl.i_max)
            i_app = applied_current(i_prev, k, q)
            for name, v in (("x", x), ("delta", delta), ("i_cmd", i_new), ("i_app", i_app),
                            ("y_com", y)):
                out[name][j, k] = v[0]
            loaded = bool(k < fa.k_disc[0])
            jammed = bool(k >= fa.k_jam[0]) and fa.k_jam[0] < NEVER
            if not jammed:
                def rhs(_t, s, i=i_app, ld=loaded):
                    return rod_rate(np.clip(s, pl.x_min, pl.x_max), i, pl, np.array([ld]))

                sol = solve_ivp(rhs, (0.0, ts), x, method="RK45", rtol=rtol, atol=atol)
                x_next = np.clip(sol.y[:, -1], pl.x_min, pl.x_max)
            else:
                x_next = x
            if loaded:
                delta = np.arcsin(x_next / pl.r_mm)
            else:
                sol = solve_ivp(lambda _t, d: float_rate(d, pl), (0.0, ts), delta,
                                method="LSODA", rtol=rtol, atol=atol)
                delta = np.clip(sol.y[:, -1], d_min, d_max)
            x = x_next
            i_prev = i_new
    return Trajectory(**out)
