"""``fdd-campaign study NAME``: the studies of :mod:`campaign.tools.studies`, one table each
(docs/design.md §7, Command line). Registered by :mod:`campaign.cli.commands`."""

from __future__ import annotations

import sys
from functools import partial

from .common import (EXIT_INTERRUPTED, EXIT_OK, UsageError, add_command, add_group,
                     check_writable)


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
        raise UsageError("--runs must be at least 1 (runs per manoeuvre and seed), got "
                         f"{args.runs}")
    if not args.duration > 0.0:
        raise UsageError(f"--duration must be > 0 s, got {args.duration}")
    run_study(tuple(args.seeds), tuple(args.surfaces), args.runs, args.duration,
              args.turbulence, args.manoeuvres,
              progress=None if args.quiet else partial(print, file=sys.stderr, flush=True))
    return EXIT_OK


def add_study_parsers(subs) -> None:
    """Sub-commands: the studies (``fdd-campaign study NAME``, :mod:`campaign.tools.studies`)."""
    ssubs = add_group(subs, "study", "reproduce a published comparison or count the aircraft "
                      "laws' surface activity (one table)",
                      "studies: fixed comparisons reproduced from a paper and censuses of the "
                      "model, one table each (campaign.tools.studies)", "study", "STUDY")
    p = add_command(ssubs, "vanek", "LTI against LPV geometric filter on the scenarios of [VANEK] "
                    "§5: residual peaks, thresholds, detection delays and DTP "
                    "(docs/vanek-geometric.md)",
                    "fdd-campaign study vanek --noise-scale 0.1", cmd_study_vanek)
    p.add_argument("--noise-scale", type=float, default=1.0,
                   help="factor on the σ of every aircraft sensor (default 1)")
    p.add_argument("--seed", type=int, default=0, help="seed of the scenarios (default 0)")
    p = add_command(ssubs, "chen-flight-data", "the global [CHEN] estimators (chen-global, "
                    "chen-global-paper with [CHEN]'s constant threshold and with our calibrated "
                    "one) on chen-mc's fault-free and disconnection runs at several sizes of the "
                    "[CHEN] Table-2 flight-data errors (VCAS, altitude, mass, CG): false alarms, "
                    "misses and delays per size (docs/chen-estimator.md §5.2)",
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
                   help="fault-free runs per manoeuvre and seed (default "
                        f"{saturation.DEFAULT_RUNS})")
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
