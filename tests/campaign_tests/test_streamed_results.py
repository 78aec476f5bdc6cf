"""Result rows read and aggregated a batch at a time: the same table, to the bit, as all the
rows at once (issue 35: memory independent of the number of runs)."""

import numpy as np
import pandas as pd
import pytest

from campaign.store.directory import CampaignDir
from reports.scoring.gate import evaluate_gate, gate_rows
from reports.scoring.summary import SummaryAccumulator, summarize

FAULTS = ("none", "runaway", "liquid_jam")
MANOEUVRES = ("cruise", "nose_up", "pitch_protection")
DETECTORS = ("comb-interval[a=0.9]", "est", "position-monitor")


def synthetic_results(seed: int, n_runs: int = 2000) -> pd.DataFrame:
    """Result rows of *n_runs* runs × 3 detectors in plan order (run, then detector):
    errors, misses, pre-onset alarms, and for detector ``est`` fault-estimation moments on
    some runs only, so that rows without an estimate fall between rows with one. The DTPs,
    delays and moments span 16 decades, so that a compensated sum depends on the order and
    the cut of its terms: a batch that saw other values, or the same ones in another order,
    gives other bits."""
    rng = np.random.default_rng(seed)
    run = np.repeat(np.arange(n_runs), len(DETECTORS))
    fault = np.asarray(FAULTS)[rng.integers(0, len(FAULTS), n_runs)][run]
    manoeuvre = np.asarray(MANOEUVRES)[rng.integers(0, len(MANOEUVRES), n_runs)][run]
    detector = np.tile(DETECTORS, n_runs)
    n = len(run)
    ok = rng.random(n) > 0.05
    faulty = fault != "none"
    detected = ok & faulty & (rng.random(n) > 0.2)
    scale = 10.0 ** rng.uniform(-8, 8, n)
    dtp = np.where(detected, rng.random(n) * scale, np.nan)
    est = ok & (detector == "est") & (rng.random(n) > 0.3)
    est_n = np.where(est, rng.integers(1, 500, n), 0)
    return pd.DataFrame({
        "run_id": [f"r{i:05d}" for i in run], "detector": detector, "fault": fault,
        "manoeuvre": manoeuvre, "status": np.where(ok, "ok", "error"),
        "error": np.where(ok, "", "RuntimeError: diverged"),
        "false_alarm": ok & (rng.random(n) < 0.1), "pre_onset_alarm": ok & (rng.random(n) < 0.1),
        "detected": detected, "first_alarm_s": np.where(detected, 20.0 + dtp, np.nan),
        "delay_s": np.where(detected, dtp * rng.uniform(0.1, 2.0, n), np.nan), "dtp": dtp,
        "margin": np.where(ok, rng.random(n) * 2.0, np.nan), "est_err_n": est_n,
        "est_err_mean_mm": np.where(est, rng.normal(0, 1, n) * scale, np.nan),
        "est_err_var_mm2": np.where(est, rng.random(n) * scale, np.nan),
        "est_range_mm": np.where(est, rng.uniform(20.0, 40.0, n), np.nan),
    })


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_summary_of_batches_equals_summary_of_all_rows(seed):
    results = synthetic_results(seed)
    whole = summarize(results)
    # the table is not trivial: detections, misses, estimates, errors and the p99 bound
    # (299 runs or more per group) are all there
    assert whole["md_count"].sum() > 0 and whole["est_err_runs"].sum() > 0
    assert whole["n_errors"].sum() > 0 and whole["dtp_p99_upper95"].notna().any()
    assert np.isfinite(whole["delay_km_median_s"]).any()
    _assert_batching_does_not_matter(results, whole, np.random.default_rng(100 + seed), 7)


def _assert_batching_does_not_matter(results: pd.DataFrame, whole: pd.DataFrame, rng,
                                     cuts: int) -> None:
    """Three random splits of *results* into cuts + 1 batches, each accumulated, give the
    summary *whole* exactly: the summary the runner writes must not depend on how rows were
    batched."""
    for _ in range(3):
        at = np.sort(rng.choice(np.arange(1, len(results)), size=cuts, replace=False))
        acc = SummaryAccumulator()
        for part in np.split(np.arange(len(results)), at):
            acc.add(results.iloc[part])
        pd.testing.assert_frame_equal(acc.summary(), whole, check_exact=True)


def test_summary_of_no_rows_is_the_empty_table():
    empty = synthetic_results(0).iloc[:0]
    pd.testing.assert_frame_equal(SummaryAccumulator().summary(), summarize(empty))


def _shards(tmp_path, results: pd.DataFrame, chunks: list) -> CampaignDir:
    """A campaign directory whose shards hold *results*' rows of each run-index list of
    *chunks*, in that order (a later shard's rows of a run replace the earlier ones)."""
    cdir = CampaignDir(tmp_path / "c")
    cdir.runs.mkdir(parents=True)
    run = results["run_id"].str[1:].astype(int).to_numpy()
    for part in chunks:
        rows = results[np.isin(run, part)]
        # shards are written detector by detector, as the runner's chunks are
        cdir.write_shard(rows.sort_values("detector", kind="stable"), "{}")
    return cdir


def test_batches_are_the_latest_rows_in_plan_order(tmp_path):
    results = synthetic_results(4, n_runs=60)
    plan_ids = [f"r{i:05d}" for i in range(60)]
    first = results.assign(status="error", error="killed")
    # chunks finished out of order, then a rerun of runs spread over the plan
    chunks = [list(range(20, 40)), list(range(0, 20)), list(range(40, 60))]
    cdir = _shards(tmp_path, first, chunks)
    retried = [3, 25, 59]
    rows = results[results["run_id"].isin([plan_ids[i] for i in retried])]
    cdir.write_shard(rows.sort_values("detector", kind="stable"), "{}")
    expected = pd.concat([first[~first["run_id"].isin(rows["run_id"])], rows])
    expected = expected.assign(_o=expected["run_id"].str[1:].astype(int)).sort_values(
        ["_o", "detector"], kind="stable").drop(columns="_o").reset_index(drop=True)
    for batch_runs in (1, 7, 1000):
        batches = list(cdir.result_batches(plan_ids, batch_runs=batch_runs))
        # no batch holds more runs than asked: the reader's memory is bounded by it
        assert max(b["run_id"].nunique() for b in batches) <= batch_runs
        pd.testing.assert_frame_equal(pd.concat(batches, ignore_index=True), expected,
                                      check_exact=True)
    done = cdir.done_mask(plan_ids)
    assert [i for i in range(60) if done[i]] == [
        i for i in retried if (results.loc[results["run_id"] == plan_ids[i], "status"]
                               == "ok").all()]


def test_batches_keep_every_run_outside_the_plan(tmp_path):
    # runs r00040…r00059 are in the shards but not in the plan: each is a run of its own,
    # as read_results keeps it, not one run per detector
    results = synthetic_results(6, n_runs=60)
    plan_ids = [f"r{i:05d}" for i in range(40)]
    cdir = _shards(tmp_path, results, [list(range(0, 30)), list(range(30, 60))])
    whole = cdir.read_results()
    for stored_order in (False, True):
        rows = pd.concat(cdir.result_batches(plan_ids, batch_runs=7, stored_order=stored_order),
                         ignore_index=True)
        assert len(rows) == len(whole) == len(results)
        outside = rows[~rows["run_id"].isin(plan_ids)]
        assert outside["run_id"].nunique() == 20
        # they come last, in the order the rule gives (by detector, or as stored)
        assert (rows.index[~rows["run_id"].isin(plan_ids)] >= len(rows) - len(outside)).all()
        key = ["run_id", "detector"]
        pd.testing.assert_frame_equal(
            outside.sort_values(key).reset_index(drop=True),
            whole[~whole["run_id"].isin(plan_ids)].sort_values(key).reset_index(drop=True),
            check_exact=True)


@pytest.mark.parametrize("fault_free", [True, False])
def test_summary_of_batches_when_pandas_adds_runs_of_values(fault_free):
    """One detector, runs planned cell by cell: every group's rows are contiguous, so pandas
    adds a column that holds no NaN with ``np.add.reduceat`` (pairwise), not its compensated
    sum — the estimation moments always, the DTPs too when every run is a detected faulty
    one. The batches must give the same bits by the same method."""
    results = synthetic_results(5, n_runs=1500)
    results = results[results["detector"] == "est"]
    if not fault_free:
        results = results[results["fault"] != "none"].assign(status="ok", detected=True)
        results = results.assign(dtp=results["margin"] * 1e6 + 1e-9,
                                 delay_s=results["margin"] * 3e-7)
    results = results.sort_values(["fault", "manoeuvre"], kind="stable", ignore_index=True)
    whole = summarize(results)
    assert whole["est_err_runs"].sum() > 0
    _assert_batching_does_not_matter(results, whole, np.random.default_rng(7), 5)


@pytest.mark.parametrize("seed", [6, 7])
def test_gate_of_the_rows_it_reads_is_the_gate_of_all_rows(seed):
    """The run keeps only :func:`gate_rows` of its batches; the gate (every check, message
    and run id named) must be the one all the rows give."""
    results = synthetic_results(seed, n_runs=300)
    summary = summarize(results)
    kept = gate_rows(results)
    # a fault-free row that is ok and silent is what the run drops
    assert len(kept) < len(results)
    for limits in ({}, {"max_md": 0.1, "max_dtp": 1.0}):
        whole = evaluate_gate(summary, results=results, **limits)
        part = evaluate_gate(summary, results=kept, **limits)
        assert [(c.name, c.message, c.run_ids) for c in part.checks] == [
            (c.name, c.message, c.run_ids) for c in whole.checks]
        assert any(c.run_ids for c in whole.checks)   # run ids are named, and compared


@pytest.mark.parametrize("size", [7, 16, 64])
def test_chunks_read_from_the_plan_file_are_the_plan_chunks(tmp_path, size):
    """The runner reads its chunks from plan.parquet as they are taken: they must be the
    chunks it cut from the plan in memory (rows, dtypes, index), with and without runs
    already done."""
    from campaign.config import load_config
    from campaign.plan import MODEL_VERSION, build_plan
    from campaign.runner import _plan_chunks

    config = load_config("smoke")
    plan = build_plan(config)
    cdir = CampaignDir(tmp_path / "c")
    cdir.runs.mkdir(parents=True)
    cdir.write_plan(plan, config.to_json(), MODEL_VERSION)
    done = np.random.default_rng(size).random(len(plan)) < 0.3
    for mask in (None, done):
        todo = plan if mask is None else plan[~mask]
        expected = [todo.iloc[s:s + size] for s in range(0, len(todo), size)]
        got = list(_plan_chunks(cdir, size, mask))
        assert len(got) == len(expected)
        for a, b in zip(got, expected):
            pd.testing.assert_frame_equal(a, b, check_exact=True)


def test_local_workers_take_a_chunk_only_when_a_worker_is_free():
    """A plan of 10⁶ runs is 10⁴ chunks: run_local must take them from their iterator as
    workers free up, so that at most 2·*jobs* + 1 chunks exist beyond those finished (on
    threads, one running and one queued behind it per worker, and the next one, taken to
    know whether there is one)."""
    jobs = 2
    finished, ahead = _chunks_ahead(40, jobs, "threading")
    assert finished == 40
    assert ahead <= 2 * jobs + 1   # running and queued on each worker, and the next


def _chunks_ahead(n: int, jobs: int, backend: str) -> tuple[int, int]:
    """run_local of *n* one-row chunks taken from a generator: (chunks finished, most
    chunks that existed beyond those finished)."""
    from campaign.execute import run_local

    taken, finished, ahead = [0], [0], []

    def chunks():
        for i in range(n):
            taken[0] += 1
            ahead.append(taken[0] - finished[0])
            yield pd.DataFrame({"run_id": [f"r{i}"]})

    def on_result(frame):
        finished[0] += 1

    run_local(chunks(), _identity, lambda rows, status, msg: rows, on_result,
              jobs=jobs, backend=backend, run_timeout_s=None)
    return finished[0], max(ahead)


def test_a_thread_worker_takes_the_queued_chunk_while_the_last_result_is_stored():
    """On threads a chunk waits queued behind the running one: the worker starts it while
    the runner is still storing the previous result, instead of idling until the runner
    submits it. (The second chunk cannot end before the first result is stored: it waits
    for that, so the first result is the first one stored.)"""
    import threading

    from campaign.execute import run_local

    second_started, first_stored = threading.Event(), threading.Event()

    def call(rows):
        if rows["run_id"].iloc[0] == "r1":
            second_started.set()
            assert first_stored.wait(10)
        return rows

    seen = []

    def on_result(frame):
        if frame["run_id"].iloc[0] == "r0":
            seen.append(second_started.wait(5))      # the worker took r1 meanwhile
            first_stored.set()

    chunks = (pd.DataFrame({"run_id": [f"r{i}"]}) for i in range(2))
    run_local(chunks, call, lambda rows, status, msg: rows, on_result, jobs=1,
              backend="threading", run_timeout_s=None)
    assert seen == [True]


def test_a_worker_process_is_given_a_chunk_only_when_it_is_free():
    """Processes get no queued chunk (a chunk's time limit counts from a worker taking it):
    at most *jobs* + 1 chunks exist beyond those finished."""
    finished, ahead = _chunks_ahead(6, 1, "loky")
    assert finished == 6 and ahead <= 1 + 1


def _identity(rows):
    return rows
