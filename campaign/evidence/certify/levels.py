"""The exceedance curve of a certificate: P(margin ≥ level) of each detector at several
levels, with a bound that never claims more than the runs can carry (docs/evidence.md,
"The exceedance curve").

Per detector (result-row name) and level x, from the fault-free runs (``fault = "none"``,
``status = "ok"``) of a finished campaign:

* the estimate and its one-sided upper bound of :func:`detectors.tail.exceedance_curve`
  with the runs' manoeuvres as classes: counted where the runs reach x, each manoeuvre's own
  generalised Pareto tail beyond, combined with the manoeuvres' shares of the runs (the tail
  of a mixture is the mixture of the tails); the pooled counted bound when it is smaller;
* **the limit of the runs**: no bound is reported more than :data:`EXTRAPOLATION_DECADES`
  decades below the counting (exact Clopper–Pearson) bound of the runs at x. A model bound
  below that limit is replaced by the limit (``method = "limit of the runs"``), and the
  note says how many runs, or how much subset simulation (``--sampling``), would carry the
  model's bound; a point estimate below the limit is not given (NaN), only said to be below.

Written to ``DIR/certificate-levels.parquet`` (:data:`LEVEL_COLUMNS`), one row per detector
× level. Assumptions: those of :func:`detectors.tail.exceedance_curve` (independent runs,
each manoeuvre's tail generalised Pareto above its threshold) and of the counting bound.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from detectors.tail import exceedance_curve
from reports.scoring.metrics import upper_bound

from scenarios.errors import ArgumentError

from ..rare import P0

__all__ = ["DEFAULT_LEVELS", "EXTRAPOLATION_DECADES", "LEVEL_COLUMNS", "detector_rows",
           "level_table", "parse_levels", "runs_to_carry", "sampling_levels_to_reach"]

#: Margins of the curve by default; 1.0 is the false alarm (the certificate's own level).
DEFAULT_LEVELS: tuple[float, ...] = (0.6, 0.7, 0.8, 0.9, 1.0)

#: How far below the counting bound a model's bound may be reported without sampling
#: evidence [decades].
EXTRAPOLATION_DECADES = 2

#: Columns of ``certificate-levels.parquet``.
LEVEL_COLUMNS: tuple[str, ...] = (
    "detector", "level", "p_estimate", "p_upper95", "method", "n_runs", "n_exceed",
    "p_counted_upper95", "p_model_upper95", "tail_class", "confidence", "note",
)



def parse_levels(text) -> tuple[float, ...]:
    """Levels from ``"0.6,0.7,1.0"`` (or a sequence of numbers): sorted, distinct, each a
    positive finite margin; :class:`scenarios.errors.ArgumentError` (a ValueError) naming the
    argument *levels* of :func:`campaign.evidence.certify.certify` and the bad entry
    otherwise."""
    items = str(text).split(",") if isinstance(text, str) else list(text)
    out = []
    for item in items:
        try:
            v = float(item)
        except (TypeError, ValueError):
            raise ArgumentError.said("{levels}: {item} is not a number; give margins "
                                     "separated by commas, e.g. {levels} 0.6,0.7,0.8,0.9,1.0",
                                     item=repr(str(item).strip())) from None
        if not (math.isfinite(v) and v > 0.0):
            raise ArgumentError.said(f"{{levels}}: {v!r} is not a positive margin; a margin is "
                                     "max |r|/τ ≥ 0 and 1 is the false alarm, e.g. {levels} "
                                     "0.6,1.0")
        out.append(v)
    if not out:
        raise ArgumentError.said("{levels}: no level given, e.g. {levels} 0.6,0.7,0.8,0.9,1.0")
    return tuple(sorted(set(out)))


def runs_to_carry(p: float, confidence: float = 0.95) -> int:
    """The fewest runs whose counting bound at 0 exceedances is within
    :data:`EXTRAPOLATION_DECADES` decades of *p*: 1 − (1 − c)^(1/n) ≤ 10^D · p, i.e.
    n ≥ ln(1 − c)/ln(1 − 10^D · p) (about 3/(100 p) at 95 %)."""
    q = p * 10.0 ** EXTRAPOLATION_DECADES
    if q >= 1.0:
        return 1
    return max(1, math.ceil(math.log1p(-confidence) / math.log1p(-q)))


def sampling_levels_to_reach(p: float) -> int:
    """The levels subset simulation needs to reach a probability *p*
    (:data:`campaign.evidence.rare.P0` each):
    ⌈log(p)/log(p0)⌉."""
    return max(1, math.ceil(math.log(p) / math.log(P0) - 1e-9))


def _limit_note(model_up: float, limit: float, counted_up: float, n: int,
                confidence: float) -> str:
    runs = runs_to_carry(model_up, confidence)
    levels = sampling_levels_to_reach(model_up)
    return (f"the tail model's bound {model_up:.2g} is more than {EXTRAPOLATION_DECADES} "
            f"decades below the counting bound {counted_up:.2g} of the {n} runs: they cannot "
            f"carry it, the bound given is their limit {limit:.2g}; to carry {model_up:.2g}, "
            f"run about {runs} fault-free runs, or sample with --sampling (subset simulation: "
            f"about {levels} levels of p0 = {P0:g} to reach it)")


def detector_rows(name: str, margins, manoeuvres, levels, confidence: float = 0.95,
                  jobs: int = 1) -> list[dict]:
    """The rows of :data:`LEVEL_COLUMNS` of one detector from its fault-free runs' margins
    and manoeuvres (module docstring); *jobs*: threads for the manoeuvres' tail fits
    (:func:`detectors.tail.exceedance_curve`)."""
    m = np.asarray(margins, float)
    keep = np.isfinite(m)
    m, cls = m[keep], np.asarray(manoeuvres)[keep]
    n = int(m.size)
    rows = []
    if n == 0:
        for v in levels:
            rows.append({"detector": name, "level": float(v), "p_estimate": math.nan,
                         "p_upper95": math.nan, "method": "none", "n_runs": 0, "n_exceed": 0,
                         "p_counted_upper95": math.nan, "p_model_upper95": math.nan,
                         "tail_class": "", "confidence": float(confidence),
                         "note": "no fault-free run with a finite margin"})
        return rows
    curve = exceedance_curve(m, levels, classes=cls, confidence=confidence, jobs=jobs)
    for e in curve:
        counted_up = float(upper_bound(e.count, n, confidence))
        limit = counted_up / 10.0 ** EXTRAPOLATION_DECADES
        est, up, method = e.estimate, e.upper, e.method
        model_up = up if method != "counted" else math.nan
        tails = [(w * u, c) for c, how, _, u, w in e.parts if how == "tail"]
        tail_class = max(tails)[1] if tails else ""
        notes = []
        if method == "mixture":
            fitted = [c for _, c in sorted(tails, reverse=True)]
            rest = len(e.parts) - len(fitted)
            notes.append(f"mixture of {len(e.parts)} manoeuvres by their shares of the runs; "
                         + (f"tail fits for {', '.join(fitted)} (largest term first)"
                            + (f", {rest} counted" if rest else "")
                            if fitted else "every manoeuvre counted"))
        elif method == "counted":
            notes.append(f"{e.count} of {n} runs at or above {e.level:g} (exact "
                         "Clopper–Pearson bound)")
        if up < limit:
            notes.append(_limit_note(up, limit, counted_up, n, confidence))
            up, method = limit, "limit of the runs"
        if est < limit:
            if e.count == 0:
                notes.append(f"point estimate below the limit {limit:.2g} (not given)")
            est = math.nan
        rows.append({"detector": name, "level": e.level, "p_estimate": float(est),
                     "p_upper95": float(up), "method": method, "n_runs": n,
                     "n_exceed": int(e.count), "p_counted_upper95": counted_up,
                     "p_model_upper95": float(model_up), "tail_class": tail_class,
                     "confidence": float(confidence),
                     "note": "; ".join(notes)})
    return rows


def level_table(results, levels=DEFAULT_LEVELS, confidence: float = 0.95,
                jobs: int = 1) -> pd.DataFrame:
    """``certificate-levels.parquet`` (:data:`LEVEL_COLUMNS`) of a campaign's result rows
    (a DataFrame, or :class:`campaign.evidence.certify.rows.CertifyRows` gathered a batch at
    a time): one row per detector (result-row name) × level, detectors in the order of the
    results. *jobs*: threads for each detector's tail fits, one manoeuvre each at a time;
    the table does not depend on it."""
    from .rows import CertifyRows

    if isinstance(results, pd.DataFrame):
        results = CertifyRows.of_table(results)
    rows = []
    for name in results.free_names():
        free = results.free(name)
        rows += detector_rows(str(name), free.margin, free.manoeuvre, levels, confidence,
                              jobs=jobs)
    out = pd.DataFrame(rows, columns=list(LEVEL_COLUMNS))
    for c in ("n_runs", "n_exceed"):
        out[c] = out[c].astype("int64")
    return out
