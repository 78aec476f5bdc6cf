"""The campaign on a dask.distributed cluster: a local scheduler and two workers started as
separate processes on 127.0.0.1 (random free ports, no dashboards), stopped by their ids."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

import distributed  # noqa: F401  (the [dask] extra, part of the [test] extra)

from campaign import run
from campaign.cli.commands import main  # noqa: E402
from campaign.config import CampaignConfig, load_config  # noqa: E402
from campaign.plan import build_plan  # noqa: E402
from detectors import registry  # noqa: E402

TESTS = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(procs) -> None:
    """Stop the processes this module started, by their ids (workers before the scheduler)."""
    for proc in reversed(procs):
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGTERM)
    for proc in reversed(procs):
        try:
            proc.wait(timeout=3)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(address, worker processes) of a scheduler and two single-threaded workers.

    ``allowed-failures = 0``: a task whose worker dies is not resubmitted to the next
    worker (which a marked run would kill too) but fails with KilledWorker at once.
    """
    from distributed import Client

    work = tmp_path_factory.mktemp("dask")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="0",
               PYTHONPATH=os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    dask = [sys.executable, "-m", "dask"]
    procs = []
    try:
        procs.append(subprocess.Popen(
            dask + ["scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            env=env, cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        workers = []
        for i in range(2):
            workers.append(subprocess.Popen(
                dask + ["worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                        "--no-nanny", "--no-dashboard", "--name", f"w{i}",
                        "--local-directory", str(work / f"w{i}")],
                env=env, cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs += workers
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        yield address, workers
    finally:
        _stop(procs)


@pytest.mark.slow
def test_smoke_on_the_cluster_is_bit_identical_to_two_local_jobs(cluster, tmp_path):
    address, _ = cluster
    assert main(["run", "smoke", "--out", str(tmp_path / "dask"), "--scheduler", address,
                 "--quiet"]) == 0
    assert main(["run", "smoke", "--out", str(tmp_path / "loky"), "--jobs", "2",
                 "--quiet"]) == 0
    on_dask = pd.read_parquet(tmp_path / "dask" / "summary.parquet")
    local = pd.read_parquet(tmp_path / "loky" / "summary.parquet")
    pd.testing.assert_frame_equal(on_dask, local, check_exact=True)
    import campaign

    rows_dask = campaign.load(tmp_path / "dask").results
    rows_local = campaign.load(tmp_path / "loky").results
    assert len(rows_dask) == len(build_plan(load_config("smoke")))
    pd.testing.assert_frame_equal(
        rows_dask.sort_values(["run_id", "detector"]).reset_index(drop=True),
        rows_local.sort_values(["run_id", "detector"]).reset_index(drop=True),
        check_exact=True)


def test_certify_sampling_on_the_cluster_equals_local_workers(cluster, tmp_path):
    """certify --sampling --scheduler: the subset simulation's batches on the cluster's
    workers, through the runner's pipeline, give the certificate of two local workers."""
    import shutil

    address, _ = cluster
    out = tmp_path / "local"
    assert main(["run", "smoke", "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    shutil.copytree(out, tmp_path / "dask")
    argv = ["--sampling", "20", "--detector", "position-monitor", "--seed", "1"]
    assert main(["certify", str(out), *argv, "--jobs", "2"]) == 0
    assert main(["certify", str(tmp_path / "dask"), *argv, "--scheduler", address]) == 0
    local = pd.read_parquet(out / "certificate.parquet")
    on_dask = pd.read_parquet(tmp_path / "dask" / "certificate.parquet")
    assert local["sampling_runs"].iloc[0] >= 20
    pd.testing.assert_frame_equal(on_dask, local, check_exact=True)


def test_chunks_on_workers_without_a_nanny_run_one_blas_thread(cluster):
    """The fixture's workers run without dask's nanny, which would have set
    OPENBLAS_NUM_THREADS=1: their BLAS has its own count (one thread per core), and the task
    of each chunk limits it to one thread while the chunk runs, then restores it."""
    from distributed import Client

    from campaign.execute import run_on_cluster
    from campaign.startup import BLAS_THREAD_VARIABLES

    address, _ = cluster

    def blas_threads(*_):
        import numpy  # noqa: F401  (loads the BLAS threadpoolctl inspects)
        from threadpoolctl import threadpool_info

        return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

    def exported():
        return any(variable in os.environ for variable in BLAS_THREAD_VARIABLES)

    seen = []
    chunks = [pd.DataFrame({"run": [i]}) for i in range(6)]
    with Client(address, timeout=60) as client:
        before = client.run(blas_threads)
        # a count set in a worker's environment wins, as in the fdd-campaign process
        expected = {w: (count if set_there else [1])
                    for (w, count), set_there in zip(before.items(),
                                                     client.run(exported).values())}
        run_on_cluster(client, chunks, blas_threads, {}, None,
                       lambda rows, status, message: message, seen.append, log=lambda m: None)
        after = client.run(blas_threads)
    assert len(seen) == len(chunks)
    assert {tuple(s) for s in seen} <= {tuple(c) for c in expected.values()}
    assert after == before


def test_a_worker_killed_mid_campaign_ends_as_error_rows_and_a_rerun_completes(
        cluster, tmp_path, monkeypatch):
    address, workers = cluster
    monkeypatch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")
    marker = tmp_path / "marked.json"
    cfg = CampaignConfig.from_dict({
        "campaign": {"name": "dask-kill", "seed": 5, "duration_s": 20.0},
        "group": [{"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"],
                   "count": 3}],
        "detector": [{"name": "misbehaving", "params": {"marker": str(marker),
                                                        "mode": "kill"}}],
        "runner": {"chunk_size": 2},
    })
    plan = build_plan(cfg)
    victim = plan["run_id"].iloc[2]
    marker.write_text(json.dumps([victim]))
    out = tmp_path / "out"
    res = run(cfg, out, scheduler=address, progress=False, log=lambda m: None)
    assert res.complete and len(res.results) == len(plan)
    failed = res.results[res.results["status"] != "ok"]
    # the chunk of the victim (runs 2 and 3) killed its worker: recorded, not lost
    assert set(failed["run_id"]) == set(plan["run_id"].iloc[2:4])
    assert failed["error"].str.contains("dask workers died").all()
    # one of the two workers was killed by the marked run
    time.sleep(0.5)
    assert sum(w.poll() is not None for w in workers) == 1

    marker.unlink()
    again = run(cfg, out, scheduler=address, progress=False, log=lambda m: None)
    assert again.complete and (again.results["status"] == "ok").all()
    assert len(again.results) == len(plan) and not again.results["run_id"].duplicated().any()
