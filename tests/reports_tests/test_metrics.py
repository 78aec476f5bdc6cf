"""Run-level metric definitions (docs/design.md §5, Metrics) on constructed alarm sequences, and the
exact binomial bounds."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from reports.scoring.metrics import (RESULT_COLUMNS, SCORE_COLUMNS, clopper_pearson, lower_bound,
                             score_runs, upper_bound)

TS = 0.1          # [s] sampling period of the constructed runs
N_STEPS = 60      # 6 s runs
ONSET = 3.0       # [s] onset, an exact decimal but not an exact binary multiple of TS
REQUIRED = 0.5    # [s] required detection time
K_ONSET = 30      # step at onset: 30 * 0.1 = 3.0000000000000004 in binary floating point

# Times are k * TS with k integer; comparisons below are against values built the same way,
# so 1e-12 absolute covers the rounding of one multiplication and one subtraction.
ATOL_S = 1e-12


def score_one(alarm_steps, *, fault="runaway", onset=ONSET, residual=None, window_s=None):
    alarm = np.zeros((1, N_STEPS), dtype=bool)
    alarm[0, list(alarm_steps)] = True
    if residual is None:
        residual = np.zeros((1, N_STEPS))
    return score_runs(
        run_id=np.array(["r0"]), fault=np.array([fault]), onset_s=np.array([onset]),
        alarm=alarm, residual=np.asarray(residual, dtype=float).reshape(1, -1), ts=TS,
        required_time_s=np.array([REQUIRED if fault != "none" else np.nan]),
        window_s=window_s,
    ).iloc[0]


def test_columns():
    row = score_one([K_ONSET])
    assert tuple(row.index) == SCORE_COLUMNS
    assert set(SCORE_COLUMNS) <= set(RESULT_COLUMNS)


def test_alarm_before_onset_is_a_false_alarm_and_not_a_detection():
    row = score_one([10])  # 1.0 s < onset, nothing afterwards
    assert row.false_alarm and row.pre_onset_alarm
    assert not row.detected
    assert math.isnan(row.first_alarm_s) and math.isnan(row.delay_s) and math.isnan(row.dtp)


def test_alarm_before_onset_and_after_onset():
    row = score_one([10, K_ONSET + 4])
    assert row.false_alarm and row.detected
    # the first alarm at/after onset counts, not the pre-onset one
    assert row.delay_s == pytest.approx(4 * TS, abs=ATOL_S)


def test_alarm_exactly_at_onset_has_zero_delay():
    # K_ONSET * TS is 3.0000000000000004, not 3.0: exact float equality would be fragile.
    row = score_one([K_ONSET])
    assert row.detected and not row.false_alarm
    assert row.first_alarm_s == pytest.approx(ONSET, abs=ATOL_S)
    assert row.delay_s == pytest.approx(0.0, abs=ATOL_S)
    assert row.dtp == pytest.approx(0.0, abs=ATOL_S)


def test_step_time_rounded_below_the_onset_still_counts_as_post_onset():
    # ts = 0.03 s, onset 0.33 s: step 11 is at 11 * 0.03 = 0.32999999999999996 < 0.33 in
    # floating point; the 1e-9 s guard must keep it as "at onset", not a false alarm.
    ts, k = 0.03, 11
    assert k * ts < 0.33  # the premise of this test
    alarm = np.zeros((1, 20), dtype=bool)
    alarm[0, k] = True
    row = score_runs(run_id=np.array(["r"]), fault=np.array(["runaway"]),
                     onset_s=np.array([0.33]), alarm=alarm, residual=np.zeros((1, 20)),
                     ts=ts, required_time_s=np.array([REQUIRED])).iloc[0]
    assert row.detected and not row.false_alarm
    assert row.delay_s == pytest.approx(0.0, abs=ATOL_S)


def test_alarm_one_step_after_onset():
    row = score_one([K_ONSET + 1])
    assert row.detected and not row.false_alarm
    assert row.delay_s == pytest.approx(TS, abs=ATOL_S)
    assert row.dtp == pytest.approx(TS / REQUIRED, abs=ATOL_S)


def test_alarm_one_step_before_onset_only_is_false_alarm_and_miss():
    row = score_one([K_ONSET - 1])
    assert row.false_alarm and not row.detected


def test_no_alarm_is_a_miss():
    row = score_one([])
    assert not row.detected and not row.false_alarm
    assert math.isnan(row.first_alarm_s) and math.isnan(row.delay_s) and math.isnan(row.dtp)


def test_alarm_after_the_window_is_a_miss():
    # window 1 s: alarm at onset + 1.5 s is too late
    row = score_one([K_ONSET + 15], window_s=1.0)
    assert not row.detected
    assert math.isnan(row.first_alarm_s)
    # the last step of the window still counts (onset + 1.0 s)
    row = score_one([K_ONSET + 10], window_s=1.0)
    assert row.detected and row.delay_s == pytest.approx(1.0, abs=ATOL_S)
    # without a window the same late alarm is a detection
    row = score_one([K_ONSET + 15])
    assert row.detected and row.delay_s == pytest.approx(1.5, abs=ATOL_S)


def test_fault_free_without_alarm():
    residual = np.linspace(0.0, 0.8, N_STEPS)
    row = score_one([], fault="none", onset=np.nan, residual=residual)
    assert not row.false_alarm and not row.pre_onset_alarm and not row.detected
    assert math.isnan(row.first_alarm_s) and math.isnan(row.delay_s) and math.isnan(row.dtp)
    assert row.margin == pytest.approx(0.8)  # whole run is fault-free


def test_fault_free_with_alarm():
    row = score_one([42, 50], fault="none", onset=np.nan)
    assert row.false_alarm and row.pre_onset_alarm and not row.detected
    assert row.first_alarm_s == pytest.approx(42 * TS, abs=ATOL_S)
    assert math.isnan(row.delay_s) and math.isnan(row.dtp)


def test_margin_only_before_onset():
    residual = np.full(N_STEPS, 0.2)
    residual[K_ONSET - 1] = 0.7     # last pre-onset sample
    residual[K_ONSET] = 5.0         # at onset: the fault's own effect, not a margin
    residual[K_ONSET + 5:] = 9.0
    row = score_one([K_ONSET], residual=residual)
    assert row.margin == pytest.approx(0.7)


def test_margin_ignores_nan_and_is_nan_without_pre_onset_sample():
    residual = np.full(N_STEPS, np.nan)
    residual[3] = 0.4
    assert score_one([K_ONSET], residual=residual).margin == pytest.approx(0.4)
    row = score_one([0], onset=0.0, residual=np.ones(N_STEPS))
    assert math.isnan(row.margin)
    assert row.detected and row.delay_s == 0.0


def test_vectorised_batch_matches_single_runs():
    cases = [([10], "runaway"), ([K_ONSET], "runaway"), ([], "solid_jam"),
             ([5], "none"), ([], "none")]
    alarm = np.zeros((len(cases), N_STEPS), dtype=bool)
    for i, (steps, _) in enumerate(cases):
        alarm[i, steps] = True
    faults = np.array([f for _, f in cases])
    out = score_runs(run_id=np.array([f"r{i}" for i in range(len(cases))]), fault=faults,
                     onset_s=np.where(faults == "none", np.nan, ONSET), alarm=alarm,
                     residual=np.zeros(alarm.shape), ts=TS,
                     required_time_s=np.where(faults == "none", np.nan, REQUIRED))
    assert out["false_alarm"].tolist() == [True, False, False, True, False]
    assert out["detected"].tolist() == [False, True, False, False, False]
    assert out["run_id"].tolist() == ["r0", "r1", "r2", "r3", "r4"]


def test_per_run_window_and_required_time():
    alarm = np.zeros((2, N_STEPS), dtype=bool)
    alarm[:, K_ONSET + 5] = True
    out = score_runs(run_id=np.array(["a", "b"]), fault=np.array(["runaway", "runaway"]),
                     onset_s=np.array([ONSET, ONSET]), alarm=alarm,
                     residual=np.zeros(alarm.shape), ts=TS,
                     required_time_s=np.array([0.5, 1.0]), window_s=np.array([0.2, np.nan]))
    assert out["detected"].tolist() == [False, True]
    assert out["dtp"].iloc[1] == pytest.approx(0.5, abs=ATOL_S)


@pytest.mark.parametrize("kwargs, match", [
    ({"onset_s": np.array([np.nan])}, "onset_s"),
    ({"required_time_s": np.array([np.nan])}, "required_time_s"),
    ({"required_time_s": np.array([0.0])}, "required_time_s"),   # a DTP denominator of 0
    ({"run_id": np.array(["r", "s"])}, "run_id"),
    ({"fault": np.array(["runaway", "none"])}, "fault"),
    ({"ts": 0.0}, "ts"),
    ({"window_s": -1.0}, "window_s"),
    ({"residual": np.zeros((1, 3))}, "residual"),
])
def test_bad_input_is_named(kwargs, match):
    args = dict(run_id=np.array(["r"]), fault=np.array(["runaway"]), onset_s=np.array([1.0]),
                alarm=np.zeros((1, 10), bool), residual=np.zeros((1, 10)), ts=TS,
                required_time_s=np.array([REQUIRED]))
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        score_runs(**args)


def test_runs_without_samples_are_refused_and_one_sample_is_enough():
    with pytest.raises(ValueError, match="no time steps"):
        score_runs(run_id=np.array(["r"]), fault=np.array(["none"]), onset_s=np.array([np.nan]),
                   alarm=np.zeros((1, 0), bool), residual=np.zeros((1, 0)), ts=TS,
                   required_time_s=np.array([np.nan]))
    out = score_runs(run_id=np.array(["r"]), fault=np.array(["none"]), onset_s=np.array([np.nan]),
                     alarm=np.ones((1, 1), bool), residual=np.full((1, 1), 2.0), ts=TS,
                     required_time_s=np.array([np.nan]))
    assert bool(out["false_alarm"].iloc[0]) and out["first_alarm_s"].iloc[0] == 0.0
    assert out["margin"].iloc[0] == 2.0


def test_missing_onsets_name_the_first_five_runs():
    n = 7
    with pytest.raises(ValueError) as exc:
        score_runs(run_id=np.array([f"run{i}" for i in range(n)]), fault=np.full(n, "runaway"),
                   onset_s=np.full(n, np.nan), alarm=np.zeros((n, 10), bool),
                   residual=np.zeros((n, 10)), ts=TS, required_time_s=np.full(n, REQUIRED))
    assert str(exc.value).endswith("run(s) run0, run1, run2, run3, run4")


def _reference(alarm_row, fault, onset, ts, required, window):
    """Step-by-step reading of docs/design.md §5, Metrics, for one run."""
    times = [k * ts for k in range(len(alarm_row))]
    if fault == "none":
        hits = [t for t, a in zip(times, alarm_row) if a]
        return bool(hits), False, (hits[0] if hits else math.nan)
    pre = any(a for t, a in zip(times, alarm_row) if t < onset - 1e-9)
    post = [t for t, a in zip(times, alarm_row)
            if a and onset - 1e-9 <= t <= onset + window + 1e-9]
    return pre, bool(post), (post[0] if post else math.nan)


def _reference_margin(residual_row, fault, onset, ts):
    """The largest non-NaN residual before onset (the whole run when fault-free), NaN when
    there is none (docs/design.md §5, Metrics)."""
    before = [r for k, r in enumerate(residual_row)
              if (fault == "none" or k * ts < onset - 1e-9) and not math.isnan(r)]
    return max(before) if before else math.nan


# database=None: nothing is written into the source tree
@settings(max_examples=150, deadline=None, database=None)
@given(alarm=hnp.arrays(bool, (6, 25)),
       onset_step=st.lists(st.integers(0, 30), min_size=6, max_size=6),
       free=st.lists(st.booleans(), min_size=6, max_size=6),
       window=st.floats(0.0, 3.0),
       residual=hnp.arrays(float, (6, 25), elements=st.one_of(
           st.floats(-2.0, 5.0, allow_subnormal=False), st.just(math.nan))))
def test_matches_step_by_step_reference(alarm, onset_step, free, window, residual):
    ts = 0.1
    fault = np.where(free, "none", "runaway")
    onset = np.where(free, np.nan, np.array(onset_step) * ts)
    out = score_runs(run_id=np.arange(6).astype(str), fault=fault, onset_s=onset, alarm=alarm,
                     residual=residual, ts=ts,
                     required_time_s=np.where(free, np.nan, 1.0), window_s=window)
    for i in range(6):
        fa, det, first = _reference(alarm[i], fault[i], onset[i], ts, 1.0, window)
        assert out["false_alarm"].iloc[i] == fa
        assert out["detected"].iloc[i] == det
        got = out["first_alarm_s"].iloc[i]
        assert (math.isnan(got) and math.isnan(first)) or got == pytest.approx(first)
        margin = _reference_margin(residual[i], fault[i], onset[i], ts)
        got = out["margin"].iloc[i]
        assert (math.isnan(got) and math.isnan(margin)) or got == margin


# ---- exact binomial bounds -------------------------------------------------------------

def test_upper_bound_zero_of_1200():
    # closed form for k = 0: (1 - p)^n = α  ⇒  p = 1 - α^(1/n)
    expected = 1 - 0.05 ** (1 / 1200)
    assert upper_bound(0, 1200) == pytest.approx(expected, rel=1e-10)
    assert round(100 * upper_bound(0, 1200), 2) == 0.25  # "FA ≤ 0.25 %"


def test_clopper_pearson_five_of_hundred():
    # published value of the exact interval for 5/100 (e.g. R binom.test: 0.01643, 0.11283);
    # 5e-6 absolute is the rounding of those five decimals
    lo, hi = clopper_pearson(5, 100)
    assert lo == pytest.approx(0.01643, abs=5e-6)
    assert hi == pytest.approx(0.11283, abs=5e-6)


def test_clopper_pearson_edges_and_vectorised():
    lo, hi = clopper_pearson([0, 10, 0], [10, 10, 0])
    assert lo[0] == 0.0 and hi[0] == pytest.approx(1 - 0.025 ** (1 / 10), rel=1e-10)
    assert lo[1] == pytest.approx(0.025 ** (1 / 10), rel=1e-10) and hi[1] == 1.0
    assert math.isnan(lo[2]) and math.isnan(hi[2])
    ub = upper_bound(np.array([0, 3, 0]), np.array([100, 100, 0]))
    assert ub.shape == (3,) and math.isnan(ub[2])
    assert ub[0] < ub[1]
    # the one-sided 95 % bound is the upper end of the two-sided 90 % interval
    assert ub[1] == pytest.approx(clopper_pearson(3, 100, confidence=0.90)[1], rel=1e-12)


@pytest.mark.parametrize("k, n, conf", [(-1, 10, 0.95), (11, 10, 0.95), (1, 10, 1.0),
                                        (1, 10, 0.0)])
def test_bounds_reject_bad_input(k, n, conf):
    with pytest.raises(ValueError):
        clopper_pearson(k, n, confidence=conf)


def test_clopper_pearson_lower_end_of_one_success():
    # closed form for k = 1: P(X ≥ 1) = 1 - (1 - p)^n = α/2  ⇒  p = 1 - (1 - α/2)^(1/n)
    lo, _ = clopper_pearson(1, 10)
    assert lo == pytest.approx(1 - 0.975 ** (1 / 10), rel=1e-10)
    assert lo > 0.0


def test_bounds_of_a_single_run():
    # n = 1 is information (only n = 0 gives NaN); Beta(1, 1) is uniform: upper = 1 - α/2
    assert clopper_pearson(0, 1) == (0.0, pytest.approx(0.975, rel=1e-12))
    assert upper_bound(0, 1) == pytest.approx(0.95, rel=1e-12)


def test_upper_bound_of_all_failures_is_one():
    # k = n: Beta(k+1, 0) is undefined, the bound is 1 by definition (docs/design.md §5)
    assert upper_bound(10, 10) == 1.0
    assert list(upper_bound(np.array([0, 5]), np.array([5, 5]))[1:]) == [1.0]


def test_lower_bound_closed_forms():
    # k = 0: nothing bounds the rate away from 0; k = n: Beta(n, 1) has CDF p^n, so the
    # one-sided lower bound is (1 − c)^(1/n): 0.05^(1/20) = 0.8609 (rel 1e-12: beta.ppf
    # is evaluated to round-off, not by root finding)
    assert lower_bound(0, 20) == 0.0
    assert lower_bound(20, 20) == pytest.approx(0.05 ** (1 / 20), rel=1e-12)
    assert math.isnan(lower_bound(0, 0))


# ---- fault-estimation error ([CHEN] §6.2) ----------------------------------------------------
def test_estimation_errors_over_the_post_onset_window_by_hand():
    from reports.scoring.metrics import estimation_errors

    nan = np.nan
    f = np.array([[nan, nan, 1.0, 1.0, 1.0],       # fault from step 2
                  [nan, nan, nan, nan, nan],       # no defined fault: no sample
                  [0.5, 0.5, 0.5, 0.5, 0.5]])
    est = np.array([[9.0, 9.0, 1.5, 0.5, 1.3],     # before onset ignored
                    [1.0, 2.0, 3.0, 4.0, 5.0],
                    [0.5, 0.5, 0.5, 0.5, nan]])    # a missing estimate sample is skipped
    n, mean, var = estimation_errors(est, f)
    assert list(n) == [3, 0, 4] and n.dtype == np.int64
    e = np.array([0.5, -0.5, 0.3])
    assert mean[0] == pytest.approx(e.mean()) and var[0] == pytest.approx(e.var())
    assert np.isnan(mean[1]) and np.isnan(var[1])
    assert mean[2] == 0.0 and var[2] == 0.0
    with pytest.raises(ValueError, match="n_runs, n_steps"):
        estimation_errors(np.zeros(3), np.zeros(3))
    # one sample is a mean and a zero variance, not "no sample"
    n1, mean1, var1 = estimation_errors(np.array([[np.nan, 2.5]]), np.array([[np.nan, 2.0]]))
    assert list(n1) == [1] and mean1[0] == 0.5 and var1[0] == 0.0
