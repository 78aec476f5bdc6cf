"""``fdd-campaign run`` and ``plan``: a campaign file, a preset or a suite into its directory
(docs/design.md §7, Command line). Registered by :mod:`campaign.cli.commands`."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from . import requirements as creq
from .common import EXIT_INPUT, EXIT_INTERRUPTED, EXIT_OK, UsageError, add_command, check_writable


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
                raise UsageError(f"--plant {args.plant}: {problem}")
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
        options = ", ".join("--" + name.replace("_", "-") for name in files.given())
        raise UsageError(f"{options} apply to a dask cluster: give --scheduler tls://HOST:PORT "
                         "too")
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
        from reports.scoring.detection_times import format_detection_times

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
    from ..plan import MODEL_VERSION, PlanBlocks, build_learning_plan, plan_counts
    from ..store.directory import CampaignDir

    from ..plant_setup import resolve
    from ..runner import remove_created, start_state

    campaign = resolve(config)          # once, for the run table and the learning set
    blocks = PlanBlocks(campaign)
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
    learning = build_learning_plan(campaign)
    counts = plan_counts(cdir.plan_batches(columns=["group", "fault", "manoeuvre"]))
    free = int(counts.loc[counts["fault"] == "none", "runs"].sum())
    total = int(counts["runs"].sum())
    print(counts.to_string(index=False))
    print(f"total: {total} runs ({free} fault-free, {total - free} faulty); learning set: "
          f"{len(learning)} runs")
    print(f"run table written to {cdir.plan_path}")


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


def add_run_parsers(subs) -> None:
    """Sub-commands: run and plan a campaign."""
    p = add_command(subs, "run",
                    "run a campaign (a preset name or a campaign file) into a directory",
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
                        "or a co-simulation FMU file to simulate the actuator on (sets [plant] "
                        "fmu; see docs/fmu.md)")
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
                   help="evaluate the detectors fitted in campaign directory DIR (same "
                        "[[detector]] entries) without learning again (copied into --out; "
                        "docs/thresholds.md)")

    p = add_command(subs, "plan", "write the run table of a campaign and print its counts",
             "fdd-campaign plan addsafe-grid --out grid/", cmd_plan)
    p.add_argument("campaign", help="preset name (see 'fdd-campaign presets') or a .toml file")
    p.add_argument("--out", required=True, help="directory to write plan.parquet into "
                   "(a suite: one subdirectory per campaign)")
    p.add_argument("--seed", type=int, help="override the campaign seed")
    _manoeuvres_option(p)
