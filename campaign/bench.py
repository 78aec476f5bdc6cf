"""``fdd-campaign bench``: simulation speed, memory, and the ratio to the per-run reference.

Everything is measured in one process run so that ratios are comparable on a shared, noisy
machine: the vectorised chunked simulation of N runs on the requested workers, and a few
runs of the straightforward per-run reference (:mod:`scenarios.reference`, ``solve_ivp`` in
a Python loop) whose per-run time is extrapolated to N.
"""

from __future__ import annotations

import resource
import time

import numpy as np
import pandas as pd
from joblib import Parallel, delayed

from scenarios.catalog import MANOEUVRES
from scenarios.envelope import DRAW_COLUMNS
from scenarios.reference import integrate_reference
from scenarios.simulate import RUN_COLUMNS, prepare, simulate


def bench_runs(n_runs: int, duration_s: float, seed: int = 1) -> pd.DataFrame:
    """A fault-free/faulty mix of *n_runs* elevator runs over the envelope (benchmark load)."""
    rng = np.random.default_rng(seed)
    faults = np.array(["none", "runaway", "liquid_jam", "solid_jam", "disconnection"])
    fault = faults[rng.integers(0, len(faults), n_runs)]
    frame = pd.DataFrame({
        "run_id": [f"bench-{i}" for i in range(n_runs)], "surface": "elevator",
        "manoeuvre": np.array(MANOEUVRES)[np.arange(n_runs) % len(MANOEUVRES)],
        "fault": fault,
        "onset_s": np.where(fault == "none", np.nan, np.round(rng.uniform(5, duration_s - 10, n_runs), 2)),
        "magnitude": np.where(fault == "runaway", 5.0, np.where(fault == "liquid_jam", 1.2, np.nan)),
        "freq_hz": np.nan,
        "alt_ft": rng.uniform(8000, 38000, n_runs), "vcas_kt": rng.uniform(160, 300, n_runs),
        "mass_t": rng.uniform(120, 233, n_runs), "cg_pct": rng.uniform(17, 41, n_runs),
        **{c: rng.uniform(-0.05, 0.05, n_runs) for c in DRAW_COLUMNS},
        "seed": seed, "stream": np.arange(n_runs), "duration_s": duration_s,
    })
    return frame[list(RUN_COLUMNS)]


def _peak_rss_mb() -> float:
    self_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    child_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(self_kb, child_kb) / 1024.0


def _simulate_chunk(rows):
    sig, _ = simulate(rows)
    return sig.n_runs, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench(n_runs: int = 2200, duration_s: float = 60.0, jobs: int = 2, chunk_size: int = 275,
          reference_runs: int = 2, echo=print) -> dict:
    """Measure and print the figures; returns them as a dict."""
    runs = bench_runs(n_runs, duration_s)
    chunks = [runs.iloc[s:s + chunk_size] for s in range(0, n_runs, chunk_size)]
    echo(f"bench: {n_runs} runs x {duration_s:g} s at 100 Hz, {jobs} worker(s), "
         f"chunks of {chunk_size}")
    t0 = time.perf_counter()
    out = Parallel(n_jobs=jobs, backend="loky")(delayed(_simulate_chunk)(c) for c in chunks)
    wall = time.perf_counter() - t0
    worker_peak = max(m for _, m in out)

    ref = runs.iloc[:reference_runs]
    t1 = time.perf_counter()
    integrate_reference(prepare(ref))
    ref_per_run = (time.perf_counter() - t1) / reference_runs
    ref_total = ref_per_run * n_runs
    figures = {
        "runs": n_runs, "wall_s": wall,
        "run_seconds_per_wall_second": n_runs * duration_s / wall,
        "worker_peak_rss_mb": worker_peak, "process_peak_rss_mb": _peak_rss_mb(),
        "reference_s_per_run": ref_per_run, "reference_extrapolated_s": ref_total,
        "speedup_vs_reference": ref_total / wall,
    }
    echo(f"  vectorised simulation : {wall:8.2f} s wall  "
         f"({figures['run_seconds_per_wall_second']:,.0f} simulated s per wall s)")
    echo(f"  peak memory           : {worker_peak:8.0f} MB per worker process")
    echo(f"  per-run reference     : {ref_per_run:8.2f} s per run (solve_ivp, {reference_runs} "
         f"runs timed) -> {ref_total:,.0f} s for {n_runs} runs")
    echo(f"  speed-up              : {figures['speedup_vs_reference']:8.0f} x")
    from .plant_bench import plant_cost

    figures.update(plant_cost(runs.iloc[:min(n_runs, chunk_size)], echo=echo))
    return figures
