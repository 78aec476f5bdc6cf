"""``fdd-campaign tradeoff``: a campaign's results at other thresholds, from its stored runs
(docs/thresholds.md, "Other thresholds from one campaign: tradeoff").

Every threshold of a detector multiplied by s (``[[detector]] threshold_scale = s``) moves
its first alarm to the first step where its decision statistic reaches s. A campaign stores
of each run what fixes it at the scales of :data:`reports.scoring.alarm_steps.ALARM_SCALES`: the
margin (false alarms, exact at every s) and the ``alarm_steps`` column (the first alarm of
each faulty run at each scale of the grid). From them this module computes, without
simulating anything:

* :func:`tradeoff`: one row per detector, fault type (``none`` for fault-free, then each
  fault type and ``all-faults``) and scale (:data:`TRADEOFF_COLUMNS`): the counts a campaign
  run at that scale would give (false alarms, misses, late detections), the Clopper–Pearson
  bound of the false alarms, the certified bound of ``certify`` where its curve has a level
  at or below the scale, the DTP quantiles and the delays; written to
  ``DIR/tradeoff.parquet``;
* :func:`operating_points`: per detector the scale that meets a false-alarm target with the
  fewest misses, then the shortest worst-case DTP;
* :func:`at_threshold_scales`: the campaign with some detectors at another scale, for
  ``gate --threshold-scale D=s``.

The results at scale 1 are the stored rows themselves (the campaign's own summary); at
another scale, those :func:`reports.scoring.alarm_steps.scaled_columns` computes, which are the rows
the campaign run with ``threshold_scale = s`` (and ``--fitted-from`` this directory) gives.
Result rows are read a batch of runs at a time: memory holds a batch, the plan's onsets and
durations, and the DTP and delay of each detected run at each scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from reports.scoring.alarm_steps import ALARM_SCALES, ALARM_STEPS_COLUMN, scaled_columns
from reports.scoring.metrics import FAULT_FREE, upper_bound
from reports.scoring.summary import ALL_FAULTS, SummaryAccumulator
from scenarios.errors import ArgumentError, InputError

from .evidence.hazard import per_hour
from .store.directory import CampaignDir

__all__ = ["SCALES", "TRADEOFF_COLUMNS", "Tradeoff", "TradeoffError", "TradeoffOptionError",
           "at_threshold_scales", "operating_points", "parse_scale_options", "parse_scales",
           "tradeoff"]

#: Every scale ``tradeoff`` can give: the stored grid and 1 (the campaign's own).
SCALES: tuple[float, ...] = tuple(sorted({1.0, *ALARM_SCALES}))

#: Columns of ``tradeoff.parquet``.
TRADEOFF_COLUMNS: tuple[str, ...] = (
    "detector", "fault", "scale", "threshold_scale", "n_runs", "n_unknown", "n_errors",
    "fa_count", "fa_rate", "fa_upper95", "fa_prob_certified_upper95", "certified_level",
    "fa_per_hour_upper95", "fa_per_hour_certified_upper95",
    "md_count", "md_rate", "late_count",
    "dtp_p50", "dtp_p95", "dtp_max", "delay_p50_s", "delay_p95_s", "delay_max_s",
)

#: The result columns read.
_COLUMNS = ["status", "fault", "false_alarm", "detected", "first_alarm_s", "delay_s", "dtp",
            "margin", ALARM_STEPS_COLUMN]


class TradeoffError(InputError, ValueError):
    """A directory or an option ``tradeoff`` (or ``gate --threshold-scale``) cannot use; the
    message says what and how to fix it (exit 2)."""


class TradeoffOptionError(TradeoffError, ArgumentError):
    """Scales (*scales* of :func:`parse_scales`, :func:`parse_scale_options` and
    :func:`at_threshold_scales`) or false-alarm targets (*max_fa_prob*, *max_fa_per_hour*
    of :func:`operating_points`) that cannot be used, named as Python names them;
    ``fdd-campaign`` names its options (:class:`scenarios.errors.ArgumentError`)."""


def parse_scales(text) -> tuple[float, ...]:
    """Scales from ``"0.8,1,1.25"``: sorted, distinct, each one of :data:`SCALES`;
    :class:`TradeoffOptionError` naming the argument *scales* otherwise."""
    items = [t.strip() for t in str(text).split(",") if t.strip()]
    if not items:
        raise TradeoffOptionError.said("{scales}: no scale given; choose among {known}",
                                       known=_scales_text())
    out = []
    for item in items:
        try:
            value = float(item)
        except ValueError:
            raise TradeoffOptionError.said(
                "{scales}: {item} is not a number; give scales separated by commas, e.g. "
                "{scales} 0.8,1,1.25", item=repr(item)) from None
        out.append(_stored_scale(value, "{scales}"))
    return tuple(sorted(set(out)))


def _scales_text() -> str:
    return ", ".join(f"{s:g}" for s in SCALES)


def _stored_scale(value: float, where: str, **values) -> float:
    """*value* as the stored scale it equals; :class:`TradeoffOptionError` otherwise, its
    message headed by *where* (an argument written ``{name}``, *values* filling the rest)."""
    for s in SCALES:
        if value == s:
            return s
    raise TradeoffOptionError.said(
        where + ": {value} is not a stored threshold scale; a campaign stores the first alarm "
        "of its runs at {known} (the R10 preferred numbers between 0.5 and 2), and only there "
        "are its detections known exactly; for another scale run the campaign with "
        "[[detector]] threshold_scale = s and {fitted_from} this directory",
        value=f"{value:g}", known=_scales_text(), **values)


def parse_scale_options(items) -> dict[str, float]:
    """``D=s`` items (repeatable or comma-separated) → {D: s}, the *scales* of
    :func:`at_threshold_scales`; :class:`TradeoffOptionError` naming that argument for an item
    it cannot read."""
    out: dict[str, float] = {}
    for item in items or ():
        for part in str(item).split(","):
            part = part.strip()
            if not part:
                continue
            name, eq, value = part.rpartition("=")
            if not eq or not name:
                raise TradeoffOptionError.said("{scales} {part}: give DETECTOR=SCALE, e.g. "
                                               "{scales} position-monitor=1.25",
                                               part=repr(part))
            try:
                scale = float(value)
            except ValueError:
                raise TradeoffOptionError.said("{scales} {part}: {value} is not a number",
                                               part=repr(part), value=repr(value)) from None
            out[name.strip()] = _stored_scale(scale, "{scales} {part}", part=part)
    return out


# ---- which detectors have a threshold scale ----------------------------------------------------
def _scaled_labels(config) -> dict[str, bool | None]:
    """[[detector]] label → whether its registered class declares a threshold scale (None:
    its class cannot be loaded here, a plugin not installed)."""
    from detectors.registry import DetectorSpecError, load_detector_class

    out: dict[str, bool | None] = {}
    for spec in config.detectors:
        try:
            caps = load_detector_class(spec.name).capabilities
            out[spec.label] = bool(getattr(caps, "threshold_scale", False))
        except (DetectorSpecError, ImportError, AttributeError):
            out[spec.label] = None
    # a detection system has a threshold scale when each of its members has one
    # (detectors.system.DetectionSystem)
    for system in getattr(config, "systems", ()):
        members = [out.get(m.split("[", 1)[0]) for m in system.members]
        out[system.name] = None if None in members else all(members)
    return out


def _has_scale(name: str, labels: dict, seen_steps: set) -> bool:
    """Whether result name *name* has a threshold scale: its [[detector]] class says so, or
    (a name that is no label's, e.g. a detection system; a plugin not installed) one of its
    faulty rows carries stored first alarms."""
    known = labels.get(name.split("[", 1)[0])
    return bool(known) if known is not None else name in seen_steps


# ---- reading the directory -------------------------------------------------------------------
@dataclass
class _Runs:
    """What scoring at another scale needs of the plan, by plan position: onset [s],
    required detection time [s] of the fault type, duration [s]."""

    onset: np.ndarray
    required: np.ndarray
    duration: np.ndarray


def _plan_runs(cdir: CampaignDir, config) -> _Runs:
    plan = cdir.read_plan(columns=["fault", "onset_s", "duration_s"])
    req = dict(config.requirements.detection_time_s)
    fault = plan["fault"].astype(str).to_numpy()
    return _Runs(onset=plan["onset_s"].to_numpy(float),
                 required=np.array([req.get(f, np.nan) for f in fault], dtype=float),
                 duration=plan["duration_s"].to_numpy(float))


def _opened(directory):
    """(Campaign, CampaignDir) of a finished campaign directory whose shards hold this
    version's scales (or none: a directory that predates the column)."""
    from .result import load

    camp = load(directory)
    cdir = CampaignDir(camp.root)
    _, seen = cdir.alarm_scales_stored()
    other = [s for s in seen if s is None or [float(v) for v in s] != list(ALARM_SCALES)]
    if other:
        raise TradeoffError(
            f"{camp.root}: its shards store first alarms at scales {other[0]}, this version "
            f"at {list(ALARM_SCALES)}; rerun the campaign into a new directory with this "
            "version (run --fitted-from reuses its fitted detectors)")
    return camp, cdir


def _at_scale(batch: pd.DataFrame, runs: _Runs, scale: float, ts: float) -> pd.DataFrame:
    """*batch* (result rows with ``plan_pos``) as scored at threshold × *scale*, with a
    ``known`` column; rows of runs outside the plan are not known."""
    pos = batch["plan_pos"].to_numpy()
    inside = pos < len(runs.onset)
    at = np.minimum(pos, max(len(runs.onset) - 1, 0))
    cols = scaled_columns(scale=scale, fault=batch["fault"].to_numpy(),
                          onset_s=np.where(inside, runs.onset[at], np.nan),
                          margin=pd.to_numeric(batch["margin"], errors="coerce").to_numpy(float),
                          steps=batch[ALARM_STEPS_COLUMN].to_numpy(object), ts=ts,
                          required_time_s=np.where(inside, runs.required[at], np.nan))
    cols["known"] = cols["known"] & inside
    out = batch.copy()
    for column, values in cols.items():
        out[column] = values
    return out


# ---- the table -------------------------------------------------------------------------------
@dataclass
class _Cell:
    """Counts and the detected runs' DTP and delays of one detector × fault × scale."""

    n_runs: int = 0
    n_unknown: int = 0
    n_errors: int = 0
    fa: int = 0
    md: int = 0
    late: int = 0
    dtp: list = field(default_factory=list)
    delay: list = field(default_factory=list)


@dataclass
class Tradeoff:
    """What :func:`tradeoff` found: the table, the detectors without a threshold scale, and
    notes for the reader (a directory that predates the stored first alarms)."""

    table: pd.DataFrame
    unscaled: list[str]
    notes: list[str]
    scales: tuple[float, ...]


def _add(cells: dict, key, rows: pd.DataFrame, known: np.ndarray) -> None:
    ok = rows["status"].astype(str).to_numpy() == "ok"
    faulty = rows["fault"].astype(str).to_numpy() != FAULT_FREE
    counted = ok & known
    detected = counted & faulty & rows["detected"].astype("boolean").fillna(False).to_numpy(
        dtype=bool)
    dtp = pd.to_numeric(rows["dtp"], errors="coerce").to_numpy(float)
    cell = cells.setdefault(key, _Cell())
    cell.n_runs += int(counted.sum())
    cell.n_unknown += int((ok & ~known).sum())
    cell.n_errors += int((~ok).sum())
    cell.fa += int((counted & rows["false_alarm"].astype("boolean").fillna(False)
                    .to_numpy(dtype=bool)).sum())
    cell.md += int((counted & faulty & ~detected).sum())
    cell.late += int((detected & ~(dtp <= 1.0)).sum())
    cell.dtp.append(dtp[detected])
    cell.delay.append(pd.to_numeric(rows["delay_s"], errors="coerce").to_numpy(float)[detected])


def _quantile(values: np.ndarray, q: float) -> float:
    return float(np.quantile(values, q)) if values.size else math.nan


def tradeoff(directory, scales=SCALES, confidence: float = 0.95) -> Tradeoff:
    """The trade-off table of the campaign in *directory* at *scales* (each one of
    :data:`SCALES`), from its stored rows (module docstring). Raises
    :class:`TradeoffError` for a directory it cannot read that way."""
    scales = tuple(sorted({_stored_scale(float(s), "scales") for s in scales}))
    camp, cdir = _opened(directory)
    config = camp.config
    ts = float(config.campaign.ts_s)
    runs = _plan_runs(cdir, config)
    labels = _scaled_labels(config)
    cells: dict = {}
    names: list[str] = []
    seen_steps: set = set()
    for batch in cdir.result_batches(columns=_COLUMNS, positions=True):
        faulty_steps = batch[(batch["fault"].astype(str) != FAULT_FREE)
                             & batch[ALARM_STEPS_COLUMN].notna()]
        seen_steps.update(faulty_steps["detector"].astype(str))
        for name, rows in batch.groupby("detector", sort=False):
            name = str(name)
            if name not in names:
                names.append(name)
            for scale in scales:
                if scale == 1.0:
                    scored, known = rows, np.ones(len(rows), dtype=bool)
                elif _has_scale(name, labels, seen_steps):
                    scored = _at_scale(rows, runs, scale, ts)
                    known = scored["known"].to_numpy(bool)
                else:
                    continue
                fault = scored["fault"].astype(str).to_numpy()
                for f in dict.fromkeys(fault):
                    sel = fault == f
                    _add(cells, (name, f, scale), scored[sel], known[sel])
                    if f != FAULT_FREE:
                        _add(cells, (name, ALL_FAULTS, scale), scored[sel], known[sel])
    free = runs.duration[np.isfinite(runs.duration)]
    mean_h = float(free.mean()) / 3600.0 if free.size else math.nan
    levels = cdir.read_certificate_levels()
    rows_out, notes, unscaled = [], [], []
    for name in names:
        scaled = _has_scale(name, labels, seen_steps)
        if not scaled:
            unscaled.append(name)
        faults = sorted({f for (n, f, _) in cells if n == name},
                        key=lambda f: (f != FAULT_FREE, f == ALL_FAULTS, f))
        for f in faults:
            for scale in scales:
                cell = cells.get((name, f, scale))
                if cell is None:
                    continue
                rows_out.append(_table_row(name, f, scale, scaled, cell, levels, mean_h,
                                           confidence))
        unknown = max([sum(c.n_unknown for (n, f, s), c in cells.items()
                           if n == name and f not in (ALL_FAULTS, FAULT_FREE) and s == scale)
                       for scale in scales if scale != 1.0] or [0])
        if scaled and unknown:
            notes.append(_predates_note(name, unknown, cdir.root))
    if not camp.complete:
        notes.append(f"the campaign is unfinished ({camp.runs_done} of {camp.runs_planned} "
                     "runs done): these are the counts of its finished runs; finish it by "
                     "running the same 'fdd-campaign run' command again")
    if unscaled:
        notes.append(f"no threshold scale (their decision is not a statistic compared with 1, "
                     f"or they give none): {', '.join(unscaled)}; given at scale 1 only, "
                     "with no curve")
    table = pd.DataFrame(rows_out, columns=list(TRADEOFF_COLUMNS))
    for c in ("n_runs", "n_unknown", "n_errors", "fa_count", "md_count", "late_count"):
        table[c] = table[c].astype("int64")
    return Tradeoff(table=table, unscaled=unscaled, notes=notes, scales=scales)


def _predates_note(name: str, unknown: int, root: Path) -> str:
    return (f"{name}: {unknown} faulty run(s) have no stored first alarms at other scales "
            "(written before this version stored them: the directory predates the "
            f"'{ALARM_STEPS_COLUMN}' column); its false alarms at every scale are exact "
            "(margins), its detections at scales other than 1 are not given. To get them, "
            f"rerun the campaign with this version: fdd-campaign run CAMPAIGN --out NEW "
            f"--fitted-from {root} (the same runs, the same fitted detectors)")


def _certified(levels: pd.DataFrame | None, name: str, scale: float) -> tuple[float, float]:
    """(bound, level) of ``certify``'s curve for *name* at the largest level ≤ *scale*: a
    valid bound of P(margin ≥ scale), since P(margin ≥ scale) ≤ P(margin ≥ level) for
    level ≤ scale; (NaN, NaN) without such a level."""
    if levels is None or levels.empty:
        return math.nan, math.nan
    mine = levels[(levels["detector"].astype(str) == name)
                  & (levels["level"].astype(float) <= scale)]
    if mine.empty:
        return math.nan, math.nan
    row = mine.loc[mine["level"].astype(float).idxmax()]
    return float(row["p_upper95"]), float(row["level"])


def _table_row(name, fault, scale, scaled, cell: _Cell, levels, mean_h, confidence) -> dict:
    n = cell.n_runs
    faulty = fault != FAULT_FREE
    dtp = np.concatenate(cell.dtp) if cell.dtp else np.empty(0)
    delay = np.concatenate(cell.delay) if cell.delay else np.empty(0)
    # detections at another scale are given only when every scored faulty run is known
    detection = faulty and not cell.n_unknown
    cp = float(upper_bound(cell.fa, n, confidence)) if n else math.nan
    cert, level = _certified(levels, name, scale) if not faulty else (math.nan, math.nan)
    nan = math.nan
    return {
        "detector": name, "fault": fault, "scale": float(scale), "threshold_scale": scaled,
        "n_runs": n, "n_unknown": cell.n_unknown, "n_errors": cell.n_errors,
        "fa_count": cell.fa, "fa_rate": cell.fa / n if n else nan, "fa_upper95": cp,
        "fa_prob_certified_upper95": cert, "certified_level": level,
        "fa_per_hour_upper95": per_hour(cp, mean_h) if not faulty else nan,
        "fa_per_hour_certified_upper95": per_hour(cert, mean_h) if not faulty else nan,
        "md_count": cell.md if faulty else 0,
        "md_rate": (cell.md / n if n else nan) if detection else nan,
        "late_count": cell.late if faulty else 0,
        "dtp_p50": _quantile(dtp, 0.5) if detection else nan,
        "dtp_p95": _quantile(dtp, 0.95) if detection else nan,
        "dtp_max": float(dtp.max()) if detection and dtp.size else nan,
        "delay_p50_s": _quantile(delay, 0.5) if detection else nan,
        "delay_p95_s": _quantile(delay, 0.95) if detection else nan,
        "delay_max_s": float(delay.max()) if detection and delay.size else nan,
    }


def write_tradeoff(directory, result: Tradeoff) -> Path:
    """Write *result*'s table to ``DIR/tradeoff.parquet`` (holding the directory's lock);
    returns its path."""
    from .result import load

    camp = load(directory)
    cdir = CampaignDir(camp.root)
    with cdir.locked():
        cdir.write_tradeoff(result.table, camp.config.to_json(),
                            scales=list(result.scales), unscaled=result.unscaled)
    return cdir.tradeoff_path


# ---- the operating point ---------------------------------------------------------------------
def operating_points(table: pd.DataFrame, *, max_fa_prob: float | None = None,
                     max_fa_per_hour: float | None = None) -> pd.DataFrame:
    """Per detector with a threshold scale: the scale whose false-alarm bound meets the
    target — per run *max_fa_prob*, or per flight hour *max_fa_per_hour* — with the fewest
    missed faulty runs, then the shortest worst-case DTP (``all-faults`` rows), then the
    largest scale. The bound is ``certify``'s where its curve gives one at that scale,
    else the Clopper–Pearson bound of the runs. A detector none of whose scales meets the
    target has ``scale`` NaN."""
    if (max_fa_prob is None) == (max_fa_per_hour is None):
        raise TradeoffOptionError.said("give one false-alarm target: {max_fa_prob} P (per "
                                       "run) or {max_fa_per_hour} R (per flight hour)")
    per_run = max_fa_prob is not None
    target = float(max_fa_prob if per_run else max_fa_per_hour)
    out = []
    for name, g in table.groupby("detector", sort=False):
        if not bool(g["threshold_scale"].iloc[0]):
            continue
        free = g[g["fault"] == FAULT_FREE].set_index("scale")
        faults = g[g["fault"] == ALL_FAULTS].set_index("scale")
        candidates = []
        for scale, r in free.iterrows():
            cert_col, cp_col = (("fa_prob_certified_upper95", "fa_upper95") if per_run else
                                ("fa_per_hour_certified_upper95", "fa_per_hour_upper95"))
            certified = np.isfinite(r[cert_col])
            bound = float(r[cert_col] if certified else r[cp_col])
            if not bound <= target:
                continue
            f = faults.loc[scale] if scale in faults.index else None
            md = int(f["md_count"]) if f is not None else 0
            dtp = float(f["dtp_max"]) if f is not None else math.nan
            if f is not None and not np.isfinite(f["md_rate"]):
                continue                    # detections not known at this scale
            candidates.append((md, dtp if np.isfinite(dtp) else math.inf, -scale, scale,
                               bound, "certified" if certified else "counted"))
        if candidates:
            md, dtp, _, scale, bound, how = min(candidates)
            out.append({"detector": name, "scale": scale, "fa_bound": bound,
                        "fa_bound_kind": how, "md_count": md,
                        "dtp_max": dtp if math.isfinite(dtp) else math.nan})
        else:
            out.append({"detector": name, "scale": math.nan, "fa_bound": math.nan,
                        "fa_bound_kind": "", "md_count": -1, "dtp_max": math.nan})
    return pd.DataFrame(out, columns=["detector", "scale", "fa_bound", "fa_bound_kind",
                                      "md_count", "dtp_max"])


# ---- gate at another scale -------------------------------------------------------------------
class _AtScales:
    """A :class:`campaign.result.Campaign` whose ``summary`` and ``gate_results`` are those
    of some detectors at other threshold scales; every other attribute is the campaign's."""

    def __init__(self, camp, summary: pd.DataFrame, gate_results: pd.DataFrame,
                 scales: dict):
        self._camp, self.summary, self.gate_results = camp, summary, gate_results
        self.threshold_scales = dict(scales)

    def __getattr__(self, name):
        return getattr(self._camp, name)

    def gate(self, *args, **kwargs):
        """:meth:`campaign.result.Campaign.gate` on these summary and gate rows."""
        from .result import Campaign

        return Campaign.gate(self, *args, **kwargs)


def at_threshold_scales(camp, scales: dict):
    """*camp* (a loaded :class:`campaign.result.Campaign`) with the detectors of *scales*
    (result name or [[detector]] label → scale of :data:`SCALES`) at those threshold scales:
    its summary and gate rows recomputed from the stored rows, a batch of runs at a time
    (:class:`reports.scoring.summary.SummaryAccumulator`, :func:`reports.scoring.gate.gate_rows`),
    as the campaign run at those scales would have them. :class:`TradeoffError` for a name that is
    no detector of the campaign, one without a threshold scale, or faulty runs whose first
    alarms at other scales are not stored."""
    from reports.scoring.gate import gate_rows

    if not scales:
        return camp
    camp, cdir = _opened(camp.root)
    names = list(dict.fromkeys(camp.summary["detector"].astype(str)))
    chosen: dict[str, float] = {}
    for key, scale in scales.items():
        hit = [n for n in names if n == key or n.split("[", 1)[0] == key]
        if not hit:
            raise TradeoffOptionError.said(
                "{scales} {item}: {key} is no detector of {root}; its detectors: {names}",
                item=f"{key}={scale:g}", key=repr(key), root=camp.root,
                names=", ".join(names))
        chosen.update({n: float(scale) for n in hit})
    labels = _scaled_labels(camp.config)
    ts = float(camp.config.campaign.ts_s)
    runs = _plan_runs(cdir, camp.config)
    acc, kept = SummaryAccumulator(), []
    for batch in cdir.result_batches(positions=True):
        if ALARM_STEPS_COLUMN not in batch:          # every shard predates the column
            batch[ALARM_STEPS_COLUMN] = None
        parts = []
        for name, rows in batch.groupby("detector", sort=False):
            scale = chosen.get(str(name), 1.0)
            if scale != 1.0:
                stored = set(rows.loc[rows[ALARM_STEPS_COLUMN].notna(), "detector"])
                if not _has_scale(str(name), labels, stored):
                    raise TradeoffOptionError.said(
                        "{scales}: {name} has no threshold scale (its decision is not a "
                        "statistic compared with 1); gate it at its own thresholds",
                        name=name)
                scored = _at_scale(rows, runs, scale, ts)
                unknown = (scored["status"] == "ok") & ~scored["known"]
                if unknown.any():
                    raise TradeoffError(_predates_note(str(name), int(unknown.sum()), camp.root))
                rows = scored.drop(columns="known")
            parts.append(rows)
        batch = pd.concat(parts).sort_index(kind="stable").drop(columns="plan_pos")
        acc.add(batch)
        kept.append(gate_rows(batch))
    gate = pd.concat(kept, ignore_index=True) if kept else pd.DataFrame()
    return _AtScales(camp, acc.summary(), gate, chosen)


# ---- the report's figures --------------------------------------------------------------------
def report_figures(camp, requirements: dict | None = None, notes: list | None = None) -> list:
    """The report's trade-off figures of *camp* (a loaded Campaign): one per fault type in
    the section "Detection per fault type" (:class:`reports.render.html.ReportFigure`), from the
    stored runs at every scale of :data:`SCALES`; *notes* receives the sentences that go
    with them (a directory that predates the stored first alarms). None for a campaign
    without faulty runs or without a detector with a threshold scale."""
    from reports.render.figures.report import figure_png
    from reports.render.html import ReportFigure
    from reports.render.figures.tradeoff import tradeoff_figure, tradeoff_points

    result = tradeoff(camp.root)
    table = result.table
    faults = sorted(set(table["fault"]) - {FAULT_FREE, ALL_FAULTS})
    max_dtp = (requirements or {}).get("max_dtp")
    figures = []
    for fault in faults:
        points = tradeoff_points(table, fault)
        if not points:
            continue
        fig = tradeoff_figure(points, title=f"{fault}: false alarms against detection time, "
                              "every threshold × the scale", max_dtp=max_dtp)
        figures.append(ReportFigure(
            "fault", fault, f"Threshold trade-off — {fault}",
            figure_png(fig),
            "Each detector at the threshold scales the campaign stores (every threshold × "
            f"{', '.join(f'{s:g}' for s in SCALES)}), computed from its stored runs "
            "(fdd-campaign tradeoff): the Clopper–Pearson bound of its fault-free false "
            "alarms (dotted: certify's bound where it has one) against the worst DTP of its "
            "detected runs; the ringed point is the campaign's own thresholds; a hollow "
            "point misses runs."))
    if notes is not None and faults:         # why a detector has no curve, among others
        notes.extend(f"Threshold trade-off: {n}" for n in result.notes)
    return figures
