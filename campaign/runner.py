"""Run a campaign: plan, learn, simulate and score in parallel chunks, store as they finish.

docs/design.md §3, data flow steps 2–6. The run table is cut into chunks; a worker simulates
a chunk (vectorised over its runs), hands the signals to every detector and scores the
detections (:func:`campaign.evaluate.evaluate`); only result rows come back. Results stream
back as chunks finish and each chunk is written at once as a Parquet shard (atomically), so
a crash, a kill or Ctrl-C loses at most the chunks in flight; rerunning into the same
directory skips the runs already done. A run that fails (bad row, detector exception) is
recorded with ``status="error"`` and its message; it never stops the campaign, and a rerun
retries it. Where the chunks run (threads, worker processes, a dask cluster) and how a dying
worker or a run over its time limit ends as per-run status is :mod:`campaign.execute`; every
file of the directory is read and written by :class:`campaign.store.directory.CampaignDir`.
"""

from __future__ import annotations

import copy
import sys
import time
from collections import deque
from concurrent.futures import Future
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from detectors import make_detector, writes_input
from detectors.base import set_threshold_scales
from detectors.compat import incompatibilities, offline_problems
from detectors.system import with_systems
from reports.scoring.detection_times import detection_time_table, fixed_onset_campaign
from reports.scoring.summary import SummaryAccumulator
from scenarios import compiled as kernels
from scenarios.errors import ArgumentError, InputError
from scenarios.memory import release_freed_memory
from scenarios.signals import Signals

from .plan import MODEL_VERSION, PlanBlocks, build_learning_plan
from .plugins import (
    batch_check_runs,
    batch_dependence,
    fit_detector,
    third_party,
)
from .evaluate import ChunkSettings, evaluate, failure_rows, simulate_signals
from .isolation import roles_of
from .execute import one_blas_thread
from .plant_setup import (
    ResolvedCampaign,
    fmu_sha256,
    resolve,
)
from .progress import Progress
from .result import Campaign
from .startup import start_up_done
from .store.directory import CampaignDir, DirLock


class CampaignSetupError(InputError, ValueError):
    """The campaign cannot start (incompatible detector, bad directory, …)."""


class RunOptionError(CampaignSetupError, ArgumentError):
    """An argument of :func:`run` it cannot take (*jobs* or *chunk_size* out of range,
    *fitted_from*, a *backend* or *scheduler* that cannot serve the campaign), named as Python
    names it; ``fdd-campaign`` names its option (:class:`scenarios.errors.ArgumentError`)."""


class BatchDependenceError(CampaignSetupError, ArgumentError):
    """A third-party detector whose result for a run depends on the other runs of its chunk
    (:func:`check_batch_invariance`); its message names :func:`run`'s argument *chunk_size*
    beside ``[runner] chunk_size``, ``fdd-campaign`` its option."""


def _evaluate_copy(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings):
    """:func:`campaign.evaluate.evaluate` on private copies of the detectors (chunks run in
    threads)."""
    return evaluate(rows, copy.deepcopy(detectors), settings)


def _check_compatibility(campaign: ResolvedCampaign, detectors: dict) -> None:
    """The one compatibility rule (:func:`detectors.compat.incompatibilities`) on the built
    detectors, whose capabilities may be an instance's own, against the resolved campaign's
    plant and run surface; a non-causal detector is refused too
    (:func:`detectors.compat.offline_problems`)."""
    capabilities = {label: det.capabilities for label, det in detectors.items()}
    problems = (incompatibilities(capabilities, campaign.plant, campaign.surface,
                                  pressure_sensor=campaign.config.campaign.pressure_sensor)
                + offline_problems(capabilities))
    if problems:
        raise CampaignSetupError("; ".join(problems))


def build_detectors(config) -> dict:
    """The configured detectors, unfitted: label → Detector."""
    return {d.label: make_detector(d.name, d.params_dict()) for d in config.detectors}


#: Largest part of the learning set simulated at once [runs] (a plant's
#: ``learning_part_runs`` or ``batch_runs``, when it has one, is used instead): the parts are
#: copied into the learning signals as they arrive, so the peak memory is the learning set
#: plus a few parts.
LEARNING_PART_RUNS = 50


def simulate_chunks(plan: pd.DataFrame, settings: ChunkSettings, chunk_size: int,
                    submit=None, workers: int = 1) -> Signals:
    """Signals of every run of *plan* (used for the small learning set). *submit*
    (an executor's ``submit``) runs the parts on its *workers*. Parts hold at most
    *chunk_size* runs and the plant's ``learning_part_runs`` or ``batch_runs`` (else
    :data:`LEARNING_PART_RUNS`); a run's signals never depend on its part, and each part is
    released once copied into the result (:meth:`Signals.concat`), its memory returned to
    the system (:func:`scenarios.memory.release_freed_memory`)."""
    plant = settings.plant
    part = (getattr(plant, "learning_part_runs", None) or getattr(plant, "batch_runs", None)
            or LEARNING_PART_RUNS)
    size = max(1, min(chunk_size, part))
    if submit is not None and workers > 1:
        size = max(1, min(size, -(-len(plan) // workers)))
        pending = deque(submit(simulate_signals, plan.iloc[s:s + size], settings)
                        for s in range(0, len(plan), size))
        results = (pending.popleft().result() for _ in range(len(pending)))
    else:
        results = (simulate_signals(plan.iloc[s:s + size], settings)
                   for s in range(0, len(plan), size))

    def parts():
        for part in results:
            yield part
            release_freed_memory()              # what the parts copied so far held
    signals = Signals.concat(parts(), n_runs=len(plan))
    release_freed_memory()
    return signals


def plant_name(plant) -> str:
    """The plant as a user names it: ``the aircraft plant``, ``the FMU plant servo.fmu``."""
    path = getattr(plant, "path", None)
    return f"the FMU plant {path}" if path else f"the {plant.kind} plant"


def _learning_signals(learning: pd.DataFrame, settings: ChunkSettings, chunk_size: int,
                      submit, workers: int) -> Signals:
    """The signals of the learning runs; a plant that fails is named (exit 2)."""
    try:
        signals = simulate_chunks(learning, settings, chunk_size, submit=submit,
                                  workers=workers)
    except Exception as exc:  # noqa: BLE001 - any failure of the plant, named for the user
        raise CampaignSetupError(
            f"{plant_name(settings.plant)} failed while simulating the learning set "
            f"({len(learning)} fault-free runs): {type(exc).__name__}: {exc}; nothing was "
            "run. Fix: simulate one run of that plant on its own (fdd-campaign simulate) to "
            "see its error") from exc
    # the learning runs' manoeuvres, for per-class threshold calibration (docs/thresholds.md)
    return replace(signals, classes=learning["manoeuvre"].to_numpy(dtype=str))


def fit_detectors(campaign, cdir: CampaignDir, settings: ChunkSettings, chunk_size: int,
                  log=print, submit=None, workers: int = 1,
                  run_timeout_s: float | None = None, fit_submit=None) -> dict:
    """Fit each detector of *campaign* (its :class:`campaign.plant_setup.ResolvedCampaign`)
    on the learning set, or reload it when this directory has it.

    Every detector fits on the same learning signals, read-only
    (:func:`detectors.base.read_only`): one that writes into them raises in its own ``fit``;
    a third-party one is fitted under *run_timeout_s* (:func:`campaign.plugins.fit_detector`).
    With *fit_submit* (a thread pool's ``submit``), the detectors whose capabilities say
    ``fit_concurrently`` are fitted on its threads while the others are fitted here, one at
    a time, in label order; a fit's result never depends on which thread ran it.
    A detector whose ``fit`` raises (anything) is a :class:`CampaignSetupError` naming its
    label — the first such label in the campaign's order, whatever finished first; so is a
    plant that fails on the learning runs. A fitted detector is stored as data
    (:meth:`CampaignDir.write_fitted`); one whose parameters or learned attributes are not
    plain data (:mod:`detectors.state`) stops the campaign here, before any run, with a
    :class:`CampaignSetupError` naming the detector and the attribute. Every third-party
    detector is then checked for batch invariance (:func:`check_batch_invariance`, under
    *run_timeout_s* when set)."""
    config = campaign.config
    detectors = build_detectors(config)
    _check_compatibility(campaign, detectors)
    names = {d.label: d.name for d in config.detectors}
    learning = build_learning_plan(campaign)
    cdir.write_learning(learning, config.to_json())
    learning_signals = None
    outcomes: dict = {}     # label → Future of its fit, or a fitted (or reloaded) detector
    for label, det in detectors.items():
        if cdir.has_fitted(label):
            outcomes[label] = cdir.read_fitted(label, names[label])
            continue
        if not det.capabilities.needs_fit:
            outcomes[label] = det
            continue
        if learning_signals is None:
            log(f"learning set: simulating {len(learning)} fault-free runs")
            learning_signals = _learning_signals(learning, settings, chunk_size, submit,
                                                 workers)
        if fit_submit is not None and det.capabilities.fit_concurrently:
            outcomes[label] = fit_submit(fit_detector, det, learning_signals, settings.engine,
                                         run_timeout_s)
            continue
        outcomes[label] = _fit_here(fit_detector, det, learning_signals, settings.engine,
                                    run_timeout_s)
        if outcomes[label].exception() is not None:
            break                   # no later label's failure could be the one reported
    fitted = {}
    for label, det in detectors.items():
        outcome = outcomes.get(label)
        if isinstance(outcome, Future):
            exc = outcome.exception()
            if exc is not None:
                for later in outcomes.values():     # let the other fits end before leaving
                    if isinstance(later, Future):
                        later.exception()
                raise _fit_failure(label, det, exc, learning_signals, settings) from exc
            outcome = outcome.result()
        if outcome is None:         # not fitted: an earlier label's fit failed
            continue
        _store_fitted(cdir, label, names[label], outcome)
        fitted[label] = outcome
    plugins = {label: det for label, det in fitted.items() if third_party(det)}
    if plugins:
        check_batch_invariance(plugins, learning, settings, learning_signals,
                               run_timeout_s=run_timeout_s, log=log)
    return fitted


def _fit_here(fit, *args) -> Future:
    """*fit(*args)* run on this thread, its result (or exception) held in a done Future."""
    done: Future = Future()
    try:
        done.set_result(fit(*args))
    except Exception as exc:  # noqa: BLE001 - reported in label order by fit_detectors
        done.set_exception(exc)
    return done


def _fit_failure(label: str, det, exc: BaseException, learning_signals: Signals,
                 settings: ChunkSettings) -> CampaignSetupError:
    """The error that names the detector *label* whose ``fit`` raised *exc*."""
    hint = ("; the learning signals are read-only: work on a copy (np.array("
            "signals.rod_com)), docs/write-a-detector.md" if writes_input(exc) else "")
    return CampaignSetupError(
        f"detector {label!r} ({type(det).__name__}) failed while fitting on the "
        f"learning set ({learning_signals.n_runs} fault-free runs of "
        f"{plant_name(settings.plant)}): {type(exc).__name__}: {exc}{hint}")


def _store_fitted(cdir: CampaignDir, label: str, name: str, det) -> None:
    """Write the fitted *det* into the directory, or stop the campaign (exit 2) naming the
    attribute that cannot be stored as data."""
    from detectors.state import PLAIN_TYPES_DOC, StateTypeError

    try:
        cdir.write_fitted(label, name, det)
    except StateTypeError as exc:
        raise CampaignSetupError(
            f"detector {label!r} ({name}): its {exc.path} cannot be stored in "
            f"the campaign directory: {exc.detail}. A fitted detector is stored as data, "
            f"never as a pickle; parameters and learned attributes (names ending in '_') "
            f"may hold {PLAIN_TYPES_DOC} (docs/write-a-detector.md, 'Learned state')"
        ) from None


def adopt_fitted(config, cdir: CampaignDir, source, log=print) -> dict:
    """The detectors fitted in the campaign directory *source*, to evaluate this campaign's
    runs without learning again (``fdd-campaign run --fitted-from DIR``).

    *source* is read through its :class:`CampaignDir` only after its files match its
    manifest; its ``[[detector]]`` entries (labels, registry names and parameters) must be
    this campaign's, else :class:`RunOptionError` (exit 2) names the differences (and
    *source* as the argument ``fitted_from`` of :func:`run` that gives it). Its
    fitted files and learning-set table are copied into *cdir* byte for byte, with
    ``fitted-origin.json`` saying where they came from, so *cdir* stands on its own; the
    detectors are rebuilt from the copies as data (:meth:`CampaignDir.read_fitted`). A
    resumed directory must hold the same fitted files (same
    :meth:`CampaignDir.fitted_sha256`).
    """
    from reports.scoring.compare import differing_keys

    from .config import CampaignConfig

    src = CampaignDir(source)

    def refused(problem: str, **values) -> RunOptionError:
        return RunOptionError.of("fitted_from", str(source), problem, **values)

    if not src.root.is_dir() or not src.is_campaign():
        raise refused("not a campaign directory (no campaign.json); give the {out} directory "
                      "of an earlier run")
    if src.root.resolve() == cdir.root.resolve():
        raise refused("that is the {out} directory itself; give the directory of another "
                      "campaign")
    src.refuse_pickles()
    src.check_manifest()
    theirs = CampaignConfig.from_dict(src.read_config(), source=str(src.config_path))
    # a threshold scale is applied when the detectors run, not learned: any is reused
    ours_d = {"detector": _without_scales(config.to_dict().get("detector"))}
    theirs_d = {"detector": _without_scales(theirs.to_dict().get("detector"))}
    differ = differing_keys(theirs_d, ours_d)
    if differ:
        raise refused(
            "its detectors are not this campaign's [[detector]] entries (labels, names and "
            "parameters must be the same; A = {a}, B = this campaign): {differ}; fix: give "
            "the same [[detector]] tables, or run without {fitted_from} to fit the detectors "
            "on this campaign's learning set", a=src.root, differ="; ".join(differ))
    labels = [d.label for d in config.detectors]
    missing = [label for label in labels if not src.has_fitted(label)]
    if missing:
        raise refused("holds no fitted detector {label} (fitted/ incomplete); rerun the "
                      "campaign that wrote it", label=repr(missing[0]))
    want = src.fitted_sha256(labels)
    held = cdir.fitted_sha256(labels)
    if held is None:
        cdir.adopt_fitted(src, labels)
        log(f"fitted detectors: taken from {src.root} (SHA-256 {want[:12]}…), not re-learned")
    elif held != want:
        raise refused("{root} already holds other fitted detectors (SHA-256 {held}… ≠ "
                      "{want}…); choose a new {out} directory", root=cdir.root,
                      held=held[:12], want=want[:12])
    names = {d.label: d.name for d in config.detectors}
    return {label: cdir.read_fitted(label, names[label]) for label in labels}


def _without_scales(entries) -> list:
    """``[[detector]]`` entries (JSON form) without their ``threshold_scale``."""
    return [{k: v for k, v in entry.items() if k != "threshold_scale"}
            for entry in entries or ()]


def check_batch_invariance(detectors: dict, learning: pd.DataFrame, settings: ChunkSettings,
                           learning_signals: Signals | None = None, *,
                           run_timeout_s: float | None = None, log=print) -> None:
    """Refuse (:class:`BatchDependenceError`, exit 2) a fitted detector whose result for a
    run depends on the other runs of its batch, so on the chunk size and on which runs share
    a chunk, which ``[runner]`` must never change (:func:`campaign.plugins.batch_dependence`
    on a few learning runs; under *run_timeout_s* when set). The runner applies it to
    third-party detectors only (:func:`third_party`): the test suite runs the full check on
    the built-in ones."""
    picks = batch_check_runs(len(learning))
    if learning_signals is not None:
        signals = learning_signals.take(list(picks))
    else:
        signals = _learning_signals(learning.iloc[picks], settings, len(picks), None, 1)
    found = batch_dependence(detectors, signals, settings.engine,
                             run_timeout_s=run_timeout_s, log=log)
    if found is not None:
        label, det, failure = found
        raise BatchDependenceError.said(
            "detector {label} ({kind}) is not batch-invariant: {failure}. Its results would "
            "depend on the chunk size ([runner] chunk_size, {chunk_size}) and on which runs "
            "share a chunk, which [runner] must never change; fix: compute every run on its "
            "own (docs/write-a-detector.md, Signals and output) and check it with "
            "detectors.testing.check_detector", label=repr(label), kind=type(det).__name__,
            failure=failure)


def settings_of(campaign) -> ChunkSettings:
    """What the workers need of *campaign* (its
    :class:`campaign.plant_setup.ResolvedCampaign`): its built plant among them."""
    config = campaign.config
    return ChunkSettings(
        ts=config.campaign.ts_s,
        pressure_sensor=config.campaign.pressure_sensor,
        required_time_s=dict(config.requirements.detection_time_s),
        window_s=config.requirements.detection_window_s,
        plant=campaign.plant,
        engine=config.runner.engine,
    )


def check_plant(config, plant) -> None:
    """Check the plant before anything runs (an FMU and its variable map: a clear FmuError)."""
    plant.check(faults={g.fault for g in config.groups} | {r.fault for r in config.runs})


@one_blas_thread()
def run(config, out, *, jobs: int = 2, chunk_size: int | None = None, seed: int | None = None,
        progress: bool = True, backend: str | None = None, log=None,
        scheduler: str | None = None, engine: str | None = None, tls=None,
        fitted_from=None) -> Campaign:
    """Run *config* into directory *out* (resuming what it already holds).

    Parameters
    ----------
    config : campaign.config.CampaignConfig
    out : output directory (created; must be empty or hold this same campaign)
    jobs : local workers (1 runs in-process)
    chunk_size : runs per chunk (default: the campaign file's ``[runner] chunk_size``)
    seed : the campaign seed (default: the campaign file's ``[campaign] seed``); like
        *chunk_size*, resolved with the campaign once (:func:`campaign.plant_setup.resolve`)
    progress : print a progress line with rate and ETA on stderr
    backend : local workers: ``"threading"`` (threads in this process; the compiled kernels
        release the GIL) or ``"loky"`` (worker processes: a dying worker or a run over
        ``[runner] run_timeout_s`` is survived). Default: threading, or loky when the
        campaign sets ``run_timeout_s`` (a thread cannot be stopped) or runs an FMU plant
        (one FMU instance per worker process). With ``run_timeout_s`` every run is bounded:
        the chunks run on loky processes (one with ``jobs=1``), and threads or a dask
        cluster are refused before any work (:func:`campaign.execute.time_limit_refusal`).
    scheduler : address ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` of a dask.distributed
        scheduler; the chunks then run on its workers (*jobs* and *backend* are not used)
    tls : :class:`campaign.execute.TlsFiles` (CA, certificate and key files) for a
        ``tls://`` scheduler; default: dask's configuration ``distributed.comm.tls.*``
    engine : ``"compiled"`` or ``"numpy"`` kernels (default: ``[runner] engine``)
    fitted_from : a campaign directory whose fitted detectors are evaluated on this
        campaign's runs instead of learning them again (:func:`adopt_fitted`); a directory
        started so keeps using them when resumed
    log : where notes go, one line each (default: stderr)

    Returns the :class:`campaign.result.Campaign` of *out*, equal to what
    ``campaign.load(out)`` reads back (with ``wall_s``, the seconds this call took);
    ``complete`` is False when it was interrupted (Ctrl-C): running it again resumes.

    Faults of the machinery (a worker that dies, a run over ``[runner] run_timeout_s``) end
    as per-run status rows; see :mod:`campaign.execute`. The directory left is the same
    whether the campaign runs from Python or from ``fdd-campaign run``. The run holds the
    directory's lock (:class:`campaign.store.directory.DirLock`) from opening it to the summary: a
    second run into the same directory meanwhile is refused
    (:class:`campaign.store.directory.CampaignLockedError`). BLAS runs one thread per process
    meanwhile (:func:`campaign.execute.one_blas_thread`).
    """
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    t_start = time.perf_counter()
    root = Path(out)
    existed, fresh = start_state(root)
    setup = None
    try:
        setup = _setup(config, out, jobs=jobs, chunk_size=chunk_size, seed=seed,
                       backend=backend, scheduler=scheduler, engine=engine, log=log, tls=tls)
        config = setup.campaign.config
        setup.cdir.check_model_version(MODEL_VERSION)
        # written as it is made, one block at a time; the chunks are read back from
        # plan.parquet: the plan is never held whole
        if not setup.cdir.has_plan():
            n_planned = setup.cdir.write_plan(PlanBlocks(setup.campaign), config.to_json(),
                                              MODEL_VERSION)
        else:
            n_planned = setup.cdir.planned_runs()
        release_freed_memory()     # what making the plan's blocks took
        detectors = with_systems(_learn(config, setup, log, fitted_from), config.systems)
    except BaseException:
        if setup is not None:       # this call holds the directory's lock
            if fresh:               # nothing that looks like a campaign is left behind
                remove_created(root, existed)
            setup.close()
        raise
    try:
        complete = _execute(config, setup, n_planned, detectors, progress=progress, log=log)
        release_freed_memory()     # what the chunks' signals took, before the summary
        return finalize(setup.cdir, config, None, complete, time.perf_counter() - t_start,
                        fmu_sha256=setup.fmu_sha256, roles=roles_of(setup.campaign))
    finally:
        setup.close()


def prepare(config, out, *, jobs: int = 2, chunk_size: int | None = None,
            backend: str | None = None, scheduler: str | None = None, tls=None,
            fitted_from=None, log=None):
    """Open directory *out* for *config* and fit its detectors as :func:`run` does (the
    same checks, workers and learning code path), without running the campaign's plan.

    Returns ``(setup, detectors)``: the started setup (its ``close()`` releases the
    directory's lock and stops the workers) and the fitted detectors, label → Detector.
    Used by ``fdd-campaign falsify`` (:mod:`campaign.evidence.falsify`), which then evaluates runs
    of its own with :func:`evaluate_rows`."""
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    setup = _setup(config, out, jobs=jobs, chunk_size=chunk_size, backend=backend,
                   scheduler=scheduler, engine=None, log=log, tls=tls)
    try:
        return setup, with_systems(_learn(config, setup, log, fitted_from), config.systems)
    except BaseException:
        setup.close()
        raise


def evaluate_rows(setup, rows: pd.DataFrame, detectors: dict, log=None) -> pd.DataFrame:
    """Result rows of the run-table *rows* on the workers of *setup* (:func:`prepare`): cut
    into one chunk per worker, evaluated as the runner's chunks are (a failing run gets
    ``status="error"``), returned in the order of *rows*. Nothing is stored."""
    from .execute import run_local, run_on_cluster

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    settings, pool, frames = setup.settings, setup.pool, []
    size = max(1, -(-len(rows) // max(setup.jobs, 1)))
    chunks = [rows.iloc[s:s + size] for s in range(0, len(rows), size)]
    labels = list(detectors)

    def fail(part, status, message):
        return failure_rows(part, labels, status, message)

    if setup.client is not None:
        run_on_cluster(setup.client, chunks, evaluate, detectors, settings, fail,
                       frames.append, log=log)
    elif pool is None:
        frames.extend(evaluate(c, detectors, settings) for c in chunks)
    else:
        call = partial(_evaluate_copy if setup.backend == "threading" else evaluate,
                       detectors=detectors, settings=settings)
        run_local(chunks, call, fail, frames.append, jobs=setup.jobs, backend=setup.backend,
                  run_timeout_s=setup.run_timeout_s, pool=pool, log=log)
    results = pd.concat(frames, ignore_index=True)
    order = {rid: i for i, rid in enumerate(dict.fromkeys(rows["run_id"]))}
    return (results.assign(_o=results["run_id"].map(order))
            .sort_values(["_o", "detector"], kind="stable").drop(columns="_o")
            .reset_index(drop=True))


def start_state(root: Path) -> tuple[bool, bool]:
    """``(existed, fresh)`` of a campaign directory about to be started: whether *root*
    exists, and whether it is absent or an empty directory — what a start that fails may
    then remove (:func:`remove_created`)."""
    existed = root.exists()
    return existed, not existed or (root.is_dir() and not any(root.iterdir()))


def remove_created(root: Path, existed: bool) -> None:
    """Remove what a campaign start that failed before its first run created in *root*:
    the directory itself when this call created it, else its content (it was empty:
    :meth:`CampaignDir.open` refuses a non-empty directory without ``campaign.json``)."""
    import shutil

    if not root.is_dir():
        return
    if not existed:
        shutil.rmtree(root, ignore_errors=True)
        return
    for child in root.iterdir():
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child, ignore_errors=True)
        else:
            child.unlink(missing_ok=True)


@dataclass
class _Setup:
    """Where and how a campaign runs, decided before any work (:func:`_setup`)."""

    cdir: CampaignDir
    resumed: bool
    campaign: ResolvedCampaign   # the campaign resolved once (its chunk size among it)
    settings: ChunkSettings
    jobs: int
    backend: str
    client: object = None   # a distributed.Client, or None
    pool: object = None     # a started campaign.execute.LocalPool, or None
    lock: object = None     # the directory's held campaign.store.directory.DirLock
    run_timeout_s: float | None = None   # [runner] run_timeout_s, enforced on the pool
    fmu_sha256: str | None = None        # SHA-256 of an FMU plant's file (plant.fmu_sha256)

    @property
    def chunk_size(self) -> int:
        """Runs per chunk [runs] (:attr:`ResolvedCampaign.chunk_size`)."""
        return self.campaign.chunk_size

    def close(self) -> None:
        try:
            if self.pool is not None:
                self.pool.stop(kill=True)
            if self.client is not None:
                self.client.close()
        finally:
            if self.lock is not None:
                self.lock.release()


def check_run_options(config, *, jobs: int, chunk_size: int | None) -> int:
    """The chunk size a run uses (*chunk_size*, or ``[runner] chunk_size``), after checking
    it against the range of the schema's ``[runner] chunk_size`` (and *jobs* ≥ 1);
    :class:`RunOptionError` (exit 2) names the argument, its range and the fix."""
    from dataclasses import fields

    from .config.sections import RunnerSection

    spec = next(f.metadata["key"] for f in fields(RunnerSection) if f.name == "chunk_size")
    size = config.runner.chunk_size if chunk_size is None else chunk_size
    if (isinstance(size, bool) or not isinstance(size, (int, np.integer))
            or spec.out_of_range(size)):
        raise RunOptionError.of(
            "chunk_size", size, f"out of range; allowed: an integer, "
            f"{spec.range_text('chunk size')} runs ([runner] chunk_size, "
            "docs/campaign-file.md)", int(spec.lower) * 100,
            "or leave it out to use the campaign file's value")
    if isinstance(jobs, bool) or not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise RunOptionError.of("jobs", jobs, "must be an integer ≥ 1 (local workers)", 2)
    return int(size)


def _setup(config, out, *, jobs, chunk_size, backend, scheduler, engine, log,
           tls=None, seed=None) -> _Setup:
    """Check the options, resolve the campaign once (:func:`campaign.plant_setup.resolve`:
    its plant built here, its seed and chunk size with it), check the plant, open the
    directory, warm the kernels and start the local workers (they start while the learning
    set is simulated here)."""
    from .execute import LocalPool, connect, time_limit_refusal

    size = check_run_options(config, jobs=jobs, chunk_size=chunk_size)
    campaign = resolve(config, seed=seed, chunk_size=size)
    config = campaign.config
    limit = config.runner.run_timeout_s
    refusal = time_limit_refusal(limit, backend=backend, scheduler=scheduler)
    if refusal:       # a limit is enforced or refused, never ignored
        text, values = refusal
        raise RunOptionError.said(text, **values)
    settings = settings_of(campaign)
    check_plant(config, settings.plant)
    if engine is not None:
        settings = replace(settings, engine=kernels.check_engine(engine))
    processes = settings.plant.needs_processes
    if backend is None:   # processes where threads cannot serve: time limits, FMU instances
        backend = ("threading" if config.runner.run_timeout_s is None and not processes
                   else "loky")
    elif backend == "threading" and processes and jobs > 1:
        raise RunOptionError.said(
            "an FMU plant is loaded once per worker process and is not safe to share between "
            "threads: use {backend} loky (the default with an FMU plant) or {jobs} 1")
    client = connect(scheduler, tls=tls, log=log) if scheduler else None   # fail fast
    cdir = CampaignDir(out)
    setup = _Setup(cdir=cdir, resumed=False, campaign=campaign, settings=settings, jobs=jobs,
                   backend=backend, client=client, run_timeout_s=limit,
                   fmu_sha256=fmu_sha256(settings.plant))
    try:
        # one run at a time writes into a directory: a second one is refused (exit 2)
        setup.lock = DirLock(cdir.lock_path).acquire(log)
        setup.resumed = cdir.open(config.to_json(), log=log)
        if settings.engine == "compiled":
            # the detectors' modules, imported when the campaign was resolved (its
            # detector_classes), have registered their kernels
            kernels.warm_up(log)
        # the modules and kernels made so far live to the exit: out of the collector's
        # reach, and the collector on again if the command line deferred it (campaign.startup)
        start_up_done()
        if client is None and (jobs > 1 or limit is not None):
            # a time limit needs a worker process to stop, even for --jobs 1
            setup.pool = LocalPool(backend, jobs)
            setup.pool.start()
    except BaseException:
        setup.close()
        raise
    return setup


def _learn(config, setup: _Setup, log, fitted_from=None) -> dict:
    """The fitted detectors (fitted on the learning set, reloaded from the directory, or
    taken from the campaign directory *fitted_from*), each at the threshold scale of its
    ``[[detector]]`` entry (:func:`with_threshold_scales`)."""
    return with_threshold_scales(config, _fitted(config, setup, log, fitted_from))


def with_threshold_scales(config, detectors: dict) -> dict:
    """*detectors* (label → fitted Detector) marked with the ``threshold_scale`` of their
    ``[[detector]]`` entries of *config* (:func:`detectors.base.set_threshold_scales`): the
    engine then multiplies every threshold of each by its factor when it runs it
    (:func:`campaign.evaluate.detect`). Fitting never sees the scale, so the detectors
    fitted at one scale serve every other (``run --fitted-from``). A detector whose own
    capabilities do not declare ``threshold_scale`` and is given another factor than 1 is a
    :class:`CampaignSetupError` naming it."""
    try:
        return set_threshold_scales(detectors, {d.label: d.scale for d in config.detectors})
    except ValueError as exc:
        raise CampaignSetupError(f"{exc}; fix: remove threshold_scale from its [[detector]] "
                                 "entry") from None


def _fitted(config, setup: _Setup, log, fitted_from=None) -> dict:
    """The fitted detectors of :func:`_learn`, at their own thresholds."""
    settings, pool = setup.settings, setup.pool
    origin = setup.cdir.read_fitted_origin()
    if fitted_from is None and origin is not None:
        fitted_from = origin.get("fitted_from")
        log(f"fitted detectors: those taken from {fitted_from} when this directory started")
        names = {d.label: d.name for d in config.detectors}
        return {label: setup.cdir.read_fitted(label, name) for label, name in names.items()}
    if fitted_from is not None:
        return adopt_fitted(config, setup.cdir, fitted_from, log=log)
    with kernels.use_engine(settings.engine):
        # the learning set on the workers that will run the chunks: processes for any
        # plant, threads for a plant that runs on threads (one that needs processes never
        # gets a thread pool, _setup)
        threads = pool is not None and setup.backend == "threading"
        # the detectors that say so fit on the worker threads too, beside the others
        return fit_detectors(setup.campaign, setup.cdir, settings, setup.chunk_size, log=log,
                             submit=pool.submit if pool is not None else None,
                             workers=setup.jobs, run_timeout_s=setup.run_timeout_s,
                             fit_submit=pool.submit if threads else None)


def _plan_chunks(cdir: CampaignDir, size: int, done: np.ndarray | None):
    """The runs of the directory's plan not *done* (a mask over the plan, or None), in
    chunks of *size* runs, read from ``plan.parquet`` as they are taken: the chunks
    ``plan[~done].iloc[s:s + size]`` would give, without the plan in memory."""
    held: list[pd.DataFrame] = []
    n_held = 0
    for frame in cdir.plan_batches(size):
        if done is not None:
            frame = frame[~done[frame.index.to_numpy()]]
        held.append(frame)
        n_held += len(frame)
        while n_held >= size:
            rows = pd.concat(held) if len(held) > 1 else held[0]
            yield rows.iloc[:size]
            held, n_held = [rows.iloc[size:]], n_held - size
    if n_held:
        yield pd.concat(held) if len(held) > 1 else held[0]


def _execute(config, setup: _Setup, n_planned: int, detectors: dict, *, progress: bool,
             log) -> bool:
    """Evaluate the runs of the directory's plan (*n_planned* runs) not done yet, chunk by
    chunk, each stored as a shard as it finishes; returns whether every chunk ran (False
    after Ctrl-C)."""
    from .execute import run_local, run_on_cluster

    cdir, settings, pool = setup.cdir, setup.settings, setup.pool
    done = cdir.done_mask(cdir.plan_run_ids()) if setup.resumed else None
    n_done = int(done.sum()) if done is not None else 0
    if setup.resumed:
        log(f"resuming {cdir.root}: {n_done} of {n_planned} runs already done")
    size = setup.chunk_size
    # each chunk read from plan.parquet when it is taken: a plan of 10⁶ runs is 10⁴ chunks
    chunks = _plan_chunks(cdir, size, done) if n_done < n_planned else None
    bar = Progress(n_planned, n_done, enabled=progress)
    labels = list(detectors)

    def store(frame: pd.DataFrame) -> None:
        # the manifest takes the shards a few seconds at a time (flushed below)
        cdir.write_shard(frame, config.to_json(), defer_manifest=True)
        bar.update(frame["run_id"].nunique())

    def fail(rows, status, message):
        return failure_rows(rows, labels, status, message)

    try:
        if chunks and setup.client is not None:
            run_on_cluster(setup.client, chunks, evaluate, detectors, settings, fail, store,
                           log=log)
        elif chunks and pool is None:       # --jobs 1 without a time limit: in-process
            for c in chunks:
                store(evaluate(c, detectors, settings))
        elif chunks:
            # threads share memory: one detector copy per chunk
            call = partial(_evaluate_copy if setup.backend == "threading" else evaluate,
                           detectors=detectors, settings=settings)
            run_local(chunks, call, fail, store, jobs=setup.jobs, backend=setup.backend,
                      run_timeout_s=setup.run_timeout_s, pool=pool, log=log)
        return True
    except KeyboardInterrupt:
        bar.close()
        log(f"\ninterrupted: the finished chunks are stored in {cdir.root}; run the same "
            "command again to resume")
        return False
    finally:
        cdir.flush_manifest()
        bar.close()


def finalize(cdir: CampaignDir, config, plan: pd.DataFrame | None, complete: bool,
             wall_s: float, fmu_sha256: str | None = None, roles=None) -> Campaign:
    """Read the shards in plan order, a batch of runs at a time, and write
    ``summary.parquet`` (its metadata also holds ``fitted_sha256``,
    :meth:`CampaignDir.fitted_sha256` of the fitted detectors, and ``fitted_from``, the
    directory they were taken from or None, and ``fmu_sha256``, the SHA-256 of an FMU plant's
    file, :func:`campaign.plant_setup.replay_plant`) and, for a campaign of fixed onsets
    (:func:`reports.scoring.detection_times.fixed_onset_campaign`), ``detection-times.parquet``.

    No batch is kept: the summary is aggregated as the batches come
    (:class:`reports.scoring.summary.SummaryAccumulator`), and of the rows only those the gate reads
    (:func:`reports.scoring.gate.gate_rows`: in a fault-free campaign, its false alarms and failed
    runs) and, for a fixed-onset campaign, the first alarms of its runs are kept."""
    from reports.scoring.gate import gate_rows

    full = plan
    columns = ["run_id", "group", "fault", "onset_s"]
    if plan is None:       # what this needs, read from plan.parquet without the whole plan
        fixed = fixed_onset_campaign(cdir.plan_batches(columns=columns[1:]))
        n_planned, run_ids = cdir.planned_runs(), cdir.plan_run_ids()
        plan = cdir.read_plan(columns) if fixed else None   # Table-1 campaigns: small
    else:
        fixed = fixed_onset_campaign(plan)
        n_planned, run_ids = len(plan), plan["run_id"].to_numpy()
    acc = SummaryAccumulator()
    runs_done, gate_parts, alarm_parts = 0, [], []
    batches = cdir.result_batches(run_ids)
    del run_ids            # the batches keep the ids as 28 bytes a run (_RunIndex)
    for batch in batches:
        acc.add(batch)
        runs_done += batch["run_id"].nunique()      # a run's rows are in one batch
        gate_parts.append(gate_rows(batch))
        if fixed:
            alarm_parts.append(batch[["run_id", "detector", "fault", "status",
                                      "first_alarm_s"]])
    summary = acc.summary() if runs_done else pd.DataFrame()
    gate_results = (pd.concat(gate_parts, ignore_index=True) if gate_parts
                    else pd.DataFrame())
    origin = cdir.read_fitted_origin() or {}
    cdir.write_summary(summary, config.to_json(), complete=complete,
                       runs_done=runs_done, runs_planned=n_planned,
                       fitted_sha256=cdir.fitted_sha256([d.label for d in config.detectors]),
                       fitted_from=origin.get("fitted_from"), fmu_sha256=fmu_sha256)
    times = None
    if runs_done and fixed:
        times = detection_time_table(plan, pd.concat(alarm_parts, ignore_index=True))
        cdir.write_detection_times(times, config.to_json())
    known = {"plan": full} if full is not None else {}
    if roles is not None:       # the resolved campaign's (campaign.isolation.roles_of)
        known["roles"] = roles
    return Campaign.of_dir(cdir, wall_s=wall_s, detection_times=times,
                           gate_results=gate_results, **known)
