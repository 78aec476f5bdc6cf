"""``fdd-campaign bench``: simulation speed, memory, and the ratio to the per-run reference.

Everything is measured in one process run so that ratios are comparable on a shared, noisy
machine: the vectorised chunked simulation of N runs on the requested workers, and a few
runs of the straightforward per-run reference (:mod:`scenarios.reference`, ``solve_ivp`` in
a Python loop) whose per-run time is extrapolated to N; then the per-step cost of every
registered detector's ``detect`` on one chunk (:func:`detector_costs`).
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


def _simulate_chunk_on(rows, plant):
    sig, _ = simulate(rows, plant=plant)
    return sig.n_runs, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench(n_runs: int = 2200, duration_s: float = 60.0, jobs: int = 2, chunk_size: int = 275,
          reference_runs: int = 2, echo=print, plant: str | None = None,
          plant_runs: int = 40) -> dict:
    """Measure and print the figures; returns them as a dict.

    *plant*: an FMU file; its first *plant_runs* runs of the same load are also simulated on
    the FMU back end (same workers) and its per-run cost is reported beside the built-in
    plant's."""
    spec = None
    if plant is not None:
        from scenarios.fmu import FmuPlant, probe

        spec = FmuPlant.of(str(__import__("pathlib").Path(plant).resolve()))
        probe(spec, faults={"disconnection"})
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
    if spec is not None:
        m = min(plant_runs, n_runs)
        fmu_rows = runs.iloc[:m]
        per = max(1, -(-m // jobs))
        t2 = time.perf_counter()
        Parallel(n_jobs=jobs, backend="loky")(
            delayed(_simulate_chunk_on)(fmu_rows.iloc[s:s + per], spec) for s in range(0, m, per))
        fmu_wall = time.perf_counter() - t2
        builtin_per_run = wall / n_runs
        fmu_per_run = fmu_wall / m
        figures.update({
            "fmu_runs": m, "fmu_wall_s": fmu_wall, "fmu_s_per_run": fmu_per_run,
            "builtin_s_per_run": builtin_per_run,
            "fmu_cost_ratio": fmu_per_run / builtin_per_run,
        })
        echo(f"  FMU plant ({plant}): {m} runs on {jobs} worker(s) in {fmu_wall:.2f} s")
        echo(f"  per-run cost (wall)   : built-in {1000 * builtin_per_run:8.1f} ms, FMU "
             f"{1000 * fmu_per_run:8.1f} ms  -> FMU costs {figures['fmu_cost_ratio']:.1f} x "
             "the built-in plant per run")
    figures["detector_ns_per_run_step"] = detector_costs(min(chunk_size, n_runs), duration_s,
                                                         echo=echo)
    return figures


def detector_costs(n_runs: int = 100, duration_s: float = 60.0, learning_runs: int = 12,
                   echo=print) -> dict[str, float]:
    """Per-step cost of every registered detector's ``detect`` on one chunk of *n_runs*
    (in this process, one after the other, so the figures compare): ns per run-step."""
    from detectors import available_detectors, make_detector

    runs = bench_runs(n_runs, duration_s)
    signals, _ = simulate(runs)
    learn_rows = bench_runs(learning_runs, duration_s, seed=2)
    learn_rows["fault"], learn_rows["onset_s"] = "none", np.nan
    learn_rows["magnitude"] = np.nan
    learning, _ = simulate(learn_rows)
    costs = {}
    for name in available_detectors():
        det = make_detector(name)
        if det.capabilities.needs_fit:
            det.fit(learning)
        t0 = time.perf_counter()
        det.detect(signals)
        costs[name] = (time.perf_counter() - t0) / (signals.n_runs * signals.n_steps) * 1e9
    echo(f"  detector cost         : per run-step of detect(), chunk of {n_runs} runs")
    for name, ns in costs.items():
        echo(f"    {name:<20}: {ns:8.0f} ns")
    return costs
