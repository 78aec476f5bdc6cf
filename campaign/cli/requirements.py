"""The campaign file's requirements on the command line (docs/design.md §7, Command line):
the lines ``run`` ends with (what it computed, the gate's verdict, then what the file's other
requirements say), the requirements ``gate`` and ``report`` apply (a finished campaign's, or
corrected ones: ``--requirements FILE``), and the answer to a resume whose file changed its
limits only."""

from __future__ import annotations

import warnings
from pathlib import Path

from .common import UsageError, print_error

__all__ = ["runs_done", "runs_line", "print_verdict", "gate_of", "verdict", "false_alarm_count",
           "other_requirements", "unmet_text", "MD_DTP_CHECKS", "refuse_limits_only_change",
           "requirements_of", "report_limits", "refuse_on_a_suite", "add_requirements_option"]


def runs_done(out) -> int:
    """Runs of campaign directory *out* already done (0: none, or no campaign there yet)."""
    from ..store.directory import CampaignDir

    cdir = CampaignDir(out)
    return cdir.runs_done() if cdir.is_campaign() else 0


def runs_line(config, result, before: int) -> str:
    """What ``run`` did: the runs done of the plan, and how many of them it computed now
    (*before*: runs done when it started)."""
    done = result.runs_done
    head = f"campaign {config.campaign.name!r}:"
    if before and done <= before:
        return (f"{head} nothing to compute, all {done} runs of the plan were already done "
                f"-> {result.root}" if done == result.runs_planned else
                f"{head} {done} of {result.runs_planned} runs done, none computed now -> "
                f"{result.root}")
    now = f" ({done - before} computed now)" if before else ""
    return (f"{head} {done} of {result.runs_planned} runs{now} in {result.wall_s:.1f} s -> "
            f"{result.root}")


def print_verdict(config, result) -> bool:
    """Print the gate's verdict on *result* (the campaign file's false-alarm limits, as
    ``fdd-campaign gate``) and, on the next line, what the file's other requirements (MD,
    DTP) say, as ``gate --all-requirements``; False when the requirements cannot be
    evaluated on these results (a detector variant they name is not among them)."""
    from reports.scoring.gate import GateInputError

    try:       # one evaluation serves both lines (the gate's checks are a part of it)
        full = gate_of(config, result, all_requirements=True)
    except GateInputError:
        full = None          # said below, after the gate's own verdict if that one holds
    try:
        print(verdict(config, result, full=full))
        print(other_requirements(config, result, full=full))
    except GateInputError as exc:
        print_error(f"the gate cannot be evaluated: {exc}")
        print(f"the results are kept: correct the file's [requirements], then: fdd-campaign "
              f"gate {result.root} --requirements FILE (nothing is run again)")
        return False
    return True


def gate_of(config, result, *, all_requirements: bool = False):
    """The gate of *config*'s requirements on a run's *result* (:meth:`Campaign.gate
    <campaign.result.Campaign.gate>`): its false-alarm limits and coverage (``fdd-campaign
    gate``), and with *all_requirements* its MD and DTP limits."""
    return result.gate(config.to_dict()["requirements"], all_requirements=all_requirements)


def verdict(config, result, *, full=None) -> str:
    """One line: would ``fdd-campaign gate`` (the campaign file's false-alarm limit) pass on
    this result, and the command to run next. *full*: the gate of all the requirements
    (``gate_of(..., all_requirements=True)``) when already evaluated; the gate's own checks
    are its checks other than :data:`MD_DTP_CHECKS`, in the same order."""
    from reports.scoring.gate import GateResult

    gate = (gate_of(config, result) if full is None else
            GateResult([c for c in full.checks if c.name not in MD_DTP_CHECKS]))
    if gate.passed:
        return (f"verdict: the gate passes ({false_alarm_count(result)}; all "
                f"{len(gate.checks)} checks); next: fdd-campaign gate {result.root} --junit "
                f"gate.xml, or fdd-campaign report {result.root}")
    first = gate.failures[0]
    runs = [run for c in gate.failures for run in c.run_ids]
    nxt = (f"fdd-campaign show {result.root} {runs[0]} --plot run.png" if runs
           else f"fdd-campaign report {result.root}")
    return (f"verdict: the gate fails ({len(gate.failures)} of {len(gate.checks)} checks; "
            f"first: {first.message.removeprefix('FAIL ')}); next: {nxt}")


def false_alarm_count(result) -> str:
    """``N false alarms in M runs``: every alarm the gate counts (fault-free runs, and faulty
    runs before their onset), over the runs scored."""
    from reports.scoring.summary import ALL_FAULTS, ALL_MANOEUVRES

    s = result.summary
    fine = s[(s["fault"] != ALL_FAULTS) & (s["manoeuvre"] != ALL_MANOEUVRES)]
    alarms, detectors = int(fine["fa_count"].sum()), fine["detector"].nunique()
    runs = result.runs_done
    of = f" of {detectors} detectors" if detectors > 1 else ""
    return f"{alarms} false alarm{'' if alarms == 1 else 's'}{of} in {runs} runs"


#: Requirement checks that only ``gate --all-requirements`` (and report.html) apply.
#: (with the informative checks of the faults a detector is not designed for and of a
#: detection system's members, :func:`reports.scoring.gate.evaluate_gate`)
MD_DTP_CHECKS = ("missed_detection", "dtp", "not_designed_for", "member")


def other_requirements(config, result, shown: int = 4, *, full=None) -> str:
    """One line: what the campaign file's MD and DTP limits say (what ``gate
    --all-requirements`` adds to the gate), the first *shown* unmet ones named. Said as the
    MD and DTP limits, not "all requirements": the line above it carries the gate's own
    checks (false alarms, errors, isolation), which may fail while these limits are met.
    *full*: ``gate_of(..., all_requirements=True)`` when already evaluated."""
    full = full if full is not None else gate_of(config, result, all_requirements=True)
    checks = [c for c in full.checks if c.name in MD_DTP_CHECKS and not c.informative]
    how = f"(fdd-campaign gate {result.root} --all-requirements)"
    req = config.requirements
    limits = f"MD ≤ {100 * req.max_md_rate:g} %, DTP ≤ {req.max_dtp:g}"
    if not checks:
        return f"MD and DTP limits: no faulty run to check {limits} on {how}"
    unmet = [c for c in checks if not c.passed]
    if not unmet:
        return f"MD and DTP limits met ({limits}, {len(checks)} checks) {how}"
    # a fault never detected fails its DTP check too: said once, by its missed detections
    missed = {(c.detector, c.fault) for c in unmet if c.name == "missed_detection"}
    unmet = [c for c in unmet if not (c.name == "dtp" and c.value != c.value
                                      and (c.detector, c.fault) in missed)]
    said = ", ".join(unmet_text(c) for c in unmet[:shown])
    more = f", and {len(unmet) - shown} more" if len(unmet) > shown else ""
    return (f"MD and DTP limits ({limits}) not met: {said}{more} {how}")


def unmet_text(check) -> str:
    """A failed MD or DTP check in a few words."""
    fault = check.fault.replace("_", " ")
    if check.name == "missed_detection":
        return f"{check.detector} misses {100 * check.value:.3g} % of {fault} runs"
    if check.value != check.value:           # NaN: no detected run
        return f"{check.detector} detects no {fault} run"
    return f"{check.detector} {fault} DTP {check.value:.3g} > {check.limit:g}"


def refuse_limits_only_change(config, args) -> None:
    """A campaign directory that holds this campaign run with other ``[requirements]``
    limits only: say that nothing needs to run again, and how to gate and report it
    against the new limits (``--requirements FILE``), instead of refusing it as a different
    campaign."""
    import json

    from ..config import SCORING_REQUIREMENTS, CampaignConfig, ConfigError, RequirementsSection
    from ..config.keys import leaf_fields
    from ..store.directory import CampaignDir, campaign_identity

    cdir = CampaignDir(args.out)
    if not cdir.is_campaign():
        return
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)      # an old spelling, noted once
            stored = json.loads(CampaignConfig.from_dict(cdir.read_config()).to_json())
    except ConfigError:
        return                          # not a campaign this version reads: the runner says so
    new = json.loads(config.to_json())
    limits = [f.name for f in leaf_fields(RequirementsSection)
              if f.name not in SCORING_REQUIREMENTS]
    changed = [k for k in limits
               if stored["requirements"].get(k) != new["requirements"].get(k)]
    if not changed:
        return
    stored["requirements"].update({k: new["requirements"].get(k) for k in changed})
    if campaign_identity(stored) != campaign_identity(new):
        return                          # more has changed: the runner refuses it
    how = (f"--requirements {args.campaign}" if Path(args.campaign).is_file()
           else "--requirements FILE")
    raise UsageError(f"{args.out} holds this campaign already run with other [requirements] "
                     f"limits ({', '.join(changed)}); limits do not change any result, so "
                     f"nothing needs to run again: fdd-campaign gate {args.out} {how} (and "
                     f"fdd-campaign report {args.out} {how}); to keep the new limits with the "
                     "results, run into another --out directory")


def requirements_of(meta: dict, args) -> dict:
    """The ``[requirements]`` of a campaign directory (*meta*: its result metadata) in their
    JSON form, or those of ``--requirements FILE`` in their place: limits do not change any
    result, so a finished campaign is gated and reported against corrected ones without
    being run again (which is said on stdout, with the limits that changed)."""
    config = meta.get("config") or {}
    stored = config.get("requirements") or {}
    if not getattr(args, "requirements", None):
        return stored
    from ..config import load_requirements

    labels = [d.get("label") or d.get("name") for d in config.get("detector") or []]
    out = load_requirements(args.requirements, stored, labels,
                            source=f"--requirements {args.requirements}")
    changed = [f"{k} = {out[k]!r} (was {stored.get(k)!r})" for k in out
               if out[k] != stored.get(k)]
    print(f"requirements: those of {args.requirements} in place of the campaign's; "
          + (", ".join(changed) if changed else "the same limits"))
    return out


def report_limits(meta: dict, args) -> dict | None:
    """The limits of ``--requirements FILE`` (:func:`requirements_of`) as the HTML report
    takes them in place of the campaign's, the keys that score the runs left out (they are
    the campaign's); None without ``--requirements``."""
    from ..config import SCORING_REQUIREMENTS

    if not getattr(args, "requirements", None):
        return None
    return {k: v for k, v in requirements_of(meta, args).items()
            if k not in SCORING_REQUIREMENTS}


def refuse_on_a_suite(args) -> None:
    """``--requirements`` names the detectors of one campaign: refused on a suite."""
    if getattr(args, "requirements", None):
        raise UsageError(f"--requirements: {args.dir} is a suite; its campaigns have their own "
                         f"detectors: give the directory of one of its campaigns "
                         f"({args.dir.rstrip('/')}/NAME)")


def add_requirements_option(p) -> None:
    p.add_argument("--requirements", metavar="FILE",
                   help="use the [requirements] of FILE (the corrected campaign file, or a file "
                        "holding only that table) in place of those the campaign ran with: its "
                        "limits do not change any result, so nothing is computed again "
                        "(detection_time_s and detection_window_s, which do, must keep the "
                        "campaign's values)")
