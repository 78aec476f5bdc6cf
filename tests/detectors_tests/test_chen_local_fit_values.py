"""chen-local's fit and decision (detectors/builtin/chen_local.py, docs/chen-estimator.md §2–§3)
pinned by value on a hand-built actuator model, in a few seconds.

The identified model of :mod:`detectors.synthesis.chen_local_model` is replaced by coefficients
chosen by hand (:data:`THETA`, with a load term large enough that the direction of motion and the
rod position move K by several 1/s), so the fit runs without the identification and every
learned quantity can be written out from the documented formulas:

* the scheduling box and [K_min, K_max]: K = C0 + C1·s·(x + C2) ([CHEN] eq. 13) over every
  realistic point of the Table-1 grid seen through the 3⁴ corners of the Table-2 errors
  (widened by ``schedule_margin``), 41 rod positions across the point's authority and
  s = ±1 (docs/chen-estimator.md §2);
* σ_min = min(1, e_sat/(order range)), D_min = 1/√(1 + κ·(C0_max·e_sat)²) with C0_max the
  largest C0 over the box, the vertices (K_min·σ_min·D_min·0.95, K_max·1.05) and the poles
  the stability check reports;
* the thresholds: ``safety`` × the largest learning value of each statistic, with the
  floor; the post-filter T(s) = (s + 1)/(s + 5) by zero-order hold; the window means of the
  liquid statistic and the least |f̂| over the solid window, by plain loops;
* the decision: |d| = τ is not beyond τ, the liquid integrator's count of n − 1 vs n steps
  (half a step rounds down), never reset, and the solid window's boundary;
* the recursion of eq. 16 with a non-zero injection gain L1 (the general form of
  docs/chen-estimator.md §2: the local design has L1 = 0, the guards and the recursion are
  written for any L1), the sign of a zero order error, and the guards that refuse a model
  with K ≤ 0 or an estimator that is not stable on the polytope.

Expected values come from the formulas written out here, never from the function under
test; the estimate f̂ the statistics start from is itself pinned against the recursion.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest

from detectors.synthesis import chen_local_model as lm
from detectors.synthesis import lpv_synthesis
from detectors.base import Capabilities
from detectors.builtin.chen_local import NUMERICS, POST_FILTER, ChenLocalEstimator
from scenarios import envelope
from scenarios.compiled import use_engine
from scenarios.params import ACTUATORS
from scenarios.servo import authority_limits, plant_arrays
from scenarios.signals import Signals

ENGINES = ("compiled", "numpy")
ACT = ACTUATORS["elevator"]
#: period [s]: a power of two, so that step counts × Ts and half a step are exact and the
#: confirmation boundaries below fall exactly on a step
TS = 1.0 / 128.0
#: hand-built coefficients of C0 [1/s], C1 [1/(s·mm)], C2 [mm] on [1, q̄/10⁴ Pa, M, α/10°]
#: (docs/chen-estimator.md §1): K from about 12 to 42 1/s over the envelope
THETA = np.array([[22.0, 1.5, -4.0, 3.0],
                  [0.12, 0.05, -0.08, 0.04],
                  [6.0, -2.0, 3.0, 8.0]])
#: the same with C2 46 mm lower and half the load term: x + C2 < 0 over every authority,
#: so K_max comes from the direction s = −1 (with THETA both extremes come from s = +1)
THETA_LOW_C2 = np.array([[22.0, 1.5, -4.0, 3.0],
                         [0.06, 0.025, -0.04, 0.02],
                         [-40.0, -2.0, 3.0, 8.0]])
E_SAT_MM = 2.0           # current-saturation error [mm] (hand-built)
KAPPA = 2e-4             # damping-neighbour coefficient [(s/mm)²] (hand-built)
#: scheduling-vector scales of docs/chen-estimator.md §1 (ρ_j = value/scale)
SCALES = {"qbar_pa": 1e4, "mach": 1.0, "alpha_deg": 10.0}
#: scheduling data of the hand-built runs (one row per run)
SCHEDULE = {"qbar_pa": [12000.0, 25000.0, 6000.0], "mach": [0.55, 0.8, 0.35],
            "alpha_deg": [2.5, 1.0, 6.0]}


def _model(theta=THETA, e_sat=E_SAT_MM, kappa=KAPPA) -> lm.LocalModelFit:
    return lm.LocalModelFit(theta=np.asarray(theta, float), e_sat_mm=e_sat, kappa=kappa,
                            rms_mm=0.1, max_abs_mm=0.4, rms_initial_mm=0.2,
                            rho_min=np.zeros(3), rho_max=np.ones(3), x_min_mm=ACT.x_min_mm,
                            x_max_mm=ACT.x_max_mm, n_points=1, ts=TS, delay=1)


@pytest.fixture
def hand_model(monkeypatch):
    """Make ``fit`` use a hand-built model instead of identifying one."""
    def use(**kwargs):
        model = _model(**kwargs)
        monkeypatch.setattr(lm, "fit_local_model", lambda act, ts: model)
        return model
    return use


@pytest.fixture
def injection_gain(monkeypatch):
    """Make the synthesis return its design with the injection gain L1 = *l1* [1/s] (the
    Z1·H⊥ term of [CHEN] eq. 20 with H⊥ = 1), everything else as synthesised."""
    real = lpv_synthesis.synthesise

    def use(l1):
        def synthesise(vertices, **kwargs):
            return replace(real(vertices, **kwargs), Z1=np.array([[l1]]),
                           H_perp=np.array([[1.0]]))
        monkeypatch.setattr(lpv_synthesis, "synthesise", synthesise)
    return use


def _signals(u, y, classes=None):
    u = np.atleast_2d(np.asarray(u, float))
    y = np.atleast_2d(np.asarray(y, float))
    n, T = u.shape
    nan = np.full((n, T), np.nan)
    return Signals(ts=TS, command=u, current=np.zeros((n, T)), rod_com=y, rod_mon=y.copy(),
                   surface=nan, pressure=nan,
                   schedule={k: np.asarray(v[:n], float) for k, v in SCHEDULE.items()},
                   actuator=ACT, run_ids=np.array([f"r{i}" for i in range(n)]),
                   classes=classes)


def _runs(T=512, offset_mm=0.0):
    """Orders [mm] (three runs: a fast step beyond e_sat up and down, a ramp, a sine) and rod
    readings: a first-order lag of 60 ms, a 0.02 mm ripple and, with *offset_mm*, a bias on
    the third run's reading from step T/2 (a liquid-jam-like offset)."""
    t = np.arange(T) * TS
    u = np.stack([np.where(t < 0.5, -5.0, 15.0) - np.where(t < 2.5, 0.0, 25.0),
                  -20.0 + 8.0 * t,
                  6.0 * np.sin(2.0 * np.pi * 0.6 * t)])
    y = np.empty_like(u)
    for r in range(3):
        x = u[r, 0] + 0.3
        for k in range(T):
            y[r, k] = x + 0.02 * math.sin(7.0 * k + r) + (offset_mm if r == 2 and k >= T // 2
                                                           else 0.0)
            x += (u[r, k] - x) * (1.0 - math.exp(-TS / 0.06))
    return u, y


# ---- references written from the documentation ------------------------------------------
def _rho(values: dict) -> list[float]:
    return [float(values[k]) / s for k, s in SCALES.items()]


def _c(theta, rho) -> list[float]:
    """(C0, C1, C2) = θ_m0 + Σ_j θ_mj·ρ_j."""
    th = np.asarray(theta, float)
    out = []
    for m in range(3):
        c = th[m, 0]
        for j, r in enumerate(rho):
            c = c + th[m, j + 1] * r
        out.append(c)
    return out


def _polytope(theta, margin, levels=(-1.0, 0.0, 1.0)):
    """(ρ box lo, hi, K_min, K_max, grid points) by the definition of docs/chen-estimator.md §2;
    *levels*: each Table-2 error at these multiples of its (widened) half-width w."""
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]]
    alt, vcas, mass, cg = (pts[c].to_numpy(float) for c in ("alt_ft", "vcas_kt", "mass_t",
                                                            "cg_pct"))
    fc = envelope.flight_condition(alt, vcas, mass, cg)
    plant = plant_arrays(ACT, qbar_pa=fc["qbar_pa"], alpha_deg=fc["alpha_deg"], mach=fc["mach"])
    d_lo, d_hi = authority_limits(plant, ACT)
    # 41 rod positions across each point's authority: x = r·sin(δ) [mm]
    x = np.stack([ACT.r_mm * np.sin(np.radians(d_lo + (d_hi - d_lo) * j / 40.0))
                  for j in range(41)], axis=1)
    w, widen = envelope.UNCERTAINTY, 1.0 + margin
    rhos, k_ext = [], []
    for ev, eh, em, ec in itertools.product(levels, repeat=4):
        meas = envelope.measured_schedule(alt, vcas, mass, cg, eh * w.alt * widen,
                                          ev * w.vcas * widen, em * w.mass * widen,
                                          ec * w.cg * widen)
        rho = np.stack([meas[k] / s for k, s in SCALES.items()], axis=1)
        rhos.append(rho)
        c0, c1, c2 = (theta[m, 0] + rho @ theta[m, 1:] for m in range(3))
        for s in (-1.0, 1.0):            # s = 0 gives C0, between the two
            k = c0[:, None] + c1[:, None] * s * (x + c2[:, None])
            k_ext.append((k.min(), k.max()))
    rho = np.concatenate(rhos)
    k_ext = np.array(k_ext)
    return (rho.min(axis=0), rho.max(axis=0), k_ext[:, 0].min(), k_ext[:, 1].max(),
            len(pts) * len(levels) ** 4 * 41 * 3)


def _pole(a):
    """φ(a) = (1 − a·Ts/2)/(1 + a·Ts/2), the bilinear step of ẋ = −a·x
    (docs/chen-estimator.md §2)."""
    return (1.0 - 0.5 * TS * a) / (1.0 + 0.5 * TS * a)


def _recursion(det, u, y, schedule):
    """(f̂, x̂, sign of u − x̂) of one run: [CHEN] eq. 13–16 as docs/chen-estimator.md §1–§2
    write it, in plain Python."""
    lo, hi = det.schedule_box_
    rho = [min(max(r, a), b) for r, a, b in zip(_rho(schedule), lo, hi)]
    c0, c1, c2 = _c(det.theta_, rho)
    L1, L2 = float(det.design_["L1"]), float(det.design_["L2"])
    x_lo, x_hi = det.x_range_mm_
    k_lo, k_hi = det.k_range_
    ke_lo, ke_hi = det.design_["vertex_K"]
    e_sat, kappa = det.saturation_["e_sat_mm"], det.saturation_["kappa"]
    xh = float(y[0])
    f, xs_out, signs = [], [], []
    for k in range(len(u)):
        xs_out.append(xh)
        f.append(L2 * (float(y[k]) - xh))
        v = float(u[max(k - 1, 0)])                  # one period of transport delay
        e = v - xh
        s = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
        signs.append(s)
        K = c0 + c1 * s * (min(max(xh, x_lo), x_hi) + c2)     # eq. 13
        K = min(max(K, k_lo), k_hi)
        sig = e_sat / abs(e) if abs(e) > e_sat else 1.0      # σ = min(1, e_sat/|e|)
        v0 = c0 * (sig * e)                                   # no-load speed [mm/s]
        K = K * sig * (1.0 / math.sqrt(1.0 + kappa * v0 * v0))
        K = min(max(K, ke_lo), ke_hi)
        a = K - L1
        target = (K * v - L1 * float(y[k])) / a
        xh = target + (xh - target) * _pole(a)
    return np.array(f), np.array(xs_out), np.array(signs)


def _liquid_statistic(f_hat, n_a, n_b):
    """d_k of docs/chen-estimator.md §3 from f̂ through T(s) = (s + 1)/(s + 5) (zero-order
    hold: T = 1 + (z − p)/(s + p), so g_k = f̂_k + β·f̂_{k−1} + E·(g_{k−1} − f̂_{k−1}) with
    E = e^{−p·Ts}, β = (z − p)(1 − E)/p)."""
    z, p = POST_FILTER.zero_rad_s, POST_FILTER.pole_rad_s
    E = math.exp(-p * TS)
    beta = (z - p) * (1.0 - E) / p
    out = np.empty_like(f_hat)
    for r in range(f_hat.shape[0]):
        g, prev_f, prev_g = [], 0.0, 0.0
        for fk in f_hat[r]:
            gk = fk + (beta - E) * prev_f + E * prev_g
            g.append(gk)
            prev_f, prev_g = fk, gk
        for k in range(len(g)):
            recent = sum(g[k - j] for j in range(n_a) if k - j >= 0) / n_a
            ref = (sum(g[k - j] for j in range(n_a, n_a + n_b) if k - j >= 0) / n_b
                   if n_b else 0.0)
            out[r, k] = recent - ref
    return out


def _least_over_window(values, n):
    """min |x_j| over j ∈ [k − n + 1, k], 0 until a full window exists."""
    a = np.abs(np.asarray(values, float))
    out = np.zeros_like(a)
    for r in range(a.shape[0]):
        for k in range(n - 1, a.shape[1]):
            out[r, k] = min(a[r, k - n + 1:k + 1])
    return out


def _step_persistence(values, n_c, n_b):
    """s_k = min over j ∈ [k − n_c + 1, k] of |f̂_j − r_k|, r_k the mean of f̂ over
    [k − n_c − n_b + 1, k − n_c] (docs/chen-estimator.md §3), f̂ = 0 before the run."""
    f = np.asarray(values, float)
    out = np.empty_like(f)
    for r in range(f.shape[0]):
        def at(j):
            return f[r, j] if j >= 0 else 0.0
        for k in range(f.shape[1]):
            ref = sum(at(k - j) for j in range(n_c, n_c + n_b)) / n_b
            out[r, k] = min(abs(at(k - j) - ref) for j in range(n_c))
    return out


def _fitted(hand_model, T=512, **params):
    hand_model()
    u, y = _runs(T)
    det = ChenLocalEstimator(threshold_method="max", **params)
    return det.fit(_signals(u, y)), u, y


# ---- the fit -----------------------------------------------------------------------------
@pytest.mark.parametrize("margin, theta", [(0.25, THETA), (0.6, THETA),
                                           (0.25, THETA_LOW_C2)])
def test_polytope_box_and_gain_range_by_definition(hand_model, margin, theta):
    hand_model(theta=theta)
    u, y = _runs(256)
    params = {} if margin == 0.25 else {"schedule_margin": margin}   # 0.25: the default
    det = ChenLocalEstimator(threshold_method="max", **params).fit(_signals(u, y))
    lo, hi, k_min, k_max, n_grid = _polytope(theta, margin)
    np.testing.assert_array_equal(det.schedule_box_[0], lo)
    np.testing.assert_array_equal(det.schedule_box_[1], hi)
    # the grid positions r·sin(δ_lo + Δδ·j/40) against linspace's j·(1/40): a few ulp
    np.testing.assert_allclose(det.k_range_, (k_min, k_max), rtol=1e-13)
    assert det.stability_["grid_points"] == n_grid
    assert 5.0 < k_min < k_max - 5.0         # the hand-built load term moves K


def test_the_zero_error_row_of_the_grid_counts(hand_model, monkeypatch):
    """Each Table-2 error is seen at −w, 0 and +w, not only at its two corners: a measured
    schedule whose α is largest at zero altitude error (a hand-made bump of 0.4° on the
    real schedule) sets the box's upper α there, and K_max with it."""
    real = envelope.measured_schedule
    det = ChenLocalEstimator(threshold_method="max")
    w_alt = envelope.UNCERTAINTY.alt * (1.0 + det.schedule_margin)     # widened half-width

    def bumped(alt, vcas, mass, cg, d_alt, d_vcas, d_mass, d_cg, *args):
        meas = real(alt, vcas, mass, cg, d_alt, d_vcas, d_mass, d_cg, *args)
        bump = 0.4 * (1.0 - (np.asarray(d_alt) / w_alt) ** 2)             # [deg]
        return {**meas, "alpha_deg": meas["alpha_deg"] + bump}

    monkeypatch.setattr(envelope, "measured_schedule", bumped)
    hand_model()
    u, y = _runs(256)
    det.fit(_signals(u, y))
    lo, hi, k_min, k_max, _ = _polytope(THETA, det.schedule_margin)
    np.testing.assert_array_equal(det.schedule_box_[1], hi)
    np.testing.assert_allclose(det.k_range_, (k_min, k_max), rtol=1e-13)
    # the corners alone would give an upper α lower by about the bump, and another K_max
    _, corners, _, k_max_corners, _ = _polytope(THETA, det.schedule_margin, (-1.0, 1.0))
    assert (hi[2] - corners[2]) * SCALES["alpha_deg"] > 0.1
    assert k_max != k_max_corners


@pytest.mark.parametrize("e_sat", [E_SAT_MM, 500.0])
def test_vertices_saturation_and_poles_by_formula(hand_model, e_sat):
    """σ_min, D_min, the vertices and the reported poles (docs/chen-estimator.md §2); an
    e_sat beyond the order range never saturates the current: σ_min = 1."""
    hand_model(e_sat=e_sat)
    u, y = _runs(256)
    det = ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))
    lo, hi = det.schedule_box_
    c0_max = max(_c(THETA, corner)[0] for corner in itertools.product(*zip(lo, hi)))
    sig_min = min(1.0, e_sat / (ACT.u_max_mm - ACT.u_min_mm))
    d_min = 1.0 / math.sqrt(1.0 + KAPPA * (c0_max * e_sat) ** 2)
    assert det.saturation_ == pytest.approx({"e_sat_mm": e_sat, "kappa": KAPPA,
                                             "sigma_min": sig_min, "damping_min": d_min},
                                            rel=1e-13)
    assert (sig_min == 1.0) == (e_sat == 500.0)
    k_min, k_max = det.k_range_
    lower = k_min * sig_min * d_min
    assert det.design_["vertex_K"] == pytest.approx((lower * 0.95, k_max * 1.05), rel=1e-13)
    assert NUMERICS.polytope_margin == 0.05          # docs/chen-estimator.md §2: 5 %
    assert det.design_["L1"] == 0.0 and det.design_["L2"] == 1.0
    st = det.stability_
    assert st["vertex_max_real_pole"] == pytest.approx(-lower * 0.95, rel=1e-9)
    assert st["grid_max_real_pole"] == pytest.approx(-lower, rel=1e-13)
    assert st["grid_max_discrete_modulus"] == pytest.approx(
        max(abs(_pole(lower)), abs(_pole(k_min)), abs(_pole(k_max))), rel=1e-13)
    assert det.gamma_ == pytest.approx(1.0 / (lower * 0.95), rel=1e-3)   # γ = 1/K̃_min (LMI)


def test_thresholds_are_safety_times_the_largest_learning_statistic(hand_model):
    det, u, y = _fitted(hand_model, safety=1.7, floor_mm=1e-6)
    b, a = det.post_filter_
    E = math.exp(-POST_FILTER.pole_rad_s * TS)
    beta = (POST_FILTER.zero_rad_s - POST_FILTER.pole_rad_s) * (1.0 - E) / POST_FILTER.pole_rad_s
    np.testing.assert_allclose(b, [1.0, beta - E], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a, [1.0, -E], rtol=1e-12)
    f_hat = det.estimate(_signals(u, y))
    # defaults: n_a = round(0.02/Ts) = 3, n_b = round(0.04/Ts) = 5; solid n_c = round(0.1/Ts)
    # = 13, its reference round(0.2/Ts) = 26
    d = _liquid_statistic(f_hat, 3, 5)
    solid = _step_persistence(f_hat, 13, 26)
    # lfilter's recursions against the plain loops: rounding only
    assert det.thresholds_["liquid"] == pytest.approx(1.7 * np.abs(d).max(), rel=1e-9)
    assert det.thresholds_["solid"] == pytest.approx(1.7 * solid.max(), rel=1e-9)
    assert det.solid_windows_ == (13, 26)
    assert det.thresholds_["solid"] > 1e-3 and det.thresholds_["liquid"] > 1e-3
    assert not hasattr(det, "calibration_")          # "max": no calibration
    assert det.learning_runs_ == 3


def test_the_floor_bounds_both_thresholds(hand_model):
    det, _, _ = _fitted(hand_model, floor_mm=50.0)
    assert det.thresholds_ == {"liquid": 50.0, "solid": 50.0}


def test_a_model_with_a_non_positive_gain_is_refused(hand_model):
    theta = np.zeros((3, 4))
    hand_model(theta=theta)
    u, y = _runs(64)
    with pytest.raises(ValueError, match=r"has K = 0 1/s ≤ 0 inside the scheduling box"):
        ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))


def test_a_slow_but_positive_gain_is_accepted(hand_model):
    """K between 0.4 and 0.6 1/s: positive, so the model is a stable lag (only K ≤ 0 is
    refused)."""
    theta = np.zeros((3, 4))
    theta[0, 0] = 0.5
    theta[1, 0] = 0.001
    hand_model(theta=theta)
    u, y = _runs(64)
    det = ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))
    assert 0.4 < det.k_range_[0] < det.k_range_[1] < 0.6


# ---- the recursion with an injection gain, and the stability guards ---------------------
@pytest.mark.parametrize("engine", ENGINES)
def test_recursion_with_an_injection_gain_follows_eq_16(hand_model, injection_gain, engine):
    """L1 = −5 1/s: x̂* = (K̃·u − L1·y)/(K̃ − L1), the pole φ(K̃ − L1); the rod starts off
    the order and the ripple makes y_0 ≠ y_1 (x̂ starts at y_0)."""
    hand_model()
    injection_gain(-5.0)
    u, y = _runs(512, offset_mm=0.8)
    det = ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))
    assert det.design_["L1"] == -5.0
    lower = det.k_range_[0] * det.saturation_["sigma_min"] * det.saturation_["damping_min"]
    assert det.stability_["grid_max_real_pole"] == pytest.approx(-lower - 5.0, rel=1e-13)
    assert det.stability_["vertex_max_real_pole"] == pytest.approx(-lower * 0.95 - 5.0,
                                                                   rel=1e-9)
    with use_engine(engine):
        f_hat = det.estimate(_signals(u, y))
    for r in range(3):
        ref, _, _ = _recursion(det, u[r], y[r], {k: v[r] for k, v in SCHEDULE.items()})
        # the same operations in the same order: the same bits
        np.testing.assert_array_equal(f_hat[r], ref)
    assert np.abs(f_hat).max() > 0.5


@pytest.mark.parametrize("engine", ENGINES)
def test_a_zero_order_error_has_no_direction(hand_model, injection_gain, engine):
    """When the delayed order equals x̂ exactly, sign(u − x̂) = 0 and K = C0 (eq. 14): with
    L1 ≠ 0 and y ≠ x̂ that step's K shows in x̂* and so in every later f̂."""
    hand_model()
    injection_gain(-5.0)
    u, y = _runs(64)
    det = ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))
    schedule = {k: v[0] for k, v in SCHEDULE.items()}
    _, xh, _ = _recursion(det, u[0], y[0], schedule)
    u[0, 1] = xh[2]                   # v_2 = u_1 = x̂_2: a zero error at step 2
    ref, _, signs = _recursion(det, u[0], y[0], schedule)
    assert signs[2] == 0.0 and y[0, 2] != xh[2]
    with use_engine(engine):
        f_hat = det.estimate(_signals(u[:1], y[:1]))
    np.testing.assert_array_equal(f_hat[0], ref)


def _vertex_pole_gain(hand_model):
    """(lower vertex K̃ [1/s], the grid's smallest K·σ_min·D_min [1/s], orders, readings)."""
    hand_model()
    u, y = _runs(64)
    det = ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))
    sat = det.saturation_
    return (det.design_["vertex_K"][0], det.k_range_[0] * sat["sigma_min"] * sat["damping_min"],
            u, y)


def test_an_estimator_pole_at_zero_on_a_vertex_is_refused(hand_model, injection_gain):
    k_vertex, _, u, y = _vertex_pole_gain(hand_model)
    injection_gain(k_vertex)          # A + L1·C = 0 at the lower vertex
    with pytest.raises(ValueError, match="not stable over the scheduling polytope"):
        ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))


def test_an_unstable_vertex_is_refused_even_with_a_stable_grid(hand_model, injection_gain):
    """L1 between the lower vertex and the grid's smallest K̃: every grid pole is stable,
    the vertex pole is not (by less than 1 1/s)."""
    k_vertex, k_grid, u, y = _vertex_pole_gain(hand_model)
    assert 0.0 < k_grid - k_vertex < 1.0
    injection_gain(0.5 * (k_vertex + k_grid))
    with pytest.raises(ValueError, match="not stable over the scheduling polytope"):
        ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))


def test_a_vertex_pole_the_discretisation_rounds_to_one_is_refused(hand_model, injection_gain):
    """L1 one ulp below the lower vertex: the continuous pole −(K̃ − L1) is negative (the
    vertex and grid checks pass), but (K̃ − L1)·Ts/2 is far below the ulp of 1, so the
    bilinear pole φ rounds to exactly 1: not stable after discretisation."""
    k_vertex, _, u, y = _vertex_pole_gain(hand_model)
    l1 = float(np.nextafter(k_vertex, 0.0))
    assert _pole(k_vertex - l1) == 1.0
    injection_gain(l1)
    with pytest.raises(ValueError, match="discretised estimator is unstable at a vertex"):
        ChenLocalEstimator(threshold_method="max").fit(_signals(u, y))


# ---- the statistics and the decision ----------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_solid_statistic_is_the_least_value_over_the_window(n):
    f_hat = np.array([[3.0, -5.0, 4.0, 2.5, -6.0, 7.0, 1.5, 8.0, -9.0, 3.5, 2.0, -4.5],
                      [-2.0, 1.0, 6.0, -3.0, 5.5, 2.2, -7.0, 4.4, 1.1, 9.0, -3.3, 2.7]])
    # solid_confirm_s = n·Ts, and 0 (one step); no reference: the level statistic
    det = ChenLocalEstimator(solid_confirm_s=0.0 if n == 1 else n * TS, solid_reference_s=0.0)
    np.testing.assert_array_equal(det._solid_statistic(f_hat, TS),
                                  _least_over_window(f_hat, n))


@pytest.mark.parametrize("n_c, n_b", [(1, 1), (1, 3), (2, 2), (3, 4), (4, 1), (10, 20)])
def test_solid_statistic_is_the_least_distance_from_the_reference_mean(n_c, n_b):
    rng = np.random.default_rng(7)
    f_hat = rng.normal(0.0, 1.0, (3, 40))
    f_hat[2, 17:] += 1.1                                  # an offset jam's step at k = 17
    det = ChenLocalEstimator(solid_confirm_s=n_c * TS, solid_reference_s=n_b * TS)
    # 1e-12: the reference mean is a sum of n_b terms in another order than the plain loop
    np.testing.assert_allclose(det._solid_statistic(f_hat, TS),
                               _step_persistence(f_hat, n_c, n_b), rtol=1e-12, atol=1e-12)


def test_solid_statistic_of_a_step_is_the_step_over_the_confirmation_window():
    """f̂ = a step m at k0 (an offset jam without noise): s = m from k0 + n_c − 1 (the whole
    window after the step, the reference before it) until the reference reaches the step;
    a pulse shorter than the window (a liquid jam's estimate, gone as the loop re-centres)
    gives at most its share of the reference mean, m·(n_c − 1)/n_b."""
    n_c, n_b, k0, m = 10, 20, 50, 1.1
    det = ChenLocalEstimator(solid_confirm_s=n_c * TS, solid_reference_s=n_b * TS)
    step = np.where(np.arange(120) >= k0, m, 0.0)[None, :]
    s = det._solid_statistic(step, TS)[0]
    assert (s[:k0 + n_c - 1] < 1e-12).all()
    np.testing.assert_allclose(s[k0 + n_c - 1:k0 + n_c], m, rtol=1e-12)
    # r_k covers only pre-step values up to k = k0 + n_c − 1; then it climbs, s falls
    assert s[k0 + n_c] < m and s[k0 + n_c + n_b - 1:].max() < 1e-12
    pulse = np.where((np.arange(120) >= k0) & (np.arange(120) < k0 + n_c - 1), m, 0.0)
    assert det._solid_statistic(pulse[None, :], TS).max() <= m * (n_c - 1) / n_b + 1e-12


def test_one_step_windows_give_the_filtered_estimate_itself(hand_model):
    """liquid_window_s = liquid_reference_s = 0: d = T f̂ (the level of [CHEN] §6.2); one
    step each: d_k = g_k − g_{k−1}."""
    hand_model()
    u, y = _runs(256, offset_mm=0.8)
    for (w, ref), (n_a, n_b) in [((0.0, 0.0), (1, 0)), ((TS, TS), (1, 1))]:
        det = ChenLocalEstimator(threshold_method="max", liquid_window_s=w,
                                 liquid_reference_s=ref).fit(_signals(u, y))
        det.thresholds_ = {"liquid": 1.0, "solid": 1.0}
        out = det.detect(_signals(u, y))
        d = _liquid_statistic(out["liquid"].estimate, n_a, n_b)
        np.testing.assert_allclose(out["liquid"].residual, np.abs(d), rtol=1e-9, atol=1e-12)


def test_residuals_are_the_statistics_over_their_thresholds(hand_model):
    det, u, y = _fitted(hand_model, solid_confirm_s=0.25)
    sig = _signals(*_runs(512, offset_mm=0.8))
    det.thresholds_ = {"liquid": 0.3, "solid": 0.2}
    out = det.detect(sig)
    f_hat = out["solid"].estimate
    np.testing.assert_array_equal(out["liquid"].estimate, f_hat)
    np.testing.assert_allclose(out["liquid"].residual,
                               np.abs(_liquid_statistic(f_hat, 3, 5)) / 0.3, rtol=1e-9,
                               atol=1e-12)
    # solid_confirm_s = 0.25 s → 32 steps, the default 0.2 s reference → 26 steps at Ts =
    # 1/128 s
    n_c, n_b = int(round(0.25 / TS)), int(round(0.2 / TS))
    np.testing.assert_allclose(out["solid"].residual,
                               _step_persistence(f_hat, n_c, n_b) / 0.2, rtol=1e-9,
                               atol=1e-12)
    # the alarm from the first step at or beyond τ_sol on (latched), the decision the
    # statistic itself
    np.testing.assert_array_equal(out["solid"].alarm, np.logical_or.accumulate(
        out["solid"].residual >= 1.0, axis=1))
    np.testing.assert_array_equal(out["solid"].decision, out["solid"].residual)
    assert out["solid"].alarm.any() and not out["solid"].alarm.all()


@pytest.mark.parametrize("confirm_steps, needed", [(0.0, 1), (2.0, 2), (2.5, 2), (3.0, 3)])
def test_liquid_alarm_after_n_steps_beyond_the_threshold(hand_model, confirm_steps, needed):
    """The integrator counts the steps with |d| ≥ τ (never reset) and the alarm is raised
    once they cover liquid_confirm_s (half a step rounds down; 0 means the first step); the
    decision statistic is the needed-th largest |d|/τ so far (≥ 1 where the alarm is
    raised)."""
    det, u, y = _fitted(hand_model, liquid_confirm_s=confirm_steps * TS)
    sig = _signals(*_runs(512, offset_mm=0.8))
    det.thresholds_ = {"liquid": 1.0, "solid": 1.0}
    level = det.detect(sig)["liquid"].residual          # |d| [mm] (τ = 1 mm)
    tau = float(np.sort(level[2])[-6])                  # six steps of run 2 at or beyond it
    det.thresholds_ = {"liquid": tau, "solid": 1.0}
    liquid = det.detect(sig)["liquid"]
    alarm = liquid.alarm
    count = np.cumsum(level >= tau, axis=1)
    np.testing.assert_array_equal(alarm, count >= needed)
    # the decision: the needed-th largest of |d|/τ so far, by a plain sort per step
    norm = level[2] / tau
    plain = [np.sort(norm[:k + 1])[-needed] if k + 1 >= needed else np.nan
             for k in range(norm.size)]
    np.testing.assert_array_equal(liquid.decision[2], plain)
    first = int(np.argmax(alarm[2]))
    assert count[2, first] == needed and not alarm[2, first - 1] and alarm[2, -1]


#: sampling periods [s]: binary fractions (exact), decimal ones (rounded), and periods over a
#: second, where (n − 1)·Ts and (n − 1)/Ts differ in the other direction
LIQUID_PERIODS = (TS, 0.01, 0.02, 0.005, 0.0125, 1.0 / 3.0, 0.1, 0.3, 0.7, 1.1, 2.5)


def test_liquid_samples_is_the_fewest_steps_that_cover_the_confirmation_time():
    """liquid_samples(Ts) is the fewest n ≥ 1 with n·Ts ≥ max(liquid_confirm_s, Ts) − Ts/2
    in floats (docs/chen-estimator.md §3), by a plain count from 1, at whole and half
    steps of every period. Among these are times where the first estimate ceil(need/Ts)
    falls short of that n, where it is one over it (n − 1 already covers need; some of
    them exactly, n·Ts = need, and some at periods over a second)."""
    short = over = at = over_long = 0
    for ts in LIQUID_PERIODS:
        for k in range(120):
            for confirm in (k * ts, (k + 0.5) * ts, k * ts + 0.5 * ts):
                need = max(confirm, ts) - 0.5 * ts
                plain = next(n for n in itertools.count(1) if n * ts >= need)
                det = ChenLocalEstimator(liquid_confirm_s=confirm)
                assert det.liquid_samples(ts) == plain, (ts, confirm)
                first = max(math.ceil(need / ts), 1)
                short += first * ts < need
                over += first > plain
                at += first > plain and plain * ts == need
                over_long += first > plain and ts > 1.0
    assert min(short, over, at, over_long) > 0, (short, over, at, over_long)


def test_a_statistic_equal_to_its_threshold_raises_the_alarm(hand_model):
    """≥, not >: a statistic exactly at τ is an alarm, so that the margin (the decision's
    largest value before onset) is ≥ s exactly when the run alarms at threshold × s."""
    det, u, y = _fitted(hand_model, liquid_confirm_s=0.0, solid_confirm_s=0.25)
    sig = _signals(*_runs(512, offset_mm=0.8))
    det.thresholds_ = {"liquid": 1.0, "solid": 1.0}
    out = det.detect(sig)
    liq, sol = out["liquid"].residual, out["solid"].residual     # the statistics [mm]
    k_liq, k_sol = int(np.argmax(liq[2])), int(np.argmax(sol[2]))
    det.thresholds_ = {"liquid": float(liq[2, k_liq]), "solid": float(sol[2, k_sol])}
    out = det.detect(sig)
    assert out["liquid"].residual[2, k_liq] == 1.0 and out["solid"].residual[2, k_sol] == 1.0
    assert out["liquid"].alarm[2, k_liq] and not out["liquid"].alarm[2, :k_liq].any()
    assert out["solid"].alarm[2, k_sol] and not out["solid"].alarm[2, :k_sol].any()


# ---- parameters and constants ------------------------------------------------------------
def test_documented_defaults_and_capabilities():
    det = ChenLocalEstimator()
    # docs/chen-estimator.md §3 and the class docstring
    assert (det.safety, det.liquid_confirm_s, det.liquid_window_s, det.liquid_reference_s,
            det.solid_confirm_s, det.solid_reference_s, det.schedule_margin,
            det.h_perturbation, det.floor_mm) == (1.5, 0.02, 0.02, 0.04, 0.1, 0.2, 0.25, 0.0,
                                                  0.05)
    assert (det.post_filter_zero_rad_s, det.post_filter_pole_rad_s) == (1.0, 5.0)
    assert ChenLocalEstimator.capabilities == Capabilities(
        needs_fit=True, needs_surface_sensor=False, causal=True, estimates_rod_fault=True,
        threshold_scale=True)


def test_each_variant_covers_its_own_jam_and_the_detector_both():
    """coverage: the liquid variant the liquid jam, the solid variant the solid jam, each
    with its [CHEN] §6.2 reason; the detector as a whole both jams, in that order."""
    det = ChenLocalEstimator()
    liquid, solid = det.coverage("liquid"), det.coverage("solid")
    assert liquid.faults == ("liquid_jam",) and solid.faults == ("solid_jam",)
    assert liquid.reason.startswith("[CHEN] §6.2: the liquid-jam statistic")
    assert solid.reason.startswith("[CHEN] §6.2: the solid-jam statistic")
    whole = det.coverage()
    assert whole.faults == ("liquid_jam", "solid_jam")
    assert whole.covers("liquid_jam") and whole.covers("solid_jam")
    assert not whole.covers("runaway") and not whole.covers("disconnection")


def test_the_warm_up_compiles_what_fit_and_detect_call(monkeypatch):
    """_warm_kernels calls the decision's kernel on a writable array (fit's learning
    statistics) and on a read-only view (detect's signals), and the estimator's on writable
    signals and schedule (fit), read-only signals (detect) and a read-only schedule too
    (scenarios.compiled.read_only_view): numba compiles each signature before a campaign's
    first run, not inside it."""
    from conftest import warm_up_writability
    from detectors.builtin import chen_local

    assert warm_up_writability(monkeypatch, chen_local, "_nth_largest_so_far") == [True, False]
    calls = []
    monkeypatch.setattr(chen_local, "_estimate_block", lambda u, y, c0, *rest: calls.append(
        (u.flags.writeable, y.flags.writeable, c0.flags.writeable)))
    chen_local._warm_kernels()
    assert calls == [(True, True, True), (False, False, True), (False, False, False)]


def test_fit_needs_no_surface_sensor(hand_model):
    """The learning runs of _signals have no surface sensor (all NaN)."""
    det, _, _ = _fitted(hand_model)
    assert det.is_fitted


def test_numerical_constants_are_frozen():
    with pytest.raises(FrozenInstanceError):
        NUMERICS.grid_x = 3
    with pytest.raises(FrozenInstanceError):
        POST_FILTER.pole_rad_s = 2.0
    assert (NUMERICS.grid_x, NUMERICS.grid_rho) == (41, 7)


def test_a_detector_fitted_before_the_solid_reference_keeps_its_level_statistic(hand_model):
    """A fitted detector stored before ``solid_reference_s`` existed has no
    ``solid_windows_``: read back, its threshold was learned on the least |f̂| over the
    window, so that is the statistic it must keep deciding on (a resumed directory is not
    scored with a threshold learned on another statistic)."""
    det, u, y = _fitted(hand_model, solid_confirm_s=0.25)
    f_hat = np.random.default_rng(3).normal(0.0, 1.0, (2, 64))
    assert det._solid_windows(TS) == (32, 26)
    del det.solid_windows_
    assert det._solid_windows(TS) == (32, 0)
    np.testing.assert_array_equal(det._solid_statistic(f_hat, TS), _least_over_window(f_hat, 32))
    # fitting again records the windows of its parameters
    det.fit(_signals(u, y))
    assert det.solid_windows_ == (32, 26)
