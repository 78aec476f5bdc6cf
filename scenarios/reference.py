"""Straightforward per-run reference simulation: a Python loop over runs and periods with
``scipy.integrate.solve_ivp`` at tight tolerance inside each FCC period.

It shares the open-loop preparation (orders, noise, fault arrays) and the sensor models with
:mod:`scenarios.simulate` and differs only in how the plant is integrated, so it serves two
purposes: the accuracy reference of the fixed-step scheme (docs/physics.md §2: RMS error far below
the sensor noise) and the speed baseline of ``fdd-campaign bench``.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from .faults import NEVER, jam_onset_position
from .params import SENSORS, SensorParams
from .servo import PlantArrays, float_rate_coef, rod_rate
from .acquisition import Prepared, Trajectory, acquire_com, applied_current


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
                        atol: float = 1e-10, per_run: bool = True) -> Trajectory:
    """Same closed loop as :func:`scenarios.simulate.integrate`, with ``solve_ivp`` (RK45
    for the rod, LSODA for a floating surface; *rtol*/*atol*) over each period instead of
    one RK4 step.

    per_run : True (default) integrates one run after the other — the straightforward
        per-run implementation that ``fdd-campaign bench`` times as its baseline. False
        integrates the runs of *p* as one ODE system per period (the error control then
        holds for every component at once): the same accuracy reference, at the cost of a
        single run, which is what the accuracy tests use.
    """
    if not per_run:
        return _integrate_block(p, sensors, rtol, atol)
    parts = [_integrate_block(_select(p, j), sensors, rtol, atol) for j in range(p.u.shape[0])]
    return Trajectory(**{name: np.concatenate([getattr(t, name) for t in parts])
                         for name in ("x", "delta", "i_cmd", "i_app", "y_com")})


def _integrate_block(p: Prepared, sensors: SensorParams, rtol: float, atol: float) -> Trajectory:
    n, T = p.u.shape
    out = {k: np.empty((n, T)) for k in ("x", "delta", "i_cmd", "i_app", "y_com")}
    pl, fa, act, ts = p.plant, p.faults, p.act, p.ts
    d_min, d_max = np.radians(act.stop_min_deg), np.radians(act.stop_max_deg)
    x = np.clip(p.u[:, 0].copy(), pl.x_min, pl.x_max)
    delta = np.arcsin(x / pl.r_mm)
    i_prev = np.zeros(n)
    y_hold = np.zeros(n)
    any_jam = bool((fa.k_jam < NEVER).any())
    for k in range(T):
        if any_jam:   # an "offset" solid jam: the rod jumps at its onset (docs/physics.md §5)
            x_prev, x = x, jam_onset_position(x, k, fa, pl.x_min, pl.x_max)
            if x is not x_prev:
                delta = np.where(x != x_prev, np.arcsin(x / pl.r_mm), delta)
        y, y_hold = acquire_com(x, k, p, sensors, y_hold)
        i_new = np.clip(pl.K * (fa.u_loop[:, k] - y), -pl.i_max, pl.i_max)
        i_app = applied_current(i_prev, k, p)
        for name, v in (("x", x), ("delta", delta), ("i_cmd", i_new), ("i_app", i_app),
                        ("y_com", y)):
            out[name][:, k] = v
        loaded = k < fa.k_disc
        moving = ~((k >= fa.k_jam) & (fa.k_jam < NEVER))   # a seized rod stays where it is

        def rhs(_t, s, i=i_app, ld=loaded, mv=moving):
            return np.where(mv, rod_rate(np.clip(s, pl.x_min, pl.x_max), i, pl, ld), 0.0)

        sol = solve_ivp(rhs, (0.0, ts), x, method="RK45", rtol=rtol, atol=atol)
        x_next = np.where(moving, np.clip(sol.y[:, -1], pl.x_min, pl.x_max), x)
        delta_next = np.arcsin(x_next / pl.r_mm)
        for j in np.flatnonzero(~loaded):
            delta_next[j] = np.clip(_float_period(delta[j], _take(pl, j), ts, rtol, atol),
                                    d_min, d_max)
        x, delta = x_next, delta_next
        i_prev = i_new
    return Trajectory(**out)


def _float_period(delta0: float, pl: PlantArrays, ts: float, rtol: float, atol: float) -> float:
    """One period of the floating surface δ̇ = −sign(e)·c(δ)·sqrt|e|, e = δ − δ_f
    (the floating law of :mod:`scenarios.servo`).

    The right-hand side is not Lipschitz at e = 0, where the surface arrives in finite time
    and stays; a tight-tolerance solver crawls there. So the law is integrated in the
    variable s = sign(e)·sqrt|e|, where it reads ṡ = −c(δ)/2 (smooth, c evaluated at the
    current δ — unlike the fixed-step scheme, which freezes c over the period), with a
    terminal event at s = 0 after which the surface rests at δ_f.
    """
    d_f = float(np.asarray(pl.delta_float_rad).reshape(-1)[0])
    e0 = float(delta0) - d_f
    if e0 == 0.0:
        return d_f
    sign = np.sign(e0)

    def rhs(_t, s):
        delta = np.array([d_f + sign * s[0] ** 2])
        return [-0.5 * float(float_rate_coef(delta, pl)[0])]

    def arrived(_t, s):
        return s[0]
    arrived.terminal = True

    sol = solve_ivp(rhs, (0.0, ts), [np.sqrt(abs(e0))], method="RK45", rtol=rtol, atol=atol,
                    events=arrived)
    if sol.status == 1:                       # reached δ_f inside the period
        return d_f
    return d_f + sign * float(sol.y[0, -1]) ** 2
