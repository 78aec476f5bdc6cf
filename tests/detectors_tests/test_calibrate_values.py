"""detectors.calibrate by value: the boundaries of every rule (docs/thresholds.md), the
notes a calibration stores, the per-class combination and the leave-one-out ratios, on
hand-built inputs whose answers follow from the documented formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from detectors.calibrate import (MIN_TAIL_FIT_RUNS, calibrate_threshold, leave_one_out_ratios,
                                 learned_threshold, min_learning_runs, tail_size,
                                 usable_classes)


def order_statistic_rank(n: int, p: float, c: float) -> int:
    """The documented rank: the largest r with P(Binomial(n, p) ≥ r) ≥ c (by summation)."""
    r = 0
    for rank in range(1, n + 1):
        tail = sum(math.comb(n, i) * p ** i * (1 - p) ** (n - i) for i in range(rank, n + 1))
        if tail >= c:
            r = rank
    return r


# ---- probabilities and factors: the open intervals, at their ends ----------------------------
@pytest.mark.parametrize("kwargs, match", [
    ({"confidence": 0.5}, r"confidence = 0.5: outside \(0.5, 1\).*e\.g\. confidence = 0.95"),
    ({"target_fa_per_run": 0.0},
     r"target_fa_per_run = 0.0: outside \(0, 1\).*e\.g\. target_fa_per_run = 0.0001"),
    ({"target_fa_per_run": "often"}, r"target_fa_per_run = 'often': not a number.*\(0, 1\)"),
    ({"confidence": None}, r"confidence = None: not a number.*\(0.5, 1\)"),
    ({"fallback_factor": "big"}, r"fallback_factor = 'big': must be a finite number ≥ 1"),
    ({"fallback_factor": math.inf}, "fallback_factor = inf"),
    ({"fallback_factor": 0.999}, "fallback_factor = 0.999"),
])
def test_a_bad_probability_or_factor_names_the_interval_and_an_example(kwargs, match):
    args = {"target_fa_per_run": 1e-3, "confidence": 0.95, **kwargs}
    with pytest.raises(ValueError, match=match):
        calibrate_threshold([1.0, 2.0], **args)


def test_the_smallest_accepted_values():
    """Two runs, a zero maximum and a fallback factor of exactly 1 are all valid."""
    cal = calibrate_threshold([0.0, 2.0], 1e-3, 0.95, fallback_factor=1.0)
    assert cal.method == "max-factor" and cal.threshold == 2.0 and cal.n == 2
    assert cal.largest == 2.0 and cal.k == 0 and math.isnan(cal.u)
    cal = calibrate_threshold(np.zeros(2), 1e-3, 0.95)
    assert cal.threshold == 0.0
    assert calibrate_threshold([1.0, 2.0], 1e-3, 0.5 + 1e-9).method == "max-factor"


def test_bad_values_name_the_first_offender():
    with pytest.raises(ValueError, match=r"values: 2 non-finite value\(s\) \(first at index 1: "
                                         r"nan\)"):
        calibrate_threshold([1.0, np.nan, 2.0, np.inf], 1e-3)
    with pytest.raises(ValueError, match="values: negative value -0.5"):
        calibrate_threshold([0.0, -0.5, 2.0], 1e-3)           # a zero is no offender
    with pytest.raises(ValueError, match="values: not an array of numbers"):
        calibrate_threshold(["a", "b"], 1e-3)
    with pytest.raises(ValueError, match=r"values: 1 value\(s\); at least 2"):
        calibrate_threshold([1.0], 1e-3)
    with pytest.raises(ValueError, match=r"got shape \(2, 1\)"):
        calibrate_threshold([[1.0], [2.0]], 1e-3)


# ---- the number of learning runs ---------------------------------------------------------------
@pytest.mark.parametrize("p, c", [(0.99, 0.9), (0.9, 0.9), (0.5, 0.75), (0.3, 0.51), (0.05, 0.95),
                                  (1e-2, 0.99), (0.2, 0.999), (1e-3, 0.6)])
def test_min_learning_runs_is_exactly_the_smallest_n(p, c):
    """1 − (1 − p)^n ≥ c > 1 − (1 − p)^(n − 1), checked by brute force from n = 1."""
    n = 1
    while 1.0 - (1.0 - p) ** n < c:
        n += 1
    assert min_learning_runs(p, c) == n


@pytest.mark.parametrize("p, n", [(0.1, 9), (0.1, 28), (0.25, 5)])
def test_a_confidence_reached_exactly_takes_that_many_runs(p, n):
    """c = 1 − (1 − p)^n exactly: n runs meet it, although ln(1 − c)/ln(1 − p) rounds to a
    little above n (the rounding guard of min_learning_runs)."""
    c = -math.expm1(n * math.log1p(-p))
    assert min_learning_runs(p, c) == n


def test_min_learning_runs_one_run_and_bad_method():
    assert min_learning_runs(0.99, 0.9) == 1           # one run already exceeds the quantile
    assert min_learning_runs(0.5, 0.5 + 1e-9) == 2
    with pytest.raises(ValueError, match="method = 'bayes': not 'order-statistic' or 'gpd'"):
        min_learning_runs(1e-3, 0.95, method="bayes")
    with pytest.raises(ValueError, match="confidence"):
        min_learning_runs(1e-3, 1.0, method="gpd")


# ---- the order-statistic route: the rank and its note ----------------------------------------
def smallest_n_with_rank(target: int, p: float, c: float) -> int:
    """The fewest runs whose documented rank (the largest r with P(Binomial(n, p) ≥ r) ≥ c)
    is *target*: the rank grows by at most one per added run, so a scan from below finds it."""
    n = target
    while True:
        ranks = np.arange(1, n + 1)
        if ranks[stats.binom.sf(ranks - 1, n, p) >= c].max(initial=0) >= target:
            return n
        n += 1


def test_the_rank_is_the_documented_one():
    for n in (59, 80, 150):
        x = np.linspace(1.0, 2.0, n)
        cal = calibrate_threshold(x, 0.05, 0.95)
        assert cal.k == order_statistic_rank(n, 0.05, 0.95)
        assert cal.threshold == cal.estimate == x[::-1][cal.k - 1]


@pytest.mark.parametrize("target, ordinal", [
    (1, "1st"), (2, "2nd"), (3, "3rd"), (4, "4th"), (11, "11th"), (12, "12th"), (13, "13th"),
    (21, "21st"), (22, "22nd"), (23, "23rd"), (111, "111th"), (112, "112th"), (121, "121st"),
])
def test_order_statistic_note_names_the_rank_in_english(target, ordinal):
    """English ordinals: 11th–13th (and 111th–113th) but 21st, 22nd, 23rd, 121st."""
    p, c = 0.05, 0.95
    n = smallest_n_with_rank(target, p, c)
    cal = calibrate_threshold(np.linspace(1.0, 2.0, n), p, c)
    assert cal.method == "order-statistic" and cal.supported and cal.k == target
    assert cal.note == (f"the {ordinal} largest of {n} values (P(Binomial({n}, {p:g}) ≥ "
                        f"{target}) ≥ {c:g}; distribution-free)")


def test_just_enough_runs_take_the_maximum_and_one_fewer_cannot():
    p, c = 0.05, 0.95
    n = min_learning_runs(p, c)                         # 59
    x = np.linspace(1.0, 3.0, n)
    cal = calibrate_threshold(x, p, c)
    assert (cal.method, cal.k, cal.threshold) == ("order-statistic", 1, 3.0)
    short = calibrate_threshold(x[1:], p, c, fallback_factor=1.25)
    assert short.method != "order-statistic"


# ---- the fallback and its reasons ----------------------------------------------------------------
def test_too_few_runs_fall_back_with_both_counts_in_the_note():
    x = np.linspace(1.0, 2.0, MIN_TAIL_FIT_RUNS - 1)
    cal = calibrate_threshold(x, 1e-3, 0.9, fallback_factor=2.0)
    assert (cal.method, cal.supported, cal.threshold) == ("max-factor", False, 4.0)
    need = min_learning_runs(1e-3, 0.9)
    assert cal.note == (f"not supported: {MIN_TAIL_FIT_RUNS - 1} runs: fewer than the "
                        f"{MIN_TAIL_FIT_RUNS} the tail fit needs and the {need} the largest "
                        "value needs to guarantee p = 0.001 at 0.9; threshold = largest value "
                        "× 2 (no probability claimed)")
    assert math.isnan(cal.estimate) and cal.largest == 2.0 and cal.n == MIN_TAIL_FIT_RUNS - 1


def test_a_target_outside_the_fitted_tail_falls_back():
    """With n = 50 runs the tail holds k = 20, k/n = 0.4: p = 0.4 is not below it (the GPD
    quantile needs p < k/n), and at a confidence of 1 − 10⁻¹² the order statistic needs 55
    runs."""
    n, c = MIN_TAIL_FIT_RUNS, 1.0 - 1e-12
    assert tail_size(n) == 20 and min_learning_runs(0.4, c) > n
    x = np.linspace(1.0, 2.0, n)
    cal = calibrate_threshold(x, 0.4, c, fallback_factor=1.5)
    assert cal.method == "max-factor"
    assert "p = 0.4 is not in the fitted tail (k/n = 0.4)" in cal.note
    assert calibrate_threshold(x, 0.39, c).method == "gpd"


def test_a_degenerate_tail_names_the_run_count_needed():
    ties = np.concatenate([np.full(60, 2.0), np.linspace(0.0, 1.0, 60)])
    cal = calibrate_threshold(ties, 1e-4, 0.95, fallback_factor=1.5)
    need = min_learning_runs(1e-4, 0.95)
    assert cal.method == "max-factor" and cal.threshold == 3.0
    assert f", and 120 runs are fewer than the {need} the largest value needs" in cal.note


# ---- the generalised Pareto route: fields and notes --------------------------------------------
def test_gpd_fields_and_note():
    x = np.random.default_rng(11).exponential(size=150)
    cal = calibrate_threshold(x, 1e-4, 0.95)
    k = tail_size(150)
    assert cal.method == "gpd" and cal.supported and cal.k == k == 30
    assert cal.u == np.sort(x)[::-1][k]                    # the (k + 1)-th largest value
    assert cal.n == 150 and cal.largest == x.max()
    assert -0.5 <= cal.shape <= 1.0 and cal.scale > 0 and 0.0 <= cal.gof_pvalue <= 1.0
    assert cal.note.startswith(f"generalised Pareto tail of the top {k} of 150 values above "
                               f"u = {cal.u:g}: ξ = {cal.shape:.3g}")
    assert f"upper 0.95 profile-likelihood bound {cal.threshold:.6g}" in cal.note
    assert f"(1 − p)-quantile {cal.estimate:.6g}" in cal.note


def test_tail_notes_say_which_shape_was_assumed():
    heavy = stats.genpareto.rvs(0.8, size=400, random_state=np.random.default_rng(3))
    light = calibrate_threshold(heavy, 1e-4, 0.95, tail="light")
    assert ("light tail (ξ ≤ 0) assumed although the likelihood-ratio test rejects ξ ≤ 0"
            in light.note)
    assert light.shape <= 0.0
    auto = calibrate_threshold(heavy, 1e-4, 0.95, tail="auto")
    assert "light tail (ξ ≤ 0) rejected by the likelihood-ratio test, free shape" in auto.note
    assert auto.shape > 0.0
    gauss = np.random.default_rng(4).standard_normal((400, 100)).max(axis=1)
    cal = calibrate_threshold(gauss, 1e-4, 0.95, tail="light")
    assert "light tail (ξ ≤ 0), ξ ≤ 0 not rejected by the likelihood-ratio test" in cal.note
    free = calibrate_threshold(gauss, 1e-4, 0.95, tail="free")
    assert "likelihood-ratio" not in free.note


def test_a_shape_at_the_edge_of_its_range_is_noted():
    """Uniform maxima: excesses with a finite end point, ξ = −1 in truth, held at −0.5."""
    x = np.linspace(0.0, 1.0, 200)
    cal = calibrate_threshold(x, 1e-3, 0.95)
    assert cal.method == "gpd" and cal.shape == -0.5
    assert "(ξ at the edge of its range)" in cal.note
    light = calibrate_threshold(x, 1e-3, 0.95, tail="light")   # −0.5 is the light range's edge
    assert light.shape == -0.5 and "(ξ at the edge of its range)" in light.note
    # a very heavy tail (ξ = 2 in truth) is held at the upper edge ξ = 1 of the free range
    heavy = stats.genpareto.rvs(2.0, size=300, random_state=np.random.default_rng(6))
    cal = calibrate_threshold(heavy, 1e-3, 0.95)
    assert cal.shape == 1.0 and "(ξ at the edge of its range)" in cal.note
    # an interior shape is not at an edge
    mid = calibrate_threshold(stats.genpareto.rvs(0.2, size=300,
                                                  random_state=np.random.default_rng(1)),
                              1e-3, 0.95)
    assert -0.5 < mid.shape < 1.0 and "edge" not in mid.note


# ---- classes -------------------------------------------------------------------------------------
def test_per_class_fields_and_note():
    a = np.linspace(1.0, 2.0, 10)                     # too few: max-factor, unsupported
    b = np.linspace(1.0, 4.0, 80)                     # 80 ≥ 59: order statistic
    x = np.concatenate([b, a])
    classes = np.array(["b"] * 80 + ["a"] * 10)
    cal = calibrate_threshold(x, 0.05, 0.95, classes=classes, fallback_factor=3.0)
    parts = dict(cal.per_class)
    assert [label for label, _ in cal.per_class] == ["a", "b"]       # sorted
    assert parts["a"].threshold == 6.0 and parts["a"].method == "max-factor"
    assert parts["b"].method == "order-statistic"
    assert cal.threshold == 6.0 and cal.supported is False and cal.n == 90
    assert cal.largest == 4.0 and cal.estimate == parts["b"].estimate
    assert cal.note == ("largest of 2 class thresholds ('a', max-factor); not supported for "
                        "class(es) 'a'")
    ok = calibrate_threshold(b, 0.1, 0.95, classes=["u", "v"] * 40)   # 40 ≥ 29 each
    assert ok.supported is True and ok.note.startswith("largest of 2 class thresholds (")
    assert "not supported" not in ok.note


def test_usable_classes_need_two_runs_each():
    assert usable_classes(None) is None
    assert usable_classes(["a", "a", "b"]) is None
    two = ["a", "b", "a", "b"]
    assert usable_classes(two) is two


# ---- learned_threshold ---------------------------------------------------------------------------
def test_learned_threshold_single_run_and_zero():
    tau, cal = learned_threshold(np.array([0.0]), "evt", 2.0, 1e-4, 0.95)
    assert tau == 0.0 and cal.method == "max-factor" and cal.n == 1
    assert "1 runs: fewer than the" in cal.note and "× 2 (no probability claimed)" in cal.note
    # a single value that is no per-run maximum is not taken as one
    for bad in (np.nan, np.inf, -1.0):
        with pytest.raises(ValueError, match="at least 2 learning runs"):
            learned_threshold(np.array([bad]), "evt", 2.0, 1e-4, 0.95)


def test_learned_threshold_passes_the_target_confidence_and_tail():
    x = np.random.default_rng(12).exponential(size=120)
    tau, cal = learned_threshold(x, "evt", 1.5, 1e-3, 0.9, tail="light")
    ref = calibrate_threshold(x, 1e-3, 0.9, fallback_factor=1.5, tail="light")
    assert tau == ref.threshold and cal == ref
    assert learned_threshold(x, "max", 1.5, 1e-3, 0.9) == (1.5 * x.max(), None)


# ---- leave-one-out ratios ------------------------------------------------------------------------
def test_leave_one_out_ratios_with_ties_zeros_and_a_floor():
    # ties: the run holding the largest value is scaled by the tied second
    np.testing.assert_array_equal(leave_one_out_ratios(np.array([[2.0], [2.0], [1.0]])),
                                  [1.0, 1.0, 0.5])
    # the others all zero: a positive value is infinitely above them, zero over zero is 0
    m = np.array([[0.0, 3.0], [0.0, 0.0], [2.0, 0.0]])
    np.testing.assert_array_equal(leave_one_out_ratios(m), [np.inf, 0.0, np.inf])
    np.testing.assert_array_equal(leave_one_out_ratios(np.zeros((2, 1))), [0.0, 0.0])
    # a floor replaces the zero denominators
    np.testing.assert_array_equal(leave_one_out_ratios(m, floor=0.5), [6.0, 0.0, 4.0])
    for bad in (np.zeros((1, 3)), np.zeros(4)):
        with pytest.raises(ValueError, match=r"maxima must be \(n_runs ≥ 2, n_checks\)"):
            leave_one_out_ratios(bad)


# ---- the declared parameters: open ranges -------------------------------------------------------
@pytest.mark.parametrize("name, good, bad", [
    ("target_fa_per_run", (1e-9, 0.05, 0.0999), (0.0, 0.1)),
    ("threshold_confidence", (0.500001, 0.9, 0.999999), (0.5, 1.0)),
])
def test_threshold_parameters_are_open_intervals(name, good, bad):
    """docs/thresholds.md: target_fa_per_run in (0, 0.1), threshold_confidence in (0.5, 1)."""
    from detectors import make_detector

    for value in good:
        assert make_detector("position-monitor", {name: value}).get_params()[name] == value
    for value in bad:
        with pytest.raises(ValueError, match=name):
            make_detector("position-monitor", {name: value})


def test_min_learning_runs_defaults_to_95_percent_confidence():
    """n ≥ ln(1 − 0.95)/ln(1 − p) (docs/thresholds.md): 29 956 runs for 10⁻⁴, 299 for 10⁻²."""
    assert min_learning_runs(1e-4) == 29956 == min_learning_runs(1e-4, 0.95)
    assert min_learning_runs(1e-2) == 299


def test_unsupported_calibration_falls_back_to_one_and_a_half_times_the_largest_value():
    cal = calibrate_threshold([1.0, 3.0, 2.0], 1e-4)         # 3 runs: nothing supported
    assert cal.method == "max-factor" and not cal.supported
    assert cal.threshold == 4.5


def test_leave_one_out_ratio_of_a_run_alone_above_zero_is_infinite():
    """Every other run at 0 (floor 0): the profile without run i is 0, so run i > 0 scales
    it infinitely and a run at 0 by 0 (not 0/1)."""
    np.testing.assert_array_equal(leave_one_out_ratios(np.array([[0.0], [0.0], [0.5]])),
                                  [0.0, 0.0, np.inf])
    np.testing.assert_array_equal(leave_one_out_ratios(np.array([[0.0], [0.0]])), [0.0, 0.0])
