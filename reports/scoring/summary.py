"""Aggregate result rows into rates, exact confidence bounds and DTP statistics.

One summary row per detector × fault × manoeuvre, plus aggregates (docs/design.md §5, Metrics, and
§6, Outputs; the layout of [CHEN] Tables 3–4):

* ``manoeuvre = "all"`` per detector × fault (e.g. the 1200 fault-free runs of a Monte Carlo
  campaign, or all runs of one fault type);
* ``fault = "all-faults"``, ``manoeuvre = "all"`` per detector: every faulty run.

Counting rules
--------------
* Only runs with ``status == "ok"`` are scored; ``n_runs`` counts them and is the
  denominator of every rate. Other runs are counted in ``n_errors`` and nowhere else.
* ``fa_count`` counts false alarms: any alarm in a fault-free run, an alarm before onset in
  a faulty run. Both are reported apart because rows are split by fault.
* ``md_*`` only concern faulty runs (``md_count`` 0 and the rate/bound NaN for
  ``fault = "none"``). A faulty run is **missed** when it is never detected within the
  detection window (``md_count``, ``md_rate``), and **late** when it is detected after its
  required detection time (DTP > 1, ``late_count``). ``md_req_*`` count the runs *not
  detected within the required time* — missed or late — the reading of a table whose MD
  and DTP together say "detected in time" ([CHEN] Tables 3–4).
* ``dtp_min/mean/max/p95`` and ``delay_min/mean/max_s`` (seconds after onset) are over
  detected runs only, so misses sit
  next to them in ``md_count``, and ``dtp_within`` is the share of all scored faulty runs
  with DTP ≤ 1, a miss counting as not within. ``dtp_p95`` uses linear interpolation
  between order statistics (numpy's default).
* ``worst_margin`` is the largest margin (max |r|/τ before onset) of the group.
* Appended: the detection delay as survival data, misses right-censored at the end of the
  window — Kaplan–Meier median and p95 delay with 95 % confidence intervals and an
  order-statistic tolerance bound on the p99 DTP (:mod:`reports.scoring.survival`); NaN for
  fault-free rows.
* ``est_err_*``: the fault-estimation error f̂ − f of detectors that estimate the fault
  ([CHEN] §6.2; result columns :data:`reports.scoring.metrics.ESTIMATE_COLUMNS`), pooled over every
  post-onset sample of the group's scored runs that have one (``est_err_runs`` of them):
  mean [mm] and population variance [mm²] of all those samples (the per-run means and
  variances combined exactly: N = Σnᵢ, mean = Σnᵢmᵢ/N, var = Σnᵢ(vᵢ + mᵢ²)/N − mean²), and
  the same normalised by the rod travel of the deflection range (``est_err_mean``,
  ``est_err_var``: fraction of the range and its square). The samples of one run are
  correlated in time, so the variance describes the spread of the error, not the
  uncertainty of its mean. NaN without samples (and for summaries of results written
  before these columns existed).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from .metrics import FAULT_FREE, upper_bound
from .survival import SURVIVAL_COLUMNS, survival_stats

__all__ = ["ALL_FAULTS", "ALL_MANOEUVRES", "SUMMARY_COLUMNS", "SummaryAccumulator",
           "detector_order", "natural_key", "summarize"]

#: ``fault`` of the per-detector aggregate over every faulty run.
ALL_FAULTS = "all-faults"
#: ``manoeuvre`` of the aggregates over manoeuvres.
ALL_MANOEUVRES = "all"

SUMMARY_COLUMNS: tuple[str, ...] = (
    "detector", "fault", "manoeuvre", "n_runs", "n_errors",
    "fa_count", "fa_rate", "fa_upper95",
    "md_count", "md_rate", "md_upper95",
    "late_count", "md_req_count", "md_req_rate", "md_req_upper95",
    "dtp_min", "dtp_mean", "dtp_max", "dtp_p95", "dtp_within",
    "delay_min_s", "delay_mean_s", "delay_max_s", "worst_margin",
    "est_err_runs", "est_err_mean_mm", "est_err_var_mm2", "est_err_mean", "est_err_var",
    *SURVIVAL_COLUMNS,
)

_REQUIRED = ("detector", "fault", "manoeuvre", "status", "false_alarm", "detected",
             "delay_s", "dtp", "margin")

_KEYS = ["detector", "fault", "manoeuvre"]


def _as_bool(series: pd.Series) -> np.ndarray:
    """Boolean values of a result column; missing values (error rows) read as False."""
    return series.astype("boolean").fillna(False).to_numpy(dtype=bool)


def _as_float(series: pd.Series) -> np.ndarray:
    return pd.to_numeric(series, errors="coerce").to_numpy(dtype=float)


def _per_row(results: pd.DataFrame) -> pd.DataFrame:
    """Per-run indicator columns; summing/reducing them per group gives the summary."""
    ok = results["status"].astype(str).to_numpy() == "ok"
    faulty = results["fault"].astype(str).to_numpy() != FAULT_FREE
    scored_faulty = ok & faulty
    detected = scored_faulty & _as_bool(results["detected"])
    dtp = _as_float(results["dtp"])
    est = _estimate_sums(results, ok)
    return pd.DataFrame({
        "detector": results["detector"].astype(str).to_numpy(),
        "fault": results["fault"].astype(str).to_numpy(),
        "manoeuvre": results["manoeuvre"].astype(str).to_numpy(),
        "ok": ok,
        "err": ~ok,
        "fa": ok & _as_bool(results["false_alarm"]),
        "miss": scored_faulty & ~detected,
        "late": detected & ~(dtp <= 1.0),
        "within": detected & (dtp <= 1.0),
        "dtp": np.where(detected, dtp, np.nan),
        "delay": np.where(detected, _as_float(results["delay_s"]), np.nan),
        "margin": np.where(ok, _as_float(results["margin"]), np.nan),
        **est,
    })


def _estimate_sums(results: pd.DataFrame, ok: np.ndarray) -> dict:
    """Per-row sums of the fault-estimation error whose group sums give the pooled mean
    and variance: n, Σe = n·m, Σe² = n·(v + m²), in mm and normalised by the range."""
    n_rows = len(results)
    if "est_err_n" not in results.columns:
        zero = np.zeros(n_rows)
        return {"e_runs": zero, "e_n": zero, "e_s1": zero, "e_s2": zero, "e_s1n": zero,
                "e_s2n": zero}
    n = np.nan_to_num(_as_float(results["est_err_n"]))
    m, v = _as_float(results["est_err_mean_mm"]), _as_float(results["est_err_var_mm2"])
    rng = _as_float(results["est_range_mm"])
    has = ok & (n > 0) & np.isfinite(m) & np.isfinite(v)
    n = np.where(has, n, 0.0)
    s1 = np.where(has, n * m, 0.0)
    s2 = np.where(has, n * (v + m * m), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        s1n = np.where(has, s1 / rng, 0.0)
        s2n = np.where(has, s2 / (rng * rng), 0.0)
    return {"e_runs": has.astype(float), "e_n": n, "e_s1": s1, "e_s2": s2, "e_s1n": s1n,
            "e_s2n": s2n}


def _aggregate(rows: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    grouped = rows.groupby(keys, sort=False, observed=True)
    out = grouped.agg(
        n_runs=("ok", "sum"),
        n_errors=("err", "sum"),
        fa_count=("fa", "sum"),
        md_count=("miss", "sum"),
        late_count=("late", "sum"),
        n_within=("within", "sum"),
        dtp_min=("dtp", "min"),
        dtp_mean=("dtp", "mean"),
        dtp_max=("dtp", "max"),
        delay_min_s=("delay", "min"),
        delay_mean_s=("delay", "mean"),
        delay_max_s=("delay", "max"),
        worst_margin=("margin", "max"),
        est_err_runs=("e_runs", "sum"),
        e_n=("e_n", "sum"), e_s1=("e_s1", "sum"), e_s2=("e_s2", "sum"),
        e_s1n=("e_s1n", "sum"), e_s2n=("e_s2n", "sum"),
    )
    out["dtp_p95"] = grouped["dtp"].quantile(0.95)
    def as_key(key):
        return key if isinstance(key, tuple) else (key,)

    surv = {as_key(key): survival_stats(g["delay"].to_numpy(), g["dtp"].to_numpy(),
                                        int(g["miss"].sum()))
            if not (g["fault"] == FAULT_FREE).all() else dict.fromkeys(SURVIVAL_COLUMNS, np.nan)
            for key, g in grouped}
    for c in SURVIVAL_COLUMNS:
        out[c] = [surv[as_key(key)][c] for key in out.index]
    return out.reset_index()


_NUMBER = re.compile(r"\d+(?:\.\d+)?")


def natural_key(name: str) -> str:
    """The natural-sort key of *name*: *name* with each number zero-padded, so variants sort
    by value (a=0.9 before a=0.95, a=0.95 before a=0.99, a=2 before a=10); a string, so it
    serves ``sorted`` and a pandas sort alike."""
    return _NUMBER.sub(lambda m: f"{float(m.group()):024.9f}", name)


def detector_order(names) -> list[str]:
    """*names* (detector result names, detection systems' among them) once each, in the one
    order every output lists detectors in: by name, numbers by value (:func:`natural_key`:
    ``comb-interval[a=0.9]`` before ``comb-interval[a=0.95]``) — the summary's order, which
    ``run``, ``gate``, ``compare``, ``show``, ``certify``, the report and
    ``repr(Campaign)`` follow (docs/report.md)."""
    return sorted(dict.fromkeys(str(n) for n in names), key=natural_key)


def _sort_key(column: pd.Series) -> pd.Series:
    """Order: detectors by name with numbers by value; fault-free first, fault types
    alphabetically, aggregates last."""
    if column.name == "detector":
        return column.map(natural_key)
    if column.name == "fault":
        rank = np.select([column == FAULT_FREE, column == ALL_FAULTS], [0, 2], 1)
    elif column.name == "manoeuvre":
        rank = np.where(column == ALL_MANOEUVRES, 1, 0)
    else:
        return column
    return pd.Series([f"{r}{v}" for r, v in zip(rank, column)], index=column.index)


def _check_columns(results: pd.DataFrame) -> None:
    missing = [c for c in _REQUIRED if c not in results.columns]
    if missing:
        raise ValueError(
            f"results lack column(s) {', '.join(missing)}; expected result rows with "
            f"columns {', '.join(_REQUIRED)}")


def summarize(results: pd.DataFrame) -> pd.DataFrame:
    """Summary table of result rows (docs/design.md §5, Metrics; see the module docstring).

    Parameters
    ----------
    results : DataFrame
        Result rows (:data:`reports.scoring.metrics.RESULT_COLUMNS`); needs at least ``detector,
        fault, manoeuvre, status, false_alarm, detected, delay_s, dtp, margin``.

    Returns
    -------
    DataFrame with :data:`SUMMARY_COLUMNS`, sorted by detector, then fault (``none`` first,
    ``all-faults`` last), then manoeuvre (``all`` last).
    """
    _check_columns(results)
    if len(results) == 0:
        return pd.DataFrame({c: pd.Series(dtype=_dtype(c)) for c in SUMMARY_COLUMNS})

    rows = _per_row(results)
    finest = _aggregate(rows, _KEYS)
    per_fault = _aggregate(rows, ["detector", "fault"]).assign(manoeuvre=ALL_MANOEUVRES)
    faulty_rows = rows[rows["fault"] != FAULT_FREE]
    parts = [finest, per_fault]
    if len(faulty_rows):
        parts.append(_aggregate(faulty_rows, ["detector"])
                     .assign(fault=ALL_FAULTS, manoeuvre=ALL_MANOEUVRES))
    return _finish(parts)


def _finish(parts: list[pd.DataFrame]) -> pd.DataFrame:
    """The summary table from the group aggregates of :func:`_aggregate` (finest, per fault,
    all faults): counts, rates, bounds and the estimation error's moments; sorted."""
    out = pd.concat(parts, ignore_index=True)

    out["md_req_count"] = out["md_count"] + out["late_count"]
    with np.errstate(invalid="ignore", divide="ignore"):
        n_e = np.where(out["e_n"] > 0, out["e_n"], np.nan)
        for suffix, s1, s2 in (("_mm", "e_s1", "e_s2"), ("", "e_s1n", "e_s2n")):
            mean = out[s1] / n_e
            out[f"est_err_mean{suffix}"] = mean
            out[f"est_err_var{'_mm2' if suffix else ''}"] = np.maximum(
                out[s2] / n_e - mean * mean, 0.0)
    for c in ("n_runs", "n_errors", "fa_count", "md_count", "late_count", "md_req_count",
              "n_within", "est_err_runs"):
        out[c] = out[c].astype("int64")
    n = out["n_runs"].to_numpy()
    has_runs = n > 0
    is_faulty = (out["fault"] != FAULT_FREE).to_numpy()
    md_n = np.where(is_faulty, n, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out["fa_rate"] = np.where(has_runs, out["fa_count"] / np.maximum(n, 1), np.nan)
        out["md_rate"] = np.where(md_n > 0, out["md_count"] / np.maximum(md_n, 1), np.nan)
        out["md_req_rate"] = np.where(md_n > 0, out["md_req_count"] / np.maximum(md_n, 1),
                                      np.nan)
        out["dtp_within"] = np.where(md_n > 0, out["n_within"] / np.maximum(md_n, 1), np.nan)
    out["fa_upper95"] = upper_bound(out["fa_count"].to_numpy(), n)
    out["md_upper95"] = upper_bound(np.where(is_faulty, out["md_count"], 0), md_n)
    out["md_req_upper95"] = upper_bound(np.where(is_faulty, out["md_req_count"], 0), md_n)

    out = out.sort_values(_KEYS, key=_sort_key, kind="stable", ignore_index=True)
    return out.loc[:, list(SUMMARY_COLUMNS)]


def _dtype(column: str) -> str:
    if column in ("detector", "fault", "manoeuvre"):
        return "object"
    if column in ("n_runs", "n_errors", "fa_count", "md_count", "late_count", "md_req_count",
                  "est_err_runs"):
        return "int64"
    return "float64"


_COUNTS = {"n_runs": "ok", "n_errors": "err", "fa_count": "fa", "md_count": "miss",
           "late_count": "late", "n_within": "within", "est_err_runs": "e_runs"}
_TIMES = ("dtp", "delay")
_SUMS = ("e_n", "e_s1", "e_s2", "e_s1n", "e_s2n")
#: The three groupings of the summary: detector × fault × manoeuvre, detector × fault (both
#: over every row), and detector over the faulty rows.
_LEVELS = ("finest", "fault", "faulty")
_LEVEL_KEYS = {"finest": _KEYS, "fault": ["detector", "fault"], "faulty": ["detector"]}


class _Layout:
    """What decides how pandas sums a column per group (``groupby(sort=False)``): when the
    groups' rows are contiguous and the column holds no NaN it adds each group's run of
    values with ``np.add.reduceat`` (pairwise), else it adds them one by one with a
    compensation (skipping NaN). Followed over the rows of one grouping, batch by batch."""

    def __init__(self):
        self.contiguous = True
        self.current = None
        self.seen: set = set()
        self.nan: set[str] = set()          # columns that held a NaN

    def add(self, keys: np.ndarray, values: dict) -> None:
        self.nan.update(c for c, v in values.items() if np.isnan(v).any())
        if not self.contiguous or len(keys) == 0:
            return
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        for key in keys[starts].tolist():
            if key == self.current:
                continue
            if key in self.seen:
                self.contiguous = False
                return
            self.seen.add(key)
            self.current = key

    def reduceat(self, column: str) -> bool:
        return self.contiguous and column not in self.nan


class SummaryAccumulator:
    """:func:`summarize` of result rows handed over a batch at a time (:meth:`add`), in the
    order :func:`summarize` would read them, without holding the rows.

    Kept between batches: per detector × fault × manoeuvre the counts and the largest margin
    (sums and maxima of the batches' own); the DTP and delay of each detected run (the
    quantile and the Kaplan–Meier statistics need every one: 20 bytes per detected run,
    none in a fault-free campaign); the estimation-error sums (:func:`_estimate_sums`) of a
    detector's rows from its first row with an estimate on, and how many zero rows came
    before; and, per grouping, whether its groups' rows were contiguous and which columns
    held a NaN (:class:`_Layout`), which decide how pandas adds a column. The table is the
    one :func:`summarize` computes from all the rows at once, to the bit: counts, minima,
    maxima and quantiles do not depend on how the rows are cut, and every mean and sum adds
    the same terms in the same order by the same method — the rows left out are NaN, which
    the compensated sum skips, or zeros before any other value of their group, which it
    adds as no change and which are put back where the pairwise sum would see them."""

    def __init__(self):
        self._keys: list[tuple] = []           # group code → (detector, fault, manoeuvre)
        self._code: dict[tuple, int] = {}
        self._counts: pd.DataFrame | None = None
        self._times: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._sums: list[pd.DataFrame] = []
        self._estimating: set[str] = set()
        self._skipped = np.zeros(0, dtype=np.int64)   # per group code: zero rows not kept
        self._layout = {level: _Layout() for level in _LEVELS}
        self._key_dtypes = None

    def add(self, results: pd.DataFrame) -> None:
        """Take in a batch of result rows (the next rows in order)."""
        _check_columns(results)
        if len(results) == 0:
            return
        rows = _per_row(results)
        grouped = rows.groupby(_KEYS, sort=False, observed=True)
        counts = grouped.agg(**{k: (c, "sum") for k, c in _COUNTS.items()},
                             worst_margin=("margin", "max"))
        if self._key_dtypes is None:
            self._key_dtypes = {k: rows[k].dtype for k in _KEYS}
        local = np.array([self._code_of(key) for key in counts.index], dtype=np.int64)
        counts.index = local
        codes = local[grouped.ngroup().to_numpy()]
        self._follow_layout(rows, codes)
        if self._counts is None:
            self._counts = counts
        else:
            both = pd.concat([self._counts, counts])
            self._counts = both.groupby(level=0, sort=False).agg(
                **{k: (k, "sum") for k in _COUNTS}, worst_margin=("worst_margin", "max"))
        dtp, delay = rows["dtp"].to_numpy(), rows["delay"].to_numpy()
        detected = ~(np.isnan(dtp) & np.isnan(delay))
        if detected.any():
            self._times.append((codes[detected], dtp[detected], delay[detected]))
        has = rows["e_runs"].to_numpy() > 0
        seen = rows["detector"].isin(list(self._estimating)).to_numpy()
        if has.any():     # from a detector's first row with an estimate on
            seen = seen | pd.Series(has).groupby(rows["detector"].to_numpy()).cummax().to_numpy()
            self._estimating.update(rows.loc[has, "detector"])
        if seen.any():
            self._sums.append(pd.DataFrame({"code": codes[seen],
                                            **{c: rows[c].to_numpy()[seen] for c in _SUMS}}))
        skipped = np.bincount(codes[~seen], minlength=len(self._keys))
        self._skipped = np.r_[self._skipped, np.zeros(len(skipped) - len(self._skipped),
                                                      dtype=np.int64)] + skipped

    def _code_of(self, key: tuple) -> int:
        if key not in self._code:
            self._code[key] = len(self._keys)
            self._keys.append(key)
        return self._code[key]

    def _follow_layout(self, rows: pd.DataFrame, codes: np.ndarray) -> None:
        """Each grouping's groups in row order (:class:`_Layout`), its keys as hashes of the
        key tuples so that batches agree on them."""
        values = {c: rows[c].to_numpy() for c in (*_TIMES, *_SUMS)}
        per_fault = np.array([hash(key[:2]) for key in self._keys], dtype=np.int64)
        per_detector = np.array([hash(key[0]) for key in self._keys], dtype=np.int64)
        faulty = rows["fault"].to_numpy() != FAULT_FREE
        self._layout["finest"].add(codes, values)
        self._layout["fault"].add(per_fault[codes], values)
        self._layout["faulty"].add(per_detector[codes[faulty]],
                                   {c: v[faulty] for c, v in values.items()})

    def summary(self) -> pd.DataFrame:
        """The summary table of every row added (:data:`SUMMARY_COLUMNS`)."""
        if self._counts is None:
            return pd.DataFrame({c: pd.Series(dtype=_dtype(c)) for c in SUMMARY_COLUMNS})
        keys = pd.DataFrame(self._keys, columns=_KEYS).astype(self._key_dtypes)
        counts = keys.join(self._counts.sort_index(), how="inner")
        counts.index.name = "code"

        def with_keys(frame: pd.DataFrame) -> pd.DataFrame:
            named = keys.iloc[frame["code"].to_numpy()].reset_index(drop=True)
            return pd.concat([named, frame.drop(columns="code")], axis=1)
        empty = {"code": np.empty(0, dtype=np.int64)}
        times = with_keys(pd.DataFrame(
            {"code": np.concatenate([c for c, _, _ in self._times]),
             "dtp": np.concatenate([d for _, d, _ in self._times]),
             "delay": np.concatenate([d for _, _, d in self._times])}
            if self._times else {**empty, "dtp": np.empty(0), "delay": np.empty(0)}))
        # an estimating detector's zero rows before its first estimate, put back in front
        estimating = np.array([key[0] in self._estimating for key in self._keys], dtype=bool)
        skipped = np.where(estimating[:len(self._skipped)], self._skipped, 0)
        lead = np.repeat(np.arange(len(skipped)), skipped)
        zeros = pd.DataFrame({"code": lead, **{c: np.zeros(len(lead)) for c in _SUMS}})
        sums = with_keys(pd.concat([zeros, *self._sums], ignore_index=True))
        faulty = counts["fault"] != FAULT_FREE
        parts = [self._level(counts, times, sums, "finest"),
                 self._level(counts, times, sums, "fault").assign(manoeuvre=ALL_MANOEUVRES)]
        if faulty.any():
            parts.append(self._level(counts[faulty], times[times["fault"] != FAULT_FREE],
                                     sums[sums["fault"] != FAULT_FREE], "faulty")
                         .assign(fault=ALL_FAULTS, manoeuvre=ALL_MANOEUVRES))
        return _finish(parts)

    def _level(self, counts: pd.DataFrame, times: pd.DataFrame, sums: pd.DataFrame,
               level: str) -> pd.DataFrame:
        """:func:`_aggregate`'s table at one grouping, from the kept parts."""
        keys, layout = _LEVEL_KEYS[level], self._layout[level]
        out = counts.groupby(keys, sort=False, observed=True).agg(
            **{k: (k, "sum") for k in _COUNTS}, worst_margin=("worst_margin", "max"))
        t = _with_nan_group(times, keys).groupby(keys, sort=False, observed=True)
        stats = t.agg(dtp_min=("dtp", "min"), dtp_mean=("dtp", "mean"),
                      dtp_max=("dtp", "max"), delay_min_s=("delay", "min"),
                      delay_mean_s=("delay", "mean"), delay_max_s=("delay", "max"))
        stats["dtp_p95"] = t["dtp"].quantile(0.95)
        for column, name in (("dtp", "dtp_mean"), ("delay", "delay_mean_s")):
            if layout.reduceat(column):
                total, size = _reduceat(times, keys, column)
                stats.loc[total.index, name] = total / size
        out = out.join(stats)
        e = _with_nan_group(sums, keys).groupby(keys, sort=False, observed=True)[
            list(_SUMS)].sum()
        for column in _SUMS:
            if layout.reduceat(column):
                e.loc[:, column] = np.nan
                total, _ = _reduceat(sums, keys, column)
                e.loc[total.index, column] = total
        out = out.join(e)
        out[list(_SUMS)] = out[list(_SUMS)].fillna(0.0)

        def as_key(key):
            return key if isinstance(key, tuple) else (key,)
        groups = {as_key(key): g for key, g in times.groupby(keys, sort=False)}
        surv = []
        for key, row in out.iterrows():
            key = as_key(key)
            if len(key) > 1 and key[1] == FAULT_FREE:     # keys[1] is "fault"
                surv.append(dict.fromkeys(SURVIVAL_COLUMNS, np.nan))
                continue
            g = groups.get(key)
            delay, dtp = ((g["delay"].to_numpy(), g["dtp"].to_numpy()) if g is not None
                          else (np.empty(0), np.empty(0)))
            surv.append(survival_stats(delay, dtp, int(row["md_count"])))
        for c in SURVIVAL_COLUMNS:
            out[c] = [s[c] for s in surv]
        return out.reset_index()


#: Key of the extra group :func:`_with_nan_group` adds (no detector is named so).
_NAN_GROUP = "\x00"


def _with_nan_group(frame: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """*frame* with one more row, of a group of its own (dropped from the result) whose
    values are NaN: pandas then adds every float column with its compensated sum, which
    skips NaN, whatever the layout of the other groups."""
    extra = pd.DataFrame({**{k: [_NAN_GROUP] for k in keys},
                          **{c: [np.nan] for c in frame.columns if c not in _KEYS}})
    out = pd.concat([frame, extra.astype({k: frame[k].dtype for k in keys})],
                    ignore_index=True)
    return out


def _reduceat(frame: pd.DataFrame, keys: list[str], column: str):
    """Per group of *keys*: the sum of *column* as pandas adds a group's contiguous run of
    values (``np.add.reduceat``), and the group's size."""
    ordered = frame.assign(_g=frame.groupby(keys, sort=False).ngroup()).sort_values(
        "_g", kind="stable")
    groups = ordered["_g"].to_numpy()
    starts = np.flatnonzero(np.r_[True, groups[1:] != groups[:-1]]) if len(groups) else \
        np.empty(0, dtype=np.intp)
    index = ordered.iloc[starts].set_index(keys).index
    values = ordered[column].to_numpy(dtype=np.float64)
    total = np.add.reduceat(values, starts) if len(starts) else np.empty(0)
    size = np.diff(starts, append=len(values)).astype(np.float64)
    return pd.Series(total, index=index), size
