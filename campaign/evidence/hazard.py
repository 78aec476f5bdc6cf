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
  one-sided Clopper–Pearson upper bound at *level* (:func:`reports.scoring.metrics.upper_bound`);
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
* what the detector is credited with: the undetected rate **without** the detector is λ_f
  (every fault of mode f goes undetected), **with** it the bound λ_f · P_MD,f^up. A
  category of AMC 25.1309 (:data:`AMC_25_1309_BUDGETS_PER_FH`) is *credited* to the
  detector only where the bound with it is under that category's budget and λ_f alone is
  not (:func:`credit`); a row whose category λ_f meets alone says so ("met by the fault
  rate alone, no credit"); a detector that detected none of the row's runs is credited
  nothing; a bound that cannot separate the categories — P_MD,f^up above
  :data:`WIDEST_CREDITED_BOUND`, or with the detector in the same category as without —
  shows nothing ("not shown"). The ``meets_*`` columns name the most severe category
  whose budget a rate does not exceed, ``"none"`` when it exceeds all three.

Also, for the stricter reading that a fault detected after its required detection time
counts as undetected: ``late_or_missed`` and ``in_time_per_fh_upper95`` (λ_f times the
bound of (missed + detected with DTP > 1)/n), credited by the same rule
(``meets_in_time``, ``credited_in_time``, ``claim_in_time``).

Every rate says where it comes from (``rate_source``): a rate equal to its default in
:data:`DEFAULT_FAULT_RATES_PER_FH` is an estimate of this project, a placeholder
(:data:`RATE_PLACEHOLDER`), whether or not the campaign file wrote it (the stored campaign
holds the merged table); any other rate is the campaign file's (:data:`RATE_GIVEN`). Every
bound says which it is (``bound``): all are counting bounds (exact one-sided
Clopper–Pearson), the model bounds of the false alarms being the certificate's.

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
           "HAZARD_COLUMNS", "RATE_GIVEN", "RATE_PLACEHOLDER", "WIDEST_CREDITED_BOUND",
           "credit", "hazard_table", "meets", "rate_source", "report_section",
           "with_claims"]

#: Occurrence rate of each actuator fault mode per flight hour [1/FH], the default of
#: ``[requirements] fault_rate_per_fh``. Placeholders (est.): one order of magnitude for a
#: servo-control fault mode of a transport aircraft's surface actuator, 10⁻⁶/FH, and
#: 10⁻⁷/FH for a rod–surface disconnection (a structural failure); no published rate is
#: cited, and a user with in-service or FMEA figures replaces them. Wherever the hazard
#: table is shown, a rate equal to one of these is labelled :data:`RATE_PLACEHOLDER`.
DEFAULT_FAULT_RATES_PER_FH: dict[str, float] = {
    "runaway": 1e-6,           # est.
    "hardover": 1e-6,          # est.
    "liquid_jam": 1e-6,        # est.
    "solid_jam": 1e-6,         # est.
    "disconnection": 1e-7,     # est.
    "ofc_liquid": 1e-6,        # est.
    "ofc_solid": 1e-6,         # est.
}

#: ``rate_source`` of a rate equal to its default (:data:`DEFAULT_FAULT_RATES_PER_FH`).
RATE_PLACEHOLDER = ("placeholder (est.): set [requirements] fault_rate_per_fh from your "
                    "safety assessment")
#: ``rate_source`` of a rate the campaign file gave, other than the default.
RATE_GIVEN = "[requirements] fault_rate_per_fh"

#: Average probability per flight hour allowed for a failure condition of each severity
#: (AMC 25.1309, "Acceptable Means of Compliance" of CS-25: major < 10⁻⁵, hazardous
#: < 10⁻⁷, catastrophic < 10⁻⁹ per flight hour), least severe first.
AMC_25_1309_BUDGETS_PER_FH: dict[str, float] = {
    "major": 1e-5,
    "hazardous": 1e-7,
    "catastrophic": 1e-9,
}

#: Severity order of :func:`meets`'s answers ("none": no budget met).
_SEVERITY = {"none": 0, "major": 1, "hazardous": 2, "catastrophic": 3}

#: Largest upper bound of the undetected probability (per run) with which a row credits a
#: category to the detector [-]. Above it the detector may, for all the runs show, miss
#: most of the faults: the bound says nothing about what it adds to the fault rate (a
#: choice of this project (est.), the brink at which missing is as likely as detecting).
WIDEST_CREDITED_BOUND = 0.5

#: Columns of the hazard table, one row per detector × fault type, plus ``"all"`` (the
#: undetected faults of every type) and ``"none"`` (the false alarms) per detector. The
#: first twelve are counted from the runs, the others follow from them
#: (:func:`with_claims`).
HAZARD_COLUMNS: tuple[str, ...] = (
    "detector", "fault", "n_runs", "events", "p_run", "p_run_upper95", "rate_per_fh",
    "per_fh", "per_fh_upper95", "late_or_missed", "in_time_per_fh_upper95", "level",
    "bound", "rate_source", "without_per_fh", "meets_without", "meets_with", "credited",
    "claim", "meets_in_time", "credited_in_time", "claim_in_time",
)
_COUNTED = HAZARD_COLUMNS[:12]

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
    "a category is credited to the detector only where its bound is under the budget and "
    "the fault rate alone is not; rates marked (est.) are placeholders, and so is every "
    "category resting on them",
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


def credit(n_runs: int, undetected: int, p_upper: float, without_per_fh: float,
           with_per_fh: float, in_time: bool = False) -> tuple[str, str]:
    """(the category credited to the detector, the row's claim in words) of one row of
    *n_runs* faulty runs of which *undetected* went undetected, *p_upper* the upper bound
    of the undetected probability per run, *without_per_fh* the undetected rate without
    the detector (the fault rate) and *with_per_fh* the bound of that with it [1/FH].

    The category is ``"none"`` unless the detector's detection brings the rate under a
    budget that the fault rate alone is not under; and it is ``"none"`` when the detector
    detected none of the runs, when *p_upper* exceeds :data:`WIDEST_CREDITED_BOUND`, or
    when the bound with the detector lands in the category of the rate without it ("not
    shown": the bound does not separate the categories). A row met by the fault rate
    alone says so. *in_time*: *undetected* counts the late detections too (the claim says
    "in time")."""
    if n_runs <= 0:
        return "n/a", "no run"
    alone = meets(without_per_fh)
    prefix = [f"met by the fault rate alone ({alone}), no credit"] if alone != "none" else []

    def no(reason: str) -> tuple[str, str]:
        return "none", "; ".join(prefix + [reason if prefix else f"no credit: {reason}"])

    if without_per_fh == 0.0:
        return no("fault rate 0 (the mode cannot occur)")
    if undetected >= n_runs:
        return no(f"detected none of its {n_runs} runs" + (" in time" if in_time else ""))
    if not p_upper <= WIDEST_CREDITED_BOUND:
        return no(f"not shown: the undetected-probability bound {p_upper:.3g} is above "
                  f"{WIDEST_CREDITED_BOUND:g}")
    got = meets(with_per_fh)
    if _SEVERITY.get(got, 0) <= _SEVERITY[alone]:
        return no(f"not shown: with the detector ≤ {with_per_fh:.3g}/FH, the category of "
                  f"the fault rate alone ({alone})")
    return got, (f"credited {got}: ≤ {with_per_fh:.3g}/FH with the detector, "
                 f"{without_per_fh:.3g}/FH ({alone}) without")


def rate_source(fault: str, rate_per_fh: float) -> str:
    """Where the rate *rate_per_fh* of fault type *fault* comes from: :data:`RATE_PLACEHOLDER`
    when it equals the default, else :data:`RATE_GIVEN`."""
    default = DEFAULT_FAULT_RATES_PER_FH.get(str(fault))
    return RATE_PLACEHOLDER if default is not None and rate_per_fh == default else RATE_GIVEN


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
    :class:`campaign.evidence.certify.rows.CertifyRows` gathered from them a batch at a time
    (*plan* then unused), and the fault modes' rates *rates* [1/FH] (fault type → rate; a
    fault type of the campaign without a rate raises ValueError)."""
    from reports.scoring.metrics import FAULT_FREE, upper_bound

    from .certify.rows import CertifyRows

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
                "late_or_missed": late,
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
                "late_or_missed": k, "in_time_per_fh_upper95": per_hour(p_up, d_h),
                "level": float(level)})
    out = pd.DataFrame(rows, columns=list(_COUNTED))
    for c in ("n_runs", "events", "late_or_missed"):
        out[c] = out[c].astype("int64")
    return with_claims(out)


def _total(per_fault: list[dict], detector: str, level: float) -> dict:
    """The ``"all"`` row: Σ λ_f P_MD,f and its Bonferroni bound over the fault types with a
    positive rate (module docstring)."""
    from reports.scoring.metrics import upper_bound

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
            "late_or_missed": sum(r["late_or_missed"] for r in per_fault),
            "in_time_per_fh_upper95": in_time, "level": level}


def with_claims(hazard: pd.DataFrame) -> pd.DataFrame:
    """*hazard* with the columns that follow from its counted ones (:data:`HAZARD_COLUMNS`
    after ``level``): the bound's name, each rate's source, the undetected rate without the
    detector, the categories with and without it and what is credited to the detector
    (:func:`credit`), on both readings of "undetected". A table stored before these columns
    existed gets them here, so that it is shown with them."""
    from reports.scoring.metrics import FAULT_FREE

    missing = [c for c in _COUNTED if c not in hazard.columns]
    if missing:
        raise ValueError(f"hazard table lacks column(s) {', '.join(missing)}; make it again "
                         "with fdd-campaign certify DIR")
    out = hazard[list(_COUNTED)].copy()
    derived = {c: [] for c in HAZARD_COLUMNS[len(_COUNTED):]}
    sources = {}
    for r in out.to_dict(orient="records"):
        if r["fault"] not in (FAULT_FREE, "all"):
            sources.setdefault(r["detector"], []).append(
                (r["fault"], r["rate_per_fh"], rate_source(r["fault"], r["rate_per_fh"])))
    for r in out.to_dict(orient="records"):
        fault, n, lam = r["fault"], int(r["n_runs"]), float(r["rate_per_fh"])
        if fault == FAULT_FREE:
            got = meets(r["per_fh_upper95"])
            row = {"bound": "counting (Clopper–Pearson) of the false alarms",
                   "rate_source": "n/a (false alarms)", "without_per_fh": 0.0,
                   "meets_without": "n/a", "meets_with": got, "credited": "n/a",
                   "claim": f"false alarms of the detector (none without it): ≤ "
                            f"{r['per_fh_upper95']:.3g}/FH, {got}",
                   "meets_in_time": got, "credited_in_time": "n/a", "claim_in_time": ""}
        else:
            if fault == "all":
                parts = sources.get(r["detector"], [])
                guessed = [f for f, rate, src in parts if rate > 0 and src != RATE_GIVEN]
                given = [f for f, rate, src in parts if rate > 0 and src == RATE_GIVEN]
                src = (RATE_GIVEN if not guessed else RATE_PLACEHOLDER if not given else
                       f"partly {RATE_PLACEHOLDER} ({', '.join(guessed)})")
                bound = ("counting (Clopper–Pearson), Bonferroni over the fault types; "
                         "P ≤: Σ λ_f P_f^up / Σ λ_f")
                p_up = r["per_fh_upper95"] / lam if lam > 0 else math.nan
                p_in = r["in_time_per_fh_upper95"] / lam if lam > 0 else math.nan
            else:
                src = rate_source(fault, lam)
                bound = "counting (Clopper–Pearson)"
                p_up = float(r["p_run_upper95"])
                p_in = r["in_time_per_fh_upper95"] / lam if lam > 0 else math.nan
            credited, claim = credit(n, int(r["events"]), p_up, lam, r["per_fh_upper95"])
            credited_t, claim_t = credit(n, int(r["late_or_missed"]), p_in, lam,
                                         r["in_time_per_fh_upper95"], in_time=True)
            row = {"bound": bound, "rate_source": src, "without_per_fh": lam,
                   "meets_without": meets(lam), "meets_with": meets(r["per_fh_upper95"]),
                   "credited": credited, "claim": claim,
                   "meets_in_time": meets(r["in_time_per_fh_upper95"]),
                   "credited_in_time": credited_t, "claim_in_time": claim_t}
        for c in derived:
            derived[c].append(row[c])
    for c, values in derived.items():
        out[c] = pd.Series(values, index=out.index,
                           dtype="float64" if c == "without_per_fh" else None)
    return out


def report_section(hazard: pd.DataFrame | None) -> tuple | None:
    """What the report shows of a hazard table (:func:`reports.render.html.hazard_section`'s
    arguments: the table with its claims (:func:`with_claims`), the AMC 25.1309 budgets,
    :data:`ASSUMPTIONS`); None for None (``certify`` has not run)."""
    if hazard is None:
        return None
    return (with_claims(hazard), AMC_25_1309_BUDGETS_PER_FH, ASSUMPTIONS)
