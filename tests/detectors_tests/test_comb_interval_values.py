"""The comb-interval detector (detectors/builtin/comb_interval.py, docs/interval-detector.md) pinned
by value on hand-built inputs, in both engines: the interval predictor and its residual
([COMB] eq. 14, 15, 18, 19) against a plain-Python recursion written from the equations, the
learned λ_q (eq. 6, ``"max"`` and ``"evt"``) and thresholds (eq. 10–13) against their
documented formulas, and the decision boundary (|ε_k| = τ_k is not an alarm, the alarm
latches, an alarm at the last step).

The expected values never come from the function under test: the predictor's from
:func:`scenarios.servo.rod_rate` (docs/physics.md §3) and the recursion written out below, the
fit's from the residual and plain loops, the decision's from a residual given by hand.
"""

from __future__ import annotations

import math
from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest
from scipy.stats import binom

from detectors.builtin.comb_interval import (NUMERICS, IntervalDetector, dead_zone,
                                             filter_threshold,
                                     g_radius, loop_gain, moving_average_maxima,
                                     power_law_bound, predictor_step, stability_margin)
from scenarios.compiled import use_engine
from scenarios.params import ELEVATOR
from scenarios.servo import plant_arrays, rod_rate
from scenarios.signals import Signals

ENGINES = ("compiled", "numpy")
TS = 0.01
#: flight point of the hand-built runs: q̄ = 10 kPa and α = 2° load the rod, so the loop
#: gain differs on the two sides of an error (docs/physics.md §3: the hinge load aids one
#: direction of motion and opposes the other)
POINT = {"qbar_pa": 10e3, "alpha_deg": 2.0, "mach": 0.7, "vcas_kt": 300.0,
         "alt_ft": 28000.0, "mass_t": 180.0, "cg_pct": 30.0}


def signals(command, rod_com, classes=None):
    """Signals of a hand-made order and COM rod acquisition [mm] (MON = COM, no surface)."""
    command = np.atleast_2d(np.asarray(command, float))
    rod_com = np.atleast_2d(np.asarray(rod_com, float))
    n, T = command.shape
    nan = np.full((n, T), np.nan)
    return Signals(ts=TS, command=command, current=np.zeros((n, T)), rod_com=rod_com,
                   rod_mon=rod_com.copy(), surface=nan, pressure=nan,
                   schedule={k: np.full(n, v) for k, v in POINT.items()}, actuator=ELEVATOR,
                   run_ids=np.array([f"r{i}" for i in range(n)]), classes=classes)


def gamma_by_hand(u, y):
    """γ = ẋ/(u − y) [1/s] of the nominal loop at the measured y ([COMB] eq. 2, current
    sat(K·e), docs/physics.md §3), |e| below 1e-6 mm evaluated at ±1e-6 mm with e's sign."""
    p = plant_arrays(ELEVATOR, qbar_pa=np.array([POINT["qbar_pa"]]),
                     alpha_deg=np.array([POINT["alpha_deg"]]), mach=np.array([POINT["mach"]]))
    e = u - y
    if abs(e) < 1e-6:
        e = -1e-6 if e < 0.0 else 1e-6
    i = min(max(float(p.K[0]) * e, -float(p.i_max[0])), float(p.i_max[0]))
    return float(rod_rate(np.array([y]), np.array([i]), p, np.array([True]))[0]) / e


def predict_by_hand(u, y, kappa, hr, x0r):
    """x^c, x^r and the dead-zone residual of one run, written out from [COMB] eq. 14, 15
    (the appendix form, module docstring), 18 and 19 with h^c = 1."""
    k1, k2, k3 = kappa
    T = len(u)
    xc_out, xr_out, r_out = np.empty(T), np.empty(T), np.empty(T)
    xc, xr = y[0], x0r
    for k in range(T):
        xc_out[k], xr_out[k] = xc, xr
        lower, upper = xc - xr, xc + xr
        r_out[k] = y[k] - upper if y[k] > upper else (y[k] - lower if y[k] < lower else 0.0)
        gc = 1.0 - gamma_by_hand(u[k], y[k]) * TS
        gr = min(k1 + k2 * abs(u[k] - xc), k3)
        xc, xr = (gc * xc + (1.0 - gc) * u[k],
                  (abs(gc) + gr) * xr + gr * abs(xc - u[k])
                  + (abs(1.0 - gc) + gr) * hr * abs(u[k]))
    return xc_out, xr_out, r_out


# ---- the equations at hand-picked points ---------------------------------------------------
def test_g_radius_measures_the_distance_of_the_order_from_the_centre():
    # κ = (0.02, 0.02 /mm, 0.06): |u − x^c| = |3 − 2| = 1 mm → 0.04; |−1 − 1| = 2 mm → 0.06
    got = g_radius(np.array([3.0, -1.0, 2.5]), np.array([2.0, 1.0, 2.0]), (0.02, 0.02, 0.06))
    assert got == pytest.approx([0.04, 0.06, 0.03], rel=1e-12)


def test_dead_zone_away_from_zero_bounds():
    # [lower, upper] = [−1, 2]: below by 2 → −2, above by 3 → 3, inside → 0
    y = np.array([-3.0, 5.0, 0.5, -1.0, 2.0])
    assert dead_zone(y, -1.0, 2.0) == pytest.approx([-2.0, 3.0, 0.0, 0.0, 0.0])


def test_filter_threshold_uses_the_given_initial_bound():
    # [COMB] eq. 10 with μ = 3 (not λ1 = 1), a = 0.5, λ = (1, 0.6):
    # r = 0: μ; r = 1: a·μ + (1 − a)·λ1 = 2; r = 2: a²μ + (1 − a)(2aλ2 + (1 − a)λ1) = 1.3
    lam = np.array([1.0, 0.6])
    assert filter_threshold(lam, 0.5, 0, mu=3.0) == 3.0
    assert filter_threshold(lam, 0.5, 1, mu=3.0) == pytest.approx(2.0, rel=1e-12)
    assert filter_threshold(lam, 0.5, 2, mu=3.0) == pytest.approx(1.3, rel=1e-12)


def test_predictor_step_defaults_and_a_static_gain_centre():
    # defaults h^c = 1, h^r = 0: x^c' = 0.8·1 + 0.2·3 = 1.4, x^r' = 0.85·0.2 + 0.05·2 = 0.27
    xc, xr = predictor_step(1.0, 0.2, 3.0, 0.8, 0.05)
    assert (xc, xr) == (pytest.approx(1.4, rel=1e-12), pytest.approx(0.27, rel=1e-12))
    # h^c = 1.1: x^c' = 0.8 + 0.2·1.1·3 = 1.46; x^r' = 0.17 + 0.05·|1 − 3.3| = 0.285
    xc, xr = predictor_step(1.0, 0.2, 3.0, 0.8, 0.05, 1.1)
    assert (xc, xr) == (pytest.approx(1.46, rel=1e-12), pytest.approx(0.285, rel=1e-12))


def test_moving_averages_start_at_the_first_sample():
    # r = (1, −1, 1, −1): every window of 2 sums to 0, so λ_2 = 0 (a window starting before
    # the run would see 1/2); windows of 3: |1|/3; of 4: 0
    r = np.array([[1.0, -1.0, 1.0, -1.0]])
    for engine in ENGINES:
        with use_engine(engine):
            assert moving_average_maxima(r, 4)[0] == pytest.approx([1.0, 0.0, 1 / 3, 0.0],
                                                                    rel=1e-15, abs=0.0)


@pytest.mark.parametrize("lam, floor", [((10.0, 4e-12), 1e-11), ((0.5, 2e-13), 5e-13)])
def test_power_law_guards_an_excess_below_1e12_of_the_largest_lambda(lam, floor):
    # β0 = min λ / 2; an excess λ_q − β0 below 1e-12·max λ (here λ_2 − β0 = λ_2/2) is raised
    # to it before the logarithm; with two points the fit is exact: γ = ln(e2/e1)/ln 2
    alpha, gamma, beta = power_law_bound(np.array(lam))
    e1, e2 = lam[0] - lam[1] / 2, floor
    assert gamma == pytest.approx(math.log(e2 / e1) / math.log(2.0), rel=1e-9)
    assert alpha == pytest.approx(e1, rel=1e-9)
    assert beta >= lam[1] / 2


@pytest.mark.parametrize("error", [-4e-7, 0.0, 4e-7, -3.0, 3.0])
def test_loop_gain_keeps_the_side_of_the_error_under_load(error):
    # under a hinge load the rate differs between opening and closing the error, so the
    # limit ẋ/(u − y) at u − y → 0 depends on the side it is taken from (u = y: the + side)
    y = 5.0
    p = plant_arrays(ELEVATOR, qbar_pa=np.array([POINT["qbar_pa"]]),
                     alpha_deg=np.array([POINT["alpha_deg"]]), mach=np.array([POINT["mach"]]))
    assert loop_gain(np.array([y + error]), np.array([y]), p)[0] == pytest.approx(
        gamma_by_hand(y + error, y), rel=1e-12)
    assert gamma_by_hand(y - 4e-7, y) != pytest.approx(gamma_by_hand(y + 4e-7, y), rel=1e-3)


# ---- the interval predictor on a hand-built run, both engines ------------------------------
#: two runs of four steps (n ≠ T): at step 1 the measurement sits within 1e-6 mm of the
#: order (below it in run 0, above it in run 1) while the centre is still far from the order,
#: so the side of γ's limit moves x^c; then measurements leaving the interval above and below
U = np.array([[0.0, 2.0, 2.0, 2.0], [-1.0, 3.0, 3.0, 3.0]])
Y = np.array([[0.0, 2.0 + 5e-7, 2.0, 2.5], [-1.0, 3.0 - 3e-7, -3.0, 0.0]])


@pytest.mark.parametrize("engine", ENGINES)
def test_predictor_over_more_runs_than_one_block(engine):
    # BLOCK + 6 runs: the compiled kernel's second block holds the last 6 runs
    from scenarios.compiled import BLOCK

    reps = BLOCK // 2 + 3
    u, y = np.tile(U, (reps, 1)), np.tile(Y, (reps, 1))
    y = y + np.repeat(np.arange(reps) * 1e-3, 2)[:, None]
    kappa, hr, x0r = (0.02, 0.03, 0.08), 0.05, 0.1
    with use_engine(engine):
        _, xc, xr = IntervalDetector(kappa=kappa, h_radius=hr, x0_radius_mm=x0r).predict(
            signals(u, y))
    for i in (0, BLOCK - 1, BLOCK, 2 * reps - 1):
        want_c, want_r, _ = predict_by_hand(u[i], y[i], kappa, hr, x0r)
        assert xc[i] == pytest.approx(want_c, rel=1e-12, abs=1e-15), i
        assert xr[i] == pytest.approx(want_r, rel=1e-12, abs=1e-15), i


@pytest.mark.parametrize("engine", ENGINES)
def test_predictor_and_residual_follow_eq14_15_18_19(engine):
    kappa, hr, x0r = (0.02, 0.03, 0.08), 0.05, 0.1
    det = IntervalDetector(kappa=kappa, h_radius=hr, x0_radius_mm=x0r)
    sig = signals(U, Y)
    with use_engine(engine):
        y, xc, xr = det.predict(sig)
        r = det.interval_residual(sig)
    np.testing.assert_array_equal(y, Y)
    assert xc.shape == xr.shape == r.shape == Y.shape
    for i in range(2):
        want_c, want_r, want_res = predict_by_hand(U[i], Y[i], kappa, hr, x0r)
        # the engines evaluate the same formulas in a different order: relative 1e-12
        assert xc[i] == pytest.approx(want_c, rel=1e-12, abs=1e-15)
        assert xr[i] == pytest.approx(want_r, rel=1e-12, abs=1e-15)
        assert r[i] == pytest.approx(want_res, rel=1e-9, abs=1e-12)
    np.testing.assert_array_equal(xc[:, 0], Y[:, 0])              # x_0^c = y_0
    assert np.all(xr[:, 0] == x0r)
    assert (r > 0).any() and (r < 0).any()                        # both sides of the interval


# ---- decision: filter, threshold schedule and latching, both engines ------------------------
def _decider(r, thresholds, a=0.5):
    """A comb-interval detector whose interval residual is *r* (given by hand) and whose
    learned threshold schedule for pole *a* is *thresholds* (q̄ = len − 1)."""
    det = IntervalDetector(poles=(a,), q_max=len(thresholds) - 1)
    det.thresholds_ = {det.variant_name(a): np.asarray(thresholds, float)}
    det.learning_runs_ = 10
    det.interval_residual = lambda _signals: np.asarray(r, float)
    return det


@pytest.mark.parametrize("engine", ENGINES)
def test_filtered_residual_at_the_threshold_is_an_alarm_just_below_none(engine):
    # a = 0.5, r ≡ c: ε_k = c exactly (ε_0 = r_0, then 0.5·c + 0.5·c), τ ≡ 1 → |ε|/τ = c.
    # The alarm is |ε|/τ ≥ 1 ([COMB] §4 writes >, which differs only at equality): with ≥
    # the run's margin ≥ s is exactly its alarm at threshold × s (Detection.decision)
    below = np.nextafter(1.0, 0.0)
    r = np.full((3, 12), below)
    r[0] = 1.0              # exactly at the threshold: alarm at step 0
    r[2, 7] = 3.0           # ε_7 = 0.5·below + 1.5 ≈ 2: alarm at step 7, latched after
    det = _decider(r, [1.0, 1.0, 1.0])
    with use_engine(engine):
        d = det.detect(signals(np.zeros((3, 12)), np.zeros((3, 12))))["a=0.5"]
    assert np.all(d.residual[0] == 1.0) and d.alarm[0].all()
    assert np.all(d.residual[1] == below) and not d.alarm[1].any()
    assert d.residual[2, 7] == 0.5 * below + 1.5
    assert not d.alarm[2, :7].any() and d.alarm[2, 7:].all()    # latched once raised
    np.testing.assert_array_equal(d.decision, d.residual)       # no confirmation logic


@pytest.mark.parametrize("engine", ENGINES)
def test_threshold_schedule_is_indexed_by_step_then_constant(engine):
    # τ = (4, 2, 1) (q̄ = 2): |ε| ≡ 1.5 gives 0.375, 0.75, then 1.5 from step q̄ on
    det = _decider(np.full((1, 6), 1.5), [4.0, 2.0, 1.0])
    with use_engine(engine):
        d = det.detect(signals(np.zeros((1, 6)), np.zeros((1, 6))))["a=0.5"]
    assert d.residual[0] == pytest.approx([0.375, 0.75, 1.5, 1.5, 1.5, 1.5], rel=1e-15)
    np.testing.assert_array_equal(d.alarm[0], [False, False, True, True, True, True])


@pytest.mark.parametrize("engine", ENGINES)
def test_the_filter_starts_at_the_first_residual(engine):
    # ε_0 = r_0 (Corollary 2), then ε_k = a·ε_{k−1} + (1 − a)·r_k: r = (2, 0, 0, 0), a = 0.5
    # gives 2, 1, 0.5, 0.25; a negative residual gives the same |ε|
    det = _decider(np.array([[2.0, 0.0, 0.0, 0.0], [-2.0, 0.0, 0.0, 0.0]]), [1.0, 1.0])
    with use_engine(engine):
        d = det.detect(signals(np.zeros((2, 4)), np.zeros((2, 4))))["a=0.5"]
    assert d.residual == pytest.approx(np.tile([2.0, 1.0, 0.5, 0.25], (2, 1)), rel=1e-15)
    assert d.alarm.all()                                       # over at step 0, latched


def test_a_pole_without_threshold_is_refused():
    det = _decider(np.ones((1, 4)), [1.0, 1.0])
    det.poles = (0.5, 0.9)
    with pytest.raises(ValueError, match=r"pole 0\.9 has no learned threshold"):
        det.detect(signals(np.zeros((1, 4)), np.zeros((1, 4))))


# ---- fit: λ_q, thresholds and the stored state by formula -------------------------------------
N_RUNS, T_LEARN = 20, 60


@pytest.fixture(scope="module")
def learning():
    """20 fault-free learning runs of 0.6 s: an order holding 2 mm, a rod with noise of a
    different size per run (so one run leads each λ_q and the leave-one-out ratios differ)."""
    rng = np.random.default_rng(3)
    u = np.full((N_RUNS, T_LEARN), 2.0)
    y = 2.0 + rng.standard_normal((N_RUNS, T_LEARN)) * np.linspace(0.01, 0.08, N_RUNS)[:, None]
    return signals(u, y)


def maxima_by_hand(r, q_max):
    """max_k |(1/q)·Σ_{j<q} r_{k+j}| of each run, q = 1…q_max (windows within a run)."""
    n, T = r.shape
    out = np.zeros((n, q_max))
    for i in range(n):
        for q in range(1, q_max + 1):
            out[i, q - 1] = max(abs(sum(r[i, k:k + q])) / q for k in range(T - q + 1))
    return out


def tau_eq13_by_hand(lam, a):
    """τ of [COMB] eq. 13 (k ≥ q̄), μ = λ1:
    a^q̄·λ1 + (1 − a)·(q̄·a^(q̄−1)·λ_q̄ + Σ_{q<q̄} q·(a^(q−1) − a^q)·λ_q)."""
    qb = len(lam)
    tail = sum(q * (a ** (q - 1) - a ** q) * lam[q - 1] for q in range(1, qb))
    return a ** qb * lam[0] + (1.0 - a) * (qb * a ** (qb - 1) * lam[qb - 1] + tail)


def test_max_rule_fit_is_safety_times_the_largest_moving_average(learning):
    det = IntervalDetector(threshold_method="max", safety=1.3, q_max=8, poles=(0.6, 0.9))
    det.fit(learning)
    r = det.interval_residual(learning)
    m = maxima_by_hand(r, 8)
    assert m.max() > 1e-3                                     # not the floor's case
    lam = np.maximum(1.3 * m.max(axis=0), 1e-4)               # eq. 6, floor_mm = 1e-4
    assert det.lambda_q_ == pytest.approx(lam, rel=1e-12)
    for a in (0.6, 0.9):
        tau = det.thresholds_[f"a={a:g}"]
        assert len(tau) == 9                                  # τ_0 … τ_q̄
        assert tau[0] == pytest.approx(lam[0], rel=1e-12)     # eq. 11 at k = 0: μ = λ1
        assert tau[-1] == pytest.approx(tau_eq13_by_hand(lam, a), rel=1e-12)
    assert det.learning_runs_ == N_RUNS
    assert not hasattr(det, "calibration_")
    err = float(np.max(np.abs(learning.command - learning.rod_com)))
    assert det.max_loop_error_mm_ == err
    assert det.stability_margin_ == stability_margin((0.02, 0.02, 0.06), ELEVATOR, TS, err)[0]
    q = np.arange(1, 9)
    assert det.variability_ == pytest.approx(
        sum((1 - lam[k] / lam[0]) / (k + 1) ** 2 for k in range(8)) / (math.pi ** 2 / 6 - 1),
        rel=1e-12)
    p = det.power_law_
    assert np.all(p["alpha"] * q ** p["gamma"] + p["beta"] >= lam * (1 - 1e-12))


def test_max_rule_floor_applies_to_every_lambda(learning):
    det = IntervalDetector(threshold_method="max", q_max=4, floor_mm=5.0, poles=(0.8,))
    det.fit(learning)
    assert np.all(det.lambda_q_ == 5.0)
    assert det.thresholds_["a=0.8"] == pytest.approx(np.full(5, 5.0), rel=1e-12)


def test_evt_fit_scales_the_learned_profile_by_the_calibrated_factor(learning):
    # p = 0.05 at 60 % confidence: 18 runs support it (1 − 0.95¹⁸ ≥ 0.6); with 20 runs the
    # largest rank r with P(Binomial(20, 0.05) ≥ r) ≥ 0.6 is r = 1: s = the largest ratio
    assert binom.sf(0, 20, 0.05) >= 0.6 > binom.sf(1, 20, 0.05)
    det = IntervalDetector(threshold_method="evt", target_fa_per_run=0.05,
                           threshold_confidence=0.6, safety=1.3, q_max=6, poles=(0.9,))
    det.fit(learning)
    m = maxima_by_hand(det.interval_residual(learning), 6)
    floor = 1e-4
    ratios = [max(m[i, q] / max(max(m[j, q] for j in range(N_RUNS) if j != i), floor)
                  for q in range(6)) for i in range(N_RUNS)]
    s = max(ratios)
    assert s > 1.0
    assert det.calibration_.supported and det.calibration_.threshold == pytest.approx(s)
    profile = np.maximum(m.max(axis=0), floor)
    assert det.lambda_q_ == pytest.approx(np.maximum(s * profile, floor), rel=1e-12)
    assert det.thresholds_["a=0.9"][-1] == pytest.approx(tau_eq13_by_hand(det.lambda_q_, 0.9),
                                                         rel=1e-12)


def test_evt_fit_falls_back_to_the_max_rule_when_unsupported(learning):
    # p = 1e-4 needs 29 956 runs: 20 cannot support it, λ_q is the "max" rule's
    det = IntervalDetector(threshold_method="evt", safety=1.3, q_max=6, poles=(0.9,))
    det.fit(learning)
    assert not det.calibration_.supported
    m = maxima_by_hand(det.interval_residual(learning), 6)
    assert det.lambda_q_ == pytest.approx(np.maximum(1.3 * m.max(axis=0), 1e-4), rel=1e-12)


def test_power_law_thresholds_come_from_the_fitted_curve(learning):
    det = IntervalDetector(threshold_method="max", q_max=8, poles=(0.8,), use_power_law=True)
    det.fit(learning)
    p = det.power_law_
    basis = [p["alpha"] * q ** p["gamma"] + p["beta"] for q in range(1, 9)]
    tau = det.thresholds_["a=0.8"]
    assert len(tau) == 9
    assert tau[0] == pytest.approx(p["alpha"] + p["beta"], rel=1e-12)   # μ = α·1^γ + β
    assert tau[-1] == pytest.approx(tau_eq13_by_hand(basis, 0.8), rel=1e-12)
    # the bound is not λ itself: the thresholds differ from the plain ones
    plain = IntervalDetector(threshold_method="max", q_max=8, poles=(0.8,)).fit(learning)
    assert tau[-1] != pytest.approx(plain.thresholds_["a=0.8"][-1], rel=1e-6)


def test_fit_refuses_learning_runs_shorter_than_q_max(learning):
    with pytest.raises(ValueError, match=r"q_max = 61 steps is longer than the learning runs "
                                         r"\(60 steps\)"):
        IntervalDetector(q_max=61).fit(learning)


def test_eq17_message_names_the_room_left_for_g_radius(learning):
    kappa = (0.3, 0.02, 0.5)
    err = float(np.max(np.abs(learning.command - learning.rod_com)))
    margin, where = stability_margin(kappa, ELEVATOR, TS, err)
    with pytest.raises(ValueError) as exc:
        IntervalDetector(kappa=kappa, q_max=5).fit(learning)
    text = str(exc.value)
    assert f"{margin:.4f} at altitude {where['alt_ft']:g} ft" in text
    assert f"stays below 1 − |g^c| = {1.0 - abs(where['g_c']):.4f} there" in text


def test_stability_margin_is_the_largest_eq17_value_on_the_documented_grid():
    """[COMB] eq. 17 over 31 deflections spanning the authority × 41 loop errors spanning
    ±max_error, at one flight point, by brute force with γ of eq. 2 at each grid node."""
    import pandas as pd

    from scenarios import envelope
    from scenarios.servo import authority_limits

    point = pd.DataFrame({"alt_ft": [10000.0], "vcas_kt": [250.0], "mass_t": [200.0],
                          "cg_pct": [30.0]})
    kappa, max_err = (0.02, 0.02, 0.06), 2.0
    margin, where = stability_margin(kappa, ELEVATOR, TS, max_err, points=point)
    fc = envelope.flight_condition(10000.0, 250.0, 200.0, 30.0)
    p = plant_arrays(ELEVATOR, qbar_pa=np.atleast_1d(fc["qbar_pa"]),
                     alpha_deg=np.atleast_1d(fc["alpha_deg"]), mach=np.atleast_1d(fc["mach"]))
    lo, hi = (float(v[0]) for v in authority_limits(p, ELEVATOR))
    best, at = -1.0, None
    for j in range(31):
        d = lo + (hi - lo) * j / 30
        y = ELEVATOR.r_mm * math.sin(math.radians(d))
        for i in range(41):
            e = -max_err + 2.0 * max_err * i / 40
            gc = 1.0 - loop_gain(np.array([y + e]), np.array([y]), p)[0] * TS
            if abs(gc) + min(0.02 + 0.02 * abs(e), 0.06) > best:
                best, at = abs(gc) + min(0.02 + 0.02 * abs(e), 0.06), (d, e, gc)
    # the grids' nodes are computed by np.linspace there: 1e-12 relative
    assert margin == pytest.approx(best, rel=1e-12)
    assert 0.8 < margin < 1.0
    assert where["alt_ft"] == 10000.0 and where["vcas_kt"] == 250.0
    assert (where["deflection_deg"] - lo) / (hi - lo) * 30 == pytest.approx(
        round((where["deflection_deg"] - lo) / (hi - lo) * 30), abs=1e-9)
    assert (where["error_mm"] + max_err) / (2 * max_err) * 40 == pytest.approx(
        round((where["error_mm"] + max_err) / (2 * max_err) * 40), abs=1e-9)
    assert where["g_c"] + where["g_r"] == pytest.approx(margin, rel=1e-12)
    # where: the deflection, the order's error u − y and g^c of that node
    assert (where["deflection_deg"], where["error_mm"], where["g_c"]) == pytest.approx(
        at, rel=1e-12)


def test_the_shortest_window_is_two_steps():
    IntervalDetector(q_max=2).validate_params()
    with pytest.raises(ValueError, match="q_max"):
        IntervalDetector(q_max=1).validate_params()


def test_learning_runs_as_long_as_q_max_are_enough(learning):
    det = IntervalDetector(threshold_method="max", q_max=T_LEARN, poles=(0.9,)).fit(learning)
    assert det.lambda_q_.shape == (T_LEARN,)


def test_the_sensor_read_as_y():
    rod = np.array([[1.0, 2.0, 3.0]])
    sig = signals(np.zeros((1, 3)), rod)
    np.testing.assert_array_equal(
        IntervalDetector(sensor="rod_mon").measurement(replace(sig, rod_mon=rod + 0.5)), rod + 0.5)
    np.testing.assert_array_equal(IntervalDetector().measurement(sig), rod)
    surface = replace(sig, surface=np.array([[0.0, 1.0, -2.0]]))          # deg
    assert IntervalDetector(sensor="surface").measurement(surface) == pytest.approx(
        ELEVATOR.r_mm * np.sin(np.radians([[0.0, 1.0, -2.0]])), rel=1e-15)
    # the surface sensor is needed only when it is read
    with pytest.raises(ValueError, match=r"sensor='surface'\) needs a surface position"):
        IntervalDetector(sensor="surface").check_signals(sig)
    IntervalDetector(sensor="rod_com").check_signals(sig)
    with pytest.raises(ValueError, match="nominal actuator parameters"):
        IntervalDetector().check_signals(replace(sig, actuator=None))


def test_repeated_poles_are_refused_by_the_parameter_check():
    with pytest.raises(ValueError, match=r"poles = \[0\.9, 0\.9\]: 0\.9 repeated"):
        IntervalDetector(poles=[0.9, 0.9]).validate_params()


def test_a_single_pole_is_one_variant(learning):
    det = IntervalDetector(poles=0.9, threshold_method="max", q_max=5)
    det.validate_params()                                   # a single number is accepted
    det.fit(learning)
    assert list(det.thresholds_) == ["a=0.9"]
    assert list(det.detect(learning)) == ["a=0.9"]


def test_numerical_constants_are_frozen():
    with pytest.raises(FrozenInstanceError):
        NUMERICS.gain_eps_mm = 1.0


def test_defaults_are_the_documented_ones():
    # docs/detectors.md and docs/interval-detector.md parameter tables ([COMB] §4, Table 1
    # for the poles, ς = 1.2; q̄ = 300 steps: 3 s at the 10 ms FCC period)
    assert IntervalDetector().get_params() == {
        "poles": (0.6, 0.8, 0.9, 0.95, 0.99), "safety": 1.2, "kappa": (0.02, 0.02, 0.06),
        "h_radius": 0.0, "q_max": 300, "x0_radius_mm": 0.5, "sensor": "rod_com",
        "use_power_law": False, "floor_mm": 1e-4, "threshold_method": "evt",
        "target_fa_per_run": 1e-4, "threshold_confidence": 0.95, "threshold_tail": "exponential"}


def test_coverage_capabilities_and_rate_evaluations():
    """On the surface sensor the detector covers every fault type; on a rod sensor every one
    but the disconnection, which leaves the rod following its order (docs/physics.md §5).
    It fits on the workers, its alarm is a decision a trade-off curve may scale, and its
    predictor evaluates the rate law once per step ([COMB] eq. 14; bench's floor)."""
    from detectors.base import Coverage
    from scenarios.catalog import FAULT_TYPES

    assert IntervalDetector(sensor="surface").coverage() == Coverage(None, "")
    for sensor in ("rod_com", "rod_mon"):
        rod = IntervalDetector(sensor=sensor).coverage()
        assert rod.faults == tuple(f for f in FAULT_TYPES if f != "disconnection")
        assert f"the {sensor} measurement" in rod.reason
    caps = IntervalDetector.capabilities
    assert (caps.needs_fit, caps.needs_surface_sensor, caps.causal, caps.fit_concurrently,
            caps.threshold_scale) == (True, False, True, True, True)
    assert IntervalDetector().rate_evaluations_per_step() == 1


def test_the_warm_up_runs_the_predictor_on_writable_and_read_only_signals(monkeypatch):
    """detect reads the signals as read-only views (scenarios.compiled.read_only_view), a
    fit's arrays are writable: the warm-up calls the predictor kernel on both, so that numba
    compiles (or loads) both signatures before a campaign's first chunk."""
    from conftest import warm_up_writability

    import detectors.builtin.comb_interval as ci

    assert warm_up_writability(monkeypatch, ci, "_predict_block") == [True, False]
