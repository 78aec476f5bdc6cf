"""The commands beside a campaign: ``simulate`` one run, ``presets``, ``init``, ``bench`` and
``fmu build`` (docs/design.md §7, Command line). Registered by :mod:`campaign.cli.commands`."""

from __future__ import annotations

import sys
from functools import partial
from pathlib import Path

from .common import EXIT_OK, UsageError, add_command, add_group, check_writable


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
        from reports.render.figures.aircraft import plot_aircraft_run

        plot_aircraft_run(frame, onset_s=onset, path=args.plot,
                          monitored=str(runs["surface"].iloc[0]),
                          title=f"{runs['surface'].iloc[0]} — {args.manoeuvre} — {args.fault}")
        print(f"plot written to {args.plot}")
    elif args.plot:
        from reports.render.figures.run import plot_run

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
    become a run-table magnitude as a group's do (:func:`campaign.plan.fixed_magnitude`)."""
    import numpy as np

    from scenarios.faults import FAULT_DEFAULTS, default_magnitude, solid_jam_offset_mm

    from ..config.rules import single_fault_problems
    from ..plan import fixed_magnitude

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


def cmd_fmu(args) -> int:
    from scenarios.fmu_build import build_servo_fmu

    check_writable(args.out, "--out")
    out = build_servo_fmu(args.out, surface=args.surface, fmi=args.fmi,     # FmuBuildError: exit 2
                          log=(lambda m: print(m, file=sys.stderr)) if args.verbose else None)
    print(f"built and validated {out} (FMI {args.fmi}.0 co-simulation, {args.surface} defaults); "
          f"run a campaign on it with: fdd-campaign run smoke --plant {out} --out "
          f"{_out_dir(Path(out))}")
    return EXIT_OK


def add_simulate_parser(subs) -> None:
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


def add_tool_parsers(subs) -> None:
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
    p.add_argument("--plant", metavar="FMU|jsbsim", help="also time this FMU plant (per-run "
                   "cost beside the built-in plant), or the JSBSim plant against its flight "
                   "model alone")
    p.add_argument("--plant-runs", type=int, default=40,
                   help="runs timed on the FMU or JSBSim plant (default 40)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")

    fsubs = add_group(subs, "fmu", "build the built-in servo-loop as an FMU", "FMU tools",
                      "fmu_command", "FMU_COMMAND")
    p = add_command(fsubs, "build", "compile the servo-loop C sources into an FMI 2.0 "
                    "co-simulation FMU and validate it with fmpy",
                    "fdd-campaign fmu build --out servo.fmu", cmd_fmu)
    p.add_argument("--out", default="servo.fmu", help="FMU file to write (default servo.fmu)")
    p.add_argument("--surface", default="elevator", choices=SURFACES,
                   help="surface whose parameters are the FMU's start values")
    p.add_argument("--fmi", default="2", choices=["2", "3"], help="FMI version (default 2)")
    p.add_argument("--verbose", action="store_true", help="print the compiler command")
