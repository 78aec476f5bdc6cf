"""chen-local's estimator pinned by value: the recursion of [CHEN] eq. 13–16 as
docs/chen-estimator.md §1–§2 writes it (gain of eq. 13 with the sign of the order error,
clipped to the polytope, the current saturation σ = min(1, e_sat/|e|), the damping-mode
factor 1/√(1 + κ(C0·σ·e)²), clipped to the vertex gains, the bilinear step, f̂ = L2·(y − x̂)),
transcribed in plain Python and compared with both engines on hand-built orders and rod
readings: steps large enough to saturate the current, both directions, a rod off the
model, a jam-like offset."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from detectors.synthesis import chen_local_model as lm
from detectors.registry import make_detector
from scenarios import compiled as kernels
from scenarios.simulate import simulate, single_run


@pytest.fixture(scope="module")
def fitted_and_schedule():
    """chen-local fitted on six short fault-free elevator runs; their scheduling data."""
    import pandas as pd

    runs = pd.concat([single_run("elevator", m, "none", seed=3, duration_s=20.0,
                                 alt_ft=a, vcas_kt=v).assign(stream=j, run_id=f"l{j}")
                      for j, (m, a, v) in enumerate([("cruise", 28000.0, 300.0),
                                                     ("nose_up", 8000.0, 220.0),
                                                     ("aoa_protection", 18000.0, 250.0),
                                                     ("pitch_protection", 38000.0, 220.0),
                                                     ("yaw_angle_mode", 12000.0, 280.0),
                                                     ("turn_coordination", 30000.0, 260.0)])],
                     ignore_index=True)
    sig, _ = simulate(runs)
    return make_detector("chen-local").fit(sig), sig


def _plain(det, u, y, schedule, ts):
    """(f̂ of one run [mm], the number of steps whose current saturated), plain Python
    (module docstring)."""
    lo, hi = det.schedule_box_
    rho = np.clip(lm.scheduling_vector({k: np.array([v]) for k, v in schedule.items()}),
                  lo, hi)[0]
    th = np.asarray(det.theta_, float).reshape(3, -1)
    c0, c1, c2 = (th[m, 0] + sum(th[m, j + 1] * rho[j] for j in range(len(rho)))
                  for m in range(3))
    L1, L2 = float(det.design_["L1"]), float(det.design_["L2"])
    d = int(det.delay_)
    x_lo, x_hi = det.x_range_mm_
    k_lo, k_hi = det.k_range_
    ke_lo, ke_hi = det.design_["vertex_K"]
    e_sat, kappa = det.saturation_["e_sat_mm"], det.saturation_["kappa"]
    u, y = [float(v) for v in u], [float(v) for v in y]
    xh, out, saturated = y[0], [], 0
    for k in range(len(u)):
        out.append(L2 * (y[k] - xh))
        v = u[max(k - d, 0)]
        e = v - xh
        s = 1.0 if e > 0 else (-1.0 if e < 0 else 0.0)
        K = c0 + c1 * s * (min(max(xh, x_lo), x_hi) + c2)          # eq. 13
        K = min(max(K, k_lo), k_hi)
        sig = min(1.0, e_sat / abs(e)) if e != 0 else 1.0
        saturated += sig < 1.0
        K = K * sig / math.sqrt(1.0 + kappa * (c0 * sig * e) ** 2)
        K = min(max(K, ke_lo), ke_hi)
        a = K - L1
        target = (K * v - L1 * y[k]) / a
        xh = target + (xh - target) * (1.0 - 0.5 * ts * a) / (1.0 + 0.5 * ts * a)
    return np.array(out), saturated


def _signals(sig, u, y):
    """Signals of the runs of *sig* with the orders *u* and the rod readings *y* [mm]."""
    n, T = u.shape
    base = sig.take(np.arange(n)).truncate(T)
    return replace(base, command=u, rod_com=y, rod_mon=y, classes=None)


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_estimate_follows_the_documented_recursion(fitted_and_schedule, engine):
    det, sig = fitted_and_schedule
    ts, T = sig.ts, 400
    t = np.arange(T) * ts
    e_sat = det.saturation_["e_sat_mm"]
    # orders: a step far beyond e_sat up then down, a slow ramp, a small sine; the rod
    # follows a first-order lag of the order, then a jam-like offset of 0.8 mm at 2 s
    u = np.stack([np.where(t < 1.0, 0.0, 4.0 * e_sat) - np.where(t < 2.5, 0.0, 7.0 * e_sat),
                  -3.0 + 2.0 * t,
                  1.5 * np.sin(2.0 * np.pi * 0.7 * t)])
    y = np.empty_like(u)
    for r in range(3):
        x = u[r, 0]
        for k in range(T):
            y[r, k] = x + (0.8 if (r == 2 and t[k] >= 2.0) else 0.0)
            x += (u[r, k] - x) * (1.0 - math.exp(-ts / 0.08))
    batch = _signals(sig, u, y)
    with kernels.use_engine(engine):
        f_hat = det.estimate(batch)
    saturated = 0
    for r in range(3):
        schedule = {k: float(np.asarray(batch.schedule[k])[r]) for k in lm.SCHEDULE}
        ref, n_sat = _plain(det, u[r], y[r], schedule, ts)
        saturated += n_sat
        # same operations, a different order in a few places (the sign, σ): 1e-9 relative
        np.testing.assert_allclose(f_hat[r], ref, rtol=1e-9, atol=1e-12)
    assert np.abs(f_hat).max() > 0.1              # the runs drive the estimate
    assert saturated > 0                          # the saturation branch was exercised
