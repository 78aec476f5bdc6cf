"""The HTML report and the re-simulation of single runs.

Everything here starts from what a campaign directory holds — ``campaign.json``,
``plan.parquet``, ``runs/part-*.parquet``, ``summary.parquet`` and the fitted detectors of
``fitted/`` (stored as data, never unpickled) — and never from the memory of the process that
ran it, so a directory copied to another machine gives the same report. Each command first
checks the directory's files against its manifest (exit 2 on any difference). Traces that are not
stored (residuals of every fault-free run, the signals of example runs) are re-simulated on demand
from the plan rows (run id, seed and stream fix every random draw, docs/design.md §9, Determinism)
and fed to the stored fitted detectors (:func:`campaign.evaluate.simulate_and_detect`, the runner's
own pipeline); the margins of the re-simulated runs are checked against the stored ones. A campaign
on an FMU plant is re-simulated only on an FMU named on the command line (``--fmu``) whose digest is
the one recorded at run time, never on the file the directory names
(:func:`campaign.plant_setup.replay_plant`); without it, what needs no simulation is shown.

Commands (``fdd-campaign``): ``report DIR`` (writes ``DIR/report.html``) and ``show DIR
RUN_ID``; ``compare DIR_A DIR_B`` is :mod:`campaign.compare`.
"""

from __future__ import annotations

import copy
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from reports.render.figures.report import bin_max, figure_png, render_png, run_figure
from reports.render.html import ReportFigure, drilldown_section, render_report, show_command
from reports.scoring.metrics import FAULT_FREE
from reports.scoring.summary import detector_order
from reports.render.table import error_lines
from scenarios import compiled as kernels
from scenarios.envelope import FLIGHT_COLUMNS
from scenarios.errors import ArgumentError

from .config import CampaignConfig
from .evaluate import ChunkSettings, score, simulate_and_detect
from .evidence.hazard import report_section
from .evidence.figures import evidence_figure_specs
from .plant_setup import replay_plant, resolve
from .result import Campaign, load
from .progress import Progress
from .runner import CampaignSetupError, settings_of
from .store.directory import CampaignDir
from .tradeoff import report_figures as tradeoff_figures

__all__ = ["ReportSettings", "build_report", "replay_settings", "show_run"]

#: Flight-point columns of the plan shown with every run and used by the envelope maps.
POINT_COLUMNS = (*FLIGHT_COLUMNS, "onset_s", "magnitude")


#: Largest number of runs re-simulated together (about 30 arrays of MAX_CHUNK × n_steps
#: floats: 0.9 GB for 60 s runs at 10 ms). The runs are re-simulated in batches of the
#: campaign's own ``[runner] chunk_size`` (default 100) up to this: on addsafe-mc's 1200
#: fault-free runs, batches of 100 took 3.7 CPU-s and batches of 600 5.4 CPU-s (memory
#: traffic of the larger arrays).
MAX_CHUNK = 600
#: Fewest figures worth drawing in worker processes (starting one costs about a second).
MIN_PARALLEL_FIGURES = 8


@dataclass(frozen=True)
class ReportSettings:
    """How the report is drawn (none of it changes a number of the verdict).

    envelope_bins : time bins of the envelope figures; each bin shows the per-run maximum
        of |r|/τ in it (max-pooling: no peak is hidden)
    envelope_runs : largest number of fault-free runs re-simulated per manoeuvre (None: all
        of them). When fewer than the campaign has, the ``worst_kept`` runs of largest
        stored margin of every detector are always kept and the rest is filled with runs
        evenly spaced in plan order.
    worst_kept : see ``envelope_runs``
    examples_per_fault : example runs shown per fault type (the slowest or a missed one,
        the median, the fastest); 0 shows no example run at all
    """

    envelope_bins: int = 600
    envelope_runs: int | None = None
    worst_kept: int = 10
    examples_per_fault: int = 3


def replay_settings(camp: Campaign, fmu=None) -> tuple[ChunkSettings | None, str]:
    """(settings to re-simulate the runs of *camp* with, or None when they cannot be: an FMU
    plant and no *fmu*, the FMU named on the command line; a note for the user)
    (:func:`campaign.plant_setup.replay_plant`)."""
    settings = settings_of(resolve(camp.config))
    plant, note = replay_plant(settings.plant, camp.provenance.fmu_sha256, fmu, camp.root)
    return (None if plant is None else replace(settings, plant=plant)), note


# ---- re-simulation -------------------------------------------------------------------------
def _run_margin(residual: np.ndarray) -> np.ndarray:
    """The largest value of a margin statistic over a whole run (the decision, else |r|/τ:
    :attr:`detectors.base.Detection.margin_statistic`), NaN samples ignored: the margin
    of a fault-free run (reports.scoring.metrics.score_runs)."""
    finite = ~np.isnan(residual)
    peak = np.where(finite, residual, -np.inf).max(axis=1)
    return np.where(finite.any(axis=1), peak, np.nan)


def _trace_chunk(env_rows: pd.DataFrame, extra_rows: pd.DataFrame, *, detectors: dict,
                 settings: ChunkSettings, n_bins: int, example_ids: frozenset):
    """Worker: re-simulate fault-free runs (binned |r|/τ and margin per detector variant)
    together with some example runs (full traces). A detector that fails is run again run
    by run; its failed runs are left out of its envelopes and returned as
    {label: {run id: message}}.

    The example runs ride along in the same batch: the time loops are vectorised over runs,
    so extra rows cost almost nothing.
    """
    rows = pd.concat([env_rows, extra_rows], ignore_index=True)
    failed: dict = {}
    signals, truth, detections = simulate_and_detect(rows, detectors, settings, failed)
    ids = rows["run_id"].astype(str).to_numpy()
    failures = {label: {ids[j]: msg for j, msg in runs.items()}
                for label, runs in failed.items()}
    n_env = len(env_rows)
    env, starts = {}, None
    if n_env:
        for name, d in detections.items():
            res = np.asarray(d.residual[:n_env], dtype=float)
            starts, binned = bin_max(res, n_bins)
            env[name] = (binned, _run_margin(np.asarray(d.margin_statistic[:n_env], float)))
    examples = {}
    for i, rid in enumerate(rows["run_id"].astype(str)):
        if rid in example_ids and rid not in examples:
            examples[rid] = (_run_frame(signals, truth, i),
                             {n: (d.residual[i], d.alarm[i]) for n, d in detections.items()},
                             float(truth.onset_s[i]))
    return env_rows["run_id"].to_numpy(), starts, env, examples, failures


def _envelope_subset(free: pd.DataFrame, results: pd.DataFrame, cfg: ReportSettings):
    """The fault-free plan rows to re-simulate (see :class:`ReportSettings`)."""
    if cfg.envelope_runs is None:
        return free
    keep = []
    margins = results[results["fault"] == FAULT_FREE].pivot_table(
        index="run_id", columns="detector", values="margin", aggfunc="max")
    for _, rows in free.groupby("manoeuvre", sort=False):
        if len(rows) <= cfg.envelope_runs:
            keep.append(rows)
            continue
        ids = set()
        m = margins.reindex(rows["run_id"])
        for det in m.columns:
            ids |= set(m[det].nlargest(cfg.worst_kept).index)
        rest = rows[~rows["run_id"].isin(ids)]
        n_fill = max(0, cfg.envelope_runs - len(ids))
        pick = np.unique(np.linspace(0, len(rest) - 1, n_fill).round().astype(int)) \
            if n_fill and len(rest) else np.array([], int)
        ids |= set(rest["run_id"].iloc[pick])
        keep.append(rows[rows["run_id"].isin(ids)])
    return pd.concat(keep) if keep else free.iloc[:0]


#: Plan columns the report reads of every run (to choose the runs it re-simulates); it
#: reads whole plan rows only of the runs it re-simulates.
PLAN_KEY_COLUMNS = ("run_id", "fault", "manoeuvre")


def _envelope_runs(plan: pd.DataFrame, cfg: ReportSettings, runs: pd.DataFrame):
    """(fault-free runs to re-simulate, number of fault-free runs scored ok): rows of
    *plan* (at least :data:`PLAN_KEY_COLUMNS`), chosen with the campaign's
    :func:`runs_table` *runs*."""
    ok_ids = set(runs.loc[runs["status"] == "ok", "run_id"])
    free = plan[(plan["fault"] == FAULT_FREE) & plan["run_id"].isin(ok_ids)]
    return _envelope_subset(free, runs, cfg), len(free)


def _chunks(free: pd.DataFrame, extra: pd.DataFrame, size: int) -> list:
    """(fault-free rows, example rows) per batch of at most *size* fault-free runs; the
    example rows are dealt over the batches (they ride along: a run simulated in any batch
    is the same run)."""
    size = max(1, min(int(size), MAX_CHUNK))
    env = [free.iloc[s:s + size] for s in range(0, len(free), size)] or [free.iloc[:0]]
    return [(e, extra.iloc[i::len(env)]) for i, e in enumerate(env)]


def _trace_chunk_copy(env_rows: pd.DataFrame, extra_rows: pd.DataFrame, *, detectors: dict,
                      **kwargs):
    """:func:`_trace_chunk` on private copies of the detectors (batches run in threads, as
    the runner's ``_evaluate_copy``)."""
    return _trace_chunk(env_rows, extra_rows, detectors=copy.deepcopy(detectors), **kwargs)


def _resimulate(chunks: list, *, detectors: dict, settings: ChunkSettings, n_bins: int,
                example_ids: frozenset, jobs: int, processes, progress) -> list:
    """The parts of :func:`_trace_chunk` of every batch of *chunks*, in order: on *jobs*
    threads of this process (the compiled kernels release the GIL; each batch with its
    own copy of the detectors, as ``run`` does), in the worker processes *processes* (a
    ``concurrent.futures`` executor) when the plant must not be shared between threads
    (an FMU), or here one after the other for one job. *progress* (a
    :class:`campaign.progress.Progress`) counts the runs as their batch ends."""
    kwargs = {"detectors": detectors, "settings": settings, "n_bins": n_bins,
              "example_ids": example_ids}
    if jobs == 1 or len(chunks) == 1:
        parts = []
        for e, x in chunks:
            parts.append(_trace_chunk(e, x, **kwargs))
            progress.update(len(e) + len(x))
        return parts
    if settings.plant.needs_processes:
        executor, own = processes, None
        if executor is None:
            from joblib.externals.loky import ProcessPoolExecutor

            executor = own = ProcessPoolExecutor(max_workers=jobs)
        call = _trace_chunk
    else:
        if settings.engine == "compiled":
            kernels.warm_up()          # compiled or loaded once, before the threads start
        executor = own = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="fdd-report")
        call = _trace_chunk_copy
    try:
        futures = {executor.submit(call, e, x, **kwargs): i for i, (e, x) in enumerate(chunks)}
        parts: list = [None] * len(chunks)
        for future in as_completed(futures):
            i = futures[future]
            parts[i] = future.result()
            progress.update(len(chunks[i][0]) + len(chunks[i][1]))
        return parts
    finally:
        if own is not None:
            own.shutdown(wait=True)


def _gather_envelopes(parts: list, free: pd.DataFrame, settings: ChunkSettings):
    parts = [p for p in parts if len(p[0])]
    if not parts:
        return None
    run_ids = np.concatenate([p[0] for p in parts])
    # a detector that failed on every run of a part has none of its variants there
    names = list(dict.fromkeys(n for p in parts for n in p[2]))
    starts = next(p[1] for p in parts if p[1] is not None)

    def part(p, n, k):
        if n in p[2]:
            return p[2][n][k]
        return np.full((len(p[0]), len(starts)) if k == 0 else len(p[0]), np.nan)

    return {"run_ids": run_ids, "t_s": starts * settings.ts,
            "binned": {n: np.concatenate([part(p, n, 0) for p in parts]) for n in names},
            "margin": {n: np.concatenate([part(p, n, 1) for p in parts]) for n in names},
            "manoeuvre": free.set_index("run_id").loc[run_ids, "manoeuvre"].to_numpy()}


def _margin_check(env, results: pd.DataFrame) -> float:
    """Largest |re-simulated margin − stored margin| over the re-simulated runs."""
    worst = 0.0
    for name, m in env["margin"].items():
        stored = (results[(results["detector"] == name) & (results["status"] == "ok")]
                  .set_index("run_id")["margin"].reindex(env["run_ids"]).to_numpy(float))
        both = np.isfinite(stored) & np.isfinite(m)
        if (np.isfinite(stored) != np.isfinite(m)).any():
            return np.inf
        if both.any():
            worst = max(worst, float(np.max(np.abs(stored[both] - m[both]))))
    return worst


# ---- example runs --------------------------------------------------------------------------
def _example_ids(results: pd.DataFrame, n_per_fault: int,
                 detectors: list[str] = ()) -> list[tuple[str, str, str]]:
    """(fault, run_id, why) of the runs shown as examples: per fault type the slowest or a
    missed run, the median and the fastest (DTP worst over detectors); the fault-free run
    of largest margin. None when *n_per_fault* is 0. Detectors named in *detectors* order."""
    if n_per_fault <= 0:
        return []
    ok = results[results["status"] == "ok"]
    out = []
    free = ok[ok["fault"] == FAULT_FREE]
    if len(free):
        m = free.groupby("run_id")["margin"].max()
        if m.notna().any():
            out.append((FAULT_FREE, m.idxmax(), f"largest margin {m.max():.3f}"))
    for fault, g in ok[ok["fault"] != FAULT_FREE].groupby("fault", sort=True):
        detected = g["detected"].astype(bool).to_numpy()
        dtp = np.where(detected, g["dtp"].astype(float), np.inf)
        per_run = pd.Series(dtp, index=g["run_id"].to_numpy()).groupby(level=0).max()
        per_run = per_run.sort_values(kind="stable")
        missers = (g.loc[~detected].groupby("run_id")["detector"]
                   .agg(lambda d: ", ".join(x for x in detectors if x in set(d))))
        worst_by = (g.assign(_d=dtp).sort_values("_d", kind="stable")
                    .groupby("run_id")["detector"].last())

        def why(rid, dtp_value, word):
            if np.isinf(dtp_value):
                return f"{word + ', ' if word else ''}missed by {missers.get(rid, '?')}"
            return f"{word}, DTP {dtp_value:.3g} ({worst_by.get(rid, '?')})"

        picks = [(per_run.index[-1], why(per_run.index[-1], per_run.iloc[-1], "slowest"
                                          if np.isfinite(per_run.iloc[-1]) else ""))]
        if len(per_run) > 2:
            mid = len(per_run) // 2
            picks.append((per_run.index[mid], why(per_run.index[mid], per_run.iloc[mid],
                                                  "median")))
        if len(per_run) > 1:
            picks.append((per_run.index[0], why(per_run.index[0], per_run.iloc[0],
                                                "fastest")))
        seen = set()
        for rid, text in picks[:n_per_fault]:
            if rid not in seen:
                seen.add(rid)
                out.append((fault, rid, text))
    return out


def _run_frame(signals, truth, i: int) -> pd.DataFrame:
    frame = signals.to_pandas(i)
    frame["true_rod [mm]"] = truth.rod_mm[i]
    frame["true_surface [deg]"] = truth.surface_deg[i]
    frame["true_current [mA]"] = truth.current_mA[i]
    return frame


def _point_text(row) -> str:
    return (f"{row['alt_ft']:.0f} ft, {row['vcas_kt']:.0f} kt, {row['mass_t']:.1f} t, "
            f"CG {row['cg_pct']:.1f} %")


# ---- report --------------------------------------------------------------------------------
def _requirements(config: CampaignConfig) -> dict:
    r = config.requirements
    return {"max_fa_rate": r.max_fa_rate, "max_md_rate": r.max_md_rate, "max_dtp": r.max_dtp,
            "detector_max_fa_rate": dict(r.detector_max_fa_rate)}


#: Result columns the report reads (its tables, figures and drill-down lists).
REPORT_COLUMNS = ("fault", "manoeuvre", "status", "error", "false_alarm", "detected", "dtp",
                  "delay_s", "margin")


def runs_table(camp: Campaign) -> pd.DataFrame:
    """Result rows with the flight point of each run (one row per run × detector), only the
    columns the report reads (:data:`REPORT_COLUMNS`, then :data:`POINT_COLUMNS`), read a
    batch of runs at a time: the report's one table of every run (it lists every run and
    maps every fault-free one): 6 text, 2 boolean and 9 float columns per run × detector,
    where the result rows have 17 columns and the plan rows 35."""
    point = camp.plan_columns(POINT_COLUMNS)           # one read of the plan's columns
    columns = {c: point[c].to_numpy() for c in POINT_COLUMNS}
    del point
    parts = []
    for batch in camp.result_batches(columns=list(REPORT_COLUMNS), positions=True):
        pos = batch.pop("plan_pos").to_numpy()
        inside = pos < len(columns[POINT_COLUMNS[0]])
        for c, values in columns.items():
            batch[c] = (values[pos] if inside.all()              # a run outside the plan:
                        else np.where(inside, values[np.where(inside, pos, 0)], np.nan))
        parts.append(batch)
    if not parts:
        return pd.DataFrame()
    return pd.concat(parts, ignore_index=True)


def campaign_gate(camp: Campaign, req: dict, *, all_requirements: bool = False):
    """:meth:`Campaign.gate <campaign.result.Campaign.gate>` as ``fdd-campaign gate DIR``
    asks it (*all_requirements*: ``… --all-requirements``): same checks, words and run ids."""
    return camp.gate(req, all_requirements=all_requirements)


@dataclass
class _ReportData:
    """What the report shows, gathered from the directory (:func:`_read_report_data`) and
    the re-simulation (:func:`_resimulate_report_runs`)."""

    camp: Campaign
    cfg: ReportSettings
    requirements: dict
    detectors: list                # detector names in the summary's order (the page's)
    runs: pd.DataFrame             # runs_table(camp)
    settings: ChunkSettings | None  # to re-simulate with (None: an FMU plant, no --fmu)
    gate: object = None            # reports.scoring.gate.GateResult of `fdd-campaign gate DIR`, and
    all_requirements: object = None  # of `fdd-campaign gate DIR --all-requirements`
    plan: pd.DataFrame | None = None  # the plan rows of the runs re-simulated, by run id
    n_free: int = 0                # fault-free runs scored ok
    env: dict | None = None        # re-simulated envelopes (_gather_envelopes)
    examples: list = field(default_factory=list)     # (fault, run_id, why)
    traces: dict = field(default_factory=dict)       # run_id → (frame, residuals, onset)
    t_sim: float = 0.0             # seconds the re-simulation took
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def _figure_worker_init() -> None:
    """Start-up of a figure worker process: matplotlib (Agg) and the figure module loaded,
    then every object made so far out of the cyclic collector's scans (``gc.freeze``; they
    live as long as the worker) and the collector run less often (after 20000 new objects
    instead of 700): matplotlib's figures make many short-lived objects, and the
    collector's passes took 12–15 % of the drawing over the loaded modules, and 10 % more
    over the figures' own objects (measured on addsafe-mc's figures; a worker then holds
    about 100 MB more)."""
    import gc

    from reports.render.figures import report as figures

    figures.new_figure()
    gc.freeze()
    gc.set_threshold(20000, 20, 100)


def _process_pool(jobs: int, initializer, preload=None):
    """A ``concurrent.futures`` pool of *jobs* worker processes, each started with
    *initializer*: forked from this one on Linux while it runs no other thread (a worker
    then starts with every module this process has loaded, and *preload* is called here
    first, instead of importing them again in each: about a second of CPU a worker), else
    loky's (a fresh interpreter each, as ``run`` starts its workers). The workers are
    forked here and now (at a first, empty task), while no other thread runs; the standard
    streams are flushed before, so that no buffered line is written again by a worker."""
    import multiprocessing
    import threading

    if sys.platform.startswith("linux") and threading.active_count() == 1 \
            and "fork" in multiprocessing.get_all_start_methods():
        from concurrent.futures import ProcessPoolExecutor

        if preload is not None:
            preload()
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        pool = ProcessPoolExecutor(max_workers=jobs, initializer=initializer,
                                   mp_context=multiprocessing.get_context("fork"))
        pool.submit(int)               # forks every worker now (they start at a first task)
        return pool
    from joblib.externals.loky import ProcessPoolExecutor

    return ProcessPoolExecutor(max_workers=jobs, initializer=initializer)


class _FigureDrawer:
    """Draws figure specs (the form noted above :func:`_envelope_specs`) in *jobs* worker
    processes (:func:`_process_pool`, started at once: their start-up overlaps the reading
    and the re-simulation), or here when *jobs* is 1, at :meth:`collect`. Specs are handed
    over in groups as they become known; :meth:`collect` returns the figures group by group
    in the order asked."""

    def __init__(self, jobs: int):
        self.jobs = jobs
        self.executor = None
        if jobs > 1:
            from reports.render.figures.report import new_figure

            self.executor = _process_pool(jobs, _figure_worker_init, preload=new_figure)
        self.specs: dict[str, list] = {}
        self.futures: dict[str, list] = {}

    def submit(self, group: str, specs: list) -> None:
        self.specs[group] = specs
        if self.executor is not None:
            self.futures[group] = [self.executor.submit(render_png, kind, args, kwargs)
                                   for *_, kind, args, kwargs in specs]

    @property
    def count(self) -> int:
        return sum(len(v) for v in self.specs.values())

    @property
    def done(self) -> int:
        """Figures drawn so far (none before :meth:`collect` without workers)."""
        return sum(f.done() for fs in self.futures.values() for f in fs)

    def collect(self, groups: list[str], progress) -> list[ReportFigure]:
        """Every figure of *groups* (in that order, each in its specs' order); *progress*
        (a :class:`campaign.progress.Progress`, started at :attr:`done`) counts them as they
        are done."""
        pngs: dict[str, list] = {}
        if self.executor is None:
            for g in groups:
                pngs[g] = []
                for *_, kind, args, kwargs in self.specs[g]:
                    pngs[g].append(render_png(kind, args, kwargs))
                    progress.update(1)
        else:
            pending = [f for g in groups for f in self.futures[g] if not f.done()]
            for _ in as_completed(pending):
                progress.update(1)
            pngs = {g: [f.result() for f in self.futures[g]] for g in groups}
        return [ReportFigure(section, group, title, png, caption)
                for g in groups
                for (section, group, title, caption, *_), png in zip(self.specs[g], pngs[g])]

    def close(self) -> None:
        if self.executor is not None:
            self.executor.shutdown(wait=True)
            self.executor = None


class _StageLog:
    """The report's progress on stderr, as ``run`` shows its own: a line per stage with the
    seconds since the start, and a :class:`campaign.progress.Progress` bar for the runs
    re-simulated and for the figures drawn; nothing when *enabled* is False
    (``--quiet``)."""

    def __init__(self, enabled: bool, t0: float, stream=None):
        self.enabled, self.t0 = enabled, t0
        self.stream = stream or sys.stderr

    def __call__(self, text: str) -> None:
        if self.enabled:
            print(f"report: {text} [{time.perf_counter() - self.t0:.1f} s]", file=self.stream,
                  flush=True)

    def bar(self, total: int, unit: str, done: int = 0) -> Progress:
        return Progress(total, done, enabled=self.enabled and total > 0, stream=self.stream,
                        label="report: ", unit=unit)


#: Figure groups in page order (each a list of figure specs).
FIGURE_GROUPS = ("envelope", "fault", "example", "map", "evidence")


def build_report(directory, *, out=None, jobs: int = 2, settings: ReportSettings | None = None,
                 log=None, requirements: dict | None = None, fmu=None,
                 progress: bool = True) -> Path:
    """Write the HTML report of a campaign directory; returns its path.

    With *jobs* > 1, worker processes start at once and draw the figures that need no
    simulation (detection per fault type, envelope maps, survival and certificate curves)
    while this process evaluates the gate and re-simulates the fault-free runs (for the
    envelopes) with the example runs riding along, on *jobs* threads as ``run`` simulates
    them (processes for an FMU plant); then the envelope and example figures are drawn too.

    Parameters
    ----------
    directory : a campaign directory (``fdd-campaign run --out``), or its
        :class:`campaign.result.Campaign` already loaded (checked against its manifest)
    out : HTML file (default ``DIR/report.html``)
    jobs : worker processes (figures) and threads (re-simulation)
    settings : :class:`ReportSettings`
    requirements : the ``[requirements]`` to report against, in their JSON form, in place of
        the campaign's (``report --requirements FILE``; :func:`campaign.config.load_requirements`)
    fmu : for a campaign on an FMU plant, the FMU to re-simulate on (``--fmu``; checked
        against the digest recorded at run time); without it nothing is re-simulated
    log : where notes go, one line each (default: stderr)
    progress : a line per stage and progress bars on stderr (``--quiet``: none)
    """
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    cfg = settings or ReportSettings()
    if jobs < 1:
        raise ArgumentError.of("jobs", jobs, "must be ≥ 1 (local workers)", 2)
    if cfg.envelope_runs is not None and cfg.envelope_runs < 1:
        raise ArgumentError.of("envelope_runs", cfg.envelope_runs,
                               "must be ≥ 1 (or left out for all runs)", 50)
    t0 = time.perf_counter()
    say = _StageLog(progress, t0)
    data = _read_report_data(directory, cfg, requirements, fmu, log)
    say(f"read {data.camp.root}: {data.runs['run_id'].nunique()} runs × "
        f"{len(data.detectors)} detectors")
    ok = data.runs[data.runs["status"] == "ok"]
    early = {"fault": _fault_specs(ok, data.requirements, data.detectors),
             "map": _map_specs(ok, data.requirements, data.detectors),
             "evidence": evidence_figure_specs(data.camp, data.runs)}
    n_early = sum(len(v) for v in early.values())
    parallel = jobs > 1 and n_early + len(data.detectors) >= MIN_PARALLEL_FIGURES
    drawer = _FigureDrawer(jobs if parallel else 1)
    try:
        for group, specs in early.items():
            drawer.submit(group, specs)
        del early, ok
        if parallel:
            say(f"drawing {n_early} figures on {jobs} processes (detection, maps, "
                "survival, certificate) while the runs are re-simulated")
        data.gate = campaign_gate(data.camp, data.requirements)
        data.all_requirements = campaign_gate(data.camp, data.requirements,
                                              all_requirements=True)
        _resimulate_report_runs(data, jobs, say, drawer.executor)
        drawer.submit("envelope", _envelope_specs(data))
        drawer.submit("example", _example_specs(data))
        t1 = time.perf_counter()
        # the page's largest part, made while the workers draw
        drilldown = drilldown_section(data.runs, data.detectors)
        done = drawer.done
        say(f"drawing {drawer.count - done} figures"
            + (f" on {jobs} processes ({done} of {drawer.count} drawn already)"
               if drawer.executor is not None else ""))
        bar = say.bar(drawer.count, "figures", done=done)
        figures = drawer.collect(list(FIGURE_GROUPS), bar)
        bar.close()
        figures += tradeoff_figures(data.camp, data.requirements, data.notes)
    finally:
        drawer.close()
    t_fig = time.perf_counter() - t1
    data.notes.append(f"Report made with {jobs} job(s) in {time.perf_counter() - t0:.1f} s: "
                      f"re-simulation {data.t_sim:.1f} s, then {t_fig:.1f} s until the last "
                      f"of the {len(figures)} figures was drawn"
                      + (" (the figures that need no simulation drawn meanwhile)"
                         if parallel else "") + ".")
    page = _assemble_page(data, figures, drilldown)
    del figures, drilldown
    path = CampaignDir(data.camp.root).write_report(page, out)
    if progress:
        log(f"report: {drawer.count} figures, {len(page) / 1e6:.1f} MB in "
            f"{time.perf_counter() - t0:.1f} s (re-simulation {data.t_sim:.1f} s, last "
            f"figures {t_fig:.1f} s, {jobs} job(s))")
    return path


def _read_report_data(directory, cfg: ReportSettings, requirements: dict | None = None,
                      fmu=None, log=print) -> _ReportData:
    """What the report reads from the directory: the runs, the requirements, the warnings,
    how to re-simulate (none on an FMU plant without *fmu*: :func:`replay_settings`)."""
    camp = directory if isinstance(directory, Campaign) else load(directory)
    runs = runs_table(camp)
    if runs.empty:
        raise CampaignSetupError(f"{camp.root} holds no result yet; run the campaign first")
    camp.evaluated      # the fitted detectors loaded now: a problem with them is said first
    req = _requirements(camp.config) if requirements is None else requirements
    warnings: list[str] = []
    if camp.meta.get("complete") is False:
        warnings.append(f"The campaign is incomplete: {camp.meta.get('runs_done')} of "
                        f"{camp.meta.get('runs_planned')} runs; rerun 'fdd-campaign run' into "
                        "this directory to finish it.")
    settings, note = replay_settings(camp, fmu)
    if note:
        log(note)
        warnings.append(f"{note} (the residual envelopes and example runs need it; the "
                        "tables and maps need no simulation).")
    order = list(dict.fromkeys(camp.summary["detector"].astype(str)))
    return _ReportData(camp=camp, cfg=cfg, requirements=req, detectors=order, runs=runs,
                       settings=settings, warnings=warnings)


def _resimulate_report_runs(data: _ReportData, jobs: int, say: _StageLog,
                            processes=None) -> None:
    """Re-simulate the fault-free runs (for the envelopes) with the example runs riding
    along, on *jobs* threads (:func:`_resimulate`; in *processes* for an FMU plant), and
    fill *data*'s envelopes, examples and traces."""
    t0 = time.perf_counter()
    cfg, camp, runs, settings = data.cfg, data.camp, data.runs, data.settings
    keys = camp.plan_columns(PLAN_KEY_COLUMNS)
    chosen, data.n_free = _envelope_runs(keys, cfg, runs)
    data.examples = (_example_ids(runs, cfg.examples_per_fault, data.detectors)
                     if settings else [])
    example_ids = frozenset(rid for _, rid, _ in data.examples)
    # whole plan rows only of the runs re-simulated (about 0.6 KB each)
    wanted = chosen.index.union(keys.index[keys["run_id"].isin(example_ids)])
    del keys
    rows = camp.plan_rows(wanted)
    free = rows.loc[chosen.index]
    data.plan = rows.set_index("run_id", drop=False)
    extra = data.plan.loc[sorted(example_ids - set(free["run_id"]))].reset_index(drop=True)
    parts = []
    if settings is not None:
        n = len(free) + len(extra)
        how = (f"on {jobs} processes" if settings.plant.needs_processes else
               f"on {jobs} threads") if jobs > 1 else "here"
        say(f"re-simulating {n} runs ({len(free)} fault-free for the envelopes, "
            f"{len(extra)} more example runs) {how}")
        bar = say.bar(n, "runs")
        parts = _resimulate(_chunks(free, extra, camp.config.runner.chunk_size),
                            detectors=camp.evaluated, settings=settings,
                            n_bins=cfg.envelope_bins, example_ids=example_ids, jobs=jobs,
                            processes=processes, progress=bar)
        bar.close()
    data.t_sim = time.perf_counter() - t0
    data.warnings += error_lines(runs)
    data.warnings += _resimulation_warnings([p[4] for p in parts])
    data.env = _gather_envelopes(parts, free, settings)
    data.traces = {rid: tr for p in parts for rid, tr in p[3].items()}


def _resimulation_warnings(parts: list[dict]) -> list[str]:
    """Warnings for the detectors that failed on runs re-simulated for the report."""
    merged: dict = {}
    for failures in parts:
        for label, runs in failures.items():
            merged.setdefault(label, {}).update(runs)
    return [f"{label} failed on {len(runs)} re-simulated run(s), left out of its envelopes "
            f"and example traces; first: run {next(iter(runs))}: {next(iter(runs.values()))}"
            for label, runs in sorted(merged.items()) if runs]


# A figure to draw (a "spec"): (section, group, title, caption, kind, args, kwargs) for
# reports.render.figures.report.render_png(kind, args, kwargs). The page shows them in FIGURE_GROUPS
# order: envelopes, detection per fault type, example runs, maps, then the evidence
# (campaign.evidence.figures). _envelope_specs and _example_specs add the notes and
# warnings that go with their figures.
def _envelope_specs(data: _ReportData) -> list[tuple]:
    env, cfg = data.env, data.cfg
    if env is None:
        return []
    n_sim = len(env["run_ids"])
    delta = _margin_check(env, data.runs)
    rule = ("all of them" if n_sim == data.n_free else
            f"{n_sim} of {data.n_free}: per manoeuvre at most {cfg.envelope_runs}, always the "
            f"{cfg.worst_kept} runs of largest stored margin of each detector, the rest "
            "evenly spaced in plan order")
    data.notes.append(f"Residual envelopes: the fault-free runs were re-simulated from "
                      f"plan.parquet with the stored fitted detectors ({rule}); each curve is "
                      f"the largest |r|/τ of a run in each of {len(env['t_s'])} time bins, so "
                      "no peak is hidden.")
    if delta <= 1e-9:
        data.notes.append(f"The re-simulated margins reproduce the stored ones of all {n_sim} "
                          f"runs (largest difference {delta:.1e}).")
    else:
        data.warnings.append(f"The re-simulated margins differ from the stored ones by up to "
                             f"{delta:.3g}: the simulator or a detector changed since the "
                             "campaign ran; the envelopes show the current code, the tables "
                             "the stored results.")
    specs = []
    for name in [d for d in data.detectors if d in env["binned"]]:
        panels, worst_ids = [], []
        for man in dict.fromkeys(env["manoeuvre"]):
            sel = env["manoeuvre"] == man
            b, m = env["binned"][name][sel], env["margin"][name][sel]
            worst = int(np.nanargmax(m)) if np.isfinite(m).any() else 0
            worst_ids.append(f"{man}: {(wid := env['run_ids'][sel][worst])}")
            panels.append((man, b, worst, f"worst {wid} (margin {m[worst]:.3f})"))
        specs.append((
            "envelope", name, f"Residual envelopes — {name}",
            f"|r|/τ of the fault-free runs, a panel per manoeuvre; threshold at 1; worst run "
            f"of each manoeuvre in red ({'; '.join(worst_ids)}; re-simulate one with "
            f"{show_command('RUN_ID')}).", "envelope", (env["t_s"], panels),
            {"title": f"{name}: residual envelopes of the fault-free runs"}))
    return specs


def _fault_specs(ok: pd.DataFrame, req: dict, detectors: list[str]) -> list[tuple]:
    """One figure per fault type across every detector (in *detectors* order)."""
    specs = []
    for fault, g in ok[ok["fault"] != FAULT_FREE].groupby("fault", sort=True):
        rows, words = [], []
        for name, gd in sorted(g.groupby("detector"), key=lambda x: detectors.index(x[0])):
            hit = gd["detected"].astype(bool).to_numpy()
            rows.append((name, gd["dtp"].to_numpy(float)[hit], int((~hit).sum())))
            words.append(f"{name} {int(hit.sum())}/{len(gd)}")
        specs.append(("fault", fault, f"Detection of {fault}", f"Runs detected per detector: "
                      f"{', '.join(words)}. The missed runs are the red bars, not part of the "
                      "DTP boxes.", "fault", (rows,), {"title": f"{fault}: detection time "
                      f"performance of {g['run_id'].nunique()} runs", "max_dtp": req["max_dtp"]}))
    return specs


def _example_specs(data: _ReportData) -> list[tuple]:
    specs = []
    for fault, rid, why in data.examples:
        frame, residuals, onset = data.traces[rid]
        residuals = {d: residuals[d] for d in data.detectors if d in residuals}
        row = data.plan.loc[rid]
        label = "fault-free" if fault == FAULT_FREE else fault
        specs.append((
            "fault", label, f"Example run {rid} — {label} ({why})",
            f"{row['manoeuvre']} at {_point_text(row)}; re-simulated from its run id and seed: "
            f"{show_command(rid)}", "run", (frame, residuals),
            {"onset_s": onset, "title": f"{rid}: {label}, {row['manoeuvre']} ({why})"}))
    if data.examples:
        data.notes.append(f"Example runs ({len(data.examples)}) were re-simulated from their "
                          "plan rows: per fault type the slowest (or a missed) run, the median "
                          "and the fastest by the worst DTP over the detectors, and the "
                          "fault-free run of largest margin.")
    return specs


def _map_specs(ok: pd.DataFrame, req: dict, detectors: list[str]) -> list[tuple]:
    specs = []
    for name, gd in sorted(ok.groupby("detector"), key=lambda x: detectors.index(x[0])):
        free_runs = gd[gd["fault"] == FAULT_FREE]
        if len(free_runs):
            specs.append((
                "map", name, f"Margin to false alarm — {name}",
                "Each dot is a fault-free run at its true flight point; dots ringed in red "
                "are its false alarms, as counted in the summary table (a margin above 1 "
                "without a confirmed alarm is not one).", "map", (free_runs, "margin"),
                {"title": f"{name}: margin max |r|/τ of {len(free_runs)} fault-free runs",
                 "label": "margin |r|/τ", "highlight_above": 1.0,
                 "flagged": "false_alarm", "flagged_label": "false alarm"}))
        faulty = gd[gd["fault"] != FAULT_FREE]
        if len(faulty):
            hit = faulty["detected"].astype(bool)
            specs.append((
                "map", name, f"Detection time performance — {name}",
                "Each dot is a detected faulty run coloured by its DTP; black crosses are "
                "missed detections; red rings exceed the DTP requirement.", "map",
                (faulty[hit], "dtp"),
                {"title": f"{name}: DTP of {len(faulty)} faulty runs", "label": "DTP",
                 "highlight_above": req["max_dtp"], "missed": faulty[~hit]}))
    return specs


def _assemble_page(data: _ReportData, figures: list, drilldown: str | None = None) -> str:
    """The HTML page: campaign facts, summary, verdict, run list, figures, notes."""
    camp = data.camp
    c = camp.config.campaign
    meta = {
        "name": c.name, "description": c.description, "directory": str(camp.root),
        "surface": c.surface, "seed": c.seed, "run duration [s]": c.duration_s,
        "runs done / planned": f"{camp.meta.get('runs_done')} / {camp.meta.get('runs_planned')}",
        "complete": camp.meta.get("complete"),
        "detectors": ", ".join(data.detectors),
        "engine version": camp.meta.get("engine_version"),
        "report written (UTC)": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S"),
    }
    cert = camp.certificate
    return render_report(meta=meta, summary=camp.summary, gate=data.gate,
                         requirements=data.requirements, runs=data.runs, figures=figures,
                         notes=data.notes, warnings=data.warnings,
                         certificate=None if cert is None else cert.table,
                         all_requirements=data.all_requirements, detectors=data.detectors,
                         hazard=report_section(None if cert is None else cert.hazard),
                         drilldown=drilldown)


# ---- show ----------------------------------------------------------------------------------
def _score_text(r) -> str:
    def num(x, fmt, unit=""):
        x = float(x)
        return "none" if not np.isfinite(x) else format(x, fmt) + unit

    return (f"margin {num(r['margin'], '.6g')}, false alarm {bool(r['false_alarm'])}, "
            f"first alarm {num(r['first_alarm_s'], '.4g', ' s')}, "
            f"detected {bool(r['detected'])}, DTP {num(r['dtp'], '.4g')}")


class ShowOptionError(CampaignSetupError, ArgumentError):
    """Arguments of :func:`show_run` it cannot serve (*plot*, *out* without the run's traces),
    named as Python names them; ``fdd-campaign show`` names its options."""


def show_run(directory, run_id: str, *, plot=None, out=None, fmu=None,
             log=print) -> pd.DataFrame:
    """Re-simulate one run of a campaign from its run id and seed.

    Prints the stored result rows next to the re-simulated margin and first alarm, writes
    the traces (signals, truth, |r|/τ and alarm of every detector) to *out* (Parquet) and a
    figure to *plot* (PNG). Returns the traces. On an FMU plant the run is re-simulated
    only on *fmu* (``--fmu``, :func:`replay_settings`); without it the stored rows are
    printed and returned, and *plot* or *out* is refused (exit 2).
    """
    camp = load(directory)
    match = camp.plan[camp.plan["run_id"].astype(str) == str(run_id)]
    if match.empty:
        from scenarios.catalog import suggest

        ids = camp.plan["run_id"].astype(str).tolist()
        raise CampaignSetupError(f"run id {run_id!r} is not in {camp.root / 'plan.parquet'}"
                                 f"{suggest(str(run_id), ids)}; the run ids are listed in "
                                 "report.html (e.g. " + ", ".join(ids[:3]) + ")")
    settings, note = replay_settings(camp, fmu)
    row = match.iloc[0]
    stored = pd.concat([b[b["run_id"].astype(str) == str(run_id)]     # a batch at a time
                        for b in camp.result_batches()] or [pd.DataFrame(columns=["detector"])],
                       ignore_index=True).set_index("detector")
    if settings is None:             # an FMU plant and no --fmu: what needs no simulation
        if plot or out:
            raise ShowOptionError.said("{plot} and {out} need the run's traces; {note}",
                                       note=note)
        log(f"{run_id}: {row['fault']} in {row['manoeuvre']} at {_point_text(row)} (seed "
            f"{row['seed']}, stream {row['stream']})")
        for name in detector_order(stored.index):
            r = stored.loc[name]
            log(f"  {name}: stored " + (_score_text(r) if r["status"] == "ok" else
                                        f"status {r['status']}: {r['error']}"))
        log(note)
        return stored.reset_index()
    if note:
        log(note)
    failed: dict = {}
    signals, truth, detections = simulate_and_detect(match, camp.evaluated, settings, failed)
    frame = _run_frame(signals, truth, 0)
    onset = float(truth.onset_s[0])
    log(f"{run_id}: {row['fault']} in {row['manoeuvre']} at {_point_text(row)}"
        + (f", onset {onset:.2f} s" if np.isfinite(onset) else "")
        + f" (seed {row['seed']}, stream {row['stream']})")
    # scored again with the campaign's own rules (campaign.evaluate.score)
    again = score(match, truth, detections, settings, signals.actuator).set_index("detector")
    residuals = {}
    detections = {name: detections[name] for name in detector_order(detections)}
    for name, d in detections.items():
        res, alarm = np.asarray(d.residual[0], float), np.asarray(d.alarm[0], bool)
        residuals[name] = (res, alarm)
        frame[f"{name} |r|/tau [-]"] = res
        if d.decision is not None:     # what the alarm compares with 1; the margin's statistic
            frame[f"{name} decision [-]"] = np.asarray(d.decision[0], float)
        frame[f"{name} alarm"] = alarm
        now = _score_text(again.loc[name])
        if name in stored.index and stored.loc[name, "status"] == "ok":
            log(f"  {name}: stored {_score_text(stored.loc[name])}")
            log(f"  {' ' * len(name)}  re-simulated {now}")
        elif name in stored.index:
            log(f"  {name}: stored status {stored.loc[name, 'status']}: "
                f"{stored.loc[name, 'error']}")
            log(f"  {' ' * len(name)}  re-simulated {now}")
        else:
            log(f"  {name}: no stored result; re-simulated {now}")
    for label, runs in failed.items():
        if runs:
            was = (f"stored status {stored.loc[label, 'status']}: {stored.loc[label, 'error']}"
                   if label in stored.index else "no stored result")
            log(f"  {label}: {was}")
            log(f"  {' ' * len(label)}  re-simulated: {runs[0]}")
    if out:
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(frame.reset_index())
        table = table.replace_schema_metadata({
            **(table.schema.metadata or {}),
            b"fdd_campaign": match.to_json(orient="records").encode()})
        pq.write_table(table, out)
        log(f"traces written to {out}")
    if plot:
        fig = run_figure(frame, residuals, onset_s=onset,
                         title=f"{run_id}: {row['fault']}, {row['manoeuvre']}")
        Path(plot).write_bytes(figure_png(fig, dpi=110))
        log(f"plot written to {plot}")
    return frame
