"""Faults in the machinery: a worker process that dies, a detector that raises, a run over
its time limit. Each ends as per-run status with its message, the campaign completes, and
a rerun into the same directory retries exactly those runs (no duplicate rows remain)."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from campaign import run
from campaign.config import CampaignConfig
from campaign.plan import build_plan
from detectors import registry


@pytest.fixture
def misbehaving(monkeypatch):
    """Register the test detector of tests/machinery_detectors.py for this test."""
    monkeypatch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")


def config(marker, mode, *, chunk_size=3, with_monitor=False, runner=None, **params):
    dets = [{"name": "misbehaving", "params": {"marker": str(marker), "mode": mode, **params}}]
    if with_monitor:
        dets.append({"name": "position-monitor", "label": "pm"})
    return CampaignConfig.from_dict({
        "campaign": {"name": "machinery", "seed": 3, "duration_s": 20.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 3},
            {"name": "jam", "fault": "solid_jam", "manoeuvres": ["cruise"], "count": 2},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": dets,
        "learning": {"runs_per_manoeuvre": 1, "manoeuvres": ["cruise"]},
        "runner": {"chunk_size": chunk_size, **(runner or {})},
    })


def mark(path, run_ids) -> None:
    path.write_text(json.dumps(list(run_ids)))


def check_complete_once(res, n_runs, n_detectors=1) -> None:
    """Every planned run has exactly one row per detector: nothing lost, nothing doubled."""
    assert res.complete
    assert len(res.results) == n_runs * n_detectors
    assert not res.results.duplicated(["run_id", "detector"]).any()
    assert set(res.results["run_id"]) == set(res.plan["run_id"])


def test_a_worker_killed_by_a_run_ends_as_an_error_row_and_a_rerun_completes(
        tmp_path, misbehaving):
    marker = tmp_path / "marked.json"
    cfg = config(marker, "kill", chunk_size=4)
    plan = build_plan(cfg)
    # last run of the last chunk (4 + 4 + 2 runs): its chunk dies next to another chunk in
    # flight, dies again alone, is split, and the run dies alone; run 8 of its chunk is saved
    victim = plan["run_id"].iloc[9]
    mark(marker, [victim])
    out = tmp_path / "out"
    res = run(cfg, out, jobs=2, backend="loky", progress=False, log=lambda m: None)
    check_complete_once(res, len(plan))
    by_run = res.results.set_index("run_id")
    assert by_run.loc[victim, "status"] == "error"
    assert "worker process died" in by_run.loc[victim, "error"]
    assert (by_run.drop(index=victim)["status"] == "ok").all()

    marker.unlink()                      # the fault is gone: rerun (in-process is enough)
    again = run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    check_complete_once(again, len(plan))
    assert (again.results["status"] == "ok").all()


@pytest.mark.slow
def test_a_run_over_its_time_limit_is_recorded_as_timeout_and_a_rerun_completes(
        tmp_path, misbehaving):
    marker = tmp_path / "marked.json"
    # the marked run sleeps 60 s against a limit of 2 s; the others take ~0.05 s each (20 s
    # runs, trivial detector), far below the limit even on a loaded machine. The worker
    # running the marked run is stopped at its limit, not after 60 s.
    cfg = config(marker, "sleep", chunk_size=1, sleep_s=60.0, runner={"run_timeout_s": 2.0})
    plan = build_plan(cfg)
    victim = plan["run_id"].iloc[8]
    mark(marker, [victim])
    out = tmp_path / "out"
    res = run(cfg, out, jobs=2, backend="loky", progress=False, log=lambda m: None)
    check_complete_once(res, len(plan))
    by_run = res.results.set_index("run_id")
    assert by_run.loc[victim, "status"] == "timeout"
    assert "run_timeout_s" in by_run.loc[victim, "error"]
    assert (by_run.drop(index=victim)["status"] == "ok").all()

    marker.unlink()
    again = run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    check_complete_once(again, len(plan))
    assert (again.results["status"] == "ok").all()


def test_a_detector_raising_on_one_run_fails_only_that_run_and_detector(tmp_path, misbehaving):
    marker = tmp_path / "marked.json"
    cfg = config(marker, "raise", chunk_size=4, with_monitor=True)
    plan = build_plan(cfg)
    victim = plan["run_id"].iloc[1]
    mark(marker, [victim])
    out = tmp_path / "out"
    res = run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    check_complete_once(res, len(plan), n_detectors=2)
    bad = res.results[res.results["status"] != "ok"]
    assert list(zip(bad["run_id"], bad["detector"])) == [(victim, "misbehaving")]
    assert "injected failure" in bad["error"].iloc[0]
    first_pm = res.results[res.results["detector"] == "pm"].reset_index(drop=True)

    marker.unlink()
    again = run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    check_complete_once(again, len(plan), n_detectors=2)
    assert (again.results["status"] == "ok").all()
    # the retried run is simulated again: its monitor row is bit-identical to the first one
    pd.testing.assert_frame_equal(
        again.results[again.results["detector"] == "pm"].reset_index(drop=True), first_pm,
        check_exact=True)
