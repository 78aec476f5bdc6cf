"""detectors.calibrate: thresholds calibrated to a target per-run false-alarm probability
(docs/thresholds.md) — coverage on constructed per-run maxima with known tails, the
fallbacks, determinism, bad input — and the built-in detectors' threshold_method."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from detectors import make_detector
from detectors.calibrate import (
    MIN_TAIL_FIT_RUNS,
    Calibration,
    calibrate_threshold,
    leave_one_out_ratios,
    learned_threshold,
    min_learning_runs,
    tail_size,
)
from detectors.state import decode, encode

#: Repetitions of the learning set in the coverage tests, its size and the target.
REPS, N, P, CONF = 200, 200, 1e-3, 0.95
#: Per-run maxima of M standard normal samples: Gumbel domain, slow to reach it.
M = 100

#: name → (draw (rng, shape) → values, exact survival function P(X > x)).
TAILS = {
    "exponential": (lambda rng, shape: rng.exponential(size=shape), stats.expon.sf),
    "pareto-0.2": (lambda rng, shape: stats.genpareto.rvs(0.2, size=shape, random_state=rng),
                   lambda x: stats.genpareto.sf(x, 0.2)),
    "gaussian-max": (lambda rng, shape: rng.standard_normal(shape + (M,)).max(axis=-1),
                     lambda x: -np.expm1(M * stats.norm.logcdf(x))),
}

#: Tolerance of the coverage test: the profile-likelihood bound is asymptotic (Wilks); with
#: k = 40 exceedances it fails a little more often than 1 − confidence (measured 7.5–11.5 %
#: for tails in the generalised Pareto family, docs/thresholds.md). The test refuses a
#: failure rate significantly above 1 − confidence + this tolerance. For the Gaussian
#: per-run maxima (a misspecified, slowly converging tail: measured 21 %) it is wider.
TOLERANCE = {"exponential": 0.10, "pareto-0.2": 0.10, "gaussian-max": 0.20}


@pytest.mark.parametrize("name", list(TAILS))
def test_calibrated_threshold_meets_the_target_at_the_stated_confidence(name):
    draw, sf = TAILS[name]
    rng = np.random.default_rng(20240917)
    learning = draw(rng, (REPS, N))
    cals = [calibrate_threshold(x, P, CONF) for x in learning]
    assert {c.method for c in cals} == {"gpd"}
    realised = np.array([sf(c.threshold) for c in cals])       # exact P(X > τ)
    failures = int((realised > P).sum())
    test = stats.binomtest(failures, REPS, (1 - CONF) + TOLERANCE[name], alternative="greater")
    assert test.pvalue > 0.01, (f"{failures}/{REPS} thresholds exceed the target "
                                f"(allowed about {(1 - CONF) + TOLERANCE[name]:.2f})")
    # the bound matters: the point estimate of the quantile alone fails about half the time
    point = int((np.array([sf(c.estimate) for c in cals]) > P).sum())
    assert point > 3 * failures


def test_realised_false_alarms_on_a_large_independent_sample():
    rng = np.random.default_rng(5)
    cal = calibrate_threshold(rng.exponential(size=N), P, CONF)
    sample = rng.exponential(size=1_000_000)
    realised = float(np.mean(sample > cal.threshold))
    exact = float(stats.expon.sf(cal.threshold))
    assert realised == pytest.approx(exact, abs=5 * math.sqrt(max(exact, 1e-6) / 1e6))


def test_order_statistic_route_is_distribution_free_and_exact():
    # n ≥ ln(0.05)/ln(0.99) = 299: the r-th largest value with P(Bin(n, p) ≥ r) ≥ 0.95
    p, n = 1e-2, 1000
    rng = np.random.default_rng(3)
    cal = calibrate_threshold(rng.standard_cauchy(n) ** 2, p, CONF)
    assert cal.method == "order-statistic" and cal.supported
    r = cal.k
    assert stats.binom.sf(r - 1, n, p) >= CONF > stats.binom.sf(r, n, p)
    # coverage over repeated learning sets, any distribution (here a heavy tail)
    X = rng.standard_cauchy((REPS, n)) ** 2
    taus = np.array([calibrate_threshold(x, p, CONF).threshold for x in X])
    realised = 2.0 * stats.cauchy.sf(np.sqrt(taus))      # P(C² > τ), C standard Cauchy
    failures = int((realised > p).sum())
    assert stats.binomtest(failures, REPS, 1 - CONF, alternative="greater").pvalue > 0.01


def test_min_learning_runs_is_the_smallest_n_that_supports_the_target():
    for p in (1e-4, 1e-3, 1e-2, 0.05):
        n = min_learning_runs(p, CONF)
        assert 1 - (1 - p) ** n >= CONF > 1 - (1 - p) ** (n - 1)
    assert min_learning_runs(1e-4, 0.95) == 29956
    assert min_learning_runs(1e-3, 0.95, method="gpd") == MIN_TAIL_FIT_RUNS
    # just enough runs: the maximum itself, supported; one fewer: not supported
    n = min_learning_runs(1e-2, CONF)
    x = np.random.default_rng(0).exponential(size=n)
    assert calibrate_threshold(x, 1e-2, CONF).threshold == x.max()


def test_fallbacks_for_short_and_degenerate_tails():
    rng = np.random.default_rng(1)
    short = rng.exponential(size=MIN_TAIL_FIT_RUNS - 1)
    cal = calibrate_threshold(short, 1e-4, CONF, fallback_factor=1.5)
    assert cal.method == "max-factor" and not cal.supported
    assert cal.threshold == 1.5 * short.max()
    assert "not supported" in cal.note and str(MIN_TAIL_FIT_RUNS) in cal.note
    # a tail of ties (many runs with the same largest value) is not fitted
    ties = np.concatenate([np.full(60, 2.0), rng.uniform(0.0, 1.0, 60)])
    cal = calibrate_threshold(ties, 1e-4, CONF, fallback_factor=2.0)
    assert cal.method == "max-factor" and "degenerate" in cal.note
    assert cal.threshold == 4.0


def test_the_fit_is_deterministic_and_independent_of_the_order():
    x = np.random.default_rng(11).exponential(size=150)
    a = calibrate_threshold(x, 1e-4, CONF)
    b = calibrate_threshold(x[::-1].copy(), 1e-4, CONF)
    assert a == b and a.method == "gpd"
    assert a.k == tail_size(150) == 30
    assert a.threshold > a.estimate > a.u
    assert np.isfinite([a.shape, a.scale, a.gof_pvalue]).all()


def test_per_class_takes_the_largest_class_threshold():
    rng = np.random.default_rng(2)
    x = np.concatenate([rng.exponential(size=400), 3.0 * rng.exponential(size=400)])
    classes = ["cruise"] * 400 + ["nose_up"] * 400
    cal = calibrate_threshold(x, 1e-2, CONF, classes=classes)
    parts = dict(cal.per_class)
    assert cal.method == "per-class" and set(parts) == {"cruise", "nose_up"}
    assert cal.threshold == max(c.threshold for c in parts.values())
    assert cal.threshold == parts["nose_up"].threshold
    assert parts["cruise"] == calibrate_threshold(x[:400], 1e-2, CONF)


def test_calibration_is_plain_data():
    cal = calibrate_threshold(np.random.default_rng(4).exponential(size=100), 1e-3, CONF,
                              classes=["a", "b"] * 50)
    doc, arrays = encode({"calibration_": cal})
    back = decode(doc, arrays)["calibration_"]
    assert isinstance(back, Calibration) and back.threshold == cal.threshold
    assert encode({"calibration_": back}) == (doc, arrays)       # NaN fields included
    assert dict(back.per_class)["a"].threshold == dict(cal.per_class)["a"].threshold


@pytest.mark.parametrize("values, kwargs, match", [
    ([1.0, np.nan, 2.0], {}, "non-finite"),
    ([1.0, np.inf], {}, "non-finite"),
    ([1.0], {}, "at least 2"),
    ([], {}, "at least 2"),
    ([[1.0, 2.0]], {}, "1-D"),
    ([1.0, -2.0], {}, "negative"),
    ([1.0, 2.0], {"target_fa_per_run": 0.0}, "target_fa_per_run"),
    ([1.0, 2.0], {"target_fa_per_run": 1.0}, "target_fa_per_run"),
    ([1.0, 2.0], {"target_fa_per_run": -1e-3}, "target_fa_per_run"),
    ([1.0, 2.0], {"confidence": 0.4}, "confidence"),
    ([1.0, 2.0], {"confidence": 1.0}, "confidence"),
    ([1.0, 2.0], {"fallback_factor": 0.5}, "fallback_factor"),
    ([1.0, 2.0], {"classes": ["a"]}, "classes"),
    ([1.0, 2.0, 3.0], {"classes": ["a", "b", "b"]}, "class 'a'"),
])
def test_bad_input_is_a_clear_value_error(values, kwargs, match):
    args = {"target_fa_per_run": 1e-3, **kwargs}
    p = args.pop("target_fa_per_run")
    with pytest.raises(ValueError, match=match):
        calibrate_threshold(values, p, **args)


def test_learned_threshold_max_is_safety_times_max():
    m = np.array([0.1, 0.3, 0.2])
    assert learned_threshold(m, "max", 1.5, 1e-4, 0.95) == (1.5 * 0.3, None)
    tau, cal = learned_threshold(m, "evt", 1.5, 1e-4, 0.95)
    assert isinstance(cal, Calibration) and tau == cal.threshold == 1.5 * 0.3
    with pytest.raises(ValueError, match="threshold_method"):
        learned_threshold(m, "mean", 1.5, 1e-4, 0.95)


def test_leave_one_out_ratios_scale_each_run_by_the_others():
    m = np.array([[1.0, 4.0], [2.0, 1.0], [0.5, 2.0]])
    # run 0: max(1/2, 4/2) = 2; run 1: max(2/1, 1/4); run 2: max(0.5/2, 2/4)
    np.testing.assert_array_equal(leave_one_out_ratios(m), [2.0, 2.0, 0.5])
    np.testing.assert_array_equal(leave_one_out_ratios(m, floor=3.0), [4.0 / 3.0, 2.0 / 3.0,
                                                                        0.5])


@pytest.mark.parametrize("name", ["position-monitor", "comb-interval", "chen-local",
                                  "chen-global", "vanek-geometric"])
def test_builtin_detectors_declare_the_threshold_parameters(name):
    det = make_detector(name)
    params = det.get_params()
    assert params["threshold_method"] == "max"
    assert params["target_fa_per_run"] == 1e-4 and params["threshold_confidence"] == 0.95
    for bad in ({"threshold_method": "gpd"}, {"target_fa_per_run": 0.5},
                {"threshold_confidence": 0.3}):
        with pytest.raises(ValueError):
            make_detector(name, bad)
