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


@pytest.mark.slow
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
    assert params["threshold_method"] == "evt"
    assert params["target_fa_per_run"] == 1e-4 and params["threshold_confidence"] == 0.95
    assert params["threshold_tail"] == "exponential"
    for bad in ({"threshold_method": "gpd"}, {"target_fa_per_run": 0.5},
                {"threshold_confidence": 0.3}, {"threshold_tail": "heavy"}):
        with pytest.raises(ValueError):
            make_detector(name, bad)


# ---- the tail's shape range: free, light, auto (detectors.tail.fit_tail) -------------------
def _gauss_maxima(rng, n):
    """Per-run maxima of 100 standard normal samples: a light (Gumbel-domain) tail."""
    return rng.standard_normal((n, 100)).max(axis=1)


def _gauss_maxima_sf(t):
    return 1.0 - stats.norm.cdf(t) ** 100


def test_light_tail_keeps_the_shape_non_positive_and_auto_rejects_it_on_a_heavy_tail():
    from detectors.tail import fit_tail

    heavy = stats.genpareto.rvs(0.8, size=400, random_state=np.random.default_rng(3))
    free, light = fit_tail(heavy, tail="free"), fit_tail(heavy, tail="light")
    assert free.shape > 0.4 and light.shape <= 0.0 and light.tail == "light"
    auto = fit_tail(heavy, tail="auto")
    assert auto.light_rejected is True and auto.tail == "free" and auto.shape == free.shape
    # a Gaussian-maxima tail is light: the test has no reason to reject it
    gauss = fit_tail(_gauss_maxima(np.random.default_rng(4), 400), tail="auto")
    assert gauss.light_rejected is False and gauss.tail == "light" and gauss.shape <= 0.0
    with pytest.raises(ValueError, match="tail"):
        fit_tail(heavy, tail="heavy")


def test_auto_tail_coverage_on_gaussian_maxima():
    """docs/thresholds.md, coverage table: 100 learning sets of n = 200 maxima of 100
    normals, p = 1e-3, c = 0.95. Measured 17/100 thresholds with an exact P(X > τ) above p
    (the profile bound is asymptotic; nominal 5 %). The bound 25 is two binomial standard
    deviations (√(100·0.17·0.83) ≈ 3.8) above the measured count; the draws are seeded."""
    rng = np.random.default_rng(12345)
    misses = sum(_gauss_maxima_sf(calibrate_threshold(_gauss_maxima(rng, 200), 1e-3,
                                                      0.95, tail="auto").threshold) > 1e-3
                 for _ in range(100))
    assert misses <= 25


def test_exponential_tail_covers_gaussian_maxima_where_the_light_fit_does_not():
    """docs/thresholds.md, "Which tail": 100 learning sets of n = 50 maxima of 100 normals
    (one class of a preset's learning set), p = 1e-4, c = 0.95. The light fit's ξ < 0 puts
    an end point under the true quantile: measured 25/100 misses here (48/200 on other
    draws); the exponential tail (ξ = 0) 1/100 (0/200). Bounds: light ≥ 12 is 2.8 binomial
    standard deviations (√(100·0.24·0.76) ≈ 4.3) below 24/100; exponential ≤ 10 is the
    nominal 5 % plus 2.3 standard deviations (√(100·0.05·0.95) ≈ 2.2). Seeded."""
    rng = np.random.default_rng(4711)
    sets = [_gauss_maxima(rng, 50) for _ in range(100)]

    def misses(tail):
        return sum(_gauss_maxima_sf(calibrate_threshold(x, 1e-4, 0.95, tail=tail).threshold)
                   > 1e-4 for x in sets)

    assert misses("exponential") <= 10
    assert misses("light") >= 12
    cal = calibrate_threshold(sets[0], 1e-4, 0.95, tail="exponential")
    assert cal.method == "gpd" and cal.shape == 0.0 and "exponential tail" in cal.note


def test_exponential_tail_reports_a_rejected_light_tail():
    """On a heavy tail (ξ = 0.5, 400 values) the exponential fit is kept and the note says
    the likelihood-ratio test rejects ξ ≤ 0."""
    x = stats.genpareto.rvs(0.5, size=400, random_state=np.random.default_rng(3))
    cal = calibrate_threshold(x, 1e-3, 0.95, tail="exponential")
    assert cal.shape == 0.0 and "rejects ξ ≤ 0" in cal.note


def test_learned_threshold_per_class_is_the_largest_class_threshold():
    rng = np.random.default_rng(8)
    a, b = _gauss_maxima(rng, 60), 2.0 * _gauss_maxima(rng, 60)   # class b: twice the scale
    m = np.concatenate([a, b])
    classes = np.array(["a"] * 60 + ["b"] * 60)
    tau, cal = learned_threshold(m, "evt", 1.5, 1e-4, 0.95, tail="auto", classes=classes)
    ta = calibrate_threshold(a, 1e-4, 0.95, tail="auto").threshold
    tb = calibrate_threshold(b, 1e-4, 0.95, tail="auto").threshold
    assert cal.method == "per-class" and tau == max(ta, tb) == tb
    # a class of one run cannot be calibrated alone: the runs are pooled
    tau1, cal1 = learned_threshold(m[:61], "evt", 1.5, 1e-4, 0.95, tail="auto",
                                   classes=classes[:61])
    assert cal1.method != "per-class"
    assert tau1 == calibrate_threshold(m[:61], 1e-4, 0.95, tail="auto").threshold


def test_learned_threshold_of_a_single_learning_run_is_safety_times_it():
    tau, cal = learned_threshold(np.array([0.4]), "evt", 1.5, 1e-4, 0.95)
    assert tau == 1.5 * 0.4
    assert cal.supported is False and cal.method == "max-factor"


def test_signals_carry_the_learning_classes_through_take_and_concat():
    from scenarios.signals import Signals

    z = np.zeros((3, 4))
    sig = Signals(ts=0.01, command=z, current=z, rod_com=z, rod_mon=z, surface=z, pressure=z,
                  classes=np.array(["cruise", "nose_up", "cruise"]))
    assert list(sig.take(np.array([2, 1])).classes) == ["cruise", "nose_up"]
    assert list(Signals.concat([sig, sig]).classes) == ["cruise", "nose_up", "cruise"] * 2
    assert sig.truncate(2).classes is sig.classes


def test_a_campaign_fits_its_detectors_with_the_learning_runs_manoeuvres(tmp_path):
    """The runner gives fit() the learning runs' manoeuvres (Signals.classes), so the
    thresholds are calibrated per manoeuvre: with 2 runs per class (fewer than a tail fit
    needs) every class falls back to safety × its largest value, and the threshold is the
    largest class threshold, noted as such in the fitted state."""
    import json

    from campaign import run
    from campaign.config import CampaignConfig

    config = CampaignConfig.from_dict({
        "campaign": {"name": "classes", "seed": 1, "duration_s": 20.0},
        "group": [{"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"],
                   "count": 2}],
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 2, "manoeuvres": ["cruise", "nose_up"]},
    })
    run(config, tmp_path / "c", jobs=1, progress=False)
    state = json.loads((tmp_path / "c" / "fitted" / "position-monitor.json").read_text())
    text = json.dumps(state["learned"]["calibration_"])
    assert "largest of 2 class thresholds" in text
    assert '"method": "max-factor"' in text and "per-class" in text


@pytest.mark.parametrize("positive", [19, 100])
def test_maxima_with_an_atom_at_zero_are_fitted_above_the_atom(positive):
    """Per-run maxima of a statistic that most fault-free runs never lift off zero (a
    CUSUM, an excess over an allowance clipped at 0): of N = 600 runs, *positive* are
    Exp(1), the rest exactly 0. The top fifth (k = 120) then holds zeros, and a generalised
    Pareto tail fitted to excesses of which most are 0 claims a threshold below values the
    learning set itself exceeds (0.13 against a largest of 0.37 on a CUSUM). The fit keeps
    the values strictly above the atom: with 19 (fewer than 20) no probability is claimed;
    with 100 the threshold meets P(X > τ) = (100/600)·e^(−τ) ≤ p in at least 90 of 100
    learning sets (the profile bound's nominal 95, less 2.3 binomial standard deviations)."""
    rng = np.random.default_rng(8086)
    misses, methods = 0, set()
    for _ in range(100):
        x = np.zeros(600)
        x[:positive] = rng.exponential(size=positive)
        cal = calibrate_threshold(x, 1e-4, 0.95, tail="exponential")
        methods.add(cal.method)
        misses += (positive / 600) * math.exp(-cal.threshold) > 1e-4
    if positive < 20:
        assert methods == {"max-factor"}
    else:
        assert methods == {"gpd"} and misses <= 10


def test_a_rounding_tie_at_the_cut_moves_it_by_the_tie_not_to_a_fallback():
    """Per-run maxima quantised by a sensor (0.01 mm steps, as com_mon's in addsafe-grid):
    of 50 values the 20th and 21st largest are equal, so the (k + 1)-th largest, u, ties
    with an exceedance. The cut moves below the tied pair (k = 21, u = the 22nd largest),
    the fit stays supported; moving above it would leave 19, fewer than the 20 a fit needs."""
    from detectors.tail import fit_tail

    x = 0.01 * np.arange(100.0, 50.0, -1.0)           # 1.00, 0.99, ..., 0.51: 50 distinct
    x[20] = x[19]                                     # the 20th and 21st largest tie at 0.81
    fit = fit_tail(x, tail="exponential")
    assert (fit.k, fit.u) == (21, x[21])
    cal = calibrate_threshold(x, 1e-4, 0.95, tail="exponential")
    assert cal.method == "gpd" and cal.k == 21 and cal.supported
