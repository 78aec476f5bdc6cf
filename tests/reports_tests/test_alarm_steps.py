"""The first alarms at other thresholds stored with each run (reports/scoring/alarm_steps.py): the
packed column round-trips, the onset step is the scoring's, and the result row at a stored
scale computed from the column is, bit for bit, the row that scoring the detection at that
scale gives (detectors.base.at_threshold_scale, then reports.scoring.metrics.score_columns); a
detection system's steps are the earliest of its members'."""

from __future__ import annotations

import numpy as np
import pytest

from detectors.base import Detection, at_threshold_scale, decide, first_steps
from reports.scoring.alarm_steps import (ALARM_SCALES, ALARM_STEPS_COLUMN, alarm_offsets,
                                 alarm_steps, decode_steps,
                                 encode_steps, onset_steps, scaled_columns)
from reports.scoring.alarm_steps import _window_steps
from reports.scoring.metrics import RESULT_COLUMNS, score_columns

SCORED = ("false_alarm", "pre_onset_alarm", "detected", "first_alarm_s", "delay_s", "dtp",
          "margin")


def test_the_column_is_a_result_column():
    assert ALARM_STEPS_COLUMN in RESULT_COLUMNS


@pytest.mark.parametrize("offsets", [[], [0], [0, 0, 0, 0, 0, 0], [5, 5, 6, 9, 9, 140],
                                     [127, 128, 16383, 16384, 2 ** 31, 2 ** 40]])
def test_packed_steps_round_trip(offsets):
    data = encode_steps(offsets)
    assert decode_steps(data) == offsets
    # small increments take one byte each: the column's size rests on it
    if offsets and max(np.diff([0, *offsets])) < 128:
        assert len(data) == len(offsets)


def test_packed_steps_refuse_what_they_cannot_hold():
    with pytest.raises(ValueError, match="non-decreasing"):
        encode_steps([3, 2])
    with pytest.raises(ValueError, match="non-decreasing"):
        encode_steps([-1])
    with pytest.raises(ValueError, match="damaged"):
        decode_steps(encode_steps([300])[:1])


@pytest.mark.parametrize("ts", [0.01, 0.025, 0.1, 1 / 60])
def test_onset_step_is_the_one_scoring_finds(ts):
    rng = np.random.default_rng(3)
    onsets = np.concatenate([rng.uniform(0.0, 60.0, 400),
                             np.arange(0, 400) * ts,            # exact multiples in decimal
                             np.round(rng.uniform(0, 60, 200), 2), [0.0, 1e-12, ts / 2]])
    t = np.arange(int(61 / ts) + 2) * ts
    want = np.searchsorted(t, onsets - 1e-9, side="left")
    assert np.array_equal(onset_steps(onsets, ts), want)


def _random_decisions(rng, n: int, n_steps: int, ts: float):
    """Decision statistics like the built-in detectors': NaN while a confirmation window
    fills, noise below 1 before onset with some excursions above the smaller scales, a rise
    of random speed after onset (some never reaching the larger scales), and values put
    exactly on the scales (where ≥ decides)."""
    t = np.arange(n_steps) * ts
    fault = np.where(rng.random(n) < 0.25, "none", rng.choice(["runaway", "solid_jam"], n))
    onset = np.where(fault == "none", np.nan, np.round(rng.uniform(0.5, 0.8 * t[-1], n), 3))
    decision = np.abs(rng.normal(0.25, 0.15, (n, n_steps)))
    spikes = rng.random((n, n_steps)) < 0.002
    decision[spikes] = rng.uniform(0.5, 1.7, spikes.sum())
    for i in np.flatnonzero(fault != "none"):
        after = np.clip(t - onset[i], 0, None)
        decision[i] += after * rng.uniform(0.05, 8.0)
    exact = rng.random((n, n_steps)) < 0.01
    decision[exact] = rng.choice([*ALARM_SCALES, 1.0], exact.sum())
    decision[:, : rng.integers(0, 6)] = np.nan
    return fault, onset, decision


@pytest.mark.parametrize("window_s", [None, 0.6])
def test_rows_at_a_stored_scale_are_those_of_the_scaled_detection(window_s):
    rng = np.random.default_rng(11)
    ts, n, n_steps = 0.01, 160, 400
    fault, onset, decision = _random_decisions(rng, n, n_steps, ts)
    # onsets at the first step, at the last and after the run's end
    fault[:3], onset[:3] = "runaway", [0.0, (n_steps - 1) * ts, n_steps * ts + 1.0]
    run_id = np.array([f"r{i}" for i in range(n)])
    required = np.where(fault == "none", np.nan, rng.uniform(0.05, 0.4, n))
    own = Detection(alarm=decide(decision), residual=decision, decision=decision)
    kw = dict(run_id=run_id, fault=fault, onset_s=onset, ts=ts, required_time_s=required,
              window_s=window_s)
    at_one = score_columns(alarm=own.alarm, residual=own.decision, **kw)
    steps = alarm_steps(decision, fault=fault, onset_s=onset, ts=ts, window_s=window_s)
    assert all((s is None) == (f == "none") for s, f in zip(steps, fault))
    assert steps[2] == b""                    # an onset after the run: no window, no alarm
    differs = 0
    for scale in ALARM_SCALES:
        det = at_threshold_scale(own, scale)
        # the scaled alarm is raised where the decision first reaches the scale
        assert np.array_equal(first_steps(det.alarm), first_steps(decision >= scale))
        want = score_columns(alarm=det.alarm, residual=det.decision, **kw)
        got = scaled_columns(scale=scale, fault=fault, onset_s=onset,
                             margin=at_one["margin"], steps=steps, ts=ts,
                             required_time_s=required)
        assert got["known"].all()
        faulty = fault != "none"
        for column in SCORED:
            a, b = got[column], want[column]
            if column == "first_alarm_s":          # not stored for fault-free runs
                a, b = a[faulty], b[faulty]
            np.testing.assert_array_equal(a, b, err_msg=f"{column} at scale {scale}")
        differs += int((want["detected"] != at_one["detected"]).sum()
                       + np.nansum(want["first_alarm_s"] != at_one["first_alarm_s"]))
    assert differs > 50          # the scales change the outcome of many runs: a real test


def test_a_faulty_run_alarmed_before_onset_is_detected_at_onset():
    # latched alarm: the first alarm of the window is the onset step at every scale ≤ margin
    decision = np.full((1, 50), 0.1)
    decision[0, 5] = 0.9
    decision[0, 30:] = 3.0
    offsets = alarm_offsets(decision[0], 20, 50)
    assert offsets == [0, 0, 0, 10, 10, 10]          # 0.5, 0.63, 0.8: at onset; then step 30
    assert alarm_offsets(decision[0], 20, 25) == [0, 0, 0]   # a window that ends first
    assert alarm_offsets(decision[0], 50, 50) == []          # an onset at the end of the run


def test_a_scale_that_is_not_stored_is_refused():
    with pytest.raises(ValueError, match="1.1 is not stored.*0.5, 0.63"):
        scaled_columns(scale=1.1, fault=np.array(["none"]), onset_s=np.array([np.nan]),
                       margin=np.array([0.5]), steps=[None], ts=0.01,
                       required_time_s=np.array([np.nan]))


def test_runs_without_stored_steps_are_unknown_except_fault_free():
    got = scaled_columns(scale=0.8, fault=np.array(["none", "runaway", "runaway"]),
                         onset_s=np.array([np.nan, 1.0, 1.0]), margin=np.array([0.9, 0.2, 0.9]),
                         steps=[None, None, encode_steps([3, 3, 3])], ts=0.01,
                         required_time_s=np.array([np.nan, 0.5, 0.5]))
    assert got["known"].tolist() == [True, False, True]
    assert got["false_alarm"].tolist() == [True, False, True]
    assert got["detected"].tolist() == [False, False, True]
    assert got["first_alarm_s"][2] == 103 * 0.01


def test_the_batch_column_is_the_one_run_search_of_every_run():
    """alarm_steps (every faulty run at once) against alarm_offsets (one run, a search in its
    running maximum) on random decisions with NaN gaps, onsets and windows."""
    rng = np.random.default_rng(11)
    ts, n, n_steps = 0.01, 150, 300
    fault, onset, decision = _random_decisions(rng, n, n_steps, ts)
    decision[rng.random(decision.shape) < 0.05] = np.nan
    got = alarm_steps(decision, fault=fault, onset_s=onset, ts=ts, window_s=0.8)
    # each run's window as the column finds it (the steps score_columns scores in)
    _, k_on, k_end = _window_steps(fault, onset, ts, 0.8, n, n_steps)
    for i in range(n):
        if fault[i] == "none":
            assert got[i] is None
        else:
            want = alarm_offsets(decision[i], int(k_on[i]), int(k_end[i]))
            assert decode_steps(got[i]) == want, i
    assert sum(len(decode_steps(g)) for g in got if g is not None) > n   # runs detected


def test_a_system_s_steps_are_the_earliest_of_its_members():
    """The column of a system's decision (the largest member decision at each step) holds,
    at each scale, the earliest of its members' first alarms (a miss where every member
    misses), recomputed here from the members' own columns."""
    rng = np.random.default_rng(5)
    ts, n, n_steps = 0.01, 120, 300
    fault, onset, a = _random_decisions(rng, n, n_steps, ts)
    b = _random_decisions(rng, n, n_steps, ts)[2]
    c = _random_decisions(rng, n, n_steps, ts)[2]
    kw = dict(fault=fault, onset_s=onset, ts=ts, window_s=0.8)
    members = [[None if m is None else decode_steps(m) for m in alarm_steps(d, **kw)]
               for d in (a, b, c)]
    system = alarm_steps(np.fmax(np.fmax(a, b), c), **kw)
    for i, got in enumerate(system):
        if fault[i] == "none":
            assert got is None
            continue
        runs = [m[i] for m in members]
        length = max(len(r) for r in runs)
        assert decode_steps(got) == [min(r[j] for r in runs if j < len(r))
                                     for j in range(length)], i
    # the members differ, and the system is earlier than the first member somewhere
    earlier = sum(decode_steps(s) != m for s, m in zip(system, members[0]) if s is not None)
    assert earlier > 10
