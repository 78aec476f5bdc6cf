"""Hazard per flight hour, both sides of a fault detector: the false alarms it raises and
the actuator faults it misses, as rates per flight hour set against the AMC 25.1309
budgets (docs/evidence.md, "Hazard per flight hour").

The combination is that of Hu, B. and Seiler, P. (2015), *A probabilistic method for
certification of analytically redundant systems*, International Journal of Applied
Mathematics and Computer Science 25(1), 103–116: the rate of a failure condition per
flight hour is the rate at which a component fault occurs times the probability that the
fault detection misses it, beside the rate of false alarms of the fault-free system.

For each detector (result-row name) and each fault type f the campaign ran:

* P_MD,f = missed/n over the faulty runs of type f (``status = "ok"``; missed: never
  detected within the detection window, the campaign's missed detection), with its exact
  one-sided Clopper–Pearson upper bound at *level* (:func:`reports.metrics.upper_bound`);
* λ_f [1/FH], the occurrence rate of fault mode f per flight hour
  (``[requirements] fault_rate_per_fh``; defaults :data:`DEFAULT_FAULT_RATES_PER_FH`);
* λ_u,f = λ_f · P_MD,f [1/FH], the rate of undetected faults of mode f, and its bound
  λ_f · P_MD,f^up (λ_f taken as known);
* the row ``fault = "all"``: Σ_f λ_u,f (fault modes exclusive, rates additive), whose
  bound is Σ_f λ_f · P_MD,f^up with each P_MD,f^up at 1 − (1 − level)/F (Bonferroni over
  the F fault types with λ_f > 0), so that the sum holds at *level* jointly;
* the false-alarm row (``fault = "none"``): the per-run probability k/n of the fault-free
  runs and its Clopper–Pearson bound turned into a rate by the exposure model of
  ``certify`` (false alarms a Poisson process of rate λ over flight time, a run of
  duration d [h] alarms with probability 1 − e^(−λd): λ = −ln(1 − p)/d);
* ``meets``: the most severe AMC 25.1309 category whose budget the row's upper bound does
  not exceed (:data:`AMC_25_1309_BUDGETS_PER_FH`), ``"none"`` when it exceeds all three.

Also, for the stricter reading that a fault detected after its required detection time
counts as undetected: ``late_or_missed`` and ``in_time_per_fh_upper95`` (λ_f times the
bound of (missed + detected with DTP > 1)/n).

Assumptions (printed with the table, :data:`ASSUMPTIONS`): fault modes occur as
independent Poisson processes over flight time, independently of the flight condition,
at most one at a time (λ_f ≪ 1/FH); the campaign's faulty runs of type f (their
magnitudes, onsets, flight points, manoeuvres and mismatch draws) stand for the
conditions in which f occurs in service; the runs are independent draws (for Sobol
designs the bounds are approximate, docs/evidence.md); a rate is per channel the campaign
simulates (for several monitored actuators, supply their sum); each detector is judged
alone, as the only monitor.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["AMC_25_1309_BUDGETS_PER_FH", "ASSUMPTIONS", "DEFAULT_FAULT_RATES_PER_FH",
           "HAZARD_COLUMNS", "hazard_table", "meets", "report_section"]

#: Occurrence rate of each actuator fault mode per flight hour [1/FH], the default of
#: ``[requirements] fault_rate_per_fh``. Estimates (est.): one order of magnitude for a
#: servo-control fault mode of a transport aircraft's surface actuator, 10⁻⁶/FH, and
#: 10⁻⁷/FH for a rod–surface disconnection (a structural failure); no published rate is
#: cited, and a user with in-service or FMEA figures replaces them.
DEFAULT_FAULT_RATES_PER_FH: dict[str, float] = {
    "runaway": 1e-6,           # est.
    "hardover": 1e-6,          # est.
    "liquid_jam": 1e-6,        # est.
    "solid_jam": 1e-6,         # est.
    "disconnection": 1e-7,     # est.
    "ofc_liquid": 1e-6,        # est.
    "ofc_solid": 1e-6,         # est.
}

#: Average probability per flight hour allowed for a failure condition of each severity
#: (AMC 25.1309, "Acceptable Means of Compliance" of CS-25: major < 10⁻⁵, hazardous
#: < 10⁻⁷, catastrophic < 10⁻⁹ per flight hour), least severe first.
AMC_25_1309_BUDGETS_PER_FH: dict[str, float] = {
    "major": 1e-5,
    "hazardous": 1e-7,
    "catastrophic": 1e-9,
}

#: Columns of the hazard table, one row per detector × fault type, plus ``"all"`` (the
#: undetected faults of every type) and ``"none"`` (the false alarms) per detector.
HAZARD_COLUMNS: tuple[str, ...] = (
    "detector", "fault", "n_runs", "events", "p_run", "p_run_upper95", "rate_per_fh",
    "per_fh", "per_fh_upper95", "meets", "late_or_missed", "in_time_per_fh_upper95",
    "level",
)

#: What the hazard table rests on, in words (printed by ``certify`` and the report).
ASSUMPTIONS: tuple[str, ...] = (
    "fault modes occur as independent Poisson processes over flight time at the rates of "
    "[requirements] fault_rate_per_fh, independently of the flight condition, one at a time",
    "the campaign's faulty runs of a type (magnitudes, onsets, flight points, manoeuvres, "
    "mismatch draws) stand for the conditions in which that fault occurs in service",
    "undetected = never detected within the detection window (the campaign's missed "
    "detection); 'in time' also counts a detection after the required time as undetected",
    "false alarms: a Poisson process over flight time, a run of duration d is d hours of "
    "exposure; the campaign's fault-free runs stand for the flight hours",
    "runs are independent draws (Sobol designs: approximate bounds); a rate is per "
    "simulated actuator channel; each detector is judged alone; the total's bound is "
    "Bonferroni-adjusted over the fault types",
)


def meets(rate_per_fh: float) -> str:
    """The most severe AMC 25.1309 category whose budget *rate_per_fh* does not exceed
    (``"catastrophic"``, ``"hazardous"``, ``"major"``), ``"none"`` above all of them,
    ``"n/a"`` for NaN."""
    if not rate_per_fh == rate_per_fh:
        return "n/a"
    out = "none"
    for name, budget in AMC_25_1309_BUDGETS_PER_FH.items():
        if rate_per_fh <= budget:
            out = name
    return out


def per_hour(p: float, duration_h: float) -> float:
    """λ = −ln(1 − p)/d [1/h] from a per-run probability *p* over runs of *duration_h* hours:
    the Poisson exposure model of ``certify`` and of this table (module docstring)."""
    if not (math.isfinite(p) and duration_h > 0):
        return math.nan
    return math.inf if p >= 1.0 else -math.log1p(-p) / duration_h


def hazard_table(results, plan: pd.DataFrame | None, rates: dict[str, float],
                 level: float = 0.95) -> pd.DataFrame:
    """The hazard table (:data:`HAZARD_COLUMNS`, module docstring) from a campaign's result
    rows and its run table *plan* (``run_id``, ``duration_s``), or from the
    :class:`campaign.evidence.certify_rows.CertifyRows` gathered from them a batch at a time
    (*plan* then unused), and the fault modes' rates *rates* [1/FH] (fault type → rate; a
    fault type of the campaign without a rate raises ValueError)."""
    from reports.metrics import FAULT_FREE, upper_bound

    from .certify_rows import CertifyRows

    if not 0.5 < float(level) < 1.0:
        raise ValueError(f"level {level!r} must be a confidence in (0.5, 1), e.g. 0.95")
    if isinstance(results, pd.DataFrame):
        results = CertifyRows.of_table(results, plan)
    names = results.ok_names()
    missing = sorted({f for name in names for f in results.faulty(name)} - set(rates))
    if missing:
        raise ValueError(f"no occurrence rate for fault type(s) {', '.join(missing)}; give "
                         "them in [requirements] fault_rate_per_fh")
    free_names = set(results.free_names())
    rows = []
    for detector in names:
        per_fault = []
        for fault, (n, missed, late) in results.faulty(detector).items():
            lam = float(rates[str(fault)])
            p_up = float(upper_bound(missed, n, level))
            per_fault.append({
                "detector": detector, "fault": str(fault), "n_runs": n, "events": missed,
                "p_run": missed / n, "p_run_upper95": p_up, "rate_per_fh": lam,
                "per_fh": lam * missed / n, "per_fh_upper95": lam * p_up,
                "meets": meets(lam * p_up), "late_or_missed": late,
                "in_time_per_fh_upper95": lam * float(upper_bound(late, n, level)),
                "level": float(level)})
        rows.extend(per_fault)
        if per_fault:
            rows.append(_total(per_fault, detector, float(level)))
        if detector in free_names:
            free = results.free(detector)
            n, k = len(free.margin), free.false_alarms
            d_h = float(np.nanmean(free.duration_s / 3600.0))
            p_up = float(upper_bound(k, n, level))
            rows.append({
                "detector": detector, "fault": FAULT_FREE, "n_runs": n, "events": k,
                "p_run": k / n, "p_run_upper95": p_up, "rate_per_fh": math.nan,
                "per_fh": per_hour(k / n, d_h), "per_fh_upper95": per_hour(p_up, d_h),
                "meets": meets(per_hour(p_up, d_h)), "late_or_missed": k,
                "in_time_per_fh_upper95": per_hour(p_up, d_h), "level": float(level)})
    out = pd.DataFrame(rows, columns=list(HAZARD_COLUMNS))
    for c in ("n_runs", "events", "late_or_missed"):
        out[c] = out[c].astype("int64")
    return out


def _total(per_fault: list[dict], detector: str, level: float) -> dict:
    """The ``"all"`` row: Σ λ_f P_MD,f and its Bonferroni bound over the fault types with a
    positive rate (module docstring)."""
    from reports.metrics import upper_bound

    counted = [r for r in per_fault if r["rate_per_fh"] > 0.0]
    joint = 1.0 - (1.0 - level) / max(len(counted), 1)
    bound = sum(r["rate_per_fh"] * float(upper_bound(r["events"], r["n_runs"], joint))
                for r in counted)
    in_time = sum(r["rate_per_fh"] * float(upper_bound(r["late_or_missed"], r["n_runs"], joint))
                  for r in counted)
    return {"detector": detector, "fault": "all",
            "n_runs": sum(r["n_runs"] for r in per_fault),
            "events": sum(r["events"] for r in per_fault), "p_run": math.nan,
            "p_run_upper95": math.nan,
            "rate_per_fh": sum(r["rate_per_fh"] for r in per_fault),
            "per_fh": sum(r["per_fh"] for r in per_fault), "per_fh_upper95": bound,
            "meets": meets(bound),
            "late_or_missed": sum(r["late_or_missed"] for r in per_fault),
            "in_time_per_fh_upper95": in_time, "level": level}


def report_section(hazard: pd.DataFrame | None) -> tuple | None:
    """What the report shows of a hazard table (:func:`reports.html.hazard_section`'s
    arguments: the table, the AMC 25.1309 budgets, :data:`ASSUMPTIONS`); None for None
    (``certify`` has not run)."""
    return None if hazard is None else (hazard, AMC_25_1309_BUDGETS_PER_FH, ASSUMPTIONS)
