"""``reports.scoring.metrics.score_runs`` finds the onset and the detection window as step indices
(``np.searchsorted`` on the step times) and the margin row by row, instead of building
(runs × steps) masks; the scores must be those of the masks, bit for bit. The reference
below is the mask form written out from docs/design.md §5 (Metrics): before onset means
t < onset − ONSET_TOL_S, the window onset − ONSET_TOL_S ≤ t ≤ onset + window + ONSET_TOL_S,
the margin the largest non-NaN residual before onset."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reports.scoring.metrics import FAULT_FREE, ONSET_TOL_S, SCORE_COLUMNS, score_runs


def masks_reference(*, run_id, fault, onset_s, alarm, residual, ts, required_time_s,
                    window_s=None) -> pd.DataFrame:
    n, n_steps = alarm.shape
    onset = np.asarray(onset_s, float)
    required = np.asarray(required_time_s, float)
    window = np.full(n, np.inf) if window_s is None else np.asarray(window_s, float)
    window = np.where(np.isnan(window), np.inf, window)
    faulty = np.asarray(fault) != FAULT_FREE
    onset_eff = np.where(faulty, onset, np.inf)
    t = np.arange(n_steps) * ts
    after = t[None, :] >= (onset_eff - ONSET_TOL_S)[:, None]
    in_window = after & (t[None, :] <= (onset_eff + window + ONSET_TOL_S)[:, None])

    def first(mask):
        idx = np.argmax(mask, axis=1)
        return idx, mask[np.arange(n), idx]

    pre = np.any(alarm & ~after, axis=1)
    idx_win, detected = first(alarm & in_window)
    idx_any, any_alarm = first(alarm)
    first_s = np.where(faulty, np.where(detected, idx_win * ts, np.nan),
                       np.where(any_alarm, idx_any * ts, np.nan))
    detected = faulty & detected
    delay = np.where(detected, first_s - onset, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        dtp = np.where(detected, delay / required, np.nan)
    valid = ~after & ~np.isnan(residual)
    margin = np.where(valid, residual, -np.inf).max(axis=1)
    margin = np.where(valid.any(axis=1), margin, np.nan)
    return pd.DataFrame({"run_id": np.asarray(run_id).astype(str).astype(object),
                         "false_alarm": pre, "pre_onset_alarm": pre, "detected": detected,
                         "first_alarm_s": first_s, "delay_s": delay, "dtp": dtp,
                         "margin": margin}, columns=list(SCORE_COLUMNS))


def random_batch(rng, n=40, n_steps=300, ts=0.01):
    """Runs of every kind the scoring distinguishes: fault-free and faulty, onsets on a step,
    between steps, within ONSET_TOL_S of a step, at 0 and after the run; alarms latched or
    not, before onset, in and after short windows, none; residuals with NaN stretches."""
    fault = rng.choice([FAULT_FREE, "runaway", "solid_jam"], size=n)
    k = rng.integers(0, n_steps + 40, size=n)
    t = np.arange(n_steps + 40) * ts
    # on a step, between steps, within ONSET_TOL_S of a step, and exactly ONSET_TOL_S after
    # one (onset − ONSET_TOL_S is then that step's time: a tie the comparison must keep)
    onset = t[k] + rng.choice([0.0, 0.4 * ONSET_TOL_S, -0.4 * ONSET_TOL_S, 0.5 * ts,
                               ONSET_TOL_S], size=n)
    onset = np.where(rng.random(n) < 0.1, 0.0, onset)
    onset = np.where(fault == FAULT_FREE, np.nan, onset)
    alarm = rng.random((n, n_steps)) < rng.choice([0.0, 0.002, 0.02, 0.2], size=(n, 1))
    latched = rng.random(n) < 0.5
    alarm[latched] = np.logical_or.accumulate(alarm[latched], axis=1)
    residual = rng.random((n, n_steps)) * 2.0
    residual[rng.random((n, n_steps)) < 0.05] = np.nan
    residual[rng.random(n) < 0.1, :] = np.nan            # a run without a valid sample
    window = rng.choice([0.0, 0.05, 0.5, np.nan, np.inf], size=n)
    # windows whose end, onset + window + ONSET_TOL_S, falls exactly on a step's time
    k_end = np.minimum(k + rng.integers(0, 30, size=n), t.size - 1)
    tie = (rng.random(n) < 0.3) & np.isfinite(onset)
    window = np.where(tie, np.maximum(t[k_end] - ONSET_TOL_S - onset, 0.0), window)
    return dict(run_id=[f"r{i}" for i in range(n)], fault=fault, onset_s=onset, alarm=alarm,
                residual=residual, ts=ts, required_time_s=np.full(n, 0.3), window_s=window)


@pytest.mark.parametrize("seed", range(25))
def test_index_scoring_equals_the_masks_bit_for_bit(seed):
    batch = random_batch(np.random.default_rng(seed))
    got = score_runs(**batch)
    want = masks_reference(**batch)
    pd.testing.assert_frame_equal(got, want, check_exact=True)
    assert got["false_alarm"].any() and got["detected"].any()     # both kinds of run scored


def test_the_batches_hold_the_ties_at_both_ends():
    # the cases where a comparison's side matters: a step at exactly onset − ONSET_TOL_S
    # and a window ending exactly on a step, in the batches above
    starts = ends = 0
    for seed in range(25):
        b = random_batch(np.random.default_rng(seed))
        t = np.arange(b["alarm"].shape[1]) * b["ts"]
        onset = b["onset_s"]
        window = np.where(np.isnan(b["window_s"]), np.inf, b["window_s"])
        starts += int(np.isin(onset - ONSET_TOL_S, t).sum())
        ends += int(np.isin(onset + window + ONSET_TOL_S, t).sum())
    assert starts >= 20 and ends >= 20


def test_without_a_window_and_with_no_runs():
    rng = np.random.default_rng(99)
    batch = random_batch(rng)
    batch["window_s"] = None
    pd.testing.assert_frame_equal(score_runs(**batch), masks_reference(**batch),
                                  check_exact=True)
    empty = {k: (v if v is None or np.isscalar(v) else v[:0]) for k, v in batch.items()}
    empty["alarm"] = np.zeros((0, 300), bool)
    empty["residual"] = np.zeros((0, 300))
    assert len(score_runs(**empty)) == 0


def test_a_chunk_s_result_table_is_the_variants_scored_one_by_one():
    # campaign.evaluate._scored assembles every variant's columns into one table; it must be
    # the table of one score_runs DataFrame per variant with the run's other columns
    # inserted, concatenated (values and dtypes), estimates included
    from types import SimpleNamespace

    from campaign.evaluate import ChunkSettings, _estimate_columns, _scored
    from detectors.base import Detection
    from reports.scoring.alarm_steps import alarm_steps
    from reports.scoring.metrics import RESULT_COLUMNS

    rng = np.random.default_rng(7)
    batch = random_batch(rng, n=30)
    n, n_steps = batch["alarm"].shape
    rows = pd.DataFrame({"run_id": batch["run_id"],
                         "manoeuvre": rng.choice(["cruise", "nose_up"], size=n)})
    fault = rng.normal(size=(n, n_steps))
    fault[:, :100] = np.nan
    truth = SimpleNamespace(fault=np.asarray(batch["fault"]), onset_s=batch["onset_s"],
                            rod_fault_mm=fault)
    detections = {
        "a": Detection(alarm=batch["alarm"], residual=batch["residual"],
                       decision=batch["residual"]),
        "b[x=1]": Detection(alarm=batch["alarm"][::-1].copy(), residual=batch["residual"],
                            estimate=rng.normal(size=(n, n_steps))),
    }
    settings = ChunkSettings(ts=batch["ts"], pressure_sensor=False,
                             required_time_s={"runaway": 0.3, "solid_jam": 0.3}, window_s=0.5)
    required = np.asarray(batch["required_time_s"])
    want = []
    for name, det in detections.items():
        frame = score_runs(run_id=rows["run_id"].to_numpy(), fault=truth.fault,
                           onset_s=truth.onset_s, alarm=det.alarm, residual=det.residual,
                           ts=settings.ts, required_time_s=required, window_s=0.5)
        frame.insert(1, "detector", name)
        frame.insert(2, "fault", truth.fault)
        frame.insert(3, "manoeuvre", rows["manoeuvre"].to_numpy())
        frame.insert(4, "status", "ok")
        frame.insert(5, "error", "")
        for column, values in _estimate_columns(det, truth, 12.5).items():
            frame[column] = values
        frame["alarm_steps"] = alarm_steps(det.decision, fault=truth.fault,
                                           onset_s=truth.onset_s, ts=settings.ts, window_s=0.5)
        want.append(frame)
    want = pd.concat(want, ignore_index=True)[list(RESULT_COLUMNS)]
    got = pd.concat(_scored(rows, truth, detections, required, settings, 12.5),
                    ignore_index=True)[list(RESULT_COLUMNS)]
    pd.testing.assert_frame_equal(got, want, check_exact=True)
    assert (got["est_err_n"] > 0).any()
    assert got["alarm_steps"].notna().any() and got["alarm_steps"].isna().any()
