"""Worst-case search for false alarms over the fault-free envelope (``fdd-campaign falsify``).

docs/evidence.md, "Worst-case search (falsify)"; docs/design.md §8. A Monte Carlo campaign
can say "0 false alarms in n runs" and nothing stronger; validation practice for monitoring
functions adds a global search for the fault-free run that comes closest to an alarm. Every
run's margin m = max |r|/τ over its fault-free part (:func:`reports.scoring.metrics.score_runs`;
m ≥ 1: the threshold is exceeded, a false alarm when the detector's confirmation holds it,
scored as ``false_alarm``) is the objective: the search maximises the margin of one
detector (variant) over

* the flight point (alt_ft, vcas_kt, mass_t, cg_pct) within the campaign's ``[envelope]``
  box (min … max of each list); with ``realistic_only`` a point outside the realistic
  envelope (:func:`scenarios.envelope.realistic_rule`, docs/physics.md §6) is *repaired*:
  moved along the segment towards a realistic anchor point to the last realistic point
  found by bisection (:data:`REPAIR_STEPS` halvings), so every evaluated run is one the
  campaign could have drawn and none of the budget is spent on points it never would;
* every draw column of the run table (:data:`scenarios.envelope.DRAW_COLUMNS`) within ± its
  half-width of ``[uncertainty]``/``[mismatch]`` (:func:`scenarios.envelope.half_widths`;
  a half-width of 0 holds the column at 0);
* the manoeuvre start time (run-table column ``manoeuvre_start_s``) within the range the
  manoeuvre model samples it from, [lead_s, lead_s + start_spread_s] (docs/physics.md §7,
  :data:`scenarios.manoeuvres.MANOEUVRE_PARAMS`), below duration_s − tail_s; not searched on
  the aircraft plant, whose pilot model times its inputs itself;
* two discrete dimensions: the cell (fault-free ``[[group]]`` × manoeuvre, with the values
  the group fixes) and the run's random stream in [0, :data:`STREAM_SPAN`) — its sensor
  noise, turbulence and manoeuvre shape (docs/design.md §9).

The strategy (:mod:`campaign.evidence.falsify_search`, chosen from what drives the margin) spends
a third of the budget screening (scrambled Sobol over every cell, fresh streams; with
``--against`` the campaign's worst runs first, as they ran), then races one CMA-ES on each of
the two worst cells (the better goes on alone) in the unit cube of the continuous
dimensions with the stream held at the best screened run's, and ends with a sweep of fresh streams
at the best run found. Each batch is evaluated through the runner's pipeline
(:func:`campaign.runner.evaluate_rows`) on the local workers or a dask cluster. Same seed → same
runs and margins at any ``--jobs`` (the runs' results do not depend on how they are chunked, and the
strategy sees margins only).

It is a search, not a proof: a search that finds no margin ≥ 1 bounds nothing; what it
gives is the worst case found with the budget, beside the worst a plain Monte Carlo found.
"""

from __future__ import annotations

import math
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from scenarios import envelope
from scenarios.catalog import AIRCRAFT_KINDS
from scenarios.envelope import FLIGHT_COLUMNS
from scenarios.errors import ArgumentError, InputError
from scenarios.manoeuvres import MANOEUVRE_PARAMS

from ..config import CampaignConfig
from ..config.text import toml_value
from ..plan import build_plan, explicit_plan, variable_ranges
from ..execute import one_blas_thread
from ..store.directory import SearchDir

__all__ = ["FalsifyError", "FalsifyOptionError", "FalsifyResult", "SearchSpace", "STREAM_SPAN",
           "falsify", "drawn_start_s", "monte_carlo_config", "scores", "search_space", "worst_toml"]

#: Random streams searched: [0, STREAM_SPAN) (below the learning streams, 2³²).
STREAM_SPAN: int = 2 ** 31
#: Bisection halvings of the realistic-envelope repair (segment length / 2^40: far below
#: any physical resolution of the flight point).
REPAIR_STEPS: int = 40
#: Group name of the searched runs in their run-table rows (and in worst.toml).
SEARCH_GROUP: str = "falsify"
#: Smallest budget: a screening run per cell of a small campaign and a stream sweep.
MIN_BUDGET: int = 10


class FalsifyError(InputError, ValueError):
    """The search cannot start (no fault-free group, unknown detector, bad budget …)."""


class FalsifyOptionError(FalsifyError, ArgumentError):
    """An argument of :func:`falsify` it cannot take (*label*, *budget*, *keep*, *against*),
    named as Python names it; ``fdd-campaign falsify`` names its option
    (:class:`scenarios.errors.ArgumentError`)."""


@dataclass(frozen=True)
class Cell:
    """One fault-free group × manoeuvre, with the run-table values the group fixes."""

    group: str
    manoeuvre: str
    fixed: tuple[tuple[str, float], ...] = ()


@dataclass
class SearchSpace:
    """What the search varies (module docstring), derived from a campaign file.

    ``bounds`` holds the continuous dimensions searched, name → (low, high), in their
    run-table units; ``held`` the dimensions whose range is one value. The search vector is
    the continuous dimensions in ``bounds`` order, then the cell index in [0, n_cells], then
    the stream in [0, :data:`STREAM_SPAN`]."""

    config: CampaignConfig
    bounds: dict[str, tuple[float, float]]
    held: dict[str, float]
    cells: tuple[Cell, ...]
    anchors: np.ndarray = field(repr=False)   # (n_cells, 4) realistic flight points
    realistic_only: bool = True

    @property
    def names(self) -> list[str]:
        """Names of the search vector's dimensions."""
        return [*self.bounds, "cell", "stream"]

    def vector_bounds(self) -> list[tuple[float, float]]:
        return [*self.bounds.values(), (0.0, float(len(self.cells))), (0.0, float(STREAM_SPAN))]

    def vectors(self, points) -> np.ndarray:
        """The search vectors, shape (n_dims, n), of the
        :class:`campaign.evidence.falsify_search.Point` s *points* (unit coordinates → run-table
        units; the cell and the stream at the middle of their unit interval)."""
        lo = np.array([b[0] for b in self.bounds.values()])
        hi = np.array([b[1] for b in self.bounds.values()])
        unit = np.array([p.unit for p in points], float).reshape(len(points), len(lo))
        return np.vstack([(lo + unit * (hi - lo)).T,
                          np.array([p.cell + 0.5 for p in points])[None],
                          np.array([p.stream + 0.5 for p in points])[None]])

    def unit_of(self, row) -> np.ndarray:
        """Unit coordinates of the run-table *row* (clipped into the box; a missing or NaN
        manoeuvre start stays NaN: drawn by the manoeuvre model)."""
        out = []
        for name, (lo, hi) in self.bounds.items():
            v = float(row.get(name, math.nan))
            out.append(v if math.isnan(v) else min(max((v - lo) / (hi - lo), 0.0), 1.0))
        return np.array(out)

    def decode(self, x: np.ndarray) -> list[dict]:
        """The runs (dicts of :func:`campaign.plan.explicit_rows`) of the search vectors
        *x*, shape (n_dims, n) — repaired into the realistic envelope when asked."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        n = x.shape[1]
        cols = {name: x[i] for i, name in enumerate(self.bounds)}
        cell = np.minimum(np.floor(x[len(self.bounds)]).astype(int), len(self.cells) - 1)
        stream = np.minimum(np.floor(x[-1]), STREAM_SPAN - 1).astype(np.int64)
        values = {name: np.full(n, v) for name, v in self.held.items()}
        values.update({name: v.copy() for name, v in cols.items()})
        for j in range(n):
            for name, v in self.cells[cell[j]].fixed:
                values[name][j] = v
        point = np.column_stack([values[c] for c in FLIGHT_COLUMNS])
        if self.realistic_only:
            point = self._repair(point, self.anchors[cell])
        runs = []
        for j in range(n):
            c = self.cells[cell[j]]
            run = {"group": SEARCH_GROUP, "manoeuvre": c.manoeuvre, "fault": "none",
                   **{k: float(point[j, i]) for i, k in enumerate(FLIGHT_COLUMNS)},
                   "draws": {d: float(values[d][j]) for d in envelope.DRAW_COLUMNS},
                   "stream": int(stream[j]),
                   "manoeuvre_start_s": (float(values["manoeuvre_start_s"][j])
                                         if "manoeuvre_start_s" in values
                                         and math.isfinite(values["manoeuvre_start_s"][j])
                                         else None)}
            runs.append(run)
        return runs

    def _realistic(self, point: np.ndarray) -> np.ndarray:
        frame = pd.DataFrame(point, columns=list(FLIGHT_COLUMNS))
        return envelope.realistic_rule(frame, self.config.uncertainty)["realistic"].to_numpy()

    def _repair(self, point: np.ndarray, anchor: np.ndarray) -> np.ndarray:
        """Each unrealistic point moved to the last realistic point of the segment from its
        cell's anchor (realistic) towards it, by bisection."""
        bad = ~self._realistic(point)
        if not bad.any():
            return point
        p, a = point[bad], anchor[bad]
        lo, hi = np.zeros(len(p)), np.ones(len(p))
        for _ in range(REPAIR_STEPS):
            mid = 0.5 * (lo + hi)
            ok = self._realistic(a + mid[:, None] * (p - a))
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        out = point.copy()
        out[bad] = a + lo[:, None] * (p - a)
        return out


def search_space(config: CampaignConfig) -> SearchSpace:
    """The search space of *config* (module docstring); :class:`FalsifyError` when the
    campaign has no fault-free group or no realistic flight point."""
    groups = [g for g in config.groups if g.fault == "none"]
    if not groups:
        raise FalsifyError(f"campaign {config.campaign.name!r} has no fault-free [[group]] "
                           "(fault = \"none\"): falsify searches its fault-free runs; fix: add "
                           "one, e.g. [[group]] fault = \"none\" count = 10")
    ranges = variable_ranges(config)
    if config.plant.kind not in AIRCRAFT_KINDS:       # the pilot model places its own start
        p, duration = MANOEUVRE_PARAMS, config.campaign.duration_s
        ranges["manoeuvre_start_s"] = (p.lead_s, min(p.lead_s + p.start_spread_s,
                                                     duration - p.tail_s))
    bounds = {k: v for k, v in ranges.items() if v[1] > v[0]}
    held = {k: v[0] for k, v in ranges.items() if not v[1] > v[0]}
    cells = []
    for g in groups:
        fixed = tuple((k, float(getattr(g, k))) for k in (*FLIGHT_COLUMNS, "manoeuvre_start_s")
                      if getattr(g, k, None) is not None)
        cells += [Cell(g.name, m, fixed) for m in g.manoeuvres]
    space = SearchSpace(config, bounds, held, tuple(cells), np.empty((0, len(FLIGHT_COLUMNS))),
                        config.campaign.realistic_only)
    space.anchors = np.array([_anchor(space, c, ranges) for c in cells])
    return space


def _anchor(space: SearchSpace, cell: Cell, ranges: dict) -> np.ndarray:
    """A realistic flight point of *cell*: of the envelope's grid points and the box
    centre (with the cell's fixed values), the realistic one nearest the centre."""
    env = space.config.envelope
    lo = np.array([ranges[c][0] for c in FLIGHT_COLUMNS])
    hi = np.array([ranges[c][1] for c in FLIGHT_COLUMNS])
    table = envelope.GridTable(**{c: tuple(getattr(env, c)) for c in FLIGHT_COLUMNS})
    grid = envelope.grid_points(table)[list(FLIGHT_COLUMNS)].to_numpy(float)
    points = np.vstack([(lo + hi) / 2.0, grid])
    fixed = dict(cell.fixed)
    for i, c in enumerate(FLIGHT_COLUMNS):
        if c in fixed:
            points[:, i] = fixed[c]
    if not space.realistic_only:
        return points[0]
    ok = space._realistic(points)
    if not ok.any():
        raise FalsifyError(f"cell {cell.group}/{cell.manoeuvre}: no realistic flight point "
                           "among the envelope's grid points (docs/physics.md §6); fix: widen "
                           "[envelope], or set [campaign] realistic_only = false")
    span = np.where(hi > lo, hi - lo, 1.0)
    dist = np.linalg.norm((points[ok] - (lo + hi) / 2.0) / span, axis=1)
    return points[ok][int(np.argmin(dist))]


@dataclass
class FalsifyResult:
    """What a search found (also written to ``DIR/search.parquet`` and ``DIR/worst.toml``)."""

    label: str
    search: pd.DataFrame            # one row per evaluated run
    worst: pd.Series                # the row of largest margin
    baseline_margin: float          # worst margin of the plain Monte Carlo (or --against)
    baseline_runs: int
    baseline_source: str
    errors: int
    #: what the margins measure: ``"decision"``, the distance to the alarm decision (margin
    #: ≥ 1 exactly when the run alarms; ``Capabilities.threshold_scale``), or
    #: ``"residual"``, a plugin's largest |r|/τ before its confirmation logic
    margin_kind: str = "decision"

    @property
    def false_alarms(self) -> int:
        """Searched runs in which the detector raised an alarm (its own decision, with its
        confirmation: a margin ≥ 1 that lasts less than the confirmation is no alarm)."""
        return int(self.search["false_alarm"].sum())

    @property
    def false_alarm(self) -> bool:
        return self.false_alarms > 0


def scores(results: pd.DataFrame, rows: pd.DataFrame, label: str):
    """Margin of *label* per row of *rows* (NaN for a run in error) and whether the
    detector raised a false alarm in it (scored, :func:`reports.scoring.metrics.score_runs`;
    False for a run in error)."""
    mine = results[results["detector"] == label].drop_duplicates("run_id")
    # plain arrays: a Series given to pd.Series(..., index=...) is reindexed by label
    ok = (mine["status"] == "ok").to_numpy()
    margin = pd.Series(np.where(ok, mine["margin"].to_numpy(float), np.nan),
                       index=mine["run_id"].to_numpy())
    alarm = pd.Series(ok & mine["false_alarm"].fillna(False).to_numpy(bool),
                      index=mine["run_id"].to_numpy())
    return (rows["run_id"].map(margin).to_numpy(float),
            rows["run_id"].map(alarm).fillna(False).to_numpy(bool))


def check_label(config: CampaignConfig, label: str) -> None:
    """*label* must name one of the campaign's detectors, a variant ``LABEL[…]`` of one
    (the variant itself is checked on the fitted detector) or one of its detection systems
    (``[[system]]``); :class:`FalsifyError` lists the labels and the systems."""
    base = label.split("[", 1)[0] if label.endswith("]") else label
    systems = tuple(getattr(config, "system_names", ()))
    if base not in config.detector_labels and label not in systems:
        also = f"; its detection systems: {', '.join(systems)}" if systems else ""
        raise FalsifyOptionError.of(
            "label", label, f"not a detector of campaign {config.campaign.name!r}; its "
            f"labels: {', '.join(config.detector_labels)}{also} (a detector with variants is "
            "named LABEL[variant] as in the results, e.g. comb-interval[a=0.9])")


def _mc_size_text(mc: pd.DataFrame, budget: int) -> str:
    """The size of the plain Monte Carlo *mc* beside the search's *budget*, as it is: whole
    runs per fault-free cell (:func:`monte_carlo_config`), so it may be below the budget."""
    runs = f"{len(mc)} fault-free run{'s' if len(mc) != 1 else ''}"
    if len(mc) == budget:
        return runs
    cells = mc.groupby(["group", "manoeuvre"], sort=False).ngroups
    return (f"{runs}: the budget of {budget} in whole runs per cell, {len(mc) // cells} in each "
            f"of {cells} cells" if len(mc) % cells == 0 else
            f"{runs} for the budget of {budget}, in whole runs per cell")


def monte_carlo_config(config: CampaignConfig, budget: int) -> CampaignConfig:
    """*config* reduced to its fault-free groups, as a Monte Carlo (Sobol) design of about
    *budget* runs (runs per manoeuvre = budget / cells, at least 1): the plain Monte Carlo
    the search is compared with."""
    data = config.to_dict()
    free = [g for g in data["group"] if g["fault"] == "none"]
    cells = sum(len(g["manoeuvres"]) for g in free)
    for g in free:
        g["count"] = max(1, budget // cells)
    data["group"] = free
    data.pop("run", None)
    data["campaign"]["design"] = "mc"
    data["campaign"].setdefault("sampler", "sobol")
    return CampaignConfig.from_dict(data, source=f"{config.source} (plain Monte Carlo)")


def worst_toml(config: CampaignConfig, runs: list[dict], *, label: str, note: str) -> str:
    """A campaign file replaying *runs* exactly: *config* with its groups replaced by one
    ``[[run]]`` each (every value as written by ``repr``, which TOML reads back to the same
    float). Checked by loading it back."""
    data = config.to_dict()
    data.pop("group")
    data["campaign"]["name"] = f"{config.campaign.name}-worst"
    data["campaign"]["description"] = (f"the {len(runs)} fault-free runs found by fdd-campaign "
                                       f"falsify for {label}: its false alarms first, "
                                       "then by largest margin")
    data["run"] = [{k: v for k, v in r.items() if v is not None} for r in runs]
    lines = [f"# {line}" for line in note.splitlines()] + [""]
    for sec, value in data.items():
        tables = value if isinstance(value, list) else [value]
        for table in tables:
            lines.append(f"[[{sec}]]" if isinstance(value, list) else f"[{sec}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
            lines.append("")
    text = "\n".join(lines)
    replay = CampaignConfig.from_dict(tomllib.loads(text), source="worst.toml")
    ids = explicit_plan(replay, replay.runs)["run_id"].tolist()
    if ids != explicit_plan(config, runs)["run_id"].tolist():
        raise AssertionError("worst.toml does not replay the runs it lists")  # a bug, not input
    return text


@one_blas_thread()
def falsify(config: CampaignConfig, label: str, *, budget: int, out, jobs: int = 2,
            seed: int = 0, scheduler: str | None = None, tls=None, fitted_from=None,
            against=None, keep: int = 10, log=None, progress=True) -> FalsifyResult:
    """Search the fault-free runs of *config* for the largest margin of detector *label*
    with at most *budget* simulated runs (module docstring); write ``out/search.parquet``,
    ``out/worst.toml`` (the *keep* worst runs) and the fitted detectors in ``out/learned``.

    The detectors are fitted on the campaign's learning set by the runner's code path
    (:func:`campaign.runner.prepare`), or taken from the campaign directory *fitted_from*.
    The worst margin is compared with that of a plain Monte Carlo of the same budget
    (:func:`monte_carlo_config`, run here: as many runs again, written to
    ``out/monte-carlo.parquet``), or with the worst fault-free margin of the campaign
    directory *against*.
    """
    from ..progress import Progress
    from ..runner import evaluate_rows, prepare

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    check_label(config, label)
    if isinstance(budget, bool) or not isinstance(budget, (int, np.integer)) or budget < 1:
        raise FalsifyOptionError.of("budget", budget,
                                    f"must be a whole number of runs ≥ {MIN_BUDGET}", 600)
    if isinstance(keep, bool) or not isinstance(keep, (int, np.integer)) or keep < 1:
        raise FalsifyOptionError.of("keep", keep, "must be a whole number ≥ 1 (runs written to "
                                    "worst.toml)", 10)
    if budget < MIN_BUDGET:
        raise FalsifyOptionError.of("budget", budget, f"too small; the search needs at least "
                                    f"{MIN_BUDGET} runs (screening, then the worst cell)", 600,
                                    f"or any other ≥ {MIN_BUDGET}")
    space = search_space(config)
    baseline, warm_rows = (_against(against, config, label, keep)
                           if against else (None, None))
    strategy = _strategy(space, config, budget, seed, warm_rows)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = SearchDir(out)
    setup, detectors = prepare(config, written.learned, jobs=jobs, scheduler=scheduler,
                               tls=tls, fitted_from=fitted_from, log=log)
    try:
        records: list[pd.DataFrame] = []
        state = {"done": 0, "errors": 0}
        worst = float("nan")
        bar = Progress(budget, enabled=progress, log=log)
        while batch := strategy.ask():
            phase = strategy.phase
            # on the campaign prepare resolved: its plant is not built again per batch
            rows = explicit_plan(setup.campaign, space.decode(space.vectors(batch)))
            results = evaluate_rows(setup, rows, detectors, log=log)
            if not state["done"]:
                _check_variant(results, label, config)
            margin, alarm = scores(results, rows, label)
            state["errors"] += int(np.isnan(margin).sum())
            records.append(rows.assign(margin=margin, false_alarm=alarm,
                                       generation=strategy.generation, phase=phase))
            state["done"] += len(rows)
            strategy.tell(batch, margin)
            if np.isfinite(margin).any():          # the running worst, not all records again
                worst = np.fmax(worst, float(np.nanmax(margin)))
            bar.label = f"{phase} (batch {len(records)}): "
            bar.update(len(rows), note=f", worst margin so far {worst:.4g}")
        search = pd.concat(records, ignore_index=True)
        if baseline is None:
            mc = build_plan(monte_carlo_config(config, budget)).iloc[:budget]
            log(f"plain Monte Carlo of about the same budget: {_mc_size_text(mc, budget)}")
            results = evaluate_rows(setup, mc, detectors, log=log)
            mc = mc.assign(margin=scores(results, mc, label)[0])
            written.write_monte_carlo(mc, config.to_json(), detector=label)
            baseline = (float(np.nanmax(mc["margin"])), len(mc),
                        f"a plain Monte Carlo of about the same budget "
                        f"({_mc_size_text(mc, budget)})")
    finally:
        setup.close()
    written.write_search(search, config.to_json(), detector=label, budget=budget, seed=seed,
                         dimensions=space.names,
                         strategy="sobol screening, CMA-ES on the worst cells, stream sweep")
    worst = _write_worst(config, search, label, keep, out, fitted_from, seed, budget)
    return FalsifyResult(label=label, search=search, worst=worst, baseline_margin=baseline[0],
                         baseline_runs=baseline[1], baseline_source=baseline[2],
                         errors=state["errors"], margin_kind=margin_kind(detectors, label))


def margin_kind(detectors: dict, label: str) -> str:
    """``"decision"`` when the fitted detector of *label* (``LABEL`` or ``LABEL[variant]``)
    declares a threshold scale (its margins are distances to the alarm decision), else
    ``"residual"`` (docs/design.md §5, Metrics)."""
    det = detectors.get(label.split("[", 1)[0] if label.endswith("]") else label)
    scaled = getattr(getattr(det, "capabilities", None), "threshold_scale", False)
    return "decision" if scaled else "residual"


def _check_variant(results: pd.DataFrame, label: str, config) -> None:
    names = list(dict.fromkeys(results["detector"]))
    if label not in names:
        raise FalsifyOptionError.of("label", label, f"not a detector of campaign "
                                    f"{config.campaign.name!r}; its results are named: "
                                    f"{', '.join(names)}")


def _against(directory, config, label, keep) -> tuple:
    """Worst fault-free margin of *label* in the campaign directory *directory* (the
    baseline), and the run-table rows of its *keep* worst fault-free runs (the warm start,
    :func:`_strategy`)."""
    from ..result import load
    from ..store.directory import CampaignDir

    camp = load(directory)
    # a batch of runs at a time, keeping the detector names, the count and largest margin
    # of the fault-free runs, and their `keep` worst rows (the worst of each batch, sorted
    # stably again: the worst of all)
    names, n_free, top, worst = set(), 0, math.nan, []
    for batch in camp.result_batches(columns=["fault", "status", "margin"], positions=True):
        names |= set(batch["detector"])
        free = batch[(batch["detector"] == label) & (batch["fault"] == "none")
                     & (batch["status"] == "ok")]
        if free.empty:
            continue
        n_free += len(free)
        top = np.fmax(top, free["margin"].max())
        worst.append(free.sort_values("margin", ascending=False, kind="stable").head(keep))
    names = sorted(names)
    if label not in names:
        raise FalsifyOptionError.of("against", str(directory), f"its results hold no detector "
                                    f"{label!r}; they hold: {', '.join(names)}")
    if not n_free:
        raise FalsifyOptionError.of("against", str(directory),
                                    f"no fault-free run of {label!r} to compare with")
    name = camp.name
    worst = (pd.concat(worst, ignore_index=True)
             .sort_values("margin", ascending=False, kind="stable").head(keep))
    # the plan rows of those runs alone, in their order (a run the plan lacks left out)
    at = worst["plan_pos"].to_numpy()
    at = at[at < CampaignDir(camp.root).planned_runs()]
    rows = camp.plan_rows(np.unique(at)).loc[at].reset_index(drop=True)
    return ((float(top), n_free,
             f"the {n_free} fault-free runs of {directory} (campaign {name!r})"), rows)


def drawn_start_s(seed: int, stream: int, duration_s: float) -> float:
    """The manoeuvre start [s] a run of campaign seed *seed* and *stream* draws when its
    ``manoeuvre_start_s`` is NaN: lead_s + u₀·start_spread_s, u₀ the first uniform of the
    run's manoeuvre generator (:func:`scenarios.runs.run_streams`, docs/physics.md §7),
    capped at duration_s − tail_s. Exact when the manoeuvre leaves at least
    start_spread_s of room in the record (the spread is then not shortened), else an
    upper estimate; used only to place a warm start, never to replay a run."""
    from scenarios.runs import run_streams

    p = MANOEUVRE_PARAMS
    u0 = float(run_streams(seed, stream)[0].random())
    return min(p.lead_s + u0 * p.start_spread_s, duration_s - p.tail_s)


def _strategy(space: SearchSpace, config, budget: int, seed: int, warm_rows):
    """The search strategy (:class:`campaign.evidence.falsify_search.Strategy`) over *space*; with
    *warm_rows* (``--against``) the campaign's worst runs as they ran (their stream, the
    start their manoeuvre model drew) open the screening, and a CMA-ES started at one of
    them starts at its drawn start (:func:`drawn_start_s`)."""
    from .falsify_search import Point, Strategy

    names = list(space.bounds)
    start_dim = names.index("manoeuvre_start_s") if "manoeuvre_start_s" in names else None
    warm, starts = [], {}
    if warm_rows is not None:
        for _, row in warm_rows.iterrows():
            cells = [i for i, c in enumerate(space.cells) if c.manoeuvre == row["manoeuvre"]]
            if not cells or int(row["seed"]) != int(config.campaign.seed):
                continue    # another campaign seed: its streams are other runs here
            unit = space.unit_of(row)
            if start_dim is not None and np.isnan(unit[start_dim]):
                lo, hi = space.bounds["manoeuvre_start_s"]
                t0 = drawn_start_s(int(row["seed"]), int(row["stream"]),
                                   float(config.campaign.duration_s))
                starts[len(warm)] = min(max((t0 - lo) / (hi - lo), 0.0), 1.0)
            warm.append(Point(tuple(unit), cells[0], int(row["stream"])))
    return Strategy(n_dims=len(names), n_cells=len(space.cells), budget=int(budget),
                    seed=int(seed), stream_span=STREAM_SPAN, warm=warm[:budget],
                    start_dim=start_dim, warm_start=starts)


def _write_worst(config, search, label, keep, out, fitted_from, seed, budget) -> pd.Series:
    ranked = (search.dropna(subset=["margin"]).sort_values("margin", ascending=False,
                                                            kind="stable")
              .drop_duplicates("run_id"))
    # the runs with a false alarm first (a regression corpus must hold them), then by margin
    corpus = ranked.sort_values("false_alarm", ascending=False, kind="stable")
    if ranked.empty:
        raise FalsifyError(f"every run of the search failed for {label!r}; see "
                           f"{SearchDir(out).search_path} and replay one with fdd-campaign "
                           "show")
    top = corpus.head(keep)
    runs = [{"group": SEARCH_GROUP, "manoeuvre": r["manoeuvre"], "fault": "none",
             **{c: float(r[c]) for c in FLIGHT_COLUMNS},
             "draws": {d: float(r[d]) for d in envelope.DRAW_COLUMNS},
             "stream": int(r["stream"]),
             "manoeuvre_start_s": (None if math.isnan(r["manoeuvre_start_s"])
                                   else float(r["manoeuvre_start_s"]))}
            for _, r in top.iterrows()]
    learned = SearchDir(out).learned
    replay = (f"fdd-campaign run worst.toml --out DIR fits the detectors again on the same\n"
              f"learning set; --fitted-from {learned} takes the ones the search used"
              if fitted_from is None else
              f"fdd-campaign run worst.toml --fitted-from {learned} --out DIR (the detectors\n"
              f"the search used, taken from {fitted_from})")
    note = (f"The {len(runs)} fault-free runs found by fdd-campaign falsify (seed {seed},\n"
            f"budget {budget}): those where {label} raised a false alarm first "
            f"({int(top['false_alarm'].sum())}), then by largest margin; margins "
            f"{', '.join(f'{m:.6g}' for m in top['margin'])}.\n"
            f"Replay (same margins): {replay}.")
    # atomic, and written last: a search directory with worst.toml holds a finished search
    SearchDir(out).write_worst(worst_toml(config, runs, label=label, note=note))
    return ranked.iloc[0]
