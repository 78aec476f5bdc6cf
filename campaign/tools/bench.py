"""``fdd-campaign bench``: simulation speed, memory, and the ratio to the per-run reference.

Everything is measured in one command run so that ratios are comparable on a shared, noisy
machine: the vectorised chunked simulation of N runs on the requested workers, and a few
runs of the straightforward per-run reference (:mod:`scenarios.reference`, ``solve_ivp`` in
a Python loop) whose per-run time is extrapolated to N; with ``--plant FMU`` the same
load's first runs on that FMU, per-run cost beside the built-in plant. With a campaign
(default ``addsafe-mc``) it also runs the whole campaign as ``fdd-campaign run`` in a
subprocess — simulation, every detector, scoring and Parquet — first with an empty
compile cache, then with the cache warm, and reports wall time, peak memory of the
process tree and the ratio to the per-run reference; and the cost of each built-in
detector per run-step.

Each campaign's arithmetic floor (:func:`arithmetic_floor`): the rate-law evaluations its
plant and detectors ask for, times the measured cost of one, plus the imports — the distance
to the limit, as a ratio. With a yardstick command (``--yardstick``), rounds of the yardstick
and the campaign back to back, wall and CPU time of each and their ratios
(:func:`yardstick_pairs`).

The in-process figures time the stages of the evaluation pipeline (:mod:`campaign.evaluate`)
one by one: the simulation (:func:`campaign.evaluate.simulate_signals`) and each detector
(:func:`campaign.evaluate.detect`), with the settings of
:func:`campaign.tools.plant_bench.bench_settings`.
"""

from __future__ import annotations

import math
import os
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
from joblib import Parallel, delayed

from scenarios.catalog import MANOEUVRES
from scenarios.envelope import DRAW_COLUMNS
from scenarios.errors import ArgumentError
from scenarios.manoeuvres import MANOEUVRE_PARAMS
from scenarios.reference import integrate_reference
from scenarios.runs import RUN_RANGES
from scenarios.simulate import RUN_COLUMNS, prepare

from ..evaluate import detect, simulate_signals
from ..startup import user_environment
from .plant_bench import bench_settings


def bench_runs(n_runs: int, duration_s: float, seed: int = 1) -> pd.DataFrame:
    """A fault-free/faulty mix of *n_runs* elevator runs over the envelope (benchmark load)."""
    rng = np.random.default_rng(seed)
    faults = np.array(["none", "runaway", "liquid_jam", "solid_jam", "disconnection"])
    fault = faults[rng.integers(0, len(faults), n_runs)]
    frame = pd.DataFrame({
        "run_id": [f"bench-{i}" for i in range(n_runs)], "surface": "elevator",
        "manoeuvre": np.array(MANOEUVRES)[np.arange(n_runs) % len(MANOEUVRES)],
        "fault": fault,
        "onset_s": np.where(fault == "none", np.nan,
                            np.round(rng.uniform(5, duration_s - 10, n_runs), 2)),
        "magnitude": np.where(fault == "runaway", 5.0,
                              np.where(fault == "liquid_jam", 1.2, np.nan)),
        "freq_hz": np.nan,
        "alt_ft": rng.uniform(8000, 38000, n_runs), "vcas_kt": rng.uniform(160, 300, n_runs),
        "mass_t": rng.uniform(120, 233, n_runs), "cg_pct": rng.uniform(17, 41, n_runs),
        **{c: rng.uniform(-0.05, 0.05, n_runs) for c in DRAW_COLUMNS},
        "seed": seed, "stream": np.arange(n_runs), "duration_s": duration_s,
    })
    return frame[list(RUN_COLUMNS)]


#: Bytes in a MiB: the peaks are measured in KiB/1024 (MiB); the speed goals are in 10⁶-byte MB.
MIB = 2 ** 20


def _peak_rss_mb() -> float:
    """Peak resident set [MiB, 2²⁰ bytes] of this process or its largest child (the figures'
    ``*_rss_mb`` keys hold MiB, as the report prints them)."""
    self_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    child_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(self_kb, child_kb) / 1024.0


def _simulate_chunk(rows, plant="actuator"):
    """Simulate *rows* on *plant*; (runs, peak resident memory [MiB] of this process)."""
    sig = simulate_signals(rows, bench_settings(plant))
    return sig.n_runs, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench(n_runs: int = 2200, duration_s: float = 60.0, jobs: int = 2, chunk_size: int = 275,
          reference_runs: int = 2, echo=print, campaign: str | None = "addsafe-mc",
          detectors: bool = True, cold: bool = True, backend: str = "threading",
          plant: str | None = None, plant_runs: int = 40, stages: bool = True,
          stage_runs: int = 200, progress=None, floor: bool = True,
          yardstick: str | None = None, yardstick_dir: str | None = None,
          pairs: int = 3) -> dict:
    """Measure and print the figures; returns them as a dict. *campaign*: preset or file run
    whole, or several separated by commas (e.g. ``"addsafe-mc,chen-mc"``; None: skip);
    *detectors*: time each built-in detector; *cold*: also time a first
    campaign run with an empty compile cache; *backend*: joblib backend of the simulation
    part ("threading", like ``fdd-campaign run``, or "loky"); *plant*: an FMU file whose
    first *plant_runs* runs of the same load are also simulated on the FMU back end, its
    per-run cost reported beside the built-in plant's, or ``"jsbsim"``: the first
    *plant_runs* runs on the JSBSim plant against its flight model alone
    (:func:`campaign.tools.plant_bench.jsbsim_cost`); *stages*: the share of each stage of
    each campaign (:func:`stage_costs` on *stage_runs* of its runs), under ``"stages"``;
    *progress*: called with a line naming each measurement as it starts (None: silent);
    *floor*: each campaign's arithmetic floor and its ratio to it (:func:`arithmetic_floor`);
    *yardstick*: a command (split as a shell would, run without one, in *yardstick_dir*)
    timed back to back with each campaign, *pairs* rounds (:func:`yardstick_pairs`)."""
    counts = {"n_runs": (n_runs, "runs simulated", 2200), "jobs": (jobs, "local workers", 2),
              "chunk_size": (chunk_size, "runs per chunk", 275),
              "reference_runs": (reference_runs, "runs timed with the solve_ivp reference", 2),
              "plant_runs": (plant_runs, "runs timed on the FMU plant", 40),
              "stage_runs": (stage_runs, "runs timed stage by stage", 200),
              "pairs": (pairs, "rounds of the yardstick and the campaign", 3)}
    problems = [(argument, value, f"must be an integer ≥ 1 ({what})", eg)
                for argument, (value, what, eg) in counts.items()
                if isinstance(value, bool) or int(value) != value or value < 1]
    shortest, longest = MANOEUVRE_PARAMS.min_duration_s, RUN_RANGES["duration_s"][1]
    if not shortest <= duration_s <= longest:
        problems.append(("duration_s", duration_s,
                         f"a run lasts {shortest:g} to {longest:g} s (the manoeuvres' shortest "
                         "record, the run table's longest)", 60))
    if problems:
        raise ArgumentError(problems)
    names = [c.strip() for c in (campaign or "").split(",") if c.strip()]
    yard_cmd = _yardstick_command(yardstick, yardstick_dir, pairs, names)
    from ..config import load_config

    for name in names:          # a campaign that cannot load: exit 2 before any measurement
        load_config(name)
    spec = None
    if plant == "jsbsim":
        from scenarios.jsbsim.fdm import jsbsim_module

        jsbsim_module()                         # missing: exit 2 naming the extra
    elif plant is not None:
        from scenarios.fmu import FmuPlant, probe

        spec = FmuPlant.of(str(__import__("pathlib").Path(plant).resolve()))
        probe(spec, faults={"disconnection"})
    runs = bench_runs(n_runs, duration_s)
    chunks = [runs.iloc[s:s + chunk_size] for s in range(0, n_runs, chunk_size)]
    echo(f"bench: {n_runs} runs x {duration_s:g} s at 100 Hz, {jobs} {backend} worker(s), "
         f"chunks of {chunk_size}")
    t0 = time.perf_counter()
    from scenarios import compiled as kernels

    kernels.warm_up(echo)                  # compile (or load) outside the timing
    step = _Steps(progress)
    step(f"simulating {n_runs} runs")
    out = Parallel(n_jobs=jobs, backend=backend)(delayed(_simulate_chunk)(c) for c in chunks)
    wall = time.perf_counter() - t0
    worker_peak = max(m for _, m in out)

    ref = runs.iloc[:reference_runs]
    step(f"timing the per-run reference on {reference_runs} run(s)")
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
    echo(f"  peak memory           : {worker_peak:8.0f} MiB "
         + ("per worker process" if backend == "loky" else "(this process)"))
    echo(f"  per-run reference     : {ref_per_run:8.2f} s per run (solve_ivp, {reference_runs} "
         f"runs timed) -> {ref_total:,.0f} s for {n_runs} runs")
    echo(f"  speed-up              : {figures['speedup_vs_reference']:8.0f} x")
    if plant == "jsbsim":
        from .plant_bench import jsbsim_cost

        step("timing the JSBSim plant and its flight model alone")
        figures.update(jsbsim_cost(runs.iloc[:min(plant_runs, n_runs)], echo=echo))
    elif spec is not None:
        step(f"timing the FMU plant {plant}")
        figures.update(_fmu_cost(runs.iloc[:min(plant_runs, n_runs)], spec, jobs,
                                 builtin_per_run=wall / n_runs, label=plant, echo=echo))
    from .plant_bench import plant_cost

    step("timing the plants (actuator, aircraft)")
    figures.update(plant_cost(runs.iloc[:min(n_runs, chunk_size)], echo=echo))
    if detectors:
        step("timing each built-in detector")
        costs = detector_costs(duration_s=duration_s)
        figures["detectors"] = costs
        for c in costs:
            echo(f"  detector {c['detector']:<13s}: {c['ns_per_run_step']:8.1f} ns per run-step "
                 f"({c['engine']})")
    for i, name in enumerate(names):
        whole = bench_campaign(name, jobs, reference_s_per_run=ref_per_run, cold=cold,
                               echo=echo, step=step)
        if floor:
            step(f"counting the rate-law evaluations of {name} and timing one")
            whole["floor"] = floor_ratios(arithmetic_floor(name, jobs), whole)
            print_floor(whole["floor"], echo)
        if yard_cmd is not None:
            whole["yardstick"] = yardstick_pairs(name, jobs, yard_cmd, yardstick_dir, pairs,
                                                 echo=echo, step=step)
        if i == 0:       # the first campaign's figures at the top level, as before
            figures.update(whole)
        figures.setdefault("campaigns", {})[name] = whole
        if stages:
            step(f"timing the stages of {name} on {stage_runs} of its runs")
            costs = stage_costs(name, sample_runs=stage_runs)
            print_stages(costs, echo)
            whole["stages"] = costs
            figures.setdefault("stages", {})[name] = costs
    step.done()
    return figures


class _Steps:
    """Progress of :func:`bench`: each measurement announced as it starts, with the time
    since the first, through *progress* (a callable taking one line; None: silent)."""

    def __init__(self, progress=None):
        self.progress, self.t0 = progress, time.perf_counter()

    def __call__(self, what: str, end: str = "…") -> None:
        if self.progress is not None:
            self.progress(f"bench [{time.perf_counter() - self.t0:6.1f} s] {what}{end}")

    def done(self) -> None:
        """Every measurement finished."""
        self("done", end="")


def _fmu_cost(rows: pd.DataFrame, spec, jobs: int, *, builtin_per_run: float, label: str,
              echo=print) -> dict:
    """Wall time of *rows* simulated on the FMU plant *spec* in *jobs* loky processes, and
    its per-run cost against the built-in plant's *builtin_per_run* [s]."""
    m = len(rows)
    per = max(1, -(-m // jobs))
    t0 = time.perf_counter()
    Parallel(n_jobs=jobs, backend="loky")(
        delayed(_simulate_chunk)(rows.iloc[s:s + per], spec) for s in range(0, m, per))
    fmu_wall = time.perf_counter() - t0
    fmu_per_run = fmu_wall / m
    figures = {"fmu_runs": m, "fmu_wall_s": fmu_wall, "fmu_s_per_run": fmu_per_run,
               "builtin_s_per_run": builtin_per_run,
               "fmu_cost_ratio": fmu_per_run / builtin_per_run}
    echo(f"  FMU plant ({label}): {m} runs on {jobs} worker(s) in {fmu_wall:.2f} s")
    echo(f"  per-run cost (wall)   : built-in {1000 * builtin_per_run:8.1f} ms, FMU "
         f"{1000 * fmu_per_run:8.1f} ms  -> FMU costs {figures['fmu_cost_ratio']:.1f} x "
         "the built-in plant per run")
    return figures


# ---- whole campaign in a subprocess ------------------------------------------------------------
def _tree_rss_kb(pid: int) -> int:
    """Resident memory [kB] of process *pid* and all its descendants (Linux /proc)."""
    total, stack, seen = 0, [pid], set()
    while stack:
        p = stack.pop()
        if p in seen:
            continue
        seen.add(p)
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1])
            for task in Path(f"/proc/{p}/task").iterdir():
                stack += [int(c) for c in (task / "children").read_text().split()]
        except (OSError, ValueError):
            continue
    return total


def run_campaign_process(campaign: str, jobs: int, cache_dir: Path | None = None,
                         poll_s: float = 0.02) -> dict:
    """Run ``fdd-campaign run CAMPAIGN`` in a subprocess; wall time [s], CPU time [s] (user +
    system, of the process and the workers it waited for), peak memory [MiB] of its process
    tree (sampled every *poll_s*), and its output. *cache_dir* points numba's compile cache
    there (an empty directory: a first run without a cache)."""
    env = user_environment()       # as from the user's shell (not this command's BLAS count)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    with tempfile.TemporaryDirectory(prefix="fdd-bench-") as tmp:
        cmd = [sys.executable, "-m", "campaign.cli", "run", campaign, "--out",
               str(Path(tmp) / "out"), "--jobs", str(jobs), "--quiet"]
        cpu0 = _children_cpu_s()
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        peak = [0]

        def sample():
            while proc.poll() is None:
                peak[0] = max(peak[0], _tree_rss_kb(proc.pid))
                time.sleep(poll_s)

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        stdout, stderr = proc.communicate()
        wall = time.perf_counter() - t0
        cpu = _children_cpu_s() - cpu0
        sampler.join()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed with exit code {proc.returncode}:\n{stderr}")
    return {"wall_s": wall, "cpu_s": cpu, "peak_rss_mb": peak[0] / 1024.0, "stdout": stdout,
            "stderr": stderr}


def _children_cpu_s() -> float:
    """User + system CPU time [s] of the child processes this process has waited for."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


# ---- detectors per run-step --------------------------------------------------------------------
def detector_costs(n_runs: int = 200, duration_s: float = 60.0, learning_runs: int = 24,
                   engines=("compiled", "numpy")) -> list[dict]:
    """Seconds per run-step of ``detect`` for each built-in detector and engine (fitted on
    *learning_runs* fault-free runs; timed on *n_runs* runs in one block; a detector that
    needs the aircraft plant gets the same runs simulated with the aircraft in the loop,
    the left inboard aileron monitored)."""
    from detectors.registry import BUILTIN, make_detector
    from scenarios import compiled as kernels

    runs = bench_runs(n_runs, duration_s, seed=2)
    learn = bench_runs(learning_runs, duration_s, seed=3).assign(fault="none", onset_s=np.nan,
                                                                  magnitude=np.nan)
    learn["run_id"] = [f"learn-{i}" for i in range(learning_runs)]
    actuator = bench_settings()
    signals = simulate_signals(runs, actuator)
    learning = simulate_signals(learn, actuator)
    aircraft = {}                   # aircraft-plant signals, for detectors that need them

    def signals_for(det):
        if not getattr(det.capabilities, "needs_aircraft", False):
            return signals, learning
        if not aircraft:
            monitored, level = "left_inboard_aileron", bench_settings("aircraft")
            aircraft["sets"] = (simulate_signals(runs.assign(surface=monitored), level),
                                simulate_signals(learn.assign(surface=monitored), level))
        return aircraft["sets"]

    kernels.warm_up()
    out = []
    for name in BUILTIN:
        for engine in engines:
            with kernels.use_engine(engine):
                det = make_detector(name)
                sig, learn_sig = signals_for(det)
                if det.capabilities.needs_fit:
                    det.fit(learn_sig)
                detect(sig.take(slice(0, 2)), {name: det})   # first call outside the timing
                t0 = time.perf_counter()
                detect(sig, {name: det})
                dt = time.perf_counter() - t0
            out.append({"detector": name, "engine": engine,
                        "ns_per_run_step": 1e9 * dt / (sig.n_runs * sig.n_steps)})
    return out


def bench_campaign(campaign: str = "addsafe-mc", jobs: int = 2, reference_s_per_run=None,
                   cold: bool = True, echo=print, step=None) -> dict:
    """Whole-campaign figures (see the module docstring); *step* announces each run
    (:class:`_Steps`)."""
    step = step or _Steps()
    from ..config import load_config
    from ..plan import build_plan

    plan = build_plan(load_config(campaign))
    figures = {"campaign": campaign, "campaign_runs": len(plan)}
    if cold:
        with tempfile.TemporaryDirectory(prefix="fdd-numba-cache-") as cache:
            step(f"running {campaign} ({len(plan)} runs) with an empty compile cache")
            first = run_campaign_process(campaign, jobs, cache_dir=Path(cache))
            step(f"running {campaign} again, the compile cache warm")
            warm = run_campaign_process(campaign, jobs, cache_dir=Path(cache))
        figures["cold_wall_s"] = first["wall_s"]
        figures["cold_peak_rss_mb"] = first["peak_rss_mb"]
        echo(f"  {campaign} first run  : {first['wall_s']:8.2f} s wall, peak "
             f"{first['peak_rss_mb']:.0f} MiB (empty compile cache: "
             f"{'compiling' in first['stderr'] and 'compiled' or 'no compile message!'})")
    else:
        step(f"running {campaign} ({len(plan)} runs)")
        warm = run_campaign_process(campaign, jobs)
    figures["wall_s_campaign"] = warm["wall_s"]
    figures["cpu_s_campaign"] = warm["cpu_s"]
    figures["peak_rss_mb_campaign"] = warm["peak_rss_mb"]
    echo(f"  {campaign} warm cache : {warm['wall_s']:8.2f} s wall, {warm['cpu_s']:.2f} s CPU "
         "(user + system), peak "
         f"{warm['peak_rss_mb']:.0f} MiB ({warm['peak_rss_mb'] * MIB / 1e6:.0f} MB) for the "
         f"process tree ({len(plan)} runs, every "
         f"detector, scoring and Parquet; {jobs} worker(s))")
    if reference_s_per_run:
        ref_total = reference_s_per_run * len(plan)
        figures["campaign_speedup_vs_reference"] = ref_total / warm["wall_s"]
        echo(f"  campaign vs per-run   : {figures['campaign_speedup_vs_reference']:8.0f} x "
             f"(reference: simulation only, {ref_total:,.0f} s for {len(plan)} runs)")
    return figures


# ---- where the time of a campaign goes, stage by stage --------------------------------------
#: What ``fdd-campaign run`` imports before its first run (timed in a fresh interpreter).
RUN_IMPORTS = ("campaign.cli.commands", "campaign.runner", "campaign.evaluate",
               "campaign.store.directory",
               "detectors.registry", "scenarios.simulate", "pyarrow.parquet")


def import_seconds(modules=RUN_IMPORTS, extra=()) -> float:
    """CPU time [s] (user + system) of a fresh interpreter that imports *modules* and
    *extra* and exits (the start-up a command pays once per process)."""
    code = "import " + ", ".join((*modules, *extra))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _spread(frame: pd.DataFrame, n: int) -> pd.DataFrame:
    """*n* rows of *frame* spread evenly over it (every group of the plan represented)."""
    if n >= len(frame):
        return frame
    return frame.iloc[np.linspace(0, len(frame) - 1, n).round().astype(int)]


def stage_costs(campaign: str = "addsafe-mc", sample_runs: int = 200,
                learning_runs: int | None = None, imports: bool = True) -> dict:
    """CPU seconds of each stage of *campaign* on one thread, scaled to its plan, and their
    shares: what a run of the whole campaign spends where (docs/execution.md, Benchmark).
    CPU time of the measuring thread (``time.thread_time``), not wall time, so that other
    work on a shared machine changes the figures little.

    Per-run stages (preparation of the open-loop inputs, the plant's time loop, the sensors
    and truth, each detector's ``detect``, scoring, writing the Parquet shard) are timed on
    *sample_runs* runs spread over the plan and scaled by its number of runs; the learning
    set (at most *learning_runs* of its runs; None: all) is simulated and each detector
    fitted once; *imports*: the start-up imports timed in a fresh interpreter. The plant
    stages are split into preparation / plant / sensors and truth on the built-in actuator
    plant, one ``simulation`` stage on other plants. Returns ``{"campaign", "runs",
    "learning_runs", "sampled_runs", "stages": [{"stage", "seconds", "share"}, …],
    "total_s"}``; the shares add up to 1.
    """
    from dataclasses import replace

    from scenarios import compiled as kernels
    from scenarios.simulate import ActuatorPlant, simulate

    from ..config import load_config
    from ..plan import build_learning_plan, build_plan
    from ..evaluate import score
    from ..plant_setup import resolve
    from ..store.files import write_parquet
    from ..runner import build_detectors, settings_of

    config = load_config(campaign)
    resolved = resolve(config)          # its plant built once for the plan, learning, runs
    plan, learning = build_plan(resolved), build_learning_plan(resolved)
    if learning_runs is not None:
        learning = _spread(learning, learning_runs)
    settings = settings_of(resolved)
    detectors = build_detectors(config)
    rows = _spread(plan, sample_runs)
    scale = len(plan) / len(rows)
    kernels.warm_up()
    seconds: dict[str, float] = {}

    def timed(stage, func, *args, factor=1.0, **kwargs):
        t0 = time.thread_time()
        out = func(*args, **kwargs)
        seconds[stage] = seconds.get(stage, 0.0) + factor * (time.thread_time() - t0)
        return out

    if imports:
        seconds["imports"] = import_seconds(
            extra=tuple(sorted({type(d).__module__ for d in detectors.values()})))
    with kernels.use_engine(settings.engine):
        learn = timed("learning set: simulation", simulate_signals, learning, settings)
        learn = replace(learn, classes=learning["manoeuvre"].to_numpy(dtype=str))
        for label, det in detectors.items():
            if det.capabilities.needs_fit:
                timed(f"fit {label}", det.fit, learn)
        plant = settings.plant
        if isinstance(plant, ActuatorPlant):    # the stages of the built-in servo-loop
            laps: dict[str, float] = {}
            signals, truth = simulate(rows, ts=settings.ts,
                                      pressure_sensor=settings.pressure_sensor, timings=laps)
            seconds.update({k: scale * v for k, v in laps.items()})
        else:
            signals, truth = timed("simulation", plant.simulate, rows, ts=settings.ts,
                                   pressure_sensor=settings.pressure_sensor)
            seconds["simulation"] *= scale
        detections = {}
        for label, det in detectors.items():
            detections.update(timed(f"detect {label}", detect, signals, {label: det},
                                    factor=scale))
        frame = timed("scoring", score, rows, truth, detections, settings, signals.actuator,
                      factor=scale)
    with tempfile.TemporaryDirectory(prefix="fdd-bench-") as tmp:
        timed("I/O (Parquet shard)", write_parquet, frame, Path(tmp) / "shard.parquet",
              config.to_json(), factor=scale)
    total = sum(seconds.values())
    return {"campaign": campaign, "runs": len(plan), "learning_runs": len(learning),
            "sampled_runs": len(rows), "total_s": total,
            "stages": [{"stage": k, "seconds": v, "share": v / total}
                       for k, v in seconds.items()]}


def print_stages(costs: dict, echo=print) -> None:
    """The table of :func:`stage_costs`."""
    echo(f"  CPU time of the stages of {costs['campaign']}, one thread "
         f"({costs['sampled_runs']} of {costs['runs']} runs timed and scaled; learning set "
         f"{costs['learning_runs']} runs):")
    for s in costs["stages"]:
        echo(f"    {s['stage']:<34s} {s['seconds']:7.2f} s  {100 * s['share']:5.1f} %")
    echo(f"    {'total (one thread)':<34s} {costs['total_s']:7.2f} s")


# ---- the arithmetic floor of a campaign -------------------------------------------------------
def rate_evaluations(campaign: str) -> dict:
    """Evaluations of the rate law (docs/physics.md §3) a run of *campaign* asks for, by part.

    Each part declares its count per run and step: the plant
    (``rate_evaluations_per_step``, 4 for the built-in servo-loop's RK4), each detector
    (``rate_evaluations_per_step()``, over the plan and, when it is fitted, the learning set)
    and, on the built-in servo-loop when a detector estimates the rod fault
    (``Capabilities.estimates_rod_fault``; otherwise it is never computed), the healthy
    noise-free model of the jam runs that defines their rod fault
    (:func:`scenarios.simulate.rod_measurement_fault`, RK4). Returns
    ``{"campaign", "steps", "runs", "learning_runs", "parts": {name: evaluations},
    "uncounted": [names without a declared count]}``."""
    from scenarios.faults import ROD_MEASUREMENT_FAULTS

    from ..config import load_config
    from ..plan import build_learning_plan, build_plan
    from ..plant_setup import resolve
    from ..runner import build_detectors, settings_of

    config = load_config(campaign)
    resolved = resolve(config)
    plan, learning = build_plan(resolved), build_learning_plan(resolved)
    settings = settings_of(resolved)
    detectors = build_detectors(config)
    steps = int(round(float(config.campaign.duration_s) / settings.ts))
    parts, uncounted = {}, []
    plant = settings.plant
    per_step = getattr(plant, "rate_evaluations_per_step", None)
    if per_step is None:
        uncounted.append(f"plant ({plant.kind})")
    else:
        parts[f"plant ({plant.kind})"] = per_step * (len(plan) + len(learning)) * steps
        if any(det.capabilities.estimates_rod_fault for det in detectors.values()):
            jams = int(plan["fault"].isin(ROD_MEASUREMENT_FAULTS).sum())
            parts["healthy rod model of the jam runs"] = per_step * jams * steps
    for label, det in detectors.items():
        count = getattr(det, "rate_evaluations_per_step", None)
        if count is None:
            uncounted.append(label)
            continue
        runs = len(plan) + (len(learning) if det.capabilities.needs_fit else 0)
        parts[f"detect {label}"] = int(count()) * runs * steps
    return {"campaign": campaign, "steps": steps, "runs": len(plan),
            "learning_runs": len(learning), "parts": parts, "uncounted": uncounted}


def rate_law_cost(n_runs: int = 128, samples: int = 1000, repeats: int = 20,
                  duration_s: float = 30.0) -> float:
    """CPU time [s] of one thread for one evaluation of the rate law as the kernels evaluate
    it (:func:`scenarios.compiled.loaded_rates_all`, block by block and step by step), on
    the rods and currents of *samples* steps of *n_runs* simulated runs of the benchmark
    load (*duration_s* each, every fault type); the best of *repeats* passes."""
    from scenarios import compiled as kernels
    from scenarios.params import SENSORS

    p = prepare(bench_runs(n_runs, duration_s, seed=4), pressure_sensor=False)
    traj = kernels.integrate_compiled(p, SENSORS)
    cols = np.linspace(0, traj.x.shape[1] - 1, samples).round().astype(int)
    x = np.ascontiguousarray(traj.x[:, cols].T)              # (samples, runs): step-major
    i = np.ascontiguousarray(traj.i_app[:, cols].T)
    pf = kernels.plant_fields(p.plant)
    out = np.empty_like(x)
    kernels.loaded_rates_all(x[:1], i[:1], pf, out[:1])     # compiled/loaded outside the timing
    best = math.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        kernels.loaded_rates_all(x, i, pf, out)
        best = min(best, time.thread_time() - t0)
    return best / x.size


def arithmetic_floor(campaign: str, jobs: int, cost_s: float | None = None,
                     imports_s: float | None = None) -> dict:
    """The least time *campaign* can take on *jobs* workers if it did nothing but the
    rate-law evaluations it asks for (:func:`rate_evaluations`) at the measured cost of one
    (:func:`rate_law_cost`, or *cost_s*), spread evenly over the workers, after the imports
    of ``fdd-campaign run`` (:func:`import_seconds`, or *imports_s*, paid once on one
    thread). Everything else a run does (random draws, sensors, scoring, Parquet) costs
    above it. ``cpu_s`` = evaluations × cost; ``wall_s`` = imports + cpu_s / jobs."""
    from ..config import load_config
    from ..runner import build_detectors

    counts = rate_evaluations(campaign)
    cost = rate_law_cost() if cost_s is None else float(cost_s)
    if imports_s is None:
        detectors = build_detectors(load_config(campaign))
        imports_s = import_seconds(extra=tuple(sorted({type(d).__module__
                                                       for d in detectors.values()})))
    evaluations = sum(counts["parts"].values())
    cpu = evaluations * cost
    return {**counts, "evaluations": evaluations, "cost_s": cost, "imports_s": imports_s,
            "jobs": jobs, "cpu_s": cpu, "wall_s": imports_s + cpu / max(jobs, 1)}


def floor_ratios(floor: dict, whole: dict) -> dict:
    """*floor* (:func:`arithmetic_floor`) with the campaign's wall and CPU times and its ratios
    to the floor (``ratio_wall``, ``ratio_cpu``) when *whole* (:func:`bench_campaign`'s figures)
    holds its warm run."""
    if "wall_s_campaign" not in whole:
        return floor
    wall, cpu = whole["wall_s_campaign"], whole["cpu_s_campaign"]
    return {**floor, "campaign_wall_s": wall, "campaign_cpu_s": cpu,
            "ratio_wall": wall / floor["wall_s"],
            "ratio_cpu": cpu / (floor["cpu_s"] + floor["imports_s"])}


def print_floor(floor: dict, echo=print) -> None:
    """The lines of :func:`arithmetic_floor`, and the ratios of :func:`floor_ratios` when
    it has them."""
    name = floor["campaign"]
    parts = ", ".join(f"{k} {v:.3g}" for k, v in floor["parts"].items())
    echo(f"  {name} arithmetic floor: {floor['evaluations']:.3g} rate-law evaluations "
         f"({parts}) x {1e9 * floor['cost_s']:.1f} ns = {floor['cpu_s']:.2f} CPU-s; "
         f"+ imports {floor['imports_s']:.2f} s -> {floor['wall_s']:.2f} s wall on "
         f"{floor['jobs']} worker(s)")
    if floor["uncounted"]:
        echo(f"    (not counted, no declared rate-law count: {', '.join(floor['uncounted'])})")
    if "ratio_wall" in floor:
        floor_cpu = floor["cpu_s"] + floor["imports_s"]
        echo(f"  {name} / floor       : {floor['ratio_wall']:.2f} x in wall time "
             f"({floor['campaign_wall_s']:.2f} s), {floor['ratio_cpu']:.2f} x in CPU time "
             f"({floor['campaign_cpu_s']:.2f} s against {floor_cpu:.2f} s)")


# ---- back to back with a yardstick -------------------------------------------------------------
def _yardstick_command(yardstick: str | None, cwd: str | None, pairs: int,
                       campaigns: list[str]) -> list[str] | None:
    """The yardstick's argument list, checked before any work (:class:`ArgumentError`
    naming the fix; *pairs* is checked with the other counts by :func:`bench`)."""
    if yardstick is None:
        if cwd is not None:
            raise ArgumentError.of("yardstick_dir", None, "without {yardstick}: name the "
                                   "command to time, e.g. {yardstick} 'python campaign.py vec'")
        return None
    cmd = shlex.split(yardstick)
    if not cmd:
        raise ArgumentError.of("yardstick", yardstick, "is empty", "python campaign.py vec")
    if cwd is not None and not Path(cwd).is_dir():
        raise ArgumentError.of("yardstick_dir", cwd, "not a directory", None,
                               "the directory the yardstick command runs in")
    if shutil.which(cmd[0], path=None if os.sep not in cmd[0] else "") is None and not (
            os.sep in cmd[0] and os.access(Path(cwd or ".") / cmd[0], os.X_OK)):
        raise ArgumentError.of("yardstick", yardstick, f"{cmd[0]!r} is not an executable on "
                               "the PATH", "python campaign.py vec")
    if not campaigns:
        raise ArgumentError.of("yardstick", None, "with {campaign} none: name the campaign "
                               "to compare")
    return cmd


def _timed_process(cmd: list[str], cwd: str | None) -> dict:
    """Wall and CPU time (user + system) [s] of *cmd* run to its end in *cwd*."""
    cpu0 = _children_cpu_s()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=user_environment())
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"yardstick {' '.join(cmd)} failed with exit code "
                           f"{proc.returncode}:\n{proc.stderr}")
    return {"wall_s": wall, "cpu_s": _children_cpu_s() - cpu0}


def yardstick_pairs(campaign: str, jobs: int, command: list[str], cwd: str | None = None,
                    pairs: int = 3, echo=print, step=None) -> dict:
    """*pairs* rounds of the yardstick *command* (run in *cwd*) and then the whole *campaign*
    (warm compile cache, :func:`run_campaign_process`), back to back, so that each pair sees
    the same load of a shared machine: wall and CPU time of both, their ratios
    (campaign / yardstick) and the medians of the ratios, with the load average at each
    start. Returns ``{"pairs": [...], "median_ratio_wall", "median_ratio_cpu"}``."""
    step = step or _Steps()
    rows = []
    for k in range(pairs):
        step(f"pair {k + 1} of {pairs}: yardstick, then {campaign}")
        load = os.getloadavg()[0]
        yard = _timed_process(command, cwd)
        ours = run_campaign_process(campaign, jobs)
        rows.append({"load": load, "yard_wall_s": yard["wall_s"], "yard_cpu_s": yard["cpu_s"],
                     "wall_s": ours["wall_s"], "cpu_s": ours["cpu_s"],
                     "peak_rss_mb": ours["peak_rss_mb"],
                     "ratio_wall": ours["wall_s"] / yard["wall_s"],
                     "ratio_cpu": ours["cpu_s"] / yard["cpu_s"] if yard["cpu_s"] > 0 else math.nan})
    out = {"command": command, "cwd": cwd, "pairs": rows,
           "median_ratio_wall": statistics.median(r["ratio_wall"] for r in rows),
           "median_ratio_cpu": statistics.median(r["ratio_cpu"] for r in rows)}
    echo(f"  {campaign} against the yardstick ({' '.join(command)}), back to back:")
    for k, r in enumerate(rows, 1):
        echo(f"    pair {k} (load {r['load']:4.1f}): yardstick {r['yard_wall_s']:6.2f} s wall "
             f"{r['yard_cpu_s']:6.2f} s CPU; {campaign} {r['wall_s']:6.2f} s wall "
             f"{r['cpu_s']:6.2f} s CPU, peak {r['peak_rss_mb']:.0f} MiB; ratio "
             f"{r['ratio_wall']:.2f} wall, {r['ratio_cpu']:.2f} CPU")
    echo(f"    median ratio: {out['median_ratio_wall']:.2f} wall, "
         f"{out['median_ratio_cpu']:.2f} CPU (user + system)")
    missing, total = modules_without_bytecode()
    if missing:
        why = " (PYTHONDONTWRITEBYTECODE is set)" if sys.flags.dont_write_bytecode else ""
        echo(f"    note: {len(missing)} of the project's {total} modules have no bytecode "
             f"cache{why}, so each start of {campaign} compiles those it imports (about "
             "0.1 s of addsafe-mc, docs/execution.md); `python -m compileall -q "
             f"{' '.join(sorted({str(m.parent) for m in _package_inits()}))}` writes it once")
    return out


#: The project's packages, whose modules a command imports from their source files.
PROJECT_PACKAGES = ("campaign", "scenarios", "detectors", "reports")


def _package_inits(packages=PROJECT_PACKAGES) -> list[Path]:
    import importlib.util

    return [Path(importlib.util.find_spec(name).origin) for name in packages]


def modules_without_bytecode(roots=None) -> tuple[list[Path], int]:
    """``(missing, total)``: the Python files under the package directories *roots*
    (default: the project's, :data:`PROJECT_PACKAGES`) whose bytecode cache
    (``importlib.util.cache_from_source``) does not exist, and how many there are. Python
    compiles such a module each time a process imports it (an editable install has no
    cache until a process writes it, and none is written under PYTHONDONTWRITEBYTECODE)."""
    import importlib.util

    dirs = [Path(r) for r in roots] if roots is not None else [
        p.parent for p in _package_inits()]
    files = [f for d in dirs for f in sorted(d.rglob("*.py"))]
    missing = [f for f in files if not Path(importlib.util.cache_from_source(str(f))).is_file()]
    return missing, len(files)
