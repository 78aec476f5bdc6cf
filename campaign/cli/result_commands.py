"""The commands that read a campaign (or suite) directory: ``gate``, ``verify``, ``report``,
``show`` and ``compare`` (docs/design.md §7, Command line). Registered by
:mod:`campaign.cli.commands`."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from . import requirements as creq
from .common import EXIT_GATE, EXIT_OK, UsageError, add_command, check_writable


@dataclass(frozen=True)
class _CampaignDirs:
    """The campaign directories a command that reads *directory* works on: iterating gives
    ``(title, campaign directory)`` of the directory itself, as given (title None), or of
    each member of a suite's directory in the suite's order, read only then
    (:func:`campaign.suite.suite_members`), so that what a suite refuses is said first."""
    directory: object
    suite: bool

    def __iter__(self):
        from ..suite import suite_members

        return iter(suite_members(self.directory) if self.suite else [(None, self.directory)])


def _campaign_dirs(directory) -> _CampaignDirs:
    """:class:`_CampaignDirs` of *directory*: a suite's when it holds ``suite.json`` and is not
    itself one campaign's directory."""
    from ..store.directory import CampaignDir
    from ..suite import is_suite_dir

    return _CampaignDirs(directory, is_suite_dir(directory)
                         and not CampaignDir(directory).is_campaign())


def cmd_gate(args) -> int:
    from reports.scoring.gate import write_junit, write_junit_suite

    from .worst_case import check_worst_case_options

    check_worst_case_options(args)          # bad --worst-case options: before any work
    if args.junit:
        check_writable(args.junit, "--junit")
    targets = _campaign_dirs(args.dir)
    suite = targets.suite
    if suite:
        creq.refuse_on_a_suite(args)
    results = []
    for title, directory in targets:
        if suite:
            print(f"== {title} ==")
        results.append((Path(directory).name, _gate_one(directory, args)))
    ok = all(result.passed for _, result in results)
    if suite:
        print(f"suite gate {'PASSED' if ok else 'FAILED'}: "
              f"{sum(r.passed for _, r in results)} of {len(results)} campaigns passed")
    if args.junit:
        if suite:
            write_junit_suite(results, args.junit)
        else:
            write_junit(results[0][1], args.junit)
        print(f"JUnit report written to {args.junit}")
    return EXIT_OK if ok else EXIT_GATE


def _gate_one(directory, args):
    from ..result import load

    camp = load(directory)
    from .tradeoff import gated_at_scales

    camp = gated_at_scales(camp, args)          # --threshold-scale D=s: from the stored runs
    meta = camp.meta
    limits = dict(creq.requirements_of(meta, args))
    if args.max_fa is not None:       # one limit for every detector: no allowance
        limits.update(max_fa_rate=args.max_fa, detector_max_fa_rate={})
    for key, given in (("max_md_rate", args.max_md), ("max_dtp", args.max_dtp)):
        # the campaign file's MD and DTP limits with --all-requirements (as the report)
        limits[key] = given if given is not None else (
            limits.get(key) if args.all_requirements else None)
    result = camp.gate(limits, all_requirements=True, allow_errors=args.allow_errors,
                       allow_incomplete=args.allow_incomplete)
    if args.max_fa_prob is not None:      # the certificate's bounds (fdd-campaign certify)
        from .evidence import fa_probability_checks

        result.checks += fa_probability_checks(camp, args.max_fa_prob)
    if args.worst_case is not None:       # the corpus, then a search per gated detector
        from .worst_case import worst_case_checks

        result.checks += worst_case_checks(camp, limits, args)
    print(result.format())
    failing = [run for c in result.failures for run in c.run_ids]
    if failing:
        print(f"replay one: fdd-campaign show {directory} {failing[0]} --plot run.png; "
              f"every run, margins and envelopes: fdd-campaign report {directory}")
    return result


def cmd_verify(args) -> int:
    from ..store.directory import CampaignDir, CampaignDirError, ManifestError

    root = Path(args.dir)
    if not root.is_dir():
        raise UsageError(f"{root} does not exist or is not a directory")
    ok = True
    for _, directory in _campaign_dirs(root):
        cdir = CampaignDir(directory)
        try:
            problems = cdir.verify()
        except ManifestError as exc:
            problems = [str(exc)]
        if problems:
            ok = False
            print(f"{directory}: {len(problems)} file(s) do not match the manifest:")
            for problem in problems:
                print(f"  {problem}")
            continue
        manifest = cdir.read_manifest()
        print(f"{directory}: all {len(manifest['files'])} files match the manifest (campaign "
              f"{(manifest.get('campaign') or {}).get('name')!r}, written by fdd-campaign "
              f"{', '.join(manifest.get('engine_versions') or ['?'])})")
    if not ok:
        raise CampaignDirError(f"{args.dir} does not match its manifest (listed above); "
                               "tamper-evident only: see docs/security.md")
    return EXIT_OK


def cmd_report(args) -> int:
    targets = _campaign_dirs(args.dir)
    if targets.suite:
        if args.html:
            raise UsageError("--html names one file; a suite directory gets one report.html "
                             "per campaign (DIR/<campaign>/report.html): leave --html out")
        creq.refuse_on_a_suite(args)
    for title, directory in targets:
        if title is not None:
            print(f"== {title} ==")
        _report_one(argparse.Namespace(**{**vars(args), "dir": str(directory)}))
    return EXIT_OK


def _report_one(args) -> None:
    from reports.render.table import error_lines

    from ..result import load

    camp = load(args.dir)
    args.requirements_values = creq.report_limits(camp.meta, args)
    if not args.no_html:
        check_writable(args.html or Path(args.dir) / "report.html", "--html")
    unfinished = _unfinished_text(camp, args.dir)
    print(f"campaign {camp.name or '?'!r}: " + (unfinished or
          f"{camp.runs_done} of {camp.runs_planned} runs"))
    print(camp.table())
    for line in error_lines(camp.gate_results):       # its failed runs
        print(f"runs not scored: {line}")
    if unfinished:          # again below the tables, which are long
        print(unfinished)
    if not args.no_html:
        write_html_report(args, camp)


def _unfinished_text(camp, directory) -> str | None:
    """What ``report`` says of a campaign that has not done every run of its plan (stopped
    by Ctrl-C, a kill or a time limit): the runs done, that every rate and table covers those
    only, and the command that finishes it (None when it is finished)."""
    planned = camp.runs_planned
    if planned is None or camp.runs_done >= planned:
        return None
    return (f"report of an unfinished campaign: {camp.runs_done} of {planned} runs done (the "
            f"tables and rates cover those runs only); finish it with: "
            f"{_resume_command(camp, directory)} (finished runs are kept)")


def _resume_command(camp, directory) -> str:
    """The ``run`` command that resumes campaign directory *directory*: the preset's name
    (with ``--seed``) when the directory holds a shipped preset, else the file's place."""
    import json

    from ..config import list_presets, load_config
    from ..store.directory import campaign_identity, identity_changes

    name = camp.name
    if name in list_presets():
        stored = campaign_identity(json.loads(camp.config.to_json()))
        preset = campaign_identity(json.loads(load_config(name).to_json()))
        changes = identity_changes(preset, stored)
        seed = stored.get("campaign", {}).get("seed")
        if all(c.startswith("[campaign] seed:") for c in changes):
            return (f"fdd-campaign run {name}{f' --seed {seed}' if changes else ''} "
                    f"--out {directory}")
    return f"fdd-campaign run CAMPAIGN.toml --out {directory} (the file it was started with)"


def write_html_report(args, camp=None) -> None:
    """The HTML part of ``fdd-campaign report`` (after the table is printed), from *camp*
    when the command has loaded it already."""
    from ..report_build import ReportSettings, build_report

    path = build_report(camp if camp is not None else args.dir, out=args.html,
                        jobs=args.jobs, fmu=args.fmu,
                        settings=ReportSettings(envelope_runs=args.envelope_runs),
                        requirements=getattr(args, "requirements_values", None),
                        progress=not getattr(args, "quiet", False))
    print(f"HTML report written to {path}")


def cmd_show(args) -> int:
    from ..report_build import show_run

    for option in ("plot", "out"):
        if getattr(args, option):
            check_writable(getattr(args, option), f"--{option}")
    show_run(args.dir, args.run_id, plot=args.plot, out=args.out, fmu=args.fmu)
    return 0


def cmd_compare(args) -> int:
    from ..compare import compare_dirs

    if not 0.0 < args.alpha < 1.0:
        raise UsageError(f"--alpha {args.alpha}: a significance level in (0, 1); fix: e.g. "
                         "--alpha 0.01")
    compare_dirs(args.dir_a, args.dir_b, alpha=args.alpha)
    return 0


def add_result_parsers(subs) -> None:
    """Sub-commands: read a campaign directory: report, show, compare, verify, gate."""
    p = add_command(subs, "report", "print the summary of a campaign directory and write its HTML "
             "report (DIR/report.html)", "fdd-campaign report results/", cmd_report)
    p.add_argument("dir", help="campaign (or suite) directory written by 'fdd-campaign run'")
    p.add_argument("--no-html", action="store_true", help="only print the table")
    p.add_argument("--html", help="HTML file to write (default DIR/report.html)")
    p.add_argument("--jobs", type=int, default=2,
                   help="threads re-simulating runs and processes drawing figures (default 2)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress lines on stderr (the stages, the runs re-simulated, "
                        "the figures drawn)")
    p.add_argument("--envelope-runs", type=int,
                   help="re-simulate at most this many fault-free runs per manoeuvre for the "
                        "envelopes (default all; the worst-margin runs are always kept)")
    creq.add_requirements_option(p)
    p.add_argument("--fmu", metavar="FILE", help="re-simulate on this FMU (docs/security.md)")

    p = add_command(subs, "show", "re-simulate one run of a campaign from its run id and seed",
             "fdd-campaign show results/ RUN_ID --plot run.png --out run.parquet\n  (RUN_ID: "
             "a run id of results/plan.parquet, e.g. one 'fdd-campaign gate results/' names)",
             cmd_show)
    p.add_argument("dir", help="campaign directory written by 'fdd-campaign run'")
    p.add_argument("run_id", help="run id of plan.parquet (listed in report.html, and by "
                   "'gate' for its failing runs)")
    p.add_argument("--plot", help="PNG file: signals, |r|/τ and alarms of every detector")
    p.add_argument("--out", help="Parquet file for the traces")
    p.add_argument("--fmu", metavar="FILE", help="re-simulate on this FMU (docs/security.md)")

    p = add_command(subs, "compare", "what changed between two campaigns: rates with a "
                    "significance test, DTP shifts, per cell",
                    "fdd-campaign compare results-v1/ results-v2/", cmd_compare)
    p.add_argument("dir_a", help="campaign directory A (the reference)")
    p.add_argument("dir_b", help="campaign directory B (compared with A)")
    p.add_argument("--alpha", type=float, default=0.01,
                   help="significance level of the worse/better flags (default 0.01)")

    p = add_command(subs, "verify", "check every file of a campaign directory against its manifest "
             "(SHA-256); exit 2 naming each file that differs, is missing or is extra",
             "fdd-campaign verify results/", cmd_verify)
    p.add_argument("dir", help="campaign (or suite) directory written by 'fdd-campaign run'")

    p = add_command(subs, "gate", "check a campaign against its requirements (exit 1 on failure)",
             "fdd-campaign gate results/ --max-fa 0 --junit gate.xml", cmd_gate)
    p.add_argument("dir", help="campaign (or suite) directory written by 'fdd-campaign run'")
    p.add_argument("--max-fa", type=float, help="largest false-alarm rate of every detector "
                   "(default: the campaign file's, per-detector allowances included)")
    p.add_argument("--max-md", type=float, help="largest missed-detection rate (default: "
                   "unchecked, or the campaign file's with --all-requirements)")
    p.add_argument("--max-dtp", type=float, help="largest DTP (default: unchecked, or the "
                   "campaign file's with --all-requirements)")
    p.add_argument("--all-requirements", action="store_true",
                   help="also check the campaign file's max_md_rate and max_dtp (the verdict "
                        "of report.html); without it only false alarms and errors are gated")
    p.add_argument("--allow-errors", action="store_true", help="do not fail on runs in error")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="gate a campaign that has not finished every run of its plan (without "
                        "it, an unfinished campaign fails: the gate is never green on part of "
                        "the evidence)")
    p.add_argument("--max-fa-prob", type=float, metavar="P",
                   help="largest per-run false-alarm probability bound of DIR/certificate.parquet "
                        "(the tail fit's, or the sampled one's when present; made by 'fdd-campaign "
                        "certify DIR' when absent; docs/evidence.md)")
    creq.add_requirements_option(p)
    p.add_argument("--junit", help="write a JUnit XML report to this file")
    from .tradeoff import add_threshold_scale_option
    from .worst_case import add_worst_case_options

    add_worst_case_options(p)
    add_threshold_scale_option(p)
