"""The acceptance gate: pass/fail checks on a summary, a human report and JUnit XML for CI.

Requirements (docs/design.md §5, Metrics; ADDSAFE's zero false alarm / zero missed detection / DTP
targets, [CHEN] §5):

* **false alarms** — checked on every finest-granularity summary row with scored runs
  (each fault-free manoeuvre, and the pre-onset alarms of each fault × manoeuvre), so a
  failure names the detector, the fault, the manoeuvre and the count;
* **missed detections** (only with ``max_md``) — the MD rate per detector × fault type;
  a failure lists the manoeuvres where the misses happened;
* **detection time** (only with ``max_dtp``) — the largest DTP per detector × fault type;
* **isolation** (only with ``isolation``) — a detector that must stay silent on the
  campaign's faults (another surface's, :mod:`campaign.isolation`): any alarm after onset
  fails, naming its runs; its MD and DTP limits do not apply;
* **run errors** — any run with ``status != "ok"`` fails the gate unless ``allow_errors``;
* every detector must have scored runs: an empty campaign proves nothing;
* **false-alarm probability** (only with a certificate, :func:`fa_probability_checks`) —
  the per-run false-alarm probability bound of each detector beyond counting;
* **coverage** (when the caller knows it) — a campaign that has not finished every run of
  its plan fails, unless ``allow_incomplete``: a gate is never green on part of the
  evidence.

A failed check names its first runs (``Check.run_ids``) when the result rows are given, so
that one can be replayed (``fdd-campaign show DIR RUN_ID``): the false alarms, the missed
detections, the runs detected later than the DTP limit (worst first).

Limits on rates are fractions (``max_fa=0.01`` is 1 %).
"""

from __future__ import annotations

import math
import os
import secrets
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from scenarios.errors import InputError

from .metrics import FAULT_FREE
from .summary import ALL_FAULTS, ALL_MANOEUVRES, detector_order

__all__ = ["Check", "GateInputError", "GateResult", "bound_label", "curve_method",
           "evaluate_gate", "fa_limits", "fa_probability_checks",
           "gate_rows", "requirements_gate",
           "junit_tree", "write_junit",
           "write_junit_suite", "write_junit_tree"]

_REQUIRED = ("detector", "fault", "manoeuvre", "n_runs", "n_errors", "fa_count",
             "md_count", "dtp_max")


class GateInputError(InputError, ValueError):
    """A summary or a limit the gate cannot evaluate; lists every problem at once.

    Survives pickling (it may cross a process boundary).
    """

    def __init__(self, problems):
        self.problems = [str(p) for p in ([problems] if isinstance(problems, str) else problems)]
        super().__init__("; ".join(self.problems))

    def __reduce__(self):
        return (type(self), (self.problems,))


@dataclass(frozen=True)
class Check:
    """One requirement evaluated on one place of the summary.

    ``value`` and ``limit`` are in the unit of the requirement (a rate as a fraction, a DTP,
    a count of failed runs); ``fault``/``manoeuvre`` are ``"all"`` when the check covers
    several of them.
    """

    name: str
    detector: str
    fault: str
    manoeuvre: str
    value: float
    limit: float
    passed: bool
    message: str
    #: the first failing runs (false alarms, misses, late detections), for replaying one
    run_ids: tuple[str, ...] = ()
    #: reported for information, never failed: a fault the detector is not designed for, or
    #: a member's part of its detection system's requirement (a JUnit ``skipped`` case)
    informative: bool = False


@dataclass
class GateResult:
    """Every check of one gate evaluation."""

    checks: list[Check] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(c.passed for c in self.checks)

    @property
    def failures(self) -> list[Check]:
        """The checks that failed, in evaluation order."""
        return [c for c in self.checks if not c.passed]

    @property
    def verdict(self) -> str:
        """The verdict line: ``gate PASSED: all N checks passed`` or ``gate FAILED: k of N
        checks failed``."""
        k = len(self.failures)
        told = sum(c.informative for c in self.checks)
        n = len(self.checks) - told
        info = f" ({told} more for information)" if told else ""
        return (f"gate FAILED: {k} of {n} checks failed{info}" if k
                else f"gate PASSED: all {n} checks passed{info}")

    def format(self) -> str:
        """Human report: one line per check, the verdict, and the failures repeated."""
        lines = [c.message for c in self.checks] + ["", self.verdict]
        return "\n".join(lines + [f"  {c.message}" for c in self.failures])


def _pct(x: float) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100 * x:.2f} %"


def _where(fault: str, manoeuvre: str) -> str:
    label = "fault-free" if fault == FAULT_FREE else fault
    return label if manoeuvre == ALL_MANOEUVRES else f"{label} {manoeuvre}"


def _validate(summary: pd.DataFrame, limits: dict) -> None:
    problems = []
    missing = [c for c in _REQUIRED if c not in summary.columns]
    if missing and not summary.empty:
        problems.append(f"summary lacks column(s) {', '.join(missing)}; "
                        "pass the output of reports.summarize")
    for name, value in limits.items():
        if value is None:
            continue
        try:
            v = float(value)
        except (TypeError, ValueError):
            problems.append(f"{name} must be a number, got {value!r}")
            continue
        if name in ("max_fa", "max_md") and not 0.0 <= v <= 1.0:
            problems.append(f"{name} is a rate as a fraction in [0, 1] (0.01 = 1 %), got {v}")
        if name == "max_dtp" and not (math.isfinite(v) and v > 0):
            problems.append(f"max_dtp must be a positive DTP (1.0 = the required time), "
                            f"got {v}")
    if problems:
        raise GateInputError(problems)


def evaluate_gate(summary: pd.DataFrame, *, max_fa: float = 0.0, max_md: float | None = None,
                  max_dtp: float | None = None, allow_errors: bool = False,
                  coverage: tuple[int, int] | None = None, allow_incomplete: bool = False,
                  results: pd.DataFrame | None = None,
                  detector_max_fa: dict | None = None,
                  isolation: dict | None = None, roles=None) -> GateResult:
    """Evaluate the acceptance requirements on a summary (see the module docstring).

    Parameters
    ----------
    summary : DataFrame
        Output of :func:`reports.scoring.summary.summarize`.
    max_fa : float
        Largest accepted false-alarm rate (fraction) in any fault-free manoeuvre and, for
        pre-onset alarms, in any fault × manoeuvre. Default 0: no false alarm at all.
    max_md : float or None
        Largest accepted missed-detection rate (fraction) per fault type; None: not checked.
    max_dtp : float or None
        Largest accepted DTP (detection delay / required time) per fault type; None: not
        checked.
    allow_errors : bool
        When False (default) any run that did not finish with ``status="ok"`` fails.
    coverage : (runs done, runs planned) or None
        When given, a campaign with fewer runs done than planned fails the ``coverage``
        check (the first check), unless *allow_incomplete*.
    results : DataFrame or None
        The result rows behind *summary*; a failed false-alarm, missed-detection or DTP
        check then lists its first failing run ids.
    detector_max_fa : dict or None
        Detector (result-row name, e.g. ``"chen-local[solid]"``, or its base label, which
        covers every variant) → its own largest accepted false-alarm rate, in place of
        *max_fa* for that detector: a campaign's documented allowance for a detector known
        not to reach zero (``[requirements] detector_max_fa_rate``). A name that matches no
        detector of the summary is an error (GateInputError).
    isolation : dict or None
        Detector (result-row name or base label) → the surface of the campaign's faults,
        which it must not alarm on (:attr:`campaign.isolation.Roles.isolation`): its faulty
        runs are checked by :func:`_isolation_checks` instead of the missed-detection and
        DTP limits.
    roles : object or None
        What each detector is designed for (:class:`campaign.isolation.Roles`):
        ``roles.coverage(name)`` the fault types it covers (``.covers(fault)``,
        ``.reason``) and ``roles.system_of(name)`` the detection system it is a member of
        (or None); its ``isolation`` is used when *isolation* is not given. The
        missed-detection and DTP limits hold a detector to the faults it covers, and a
        member of a system to none (the system is held to them): those rows are reported
        as informative checks, which pass (:func:`_informative_checks`). None: every
        detector is held to every fault.

    Raises
    ------
    GateInputError
        When the summary lacks columns or a limit is out of range.
    """
    _validate(summary, {"max_fa": max_fa, "max_md": max_md, "max_dtp": max_dtp})
    allowance = _allowances(summary, detector_max_fa or {})
    if isolation is None and roles is not None:
        isolation = getattr(roles, "isolation", None)
    checks: list[Check] = []
    if coverage is not None:
        checks.append(_coverage_check(*coverage, allow_incomplete))
    if summary.empty:
        checks.append(Check("runs", "all", "all", "all", 0.0, 1.0, False,
                            "FAIL scored runs: no run has finished yet"))
        return GateResult(checks)
    fine = summary[(summary["fault"] != ALL_FAULTS) & (summary["manoeuvre"] != ALL_MANOEUVRES)]
    # the one order of the detectors (by name, numbers by value), whatever the rows' order
    for detector in detector_order(fine["detector"]):
        rows = fine[fine["detector"] == detector]
        checks += _runs_check(detector, rows)
        checks += _fa_checks(detector, rows, float(allowance(detector, max_fa)),
                             _alarmed_runs(results, detector))
        isolated = _isolated_surface(detector, isolation or {})
        if isolated is not None:
            checks += _isolation_checks(detector, rows, isolated, results)
        else:
            scored = _faulty_runs(results, detector)
            held, told = _held_rows(detector, rows, roles)
            if max_md is not None:
                checks += _md_checks(detector, held, float(max_md), scored)
            if max_dtp is not None:
                checks += _dtp_checks(detector, held, float(max_dtp), scored)
            if max_md is not None or max_dtp is not None:
                checks += _informative_checks(detector, told, roles)
        checks += _error_checks(detector, rows, allow_errors, _first_error(results, detector))
    if fine.empty:
        checks.append(Check("runs", "all", "all", "all", 0.0, 1.0, False,
                            "FAIL scored runs: the summary holds no runs"))
    return GateResult(checks)



def requirements_gate(summary: pd.DataFrame, results: pd.DataFrame | None, requirements,
                      *, isolation: dict | None = None, roles=None,
                      coverage: tuple[int, int] | None = None,
                      all_requirements: bool = False, allow_errors: bool = False,
                      allow_incomplete: bool = False) -> GateResult:
    """The gate of a campaign file's ``[requirements]`` (*requirements*: their JSON form, a
    mapping): what ``fdd-campaign gate DIR`` checks — the false-alarm limit
    ``max_fa_rate`` with the ``detector_max_fa_rate`` allowances, run errors, *coverage*
    and *isolation* — and with *all_requirements* (``gate --all-requirements``) also
    ``max_md_rate`` and ``max_dtp`` (a limit that is None is not checked). One place for the
    verdict that ``gate`` prints, ``run`` repeats and the report shows."""
    return evaluate_gate(
        summary, results=results, max_fa=float(requirements.get("max_fa_rate", 0.0)),
        detector_max_fa=dict(requirements.get("detector_max_fa_rate") or {}),
        max_md=requirements.get("max_md_rate") if all_requirements else None,
        max_dtp=requirements.get("max_dtp") if all_requirements else None,
        isolation=isolation, roles=roles, coverage=coverage, allow_errors=allow_errors,
        allow_incomplete=allow_incomplete)


def _allowances(summary: pd.DataFrame, limits: dict):
    """detector → its false-alarm limit: *limits* by result-row name, else by base label
    (the name before ``[``), else the campaign-wide one; unknown names are refused."""
    names = set(summary["detector"]) if "detector" in summary else set()
    bases = {n.split("[", 1)[0] for n in names}
    problems = []
    for name, value in limits.items():
        if name not in names and name not in bases:
            problems.append(f"detector_max_fa_rate names {name!r}, which is no detector of "
                            f"these results ({', '.join(sorted(names))}); fix: use one of "
                            "those names or remove it (a finished campaign: correct its file "
                            "and gate it with --requirements FILE, nothing is run again)")
        elif not 0.0 <= float(value) <= 1.0:
            problems.append(f"detector_max_fa_rate {name!r} = {value!r}: a rate is a "
                            "fraction in [0, 1], e.g. 0.05 for 5 %")
    if problems:
        raise GateInputError(problems)

    def limit(detector: str, default: float) -> float:
        if detector in limits:
            return float(limits[detector])
        return float(limits.get(detector.split("[", 1)[0], default))
    return limit


def fa_limits(summary: pd.DataFrame, requirements) -> dict[str, float]:
    """Each detector (result-row name) of *summary* → the false-alarm rate the gate accepts
    for it under *requirements* (their JSON form, as :func:`requirements_gate` takes them):
    its ``detector_max_fa_rate`` allowance, else ``max_fa_rate``."""
    limit = _allowances(summary, dict(requirements.get("detector_max_fa_rate") or {}))
    default = float(requirements.get("max_fa_rate", 0.0))
    names = summary["detector"].astype(str) if "detector" in summary else []
    return {name: float(limit(name, default)) for name in dict.fromkeys(names)}


def _coverage_check(done: int, planned: int, allow_incomplete: bool) -> Check:
    done, planned = int(done), int(planned)
    if done >= planned:
        return Check("coverage", "all", "all", "all", float(done), float(planned), True,
                     f"PASS coverage: all {planned} runs of the plan done")
    verdict = "PASS (allowed)" if allow_incomplete else "FAIL"
    return Check("coverage", "all", "all", "all", float(done), float(planned),
                 bool(allow_incomplete),
                 f"{verdict} coverage: incomplete: {done} of {planned} runs done; finish the "
                 "campaign by running the same 'fdd-campaign run' command again"
                 + ("" if allow_incomplete else " (or gate part of it with --allow-incomplete)"))


def gate_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The result rows :func:`evaluate_gate` reads of *results*, in their order: every row
    that did not finish ``ok``, every false alarm, every row of a faulty run. The gate of a
    summary with these rows is the gate with all the rows; a fault-free campaign of 10⁶
    runs passes it its few alarms and failures instead of its millions of rows."""
    if results.empty:
        return results
    ok = results["status"] == "ok"
    alarm = results["false_alarm"].astype("boolean").fillna(False).astype(bool)
    keep = ~ok | alarm | (results["fault"] != FAULT_FREE)
    return results[keep.to_numpy()]


def _alarmed_runs(results: pd.DataFrame | None, detector: str) -> dict:
    """(fault, manoeuvre) → the run ids of *detector*'s false alarms (ok runs, plan order)."""
    if results is None or results.empty:
        return {}
    r = results[(results["detector"] == detector) & (results["status"] == "ok")
                & results["false_alarm"].astype(bool)]
    return {key: tuple(g["run_id"].astype(str)) for key, g in
            r.groupby(["fault", "manoeuvre"], sort=False)}


def _faulty_runs(results: pd.DataFrame | None, detector: str) -> pd.DataFrame:
    """*detector*'s faulty runs scored ok, in plan order: ``run_id``, ``fault``,
    ``detected`` and ``dtp`` (empty without result rows)."""
    columns = ["run_id", "fault", "detected", "dtp"]
    if results is None or results.empty:
        return pd.DataFrame(columns=columns)
    r = results[(results["detector"] == detector) & (results["status"] == "ok")
                & (results["fault"] != FAULT_FREE)]
    return pd.DataFrame({"run_id": r["run_id"].astype(str), "fault": r["fault"],
                         "detected": r["detected"].astype("boolean").fillna(False).astype(bool),
                         "dtp": pd.to_numeric(r["dtp"], errors="coerce")})


def _missed(scored: pd.DataFrame, fault: str) -> tuple[str, ...]:
    """Run ids of the *fault* runs of *scored* (:func:`_faulty_runs`) never detected."""
    r = scored[(scored["fault"] == fault) & ~scored["detected"]]
    return tuple(r["run_id"])


def _late(scored: pd.DataFrame, fault: str, limit: float) -> tuple[str, ...]:
    """Run ids of the *fault* runs of *scored* detected with a DTP above *limit*, worst
    first."""
    r = scored[(scored["fault"] == fault) & scored["detected"] & (scored["dtp"] > limit)]
    return tuple(r.sort_values("dtp", ascending=False, kind="stable")["run_id"])


def _runs_text(ids: tuple[str, ...], what: str = "runs") -> str:
    """``; runs: a, b, c and N more`` for a failure message ('' without ids)."""
    if not ids:
        return ""
    return (f"; {what}: {', '.join(ids[:3])}"
            + (f" and {len(ids) - 3} more" if len(ids) > 3 else ""))


def _runs_check(detector, rows) -> list[Check]:
    n = int(rows["n_runs"].sum())
    if n > 0:
        return []
    return [Check("runs", detector, "all", "all", float(n), 1.0, False,
                  f"FAIL scored runs: {detector}: no run finished with status ok")]


def _fa_checks(detector, rows, limit, alarmed: dict) -> list[Check]:
    out = []
    for r in rows[rows["n_runs"] > 0].itertuples(index=False):
        ids = alarmed.get((r.fault, r.manoeuvre), ())
        rate = r.fa_count / r.n_runs
        passed = rate <= limit
        what = "false alarms" if r.fault == FAULT_FREE else "false alarms before onset"
        rel = "≤" if passed else ">"
        bound = f"; FA ≤ {_pct(r.fa_upper95)} at 95 %" if hasattr(r, "fa_upper95") else ""
        msg = (f"{'PASS' if passed else 'FAIL'} {what}: {detector}, "
               f"{_where(r.fault, r.manoeuvre)}: {r.fa_count}/{r.n_runs} runs "
               f"({_pct(rate)} {rel} {_pct(limit)}{bound if passed else ''})")
        if not passed:
            msg += _runs_text(ids)
        out.append(Check("false_alarm", detector, r.fault, r.manoeuvre, rate, limit,
                         bool(passed), msg, ids[:3] if not passed else ()))
    return out


def _md_checks(detector, rows, limit, scored: pd.DataFrame) -> list[Check]:
    out = []
    faulty = rows[(rows["fault"] != FAULT_FREE) & (rows["n_runs"] > 0)]
    for fault, g in faulty.groupby("fault", sort=True):
        n, k = int(g["n_runs"].sum()), int(g["md_count"].sum())
        rate = k / n
        passed = rate <= limit
        rel = "≤" if passed else ">"
        late = int(g["late_count"].sum()) if "late_count" in g else 0
        msg = (f"{'PASS' if passed else 'FAIL'} missed detections: {detector}, {fault}: "
               f"{k}/{n} runs never detected ({_pct(rate)} {rel} {_pct(limit)})"
               + (f"; {late} more detected late (DTP > 1, see the detection time check)"
                  if late else ""))
        if k:
            where = ", ".join(f"{m} {c}/{t}" for m, c, t in
                              zip(g["manoeuvre"], g["md_count"], g["n_runs"]) if c)
            msg += f"; misses in: {where}"
        ids = () if passed else _missed(scored, fault)
        msg += _runs_text(ids, "missed runs")
        out.append(Check("missed_detection", detector, fault, ALL_MANOEUVRES, rate, limit,
                         bool(passed), msg, ids[:3]))
    return out


def _dtp_checks(detector, rows, limit, scored: pd.DataFrame) -> list[Check]:
    out = []
    faulty = rows[(rows["fault"] != FAULT_FREE) & (rows["n_runs"] > 0)]
    for fault, g in faulty.groupby("fault", sort=True):
        misses = int(g["md_count"].sum())
        n = int(g["n_runs"].sum())
        dtp = g["dtp_max"].to_numpy(dtype=float)
        miss_note = f" ({misses} of {n} runs missed, not in DTP)" if misses else ""
        if np.all(np.isnan(dtp)):
            ids = _missed(scored, fault)
            out.append(Check("dtp", detector, fault, ALL_MANOEUVRES, math.nan, limit, False,
                             f"FAIL detection time: {detector}, {fault}: no detected run, "
                             f"DTP ≤ {limit:g} not shown{miss_note}"
                             + _runs_text(ids, "missed runs"), ids[:3]))
            continue
        i = int(np.nanargmax(dtp))
        worst, where = float(dtp[i]), g["manoeuvre"].iloc[i]
        passed = worst <= limit
        rel = "≤" if passed else ">"
        ids = () if passed else _late(scored, fault, limit)
        msg = (f"{'PASS' if passed else 'FAIL'} detection time: {detector}, {fault}: "
               f"max DTP {worst:.3g} {rel} {limit:g} (worst in {where}){miss_note}"
               + _runs_text(ids, "runs above it, worst first"))
        out.append(Check("dtp", detector, fault, ALL_MANOEUVRES, worst, limit, bool(passed),
                         msg, ids[:3]))
    return out


def _held_rows(detector: str, rows: pd.DataFrame, roles) -> tuple[pd.DataFrame, pd.DataFrame]:
    """*detector*'s rows split into those its missed-detection and DTP limits hold it to
    (faulty rows of fault types it covers, when it belongs to no detection system) and the
    faulty rows reported for information only."""
    faulty = rows["fault"] != FAULT_FREE
    if roles is None:
        return rows, rows.iloc[0:0]
    if roles.system_of(detector) is not None:
        return rows[~faulty], rows[faulty]
    coverage = roles.coverage(detector)
    covered = rows["fault"].map(lambda f: f == FAULT_FREE or coverage.covers(f)).astype(bool)
    return rows[covered], rows[~covered]


def _informative_checks(detector: str, rows: pd.DataFrame, roles) -> list[Check]:
    """One passing, informative check per fault type of *rows* (:func:`_held_rows`): what
    the detector detected of a fault it is not designed for, or, for a member of a
    detection system, of the faults the system is held to."""
    out = []
    rows = rows[rows["n_runs"] > 0]
    if rows.empty:
        return out
    system = roles.system_of(detector)
    coverage = roles.coverage(detector)
    for fault, g in rows.groupby("fault", sort=True):
        n = int(g["n_runs"].sum())
        k = n - int(g["md_count"].sum())
        dtp = g["dtp_max"].to_numpy(dtype=float)
        worst = "" if np.all(np.isnan(dtp)) else f", max DTP {np.nanmax(dtp):.3g}"
        if system is not None:
            name, what = "member", f"member of {system}"
            why = "the detection system is held to the missed-detection and DTP limits"
        else:
            name, what = "not_designed_for", "not designed for"
            why = coverage.reason or "the detector does not declare this fault type"
        msg = f"INFO {what}: {detector}, {fault}: {k}/{n} detected{worst} ({why})"
        out.append(Check(name, detector, fault, ALL_MANOEUVRES, k / n, math.nan, True, msg,
                         informative=True))
    return out


def _isolated_surface(detector: str, isolation: dict) -> str | None:
    """The surface *detector* (result-row name) must not alarm on, by name or base label."""
    if detector in isolation:
        return str(isolation[detector])
    base = detector.split("[", 1)[0]
    return None if base not in isolation else str(isolation[base])


def _isolation_checks(detector, rows, surface: str, results) -> list[Check]:
    """One check per fault type: no run of a fault on *surface* may make *detector* alarm
    after onset (scored as "detected"); the failing run ids are named from *results*."""
    out = []
    scored = _faulty_runs(results, detector)
    faulty = rows[(rows["fault"] != FAULT_FREE) & (rows["n_runs"] > 0)]
    for fault, g in faulty.groupby("fault", sort=True):
        n = int(g["n_runs"].sum())
        k = n - int(g["md_count"].sum())
        alarmed = scored[(scored["fault"] == fault) & scored["detected"]]
        ids = tuple(alarmed["run_id"]) if k else ()
        passed = k == 0
        msg = (f"{'PASS' if passed else 'FAIL'} isolation: {detector}, {fault} of "
               f"{surface}: {k}/{n} runs alarmed after onset (it must stay silent on another "
               "surface's faults)") + _runs_text(ids)
        out.append(Check("isolation", detector, fault, ALL_MANOEUVRES, k / n, 0.0,
                         passed, msg, ids[:3]))
    return out


def _first_error(results: pd.DataFrame | None, detector: str) -> str:
    """``run <id>: <message>`` of *detector*'s first run that did not finish ('' if none
    or no result rows were given)."""
    if results is None or results.empty or "error" not in results.columns:
        return ""
    bad = results[(results["detector"] == detector) & (results["status"] != "ok")]
    if bad.empty:
        return ""
    first = bad.iloc[0]
    n_msgs = bad["error"].nunique()
    more = f" ({n_msgs - 1} other message(s): fdd-campaign report)" if n_msgs > 1 else ""
    return f"run {first['run_id']}: {first['error']}{more}"


def _error_checks(detector, rows, allow_errors, first: str = "") -> list[Check]:
    n_err = int(rows["n_errors"].sum())
    if n_err == 0:
        return [Check("errors", detector, "all", "all", 0.0, 0.0, True,
                      f"PASS run errors: {detector}: none")]
    where = ", ".join(f"{_where(f, m)} {int(e)}" for f, m, e in
                      zip(rows["fault"], rows["manoeuvre"], rows["n_errors"]) if e)
    verdict = "PASS (allowed)" if allow_errors else "FAIL"
    return [Check("errors", detector, "all", "all", float(n_err), 0.0, bool(allow_errors),
                  f"{verdict} run errors: {detector}: {n_err} run(s) did not finish "
                  f"(status != ok): {where}" + (f"; first: {first}" if first else ""))]


def junit_tree(result: GateResult, name: str = "fdd-campaign gate") -> ET.Element:
    """The gate as one JUnit ``<testsuite>`` named *name*: a testcase per check, a
    ``failure`` per failed check."""
    failures = result.failures
    n, k = str(len(result.checks)), str(len(failures))
    skipped = str(sum(c.informative for c in result.checks))
    suite = ET.Element("testsuite", name=name, tests=n, failures=k, errors="0",
                       skipped=skipped)
    for c in result.checks:
        case = ET.SubElement(suite, "testcase", classname=f"gate.{c.detector}",
                             name=f"{c.name}[{c.fault}/{c.manoeuvre}]")
        if not c.passed:
            fail = ET.SubElement(case, "failure", message=c.message, type=c.name)
            fail.text = c.message
        elif c.informative:
            ET.SubElement(case, "skipped", message=c.message)
        else:
            ET.SubElement(case, "system-out").text = c.message
    return suite


def write_junit(result: GateResult, path) -> None:
    """Write the gate as JUnit XML: one testcase per check, a ``failure`` per failed check.

    The root is ``<testsuites>`` holding one ``<testsuite name="fdd-campaign gate">`` with
    ``tests`` and ``failures`` counts. The file is replaced atomically.
    """
    write_junit_tree([junit_tree(result)], path)


def write_junit_suite(results: list, path) -> None:
    """One JUnit file for a suite of campaigns: a ``<testsuite>`` per (name, GateResult)."""
    write_junit_tree([junit_tree(result, f"fdd-campaign gate {name}")
                      for name, result in results], path)


def write_junit_tree(suites: list, path) -> None:
    """Write ``<testsuites>`` holding *suites* (:func:`junit_tree`) to *path*, atomically."""
    tests = sum(int(x.get("tests")) for x in suites)
    failures = sum(int(x.get("failures")) for x in suites)
    root = ET.Element("testsuites", name="fdd-campaign", tests=str(tests),
                      failures=str(failures), errors="0")
    root.extend(suites)
    tree = ET.ElementTree(root)
    ET.indent(tree)
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    # created by open(): the mode the user's umask gives (mkstemp would make it 0600)
    tmp = os.path.join(directory, f".junit-{os.getpid()}-{secrets.token_hex(4)}.xml.tmp")
    try:
        with open(tmp, "xb") as fh:
            tree.write(fh, encoding="utf-8", xml_declaration=True)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


#: The name of the certificate's ``fa_prob_evt_upper95`` by its ``evt_method``
#: (campaign.evidence.certify: the exceedance curve at margin 1).
_CURVE_BOUNDS = {
    "mixture": "tail fit",
    "counted per manoeuvre": "counting, Clopper–Pearson per manoeuvre of the margins ≥ 1, "
                             "mixed by the manoeuvres' shares; no tail fit",
    "counted": "counting, Clopper–Pearson, of the margins ≥ 1",
    "limit of the runs": "limit of the runs: the counting (Clopper–Pearson) bound / 100; "
                         "the tail fit claims less",
}


def curve_method(row: dict) -> str:
    """Which bound a certificate row's ``fa_prob_evt_upper95`` is: its ``evt_method``, or,
    for a certificate made before that column, the method that begins its ``evt_note``
    ("mixture" whose note says every manoeuvre was counted: "counted per manoeuvre"); ""
    when neither says."""
    method = row.get("evt_method")
    if isinstance(method, str) and method:
        return method
    note = row.get("evt_note")
    if not isinstance(note, str):
        return ""
    method = next((m for m in ("counted", "mixture", "limit of the runs", "none")
                   if note.startswith(m)), "")
    if method == "mixture" and "every manoeuvre counted" in note:
        return "counted per manoeuvre"
    return method


def bound_label(row: dict, which: str) -> str:
    """The name of the bound a ``fa_probability`` check shows, from the certificate's row
    *row*: *which* is ``"counting"`` (``fa_upper95_cp``), ``"curve"``
    (``fa_prob_evt_upper95``, by :func:`curve_method`) or ``"sampling"``
    (``sampling_upper95``: subset simulation, at the highest level it reached when that is
    below margin 1)."""
    if which == "counting":
        return "counting, Clopper–Pearson; no tail fit or sampling"
    if which == "sampling":
        reached = row.get("sampling_reached_level")
        try:
            reached = float(reached)
        except (TypeError, ValueError):
            reached = math.nan
        return ("subset simulation" if not reached < 1.0 else
                f"subset simulation, P(margin ≥ {reached:.3g}) at the highest level reached")
    return _CURVE_BOUNDS.get(curve_method(row),
                             "tail fit or counting (the certificate does not say which: "
                             "make it again with fdd-campaign certify DIR)")


def fa_probability_checks(certificate: pd.DataFrame, limit: float) -> list[Check]:
    """One ``fa_probability`` check per detector of a false-alarm certificate
    (``fdd-campaign certify``, docs/evidence.md): the per-run false-alarm probability bound
    must be ≤ *limit*. The bound is the larger of the exceedance curve's at margin 1
    (``fa_prob_evt_upper95``) and the sampled estimate's (``sampling_upper95``) where they
    are present; a detector with neither is held to its counting bound
    (``fa_upper95_cp``). The message names the bound it shows (:func:`bound_label`): the
    curve's is a tail fit, a counting bound or the limit of the runs by its ``evt_method``.

    Raises :class:`GateInputError` when *limit* is not a probability in [0, 1] or the
    certificate lacks its columns.
    """
    problems = []
    try:
        limit = float(limit)
    except (TypeError, ValueError):
        problems.append(f"max_fa_prob must be a number, got {limit!r}")
    else:
        if not 0.0 <= limit <= 1.0:
            problems.append(f"max_fa_prob is a per-run probability in [0, 1] (1e-5 = one run in "
                            f"100 000), got {limit}")
    need = ("detector", "level", "fa_upper95_cp", "fa_prob_evt_upper95")
    missing = [c for c in need if c not in certificate.columns]
    if missing:
        problems.append(f"certificate lacks column(s) {', '.join(missing)}; make it again "
                        "with fdd-campaign certify DIR")
    if problems:
        raise GateInputError(problems)
    out = []
    for r in certificate.to_dict(orient="records"):
        bounds = {"curve": r.get("fa_prob_evt_upper95"),
                  "sampling": r.get("sampling_upper95")}
        bounds = {k: float(v) for k, v in bounds.items()
                  if v is not None and math.isfinite(float(v))}
        if bounds:
            which = max(bounds, key=bounds.get)
            source, value = bound_label(r, which), bounds[which]
        else:
            source, value = bound_label(r, "counting"), float(r["fa_upper95_cp"])
        passed = value <= limit
        level = f"{100 * float(r['level']):g} %"
        msg = (f"{'PASS' if passed else 'FAIL'} false-alarm probability: {r['detector']}: "
               f"P(FA per run) ≤ {value:.3g} at {level} ({source}) "
               f"{'≤' if passed else '>'} {limit:g}")
        out.append(Check("fa_probability", r["detector"], FAULT_FREE, ALL_MANOEUVRES, value,
                         limit, bool(passed), msg))
    return out
