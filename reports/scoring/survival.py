"""Detection time as survival data (docs/evidence.md, "Detection time as survival data").

A faulty run's detection delay is observed when the fault is detected within the detection
window, and *right-censored* at the end of the window when it is missed: the delay is then
only known to exceed the window. The Kaplan–Meier estimate (``scipy.stats.ecdf`` of
``scipy.stats.CensoredData``) uses both, where the delay statistics over detected runs
alone (``dtp_mean``, ``dtp_p95``) leave the misses out. Since every detection falls within
the window, each censoring time is above every observed delay, and the estimate below the
window's end does not depend on the window's length (the misses stay at risk throughout):
the curve then stops at 1 − (misses/runs), and a quantile above that level does not exist
(NaN).

* ``delay_km_median_s``, ``delay_km_p95_s``: the q-quantiles of the Kaplan–Meier
  distribution function F̂, inf{t : F̂(t) ≥ q} (a step function: no interpolation, so
  ``delay_km_p95_s`` may differ from the interpolated ``dtp_p95`` × required time);
* ``…_lo_s``/``…_hi_s``: their 95 % confidence interval, from the pointwise 95 % band of
  F̂ (``method="log-log"``): [inf{t : F_hi(t) ≥ q}, inf{t : F_lo(t) ≥ q}] (Brookmeyer and
  Crowley, *A confidence interval for the median survival time*, Biometrics 38, 1982,
  with the log-log band); NaN where the band never reaches q;
* ``dtp_p99_upper95``: a distribution-free upper tolerance bound, "99 % of the runs have
  DTP ≤ x, with 95 % confidence": x = the r-th smallest DTP of the n runs (a miss counting
  as +inf), r the smallest rank with P(Binomial(n, 0.99) ≤ r − 1) ≥ 0.95 (the r-th order
  statistic is above the 0.99-quantile exactly when at most r − 1 runs fall below it). It
  exists when n ≥ 299 (r = n needs 1 − 0.99ⁿ ≥ 0.95); NaN for fewer runs, +inf when the
  r-th run is a miss.

Assumptions: the runs are independent draws of one population (a Sobol design's runs are
not independent; see docs/evidence.md) and censoring is independent of the delay.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["SURVIVAL_COLUMNS", "kaplan_meier", "survival_stats", "tolerance_rank"]

#: Summary columns of this module (appended after the counting columns).
SURVIVAL_COLUMNS: tuple[str, ...] = (
    "delay_km_median_s", "delay_km_median_lo_s", "delay_km_median_hi_s",
    "delay_km_p95_s", "delay_km_p95_lo_s", "delay_km_p95_hi_s", "dtp_p99_upper95",
)


def kaplan_meier(delays, n_missed: int, confidence: float = 0.95):
    """(t, F̂(t), F_lo(t), F_hi(t)) at the distinct observed delays *delays* [s] with
    *n_missed* runs censored beyond them (module docstring); empty arrays without any
    detection."""
    from scipy.stats import CensoredData, ecdf

    events = np.asarray(delays, float)
    events = events[np.isfinite(events)]
    if events.size == 0:
        empty = np.empty(0)
        return empty, empty, empty, empty
    beyond = float(events.max()) + 1.0       # any time above every event: same estimate
    data = CensoredData(uncensored=events, right=np.full(int(n_missed), beyond))
    res = ecdf(data)
    t = np.unique(events)
    f = res.cdf.evaluate(t)
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)    # undefined where S = 0 or 1
        band = res.sf.confidence_interval(confidence, method="log-log")
        s_lo, s_hi = band.low.evaluate(t), band.high.evaluate(t)
    f_lo = np.where(np.isnan(s_hi), f, 1.0 - s_hi)
    f_hi = np.where(np.isnan(s_lo), f, 1.0 - s_lo)
    return t, f, f_lo, f_hi


def _first(t: np.ndarray, f: np.ndarray, q: float) -> float:
    hit = np.flatnonzero(f >= q - 1e-12)
    return float(t[hit[0]]) if hit.size else math.nan


def tolerance_rank(n: int, coverage: float = 0.99, confidence: float = 0.95) -> int | None:
    """The smallest rank r with P(Binomial(n, coverage) ≤ r − 1) ≥ confidence (the r-th
    smallest of n values bounds the *coverage*-quantile with that confidence), or None
    when even the largest does not (module docstring)."""
    from scipy.stats import binom

    if n < 1:
        return None
    ranks = np.arange(1, n + 1)
    ok = binom.cdf(ranks - 1, n, coverage) >= confidence
    return int(ranks[ok][0]) if ok.any() else None


def survival_stats(delays, dtps, n_missed: int) -> dict:
    """:data:`SURVIVAL_COLUMNS` of one group: the delays [s] and DTPs of its detected runs
    and its number of missed runs."""
    out = dict.fromkeys(SURVIVAL_COLUMNS, math.nan)
    t, f, f_lo, f_hi = kaplan_meier(delays, n_missed)
    if t.size:
        for q, name in ((0.5, "median"), (0.95, "p95")):
            out[f"delay_km_{name}_s"] = _first(t, f, q)
            out[f"delay_km_{name}_lo_s"] = _first(t, f_hi, q)
            out[f"delay_km_{name}_hi_s"] = _first(t, f_lo, q)
    d = np.asarray(dtps, float)
    d = d[np.isfinite(d)]
    n = d.size + int(n_missed)
    r = tolerance_rank(n)
    if r is not None:
        ordered = np.r_[np.sort(d), np.full(int(n_missed), np.inf)]
        out["dtp_p99_upper95"] = float(ordered[r - 1])
    return out
