"""``fdd-campaign``: the command line (docs/design.md §7, Command line). Exit codes: 0 ok, 1 gate
failed, 2 bad input, 3 internal error, 130 interrupted."""

from __future__ import annotations

import argparse
import sys
import textwrap
import warnings
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from scenarios.errors import InputError

from . import requirements as creq
from .common import (  # noqa: F401  (part of this module's interface)
    EXIT_GATE,
    EXIT_INPUT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    UsageError,
    add_command,
    check_writable,
    print_error,
    report_internal_error,
)
from ..isolation import roles_of_stored
from ..startup import defer_collection, start_up_done


# ---- the command line's overrides ---------------------------------------------------------
def _overridden(config, args):
    """*config* with the command line's --seed, --plant, --manoeuvres and --turbulence."""
    from .. import config as cfg

    if args.seed is not None:
        config = cfg.with_overrides(config, seed=args.seed)
    if getattr(args, "plant", None) is not None:
        from scenarios.catalog import PLANT_KINDS

        if args.plant in PLANT_KINDS:
            problem = cfg.preset_plant_problem(getattr(args, "campaign", ""), args.plant)
            if problem:
                raise UsageError(problem)
            values = {"plant.kind": args.plant}
        elif args.plant.lower().endswith(".fmu") or Path(args.plant).exists():
            values = {"plant.fmu": args.plant}
        else:
            from scenarios.catalog import suggest

            raise UsageError(f"--plant {args.plant}: neither a plant kind "
                             f"({', '.join(PLANT_KINDS)}){suggest(args.plant, PLANT_KINDS)} "
                             "nor an .fmu file; fix: name a kind or an existing FMU file")
        config = cfg.with_overrides(config, values=values)
    if getattr(args, "manoeuvres", None) is not None:
        config = cfg.with_overrides(config, values={"manoeuvres.set": args.manoeuvres})
    if getattr(args, "turbulence", None) is not None:
        config = cfg.with_overrides(config, values={"plant.turbulence": args.turbulence})
    return config


def _tls_files(args):
    """The --tls-* options as :class:`campaign.execute.TlsFiles` (None when none is given)."""
    from ..execute import TlsFiles

    files = TlsFiles(ca_file=args.tls_ca_file, cert=args.tls_cert, key=args.tls_key)
    if files.given() and not args.scheduler:
        raise UsageError(f"{', '.join(files.given())} apply to a dask cluster: give "
                         "--scheduler tls://HOST:PORT too")
    return files if files.given() else None


def _run_campaign(config, out, args):
    from ..runner import run

    before = creq.runs_done(out)
    result = run(config, out, jobs=args.jobs, chunk_size=args.chunk_size,
                 progress=not args.quiet, backend=args.backend, scheduler=args.scheduler,
                 engine=args.engine, tls=_tls_files(args),
                 fitted_from=getattr(args, "fitted_from", None))
    print(creq.runs_line(config, result, before))
    if not result.summary.empty:
        print(result.table())
    if result.detection_times is not None:   # fixed-scenario campaigns, e.g. comb-table1
        from reports.detection_times import format_detection_times

        print(format_detection_times(result.detection_times))
    return result, creq.print_verdict(config, result)


# ---- one campaign or a suite: what a command works on -----------------------------------
@dataclass(frozen=True)
class _Campaigns:
    """The campaigns a command that runs a campaign file or a suite works on: iterating gives
    ``(title, configuration, output directory)`` of each — the campaign itself into ``--out``
    (title None), or each member of a suite into ``--out/<member>``."""
    members: tuple

    @property
    def suite(self) -> bool:
        return self.members[0][0] is not None

    def __iter__(self):
        return iter(self.members)


def _campaigns(spec, args) -> _Campaigns:
    """:class:`_Campaigns` of *spec* (a campaign configuration or a
    :class:`campaign.suite.Suite`). Every configuration (with the command line's
    overrides) is built, hence checked, before the first campaign starts."""
    from ..suite import Suite

    if not isinstance(spec, Suite):
        return _Campaigns(((None, _overridden(spec, args), Path(args.out)),))
    return _Campaigns(tuple((m.title, _overridden(m.config, args), Path(args.out) / m.name)
                            for m in spec.members))


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


# ---- commands ------------------------------------------------------------------------------
def cmd_run(args) -> int:
    from ..suite import load_spec, write_suite_json

    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: must be ≥ 1 (local workers); fix: e.g. --jobs 2")
    spec = load_spec(args.campaign)
    check_writable(args.out, "--out", directory=True)
    campaigns = _campaigns(spec, args)
    suite = campaigns.suite
    complete: dict[str, bool] = {}
    if suite:
        _check_suite_run(spec, campaigns, args)
        write_suite_json(spec, args.out, complete)
    else:
        creq.refuse_limits_only_change(campaigns.members[0][1], args)
    evaluated = True
    for title, config, out in campaigns:
        if suite:
            print(f"\n== {title} ==")
        result, ok = _run_campaign(config, out, args)
        evaluated = evaluated and ok
        if suite:
            complete[out.name] = bool(result.complete)
            write_suite_json(spec, args.out, complete)
        if not result.complete:
            return EXIT_INTERRUPTED
    if suite:
        print(f"\nsuite {spec.name!r}: {len(campaigns.members)} campaigns -> {Path(args.out)}")
    return EXIT_OK if evaluated else EXIT_INPUT


def _check_suite_run(suite, campaigns: _Campaigns, args) -> None:
    """Refuse, before the first member runs, what a suite cannot be run with: --fitted-from,
    a member's options out of range, an --out that is one campaign's directory."""
    from ..runner import check_run_options
    from ..store.directory import CampaignDir

    if getattr(args, "fitted_from", None):
        raise UsageError(f"--fitted-from: one campaign only, not the suite {suite.name!r}")
    for _, config, _ in campaigns:
        check_run_options(config, jobs=args.jobs, chunk_size=args.chunk_size)
    if CampaignDir(args.out).is_campaign():
        raise UsageError(f"{args.out} is the directory of one campaign; a suite writes its "
                         "campaigns into subdirectories of a directory of its own: choose "
                         "another --out")


def cmd_plan(args) -> int:
    from ..suite import load_spec

    spec = load_spec(args.campaign)
    check_writable(args.out, "--out", directory=True)
    for title, config, out in _campaigns(spec, args):
        if title is not None:
            print(f"== {title} ==")
        _plan_one(config, out)
    return EXIT_OK


def _plan_one(config, out: Path) -> None:
    from ..design import MODEL_VERSION, PlanBlocks, build_learning_plan, plan_counts
    from ..store.directory import CampaignDir

    from ..runner import remove_created, start_state

    blocks = PlanBlocks(config)
    cdir = CampaignDir(out)
    existed, fresh = start_state(out)
    with cdir.locked():
        # the campaign's directory, as run makes it: a run into it starts from there
        cdir.check_model_version(MODEL_VERSION)
        try:
            cdir.open(config.to_json(), log=partial(print, file=sys.stderr))
            # written as it is made: a plan it refuses (a group without enough realistic
            # points, two equal runs) leaves no directory behind
            cdir.write_plan(blocks, config.to_json(), MODEL_VERSION)
        except BaseException:
            if fresh:
                remove_created(out, existed)
            raise
    learning = build_learning_plan(config)
    counts = plan_counts(cdir.plan_batches(columns=["group", "fault", "manoeuvre"]))
    free = int(counts.loc[counts["fault"] == "none", "runs"].sum())
    total = int(counts["runs"].sum())
    print(counts.to_string(index=False))
    print(f"total: {total} runs ({free} fault-free, {total - free} faulty); learning set: "
          f"{len(learning)} runs")
    print(f"run table written to {cdir.plan_path}")


def cmd_gate(args) -> int:
    from reports.gate import write_junit, write_junit_suite

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
    from reports.gate import requirements_gate

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
    result = requirements_gate(camp.summary, camp.gate_results, limits, all_requirements=True,
                               roles=roles_of_stored(meta.get("config")),
                               coverage=camp.coverage, allow_errors=args.allow_errors,
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
    from reports.table import error_lines

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
    from ..replay import ReportSettings, build_report

    path = build_report(camp if camp is not None else args.dir, out=args.html,
                        jobs=args.jobs, fmu=args.fmu,
                        settings=ReportSettings(envelope_runs=args.envelope_runs),
                        requirements=getattr(args, "requirements_values", None),
                        progress=not getattr(args, "quiet", False))
    print(f"HTML report written to {path}")


def cmd_show(args) -> int:
    from ..replay import show_run

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


def cmd_presets(args) -> int:
    from ..config import list_presets
    from ..suite import list_suites

    for name, description in list_presets().items():
        print(f"{name:16s} {description}")
    for name, description in list_suites().items():
        print(f"{name:16s} (suite) {description}")
    return EXIT_OK


def cmd_init(args) -> int:
    from ..config import init_text

    path = Path(args.file)
    if path.exists() and not args.force:
        raise UsageError(f"{path} exists; use --force to overwrite it")
    check_writable(path, "init")
    path.write_text(init_text())
    print(f"wrote {path}; check it with: fdd-campaign plan {path} --out {_out_dir(path)}, run "
          f"it with: fdd-campaign run {path} --out {_out_dir(path)}")
    return EXIT_OK


def _out_dir(file: Path) -> str:
    """The directory a hint runs *file* into: its name (not the README's ``results/``)."""
    return f"{file.with_suffix('')}/"


def cmd_simulate(args) -> int:
    from scenarios.catalog import AIRCRAFT_KINDS
    from scenarios.plants import get_plant
    from scenarios.simulate import single_run

    for option in ("plot", "out"):
        if getattr(args, option):
            check_writable(getattr(args, option), f"--{option}")
    plant = get_plant(args.plant)
    plant.check((args.fault,))          # e.g. JSBSim not installed: exit 2 naming the extra
    if args.surface in plant.surfaces:
        surface = args.surface
    elif plant.kind in AIRCRAFT_KINDS:      # elevator/aileron: their left surface
        surface = plant.run_surface(args.surface)
    else:
        raise UsageError(f"invalid choice --surface {args.surface} at the actuator plant "
                         f"level: it is an aircraft surface; use --plant aircraft, or one "
                         f"of {', '.join(plant.surfaces)}")
    magnitude = _simulate_magnitude(args, plant.actuator(surface))
    runs = single_run(surface, args.manoeuvre, args.fault, seed=args.seed,
                      onset_s=args.onset, duration_s=args.duration,
                      **({} if magnitude is None else {"magnitude": magnitude}))
    signals, truth = plant.simulate(runs, pressure_sensor=args.pressure)
    frame = signals.to_pandas(0)
    frame["true_rod [mm]"] = truth.rod_mm[0]
    frame["true_surface [deg]"] = truth.surface_deg[0]
    frame["true_current [mA]"] = truth.current_mA[0]
    for name, series in (truth.surfaces_deg or {}).items():
        frame[f"true_{name} [deg]"] = series[0]
    onset = float(truth.onset_s[0])
    print(f"{args.surface} / {args.manoeuvre} / fault {args.fault}"
          + (f" at {onset:.2f} s" if onset == onset else "")
          + f": {signals.n_steps} steps of {signals.ts * 1000:.0f} ms")
    if args.out:
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(frame.reset_index())
        table = table.replace_schema_metadata({
            **(table.schema.metadata or {}),
            b"fdd_campaign": runs.to_json(orient="records").encode()})
        pq.write_table(table, args.out)
        print(f"signals and truth written to {args.out}")
    if args.plot and plant.kind in AIRCRAFT_KINDS:
        from reports.aircraft_plot import plot_aircraft_run

        plot_aircraft_run(frame, onset_s=onset, path=args.plot, monitored=str(runs["surface"].iloc[0]),
                          title=f"{runs['surface'].iloc[0]} — {args.manoeuvre} — {args.fault}")
        print(f"plot written to {args.plot}")
    elif args.plot:
        from reports.plots import plot_run

        plot_run(frame, onset_s=onset, title=f"{args.surface} — {args.manoeuvre} — {args.fault}",
                 path=args.plot)
        print(f"plot written to {args.plot}")
    return EXIT_OK


#: How ``simulate`` spells the [[group]] keys of a fault (its options).
_SIMULATE_NAMES = {"magnitude": "--magnitude", "variant": "--variant", "sign": "--sign",
                   "onset_s": "--onset", "duration_s": "--duration"}


def _simulate_magnitude(args, act) -> float | None:
    """The run-table magnitude of ``simulate``'s fault (None: the single run's default,
    :func:`scenarios.faults.default_magnitude`). ``--magnitude``, ``--variant`` and ``--sign``
    follow the rules of a campaign file's ``[[group]]`` keys of the same names
    (:func:`campaign.config.rules.single_fault_problems`: the unit and bounds of the fault's
    ``[faults.*]`` range, a jam's % of the deflection range; exit 2 naming the option), and
    become a run-table magnitude as a group's do (:func:`campaign.design.fixed_magnitude`)."""
    import numpy as np

    from scenarios.faults import FAULT_DEFAULTS, default_magnitude, solid_jam_offset_mm

    from ..config.rules import single_fault_problems
    from ..design import fixed_magnitude

    problems = single_fault_problems(args.fault, magnitude=args.magnitude,
                                     variant=args.variant, sign=args.sign, onset_s=args.onset,
                                     duration_s=args.duration, names=_SIMULATE_NAMES)
    if problems:
        raise UsageError("; ".join(problems))
    direction = np.array([-1.0 if args.sign == "negative" else 1.0])
    if args.magnitude is not None:
        return float(fixed_magnitude(args.fault, args.magnitude, direction, act)[0])
    if args.fault == "solid_jam" and args.variant == "offset":
        return float(direction[0] * solid_jam_offset_mm(
            act, FAULT_DEFAULTS.solid_jam_offset_pct_range))
    if args.sign is not None:
        return float(direction[0] * abs(default_magnitude(args.fault, act)))
    return None


def cmd_bench(args) -> int:
    from ..tools.bench import bench
    bench(n_runs=args.runs, duration_s=args.duration, jobs=args.jobs, chunk_size=args.chunk_size,
          reference_runs=args.reference_runs, plant=args.plant, plant_runs=args.plant_runs,
          campaign=None if args.campaign == "none" else args.campaign, cold=not args.no_cold,
          detectors=not args.no_detectors, stages=not args.no_stages, stage_runs=args.stage_runs,
          progress=None if args.quiet else partial(print, file=sys.stderr, flush=True),
          floor=not args.no_floor, yardstick=args.yardstick, yardstick_dir=args.yardstick_dir,
          pairs=args.pairs)
    return EXIT_OK


def cmd_study_vanek(args) -> int:
    from ..tools.studies.vanek import run_study

    if not args.noise_scale > 0.0:
        raise UsageError(f"--noise-scale must be > 0, got {args.noise_scale}")
    run_study(args.noise_scale, args.seed)
    return EXIT_OK


def cmd_study_chen_flight_data(args) -> int:
    from ..tools.studies.chen_flight_data import run_study

    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: must be ≥ 1 (local workers); fix: e.g. --jobs 2")
    check_writable(args.out, "--out", directory=True)
    table = run_study(args.out, seed=args.seed, levels=args.levels, jobs=args.jobs,
                      turbulence=args.turbulence, progress=not args.quiet,
                      fault_free=args.fault_free, disconnections=args.disconnections,
                      learning_runs=args.learning_runs)
    return EXIT_INTERRUPTED if table is None else EXIT_OK


def cmd_study_vanek_jam_limit(args) -> int:
    from ..tools.studies.vanek_jam_limit import run_study

    if not abs(args.bias_deg) < 5.0:
        raise UsageError(f"--bias-deg {args.bias_deg}: a β-vane bias must be below 5° in size; "
                         "fix: e.g. --bias-deg 0.02")
    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: must be ≥ 1 (local workers); fix: e.g. --jobs 2")
    table = run_study(args.directory, group=args.group, bias_deg=args.bias_deg,
                      seed=args.seed, jobs=args.jobs, learning_runs=args.learning_runs,
                      progress=not args.quiet)
    return EXIT_INTERRUPTED if table is None else EXIT_OK


def cmd_study_saturation(args) -> int:
    from scenarios.aircraft.data import AIRCRAFT_SURFACES

    from ..tools.studies.saturation import run_study

    bad = [s for s in args.surfaces if s not in AIRCRAFT_SURFACES]
    if bad:
        raise UsageError(f"--surfaces: unknown aircraft surface(s) {', '.join(bad)}; allowed: "
                         f"{', '.join(AIRCRAFT_SURFACES)}")
    if args.runs < 1:
        raise UsageError(f"--runs must be at least 1 (runs per manoeuvre and seed), got {args.runs}")
    if not args.duration > 0.0:
        raise UsageError(f"--duration must be > 0 s, got {args.duration}")
    run_study(tuple(args.seeds), tuple(args.surfaces), args.runs, args.duration,
              args.turbulence, args.manoeuvres,
              progress=None if args.quiet else partial(print, file=sys.stderr, flush=True))
    return EXIT_OK


def cmd_fmu(args) -> int:
    from scenarios.fmu_build import build_servo_fmu

    check_writable(args.out, "--out")
    out = build_servo_fmu(args.out, surface=args.surface, fmi=args.fmi,     # FmuBuildError: exit 2
                          log=(lambda m: print(m, file=sys.stderr)) if args.verbose else None)
    print(f"built and validated {out} (FMI {args.fmi}.0 co-simulation, {args.surface} defaults); run a "
          f"campaign on it with: fdd-campaign run smoke --plant {out} --out "
          f"{_out_dir(Path(out))}")
    return EXIT_OK


# ---- parser --------------------------------------------------------------------------------
def _manoeuvres_option(p) -> None:
    from scenarios.catalog import MANOEUVRE_SETS
    from scenarios.turbulence import LEVELS

    p.add_argument("--manoeuvres", choices=MANOEUVRE_SETS,
                   help="manoeuvre set (overrides [manoeuvres] set): normal operations, or "
                        "stress (turns rolled in at 15 deg/s, amplitudes at their high end; "
                        "docs/physics.md §7)")
    p.add_argument("--turbulence", choices=tuple(LEVELS),
                   help="aircraft plant: the Dryden turbulence it flies in (overrides [plant] "
                        "turbulence; none: calm air, as the ADDSAFE runs of [CHEN]; "
                        "docs/physics.md §7.2)")


def _add_run_parsers(subs) -> None:
    """Sub-commands: run and plan a campaign."""
    p = add_command(subs, "run", "run a campaign (a preset name or a campaign file) into a directory",
             "fdd-campaign run addsafe-mc --jobs 2 --out results/", cmd_run)
    p.add_argument("campaign", help="preset name (see 'fdd-campaign presets') or a .toml file")
    p.add_argument("--out", required=True, help="output directory (rerun into it to resume)")
    p.add_argument("--jobs", type=int, default=2,
                   help="local workers (default 2; threads or processes, see --backend)")
    p.add_argument("--seed", type=int, help="override the campaign seed")
    p.add_argument("--chunk-size", type=int, help="runs per chunk (default: campaign file)")
    p.add_argument("--backend", choices=["threading", "loky"],
                   help="local workers: threading (default; measured faster and lighter) or "
                        "loky processes (survive a dying worker; default when [runner] "
                        "run_timeout_s is set)")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.add_argument("--plant", metavar="LEVEL|FMU",
                   help="actuator, aircraft or jsbsim (overrides [plant] kind; see "
                        "docs/aircraft.md; jsbsim needs the [jsbsim] extra), "
                        "or a co-simulation FMU file to simulate the actuator on (sets [plant] fmu; "
                        "see docs/fmu.md)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the chunks on this dask.distributed scheduler's workers "
                        "(needs the [dask] extra; tls://HOST:PORT with the --tls-* options or "
                        "dask's distributed.comm.tls configuration; see docs/security.md)")
    p.add_argument("--tls-ca-file", metavar="FILE",
                   help="CA certificate (PEM) that signed the cluster's certificates")
    p.add_argument("--tls-cert", metavar="FILE",
                   help="client certificate (PEM) for a tls:// scheduler")
    p.add_argument("--tls-key", metavar="FILE",
                   help="private key of --tls-cert (PEM), unless that file holds it")
    p.add_argument("--engine", choices=["compiled", "numpy"],
                   help="time-loop kernels (default: the campaign file's [runner] engine)")
    _manoeuvres_option(p)
    p.add_argument("--fitted-from", metavar="DIR",
                   help="evaluate the detectors fitted in campaign directory DIR (same [[detector]] "
                        "entries) without learning again (copied into --out; docs/thresholds.md)")

    p = add_command(subs, "plan", "write the run table of a campaign and print its counts",
             "fdd-campaign plan addsafe-grid --out grid/", cmd_plan)
    p.add_argument("campaign", help="preset name (see 'fdd-campaign presets') or a .toml file")
    p.add_argument("--out", required=True, help="directory to write plan.parquet into "
                   "(a suite: one subdirectory per campaign)")
    p.add_argument("--seed", type=int, help="override the campaign seed")
    _manoeuvres_option(p)


def _add_result_parsers(subs) -> None:
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

    p = add_command(subs, "compare", "what changed between two campaigns: rates with a significance "
             "test, DTP shifts, per cell", "fdd-campaign compare results-v1/ results-v2/",
             cmd_compare)
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


def _add_simulate_parser(subs) -> None:
    """Sub-commands: simulate one run."""
    from scenarios.aircraft.data import AIRCRAFT_SURFACES
    from scenarios.catalog import PLANT_KINDS
    from scenarios.catalog import FAULTS, MANOEUVRES, SURFACES
    from scenarios.faults import SOLID_JAM_VARIANTS

    from ..config.sections import SIGNED_FAULT_DIRECTIONS

    p = add_command(subs, "simulate", "simulate one run and write/plot its signals and truth",
             "fdd-campaign simulate --surface elevator --manoeuvre turn_coordination "
             "--fault solid_jam --plot run.png --out run.parquet", cmd_simulate)
    p.add_argument("--surface", default="elevator", choices=SURFACES + AIRCRAFT_SURFACES,
                   help="surface (with --plant aircraft or jsbsim: the monitored one; elevator → "
                   "left_elevator, aileron → left_inboard_aileron)")
    p.add_argument("--plant", default="actuator", choices=PLANT_KINDS,
                   help="actuator: the servo-loop alone; aircraft: aircraft, laws and every "
                   "surface in the loop; jsbsim: JSBSim's 737 flown by the same laws and "
                   "servo-loops (the [jsbsim] extra)")
    p.add_argument("--manoeuvre", default="cruise", choices=MANOEUVRES,
                   help="manoeuvre (default cruise; docs/physics.md §7)")
    p.add_argument("--fault", default="none", choices=FAULTS,
                   help="fault injected at --onset (default none; docs/physics.md §5)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random draw (default 0)")
    p.add_argument("--onset", type=float, default=10.0, help="fault onset [s] (default 10)")
    p.add_argument("--magnitude", type=float,
                   help="fixed fault magnitude, > 0, in the unit and within the bounds of a "
                        "campaign file's [[group]] magnitude: runaway deg/s, liquid_jam and "
                        "solid_jam (with --variant offset) %% of the deflection range, "
                        "ofc_liquid mA, ofc_solid mm (default: docs/physics.md §5, Default "
                        "magnitudes)")
    p.add_argument("--variant", choices=SOLID_JAM_VARIANTS,
                   help="solid_jam only: seized (default; no magnitude) or offset (seized "
                        "--magnitude %% of the deflection range away)")
    p.add_argument("--sign", choices=SIGNED_FAULT_DIRECTIONS,
                   help="direction of a runaway, hardover, liquid_jam or offset solid_jam "
                        "(default positive)")
    p.add_argument("--duration", type=float, default=30.0, help="run duration [s]")
    p.add_argument("--pressure", action="store_true", help="simulate the chamber pressure sensor")
    p.add_argument("--out", help="Parquet file for the signals and the truth")
    p.add_argument("--plot", help="PNG file for a plot of the run")


def _add_tool_parsers(subs) -> None:
    """Sub-commands: presets, init, bench and the FMU tools."""
    from scenarios.catalog import SURFACES

    add_command(subs, "presets", "list the campaign presets shipped with the package",
         "fdd-campaign presets", cmd_presets)

    p = add_command(subs, "init", "write an annotated starting campaign file",
             "fdd-campaign init campaign.toml", cmd_init)
    p.add_argument("file", nargs="?", default="campaign.toml",
                   help="campaign file to write (default campaign.toml)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")

    p = add_command(subs, "bench", "measure simulation speed, memory and the ratio to the per-run "
             "reference", "fdd-campaign bench --runs 2200 --jobs 2", cmd_bench)
    p.add_argument("--runs", type=int, default=2200, help="runs simulated (default 2200)")
    p.add_argument("--duration", type=float, default=60.0,
                   help="run duration [s] (default 60)")
    p.add_argument("--jobs", type=int, default=2, help="local workers (default 2)")
    p.add_argument("--chunk-size", type=int, default=275,
                   help="runs per chunk (default 275)")
    p.add_argument("--reference-runs", type=int, default=2,
                   help="runs timed with the solve_ivp reference (default 2)")
    p.add_argument("--campaign", default="addsafe-mc", help="campaign(s) run whole, and "
                   "stage by stage (default addsafe-mc; e.g. addsafe-mc,chen-mc; none: skip)")
    p.add_argument("--no-stages", action="store_true", help="skip the stage shares")
    p.add_argument("--no-floor", action="store_true", help="skip the arithmetic floor "
                   "(rate-law evaluations x their measured cost + imports) and the ratio to it")
    p.add_argument("--yardstick", metavar="CMD", help="a command timed back to back with each "
                   "campaign (e.g. 'python campaign.py vec'): wall and CPU ratios per pair and "
                   "their medians")
    p.add_argument("--yardstick-dir", metavar="DIR", help="directory the yardstick runs in")
    p.add_argument("--pairs", type=int, default=3,
                   help="rounds of yardstick and campaign, back to back (default 3)")
    p.add_argument("--stage-runs", type=int, default=200, help="runs timed stage by stage")
    p.add_argument("--no-cold", action="store_true",
                   help="skip the first campaign run with an empty compile cache")
    p.add_argument("--no-detectors", action="store_true",
                   help="skip the per-detector cost per run-step")
    p.add_argument("--plant", metavar="FMU", help="also time this FMU plant (per-run cost "
                   "beside the built-in plant)")
    p.add_argument("--plant-runs", type=int, default=40,
                   help="runs timed on the FMU plant (default 40)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")

    fmu = subs.add_parser("fmu", help="build the built-in servo-loop as an FMU",
                          description="FMU tools")
    fsubs = fmu.add_subparsers(dest="fmu_command", metavar="FMU_COMMAND", required=True)
    p = add_command(fsubs, "build", "compile the servo-loop C sources into an FMI 2.0 co-simulation "
             "FMU and validate it with fmpy", "fdd-campaign fmu build --out servo.fmu", cmd_fmu)
    p.add_argument("--out", default="servo.fmu", help="FMU file to write (default servo.fmu)")
    p.add_argument("--surface", default="elevator", choices=SURFACES,
                   help="surface whose parameters are the FMU's start values")
    p.add_argument("--fmi", default="2", choices=["2", "3"], help="FMI version (default 2)")
    p.add_argument("--verbose", action="store_true", help="print the compiler command")

def _add_study_parsers(subs) -> None:
    """Sub-commands: the studies (``fdd-campaign study NAME``, :mod:`campaign.tools.studies`)."""
    study = subs.add_parser("study", help="reproduce a published comparison or count the "
                            "aircraft laws' surface activity (one table)",
                            description="studies: fixed comparisons reproduced from a paper and "
                                        "censuses of the model, one table each "
                                        "(campaign.tools.studies)")
    ssubs = study.add_subparsers(dest="study", metavar="STUDY", required=True)
    p = add_command(ssubs, "vanek", "LTI against LPV geometric filter on the scenarios of [VANEK] §5: "
             "residual peaks, thresholds, detection delays and DTP (docs/vanek-geometric.md)",
             "fdd-campaign study vanek --noise-scale 0.1", cmd_study_vanek)
    p.add_argument("--noise-scale", type=float, default=1.0,
                   help="factor on the σ of every aircraft sensor (default 1)")
    p.add_argument("--seed", type=int, default=0, help="seed of the scenarios (default 0)")
    p = add_command(ssubs, "chen-flight-data", "the global [CHEN] estimators (chen-global, "
                    "chen-global-paper with its calibrated and its max threshold) on chen-mc's "
                    "fault-free and disconnection runs at several sizes of the [CHEN] Table-2 "
                    "flight-data errors (VCAS, altitude, mass, CG): false alarms, misses and "
                    "delays per size (docs/chen-estimator.md §5.2)",
                    "fdd-campaign study chen-flight-data --seed 4711 --jobs 2 --out fd/",
                    cmd_study_chen_flight_data)
    p.add_argument("--out", required=True, help="directory of the campaigns, one per size "
                   "(rerun into it to resume)")
    p.add_argument("--seed", type=int, default=None, help="campaign seed (default: chen-mc's)")
    p.add_argument("--levels", type=float, nargs="+", default=[0.10, 0.05, 0.02, 0.0],
                   metavar="W", help="relative half-widths of the VCAS, altitude, mass and CG "
                   "errors, each 0–0.5 (default 0.1 0.05 0.02 0: [CHEN] Table 2's ±10 %%, then "
                   "smaller)")
    p.add_argument("--jobs", type=int, default=2, help="local workers (default 2)")
    p.add_argument("--turbulence", choices=["moderate", "none"], default=None,
                   help="the Dryden turbulence flown (default: chen-mc's calm air)")
    p.add_argument("--fault-free", type=int, default=None, metavar="N",
                   help="fault-free runs per manoeuvre (default chen-mc's 200)")
    p.add_argument("--disconnections", type=int, default=None, metavar="N",
                   help="disconnection runs (default chen-mc's 334)")
    p.add_argument("--learning-runs", type=int, default=None, metavar="N",
                   help="learning runs per manoeuvre (default chen-mc's 50)")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p = add_command(ssubs, "vanek-jam-limit", "why vanek-geometric's LPV filter misses most "
                    "default-size aileron jams: each jam run of a vanek-scenarios campaign "
                    "beside its fault-free twin — steady residual, τ0, the allowance b(t) and "
                    "its largest Table-2 term, the effect of a β-vane bias "
                    "(docs/vanek-geometric.md)",
                    "fdd-campaign study vanek-jam-limit vanek-jams/ --seed 90210",
                    cmd_study_vanek_jam_limit)
    p.add_argument("directory", help="a vanek-scenarios campaign directory (or a vanek-section5 "
                   "suite directory); an empty or new one gets the preset run into it first")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the campaign run into an empty directory (default the "
                   "preset's); with a finished one, its seed or nothing")
    p.add_argument("--jobs", type=int, default=2, help="local workers (default 2)")
    p.add_argument("--learning-runs", type=int, default=None, metavar="N",
                   help="learning runs of the campaign run into an empty directory "
                   "(default the preset's 60)")
    p.add_argument("--group", default="liquid-jam-default",
                   help="the jam group studied (default liquid-jam-default)")
    p.add_argument("--bias-deg", type=float, default=0.02,
                   help="constant bias added to the β vane of the fault-free twins [deg] "
                   "(default 0.02)")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    from scenarios.catalog import MANOEUVRE_SETS
    from scenarios.turbulence import LEVELS

    from ..tools.studies import saturation

    p = add_command(ssubs, "saturation", "census of the control laws on the aircraft plant: per "
             "monitored surface and manoeuvre, fault-free runs in turbulence whose servo "
             "current saturates, extreme deflections and RMS surface rate (docs/aircraft.md §5)",
             "fdd-campaign study saturation --seeds 52361 70913 --runs 50", cmd_study_saturation)
    p.add_argument("--seeds", type=int, nargs="+", default=list(saturation.DEFAULT_SEEDS),
                   help="campaign seeds of the sampled runs (default: "
                        f"{' '.join(map(str, saturation.DEFAULT_SEEDS))})")
    p.add_argument("--runs", type=int, default=saturation.DEFAULT_RUNS,
                   help=f"fault-free runs per manoeuvre and seed (default {saturation.DEFAULT_RUNS})")
    p.add_argument("--duration", type=float, default=saturation.DEFAULT_DURATION_S,
                   help=f"run duration [s] (default {saturation.DEFAULT_DURATION_S:g})")
    p.add_argument("--surfaces", nargs="+", default=list(saturation.DEFAULT_SURFACES),
                   help="monitored surfaces (default: "
                        f"{' '.join(saturation.DEFAULT_SURFACES)})")
    p.add_argument("--turbulence", choices=tuple(LEVELS), default="moderate",
                   help="Dryden turbulence level (default moderate)")
    p.add_argument("--manoeuvres", choices=MANOEUVRE_SETS, default="normal",
                   help="manoeuvre set (default normal; stress: turns rolled in at 15 deg/s, "
                        "amplitudes at their high end, docs/physics.md §7)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fdd-campaign",
        description="Monte Carlo evaluation campaigns for control-surface fault detectors: "
                    "false alarms, missed detections and detection time performance (DTP).",
        epilog=textwrap.dedent("""\
            examples:
              fdd-campaign run addsafe-mc --jobs 2 --out results/
              fdd-campaign gate results/ --junit gate.xml
              fdd-campaign simulate --surface elevator --manoeuvre turn_coordination \\
                  --fault solid_jam --plot run.png --out run.parquet"""),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    from ..store.files import UNKNOWN_VERSION, engine_version

    v = engine_version()
    v += " (not installed)" if v == UNKNOWN_VERSION else ""
    parser.add_argument("--version", action="version", version=f"fdd-campaign {v}")
    subs = parser.add_subparsers(dest="command", metavar="COMMAND")
    from .evidence import add_evidence_parsers
    from .falsify import add_falsify_parser
    from .tradeoff import add_tradeoff_parser

    for add in (_add_run_parsers, _add_result_parsers, _add_simulate_parser, _add_tool_parsers,
                _add_study_parsers, add_falsify_parser, add_evidence_parsers,
                add_tradeoff_parser):
        add(subs)
    return parser


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line on stderr (an old campaign-file spelling, a solver's remark)."""
    prefix = "note" if issubclass(category, FutureWarning) else category.__name__
    print(f"{prefix}: {message}", file=sys.stderr, flush=True)


class _ReaderMayLeave:
    """Standard output that a reader may stop reading (``fdd-campaign run … | head -1``):
    once a write finds the pipe closed, the rest of the output goes to the null device, so
    the command finishes its work and exits with its own status (a gate's verdict
    included) instead of stopping half-way with an error about a path."""

    def __init__(self, stream):
        self._stream = stream

    def _left(self):
        import os

        self._stream = open(os.devnull, "w")

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._left()
            return len(text)

    def flush(self):
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._left()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def main(argv=None) -> int:
    """Run the command of *argv* (default the process's arguments); returns its exit code."""
    if isinstance(sys.stdout, _ReaderMayLeave):
        return _main(argv)
    stdout = sys.stdout
    sys.stdout = _ReaderMayLeave(stdout)
    try:
        return _main(argv)
    finally:
        if isinstance(sys.stdout, _ReaderMayLeave):
            sys.stdout = stdout


def _main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_INPUT
    if args.func is not cmd_run:
        # the collector deferred by console_main waits for a campaign's kernels only
        # (campaign.runner turns it on again); every other command has it from here on
        start_up_done()
    from ..execute import one_blas_thread

    try:
        with warnings.catch_warnings(), one_blas_thread():
            warnings.showwarning = _note
            return args.func(args)
    # bad input: the user's mistake (scenarios.errors.InputError: a campaign file, an option,
    # a directory, an FMU, a detector's name or parameters, a plugin that fails at the
    # start), or a file that is missing; the message names the field and the fix
    except (InputError, FileNotFoundError) as exc:
        print_error(str(exc))
        return EXIT_INPUT
    except OSError as exc:    # a path the checks above could not foresee (disk full, …)
        where = f" {exc.filename}" if exc.filename else ""
        print_error(f"cannot access{where}: {exc.strerror or exc}; fix: check that the path exists, "
             "that you may write there and that the disk has room")
        return EXIT_INPUT
    except KeyboardInterrupt:
        print_error("interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:  # noqa: BLE001 - anything else is a fault of the engine or a library
        report_internal_error(exc, sys.argv[1:] if argv is None else list(argv))
        return EXIT_INTERNAL


def console_main() -> None:
    """:func:`campaign.cli.console_main` once this module is imported (NumPy with it, so BLAS
    keeps the threads it started: :func:`campaign.execute.one_blas_thread` limits them): the
    executable of an installation made before it moved there, and ``python -m
    campaign.cli.commands``."""
    defer_collection()
    leave(main())


def leave(code: int) -> None:
    """Exit the process with *code*, skipping the interpreter's teardown when that is safe.

    The teardown frees every module and object one by one (numba's compiled libraries,
    pandas, scipy.stats, the campaign's arrays): 0.35–0.4 s after a campaign of a few seconds
    (docs/execution.md, "Leaving the process"), none of it output. The exit handlers still run
    (temporary directories, logging, what a library registered), the standard streams are
    flushed, and then the process ends with ``os._exit``. With another thread or a child
    process still alive (a library's worker that the normal exit would join) it is the
    normal exit, ``sys.exit(code)``."""
    import atexit
    import os
    import threading

    busy = any(t is not threading.main_thread() and t.is_alive() and not t.daemon
               for t in threading.enumerate())
    children = sys.modules.get("multiprocessing") is not None and bool(
        sys.modules["multiprocessing"].active_children())
    run_handlers = getattr(atexit, "_run_exitfuncs", None)
    if busy or children or run_handlers is None:
        sys.exit(code)
    run_handlers()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):   # a reader that left (``| head``), a closed stream
        pass
    os._exit(code or 0)


if __name__ == "__main__":
    console_main()
