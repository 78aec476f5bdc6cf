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
  order-statistic tolerance bound on the p99 DTP (:mod:`reports.survival`); NaN for
  fault-free rows.
* ``est_err_*``: the fault-estimation error f̂ − f of detectors that estimate the fault
  ([CHEN] §6.2; result columns :data:`reports.metrics.ESTIMATE_COLUMNS`), pooled over every
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

__all__ = ["ALL_FAULTS", "ALL_MANOEUVRES", "SUMMARY_COLUMNS", "summarize"]

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


def summarize(results: pd.DataFrame) -> pd.DataFrame:
    """Summary table of result rows (docs/design.md §5, Metrics; see the module docstring).

    Parameters
    ----------
    results : DataFrame
        Result rows (:data:`reports.metrics.RESULT_COLUMNS`); needs at least ``detector,
        fault, manoeuvre, status, false_alarm, detected, delay_s, dtp, margin``.

    Returns
    -------
    DataFrame with :data:`SUMMARY_COLUMNS`, sorted by detector, then fault (``none`` first,
    ``all-faults`` last), then manoeuvre (``all`` last).
    """
    missing = [c for c in _REQUIRED if c not in results.columns]
    if missing:
        raise ValueError(
            f"results lack column(s) {', '.join(missing)}; expected result rows with "
            f"columns {', '.join(_REQUIRED)}")
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
