"""Run a campaign: plan, learn, simulate and score in parallel chunks, store as they finish.

docs/design.md §3, data flow steps 2–6. The run table is cut into chunks; a worker simulates a chunk
(vectorised over its runs), hands the signals to every detector and scores the detections;
only result rows come back. Results stream back as chunks finish and each chunk is written
at once as a Parquet shard (atomically), so a crash, a kill or Ctrl-C loses at most the
chunks in flight; rerunning into the same directory skips the runs already done.
A run that fails (bad row, detector exception) is recorded with ``status="error"`` and its
message; it never stops the campaign, and a rerun retries it. Where the chunks run (threads,
worker processes, a dask cluster) and how a dying worker or a run over its time limit ends
as per-run status is :mod:`campaign.execute`.
"""

from __future__ import annotations

import copy
import sys
import time
import traceback
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from detectors import as_variants, make_detector
from detectors.registry import load_detector_class
from reports.metrics import RESULT_COLUMNS, score_runs
from reports.summary import summarize
from reports.table import format_table
from scenarios import kernels
from scenarios.signals import Signals
from scenarios.plants import Plant
from scenarios.simulate import ActuatorPlant

from .design import build_learning_plan, build_plan
from .plant import detector_problems, plant_of
from .storage import CampaignDir, read_metadata, write_parquet, write_pickle, write_text


class CampaignSetupError(ValueError):
    """The campaign cannot start (incompatible detector, bad directory, …)."""


@dataclass(frozen=True)
class ChunkSettings:
    """What a worker needs besides the rows and the fitted detectors (picklable)."""

    ts: float
    pressure_sensor: bool
    required_time_s: dict
    window_s: float | None
    plant: Plant = ActuatorPlant()   # what the runs are simulated on (scenarios.plants)
    engine: str = "compiled"


def _error_rows(rows: pd.DataFrame, detector: str, message: str,
                status: str = "error") -> pd.DataFrame:
    n = len(rows)
    return pd.DataFrame({
        "run_id": rows["run_id"].to_numpy(), "detector": detector,
        "fault": rows["fault"].to_numpy(), "manoeuvre": rows["manoeuvre"].to_numpy(),
        "status": status, "error": message,
        "false_alarm": np.zeros(n, bool), "pre_onset_alarm": np.zeros(n, bool),
        "detected": np.zeros(n, bool), "first_alarm_s": np.nan, "delay_s": np.nan,
        "dtp": np.nan, "margin": np.nan,
    })


def _describe(exc: BaseException) -> str:
    last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    where = f" (at {Path(last[0].filename).name}:{last[0].lineno})" if last else ""
    return f"{type(exc).__name__}: {exc}{where}"


def run_chunk(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings) -> pd.DataFrame:
    """Simulate, detect and score one chunk of runs; returns its result rows.

    Never raises for a bad run or a failing detector: those rows get ``status="error"``.
    A chunk whose simulation fails, or a detector that raises on a chunk, is retried run by
    run, so one bad run does not take the others of its chunk down with it. The kernels
    are those of ``settings.engine``.
    """
    with kernels.use_engine(settings.engine):
        return _run_chunk(rows, detectors, settings)


def _run_chunk(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings) -> pd.DataFrame:
    try:
        signals, truth = _simulate(rows, settings)
    except Exception as exc:  # noqa: BLE001 - recorded per run, never fatal
        if len(rows) > 1:
            return pd.concat([_run_chunk(rows.iloc[[j]], detectors, settings)
                              for j in range(len(rows))], ignore_index=True)
        return pd.concat([_error_rows(rows, label, f"simulation failed: {_describe(exc)}")
                          for label in detectors], ignore_index=True)
    truth = _scoring_truth(truth)
    required = np.array([settings.required_time_s.get(f, np.nan) for f in truth.fault])
    frames = []
    for label, det in detectors.items():
        try:
            frames.extend(_detect_and_score(label, det, signals, truth, rows, required,
                                            settings))
        except Exception as exc:  # noqa: BLE001
            if len(rows) == 1:
                frames.append(_error_rows(rows, label, f"detector failed: {_describe(exc)}"))
                continue
            # run by run, so that only the runs the detector fails on are recorded as errors
            for j in range(len(rows)):
                try:
                    frames.extend(_detect_and_score(
                        label, det, signals.take([j]), truth.take([j]), rows.iloc[[j]],
                        required[[j]], settings))
                except Exception as exc_j:  # noqa: BLE001
                    frames.append(_error_rows(rows.iloc[[j]], label,
                                              f"detector failed: {_describe(exc_j)}"))
    return pd.concat(frames, ignore_index=True)[list(RESULT_COLUMNS)]


def _scoring_truth(truth):
    """*truth* without its (n, T) true series, which scoring does not read (fault type and
    onset only): their memory is freed before the detectors run. The series become
    all-NaN read-only views of the same shape."""
    shape = np.shape(truth.rod_mm)
    nan = np.broadcast_to(np.nan, shape)
    return replace(truth, rod_mm=nan, surface_deg=nan, current_mA=nan, aircraft=None,
                   surfaces_deg=None)


def _run_chunk_copy(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings):
    """:func:`run_chunk` on private copies of the detectors (chunks run in threads)."""
    return run_chunk(rows, copy.deepcopy(detectors), settings)


def _detect_and_score(label, det, signals, truth, rows, required, settings) -> list:
    frames = []
    variants = as_variants(label, det.detect(signals))
    for name, detection in variants.items():
        scored = score_runs(
            run_id=rows["run_id"].to_numpy(), fault=truth.fault, onset_s=truth.onset_s,
            alarm=detection.alarm, residual=detection.residual, ts=settings.ts,
            required_time_s=required, window_s=settings.window_s)
        scored.insert(1, "detector", name)
        scored.insert(2, "fault", truth.fault)
        scored.insert(3, "manoeuvre", rows["manoeuvre"].to_numpy())
        scored.insert(4, "status", "ok")
        scored.insert(5, "error", "")
        frames.append(scored)
    return frames


class Progress:
    """A progress line on stderr with rate and ETA, driven by finished chunks."""

    def __init__(self, total: int, done: int = 0, enabled: bool = True, stream=None):
        self.total, self.done, self.enabled = total, done, enabled
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self.start_done = done
        self.last_print = -1.0
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def update(self, n: int) -> None:
        self.done += n
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        new = self.done - self.start_done
        rate = new / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        frac = self.done / self.total if self.total else 1.0
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        line = (f"[{bar}] {self.done}/{self.total} runs {100 * frac:5.1f} %  "
                f"{rate:7.1f} runs/s  ETA {eta:5.1f} s")
        if self.tty:
            print("\r" + line, end="", file=self.stream, flush=True)
        elif elapsed - self.last_print >= 5.0 or self.done >= self.total:
            print(line, file=self.stream, flush=True)
            self.last_print = elapsed

    def close(self) -> None:
        if self.enabled and self.tty:
            print(file=self.stream, flush=True)


def _check_compatibility(config, detectors: dict, plant) -> None:
    problems = detector_problems(config, {label: det.capabilities
                                          for label, det in detectors.items()}, plant)
    if problems:
        raise CampaignSetupError("; ".join(problems))


def build_detectors(config) -> dict:
    """The configured detectors, unfitted: label → Detector."""
    return {d.label: make_detector(d.name, d.params_dict()) for d in config.detectors}


def _simulate(rows: pd.DataFrame, settings: ChunkSettings):
    """(Signals, Truth) of *rows* on the campaign's plant."""
    return settings.plant.simulate(rows, ts=settings.ts, pressure_sensor=settings.pressure_sensor)


def _simulate_signals(rows: pd.DataFrame, settings: ChunkSettings) -> Signals:
    with kernels.use_engine(settings.engine):
        return _simulate(rows, settings)[0]


def simulate_chunks(plan: pd.DataFrame, settings: ChunkSettings, chunk_size: int,
                    submit=None, workers: int = 1) -> Signals:
    """Signals of every run of *plan* (used for the small learning set). *submit*
    (an executor's ``submit``) runs the parts on *workers* threads, in parts of at most
    *chunk_size* runs spread evenly over them; a run's signals never depend on its part."""
    if submit is not None and workers > 1:
        size = max(1, min(chunk_size, -(-len(plan) // workers)))
        futures = [submit(_simulate_signals, plan.iloc[s:s + size], settings)
                   for s in range(0, len(plan), size)]
        return Signals.concat([f.result() for f in futures])
    parts = []
    for start in range(0, len(plan), chunk_size):
        sig, _ = _simulate(plan.iloc[start:start + chunk_size], settings)
        parts.append(sig)
    return Signals.concat(parts)


def fit_detectors(config, cdir: CampaignDir, settings: ChunkSettings, chunk_size: int,
                  log=print, submit=None, workers: int = 1) -> dict:
    """Fit each detector on the learning set, or reload it when this directory has it."""
    detectors = build_detectors(config)
    _check_compatibility(config, detectors, settings.plant)
    learning = build_learning_plan(config)
    write_parquet(learning, cdir.root / "learning.parquet", config.to_json(), kind="learning")
    learning_signals = None
    fitted = {}
    for label, det in detectors.items():
        path = cdir.fitted / f"{label}.pkl"
        if path.exists():
            import pickle

            fitted[label] = pickle.loads(path.read_bytes())
            continue
        if det.capabilities.needs_fit:
            if learning_signals is None:
                log(f"learning set: simulating {len(learning)} fault-free runs")
                learning_signals = simulate_chunks(learning, settings, chunk_size,
                                                   submit=submit, workers=workers)
            det.fit(learning_signals)
        write_pickle(path, det)
        write_text(cdir.fitted / f"{label}.json", _json_state(det))
        fitted[label] = det
    return fitted


def _json_state(det) -> str:
    import json

    def plain(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, (np.floating, np.integer)):
            return v.item()
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    return json.dumps({"detector": type(det).__name__, "params": plain(det.get_params()),
                       "fitted": plain(det.fitted_state())}, indent=2, default=str)


@dataclass
class CampaignResult:
    """What a finished (or interrupted) campaign left in its directory."""

    out: Path
    plan: pd.DataFrame
    results: pd.DataFrame
    summary: pd.DataFrame
    complete: bool
    wall_s: float

    def table(self) -> str:
        return format_table(self.summary)


def settings_of(config) -> ChunkSettings:
    return ChunkSettings(
        ts=config.campaign.ts_s,
        pressure_sensor=config.campaign.pressure_sensor,
        required_time_s=dict(config.requirements.detection_time_s),
        window_s=config.requirements.detection_window_s,
        plant=plant_of(config),
        engine=config.runner.engine,
    )


def check_plant(config, plant) -> None:
    """Check the plant before anything runs (an FMU and its variable map: a clear FmuError)."""
    plant.check(faults={g.fault for g in config.groups})


def failure_rows(rows: pd.DataFrame, labels, status: str, message: str) -> pd.DataFrame:
    """Result rows of runs that could not be run (*status* ``error`` or ``timeout``)."""
    return pd.concat([_error_rows(rows, label, message, status) for label in labels],
                     ignore_index=True)[list(RESULT_COLUMNS)]


def run(config, out, *, jobs: int = 2, chunk_size: int | None = None, progress: bool = True,
        backend: str | None = None, log=None, scheduler: str | None = None,
        engine: str | None = None) -> CampaignResult:
    """Run *config* into directory *out* (resuming what it already holds).

    Parameters
    ----------
    config : campaign.config.CampaignConfig
    out : output directory (created; must be empty or hold this same campaign)
    jobs : local workers (1 runs in-process)
    chunk_size : runs per chunk (default: the campaign file's ``[runner] chunk_size``)
    backend : local workers: ``"threading"`` (threads in this process; the compiled kernels
        release the GIL) or ``"loky"`` (worker processes: a dying worker or a run over
        ``[runner] run_timeout_s`` is survived). Default: threading, or loky when the
        campaign sets ``run_timeout_s`` (a thread cannot be stopped) or runs an FMU plant
        (one FMU instance per worker process).
    scheduler : address ``tcp://HOST:PORT`` of a dask.distributed scheduler; the chunks then
        run on its workers (*jobs* and *backend* are not used)
    engine : ``"compiled"`` or ``"numpy"`` kernels (default: ``[runner] engine``)

    Faults of the machinery (a worker that dies, a run over ``[runner] run_timeout_s``) end
    as per-run status rows; see :mod:`campaign.execute`.
    """
    from .execute import LocalPool, connect, run_local, run_on_cluster

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    t_start = time.perf_counter()
    settings = settings_of(config)
    check_plant(config, settings.plant)
    if engine is not None:
        settings = replace(settings, engine=kernels.check_engine(engine))
    processes = settings.plant.needs_processes
    if backend is None:   # processes where threads cannot serve: time limits, FMU instances
        backend = ("threading" if config.runner.run_timeout_s is None and not processes
                   else "loky")
    elif backend == "threading" and processes and jobs > 1:
        raise CampaignSetupError(
            "an FMU plant is loaded once per worker process and is not safe to share between "
            "threads: use --backend loky (the default with an FMU plant) or --jobs 1")
    client = connect(scheduler) if scheduler else None   # fail fast, before any work
    cdir = CampaignDir(out)
    resumed = cdir.open(config.to_json())
    chunk_size = int(chunk_size or config.runner.chunk_size)
    if settings.engine == "compiled":
        for spec in config.detectors:   # import their modules: they register their kernels
            load_detector_class(spec.name)
        kernels.warm_up(log)
    pool = None
    if client is None and jobs > 1:
        pool = LocalPool(backend, jobs)
        pool.start()              # workers start while the learning set is simulated here

    try:
        plan = build_plan(config)
        plan_path = cdir.root / "plan.parquet"
        if not plan_path.exists():
            write_parquet(plan, plan_path, config.to_json(), kind="plan")
        with kernels.use_engine(settings.engine):
            # the learning set on the worker threads (the built-in plant's kernels release
            # the GIL; an FMU plant is simulated here, one instance at a time)
            threads = (pool is not None and backend == "threading"
                       and settings.plant.kind == "actuator")
            detectors = fit_detectors(config, cdir, settings, chunk_size, log=log,
                                      submit=pool.submit if threads else None, workers=jobs)

        done = cdir.done_run_ids() if resumed else set()
        todo = plan[~plan["run_id"].isin(done)]
        if resumed:
            log(f"resuming {cdir.root}: {len(plan) - len(todo)} of {len(plan)} runs already "
                "done")
        chunks = [todo.iloc[s:s + chunk_size] for s in range(0, len(todo), chunk_size)]
        bar = Progress(len(plan), len(plan) - len(todo), enabled=progress)
        labels = list(detectors)
        complete = False

        def store(frame: pd.DataFrame) -> None:
            write_parquet(frame, cdir.next_shard_path(), config.to_json(), kind="results")
            bar.update(frame["run_id"].nunique())

        def fail(rows, status, message):
            return failure_rows(rows, labels, status, message)

        try:
            if chunks and client is not None:
                run_on_cluster(client, chunks, run_chunk, detectors, settings, fail, store,
                               log=log)
            elif chunks and pool is None:
                if config.runner.run_timeout_s is not None:
                    log("note: run_timeout_s is enforced on worker processes only (--jobs ≥ 2 "
                        "with the loky backend, or a dask cluster); running in-process "
                        "without a limit")
                for c in chunks:
                    store(run_chunk(c, detectors, settings))
            elif chunks:
                if backend == "threading":   # threads share memory: one detector copy each
                    call = partial(_run_chunk_copy, detectors=detectors, settings=settings)
                else:
                    call = partial(run_chunk, detectors=detectors, settings=settings)
                run_local(chunks, call,
                          fail, store, jobs=jobs, backend=backend,
                          run_timeout_s=config.runner.run_timeout_s, pool=pool, log=log)
            complete = True
        except KeyboardInterrupt:
            bar.close()
            log(f"\ninterrupted: the finished chunks are stored in {cdir.root}; run the same "
                "command again to resume")
        finally:
            bar.close()
    finally:
        if pool is not None:
            pool.stop(kill=True)
        if client is not None:
            client.close()
    return finalize(cdir, config, plan, complete, time.perf_counter() - t_start)


def finalize(cdir: CampaignDir, config, plan: pd.DataFrame, complete: bool,
             wall_s: float) -> CampaignResult:
    """Gather the shards in plan order and write ``summary.parquet``."""
    results = cdir.read_results()
    if not results.empty:
        order = pd.Series(np.arange(len(plan)), index=plan["run_id"].to_numpy())
        results = (results.assign(_o=results["run_id"].map(order))
                   .sort_values(["_o", "detector"], kind="stable")
                   .drop(columns="_o").reset_index(drop=True))
        summary = summarize(results)
    else:
        summary = pd.DataFrame()
    write_parquet(summary, cdir.root / "summary.parquet", config.to_json(), kind="summary",
                  complete=complete, runs_done=int(results["run_id"].nunique())
                  if not results.empty else 0, runs_planned=len(plan))
    return CampaignResult(out=cdir.root, plan=plan, results=results, summary=summary,
                          complete=complete, wall_s=wall_s)


def load_results(out) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """(results, summary, metadata) of a campaign directory, for ``report`` and ``gate``."""
    cdir = CampaignDir(out)
    summary_path = cdir.root / "summary.parquet"
    if not summary_path.exists():
        raise CampaignSetupError(f"{cdir.root} holds no summary.parquet: is it a campaign "
                                 "directory written by 'fdd-campaign run'?")
    import pyarrow.parquet as pq

    return cdir.read_results(), pq.read_table(summary_path).to_pandas(), read_metadata(summary_path)
