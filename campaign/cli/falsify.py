"""``fdd-campaign falsify``: its options and its command (docs/design.md §7; the search is
:mod:`campaign.evidence.falsify`). Exit 1 when the search finds a false alarm (margin ≥ 1), 0
otherwise, 2 on bad input (before any run)."""

from __future__ import annotations

import math
from pathlib import Path

from .common import (EXIT_GATE, EXIT_INTERRUPTED, EXIT_OK, UsageError, add_command,
                     argument_flags, check_writable)

EXAMPLE = ("fdd-campaign falsify addsafe-mc --detector position-monitor --budget 600 "
           "--jobs 2 --against results/ --out falsify-mc/")


def add_falsify_parser(subs) -> None:
    """The ``falsify`` sub-command."""
    help_ = ("search the campaign's fault-free envelope for the run of largest margin of one "
             "detector (Sobol screening, CMA-ES on the worst cells, stream sweep; exit 1 if it "
             "finds a false alarm)")
    p = add_command(subs, "falsify", help_, EXAMPLE, cmd_falsify)
    argument_flags(p, {"label": "--detector"})        # falsify(config, label, …)
    p.add_argument("campaign", help="preset name (see 'fdd-campaign presets') or a .toml file")
    p.add_argument("--detector", required=True, metavar="LABEL",
                   help="detector label as in the results (e.g. position-monitor, "
                        "comb-interval[a=0.9])")
    p.add_argument("--budget", required=True, type=int, metavar="N",
                   help="most simulated runs the search spends (at least 10)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="directory for search.parquet, worst.toml and learned/")
    p.add_argument("--jobs", type=int, default=2, help="local workers (default 2)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the search (default 0; same seed → same search.parquet)")
    p.add_argument("--keep", type=int, default=10, metavar="K",
                   help="worst runs written to worst.toml (default 10)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="evaluate each generation on this dask.distributed scheduler's workers")
    p.add_argument("--fitted-from", metavar="DIR",
                   help="take the fitted detectors of campaign directory DIR (same "
                        "[[detector]] entries) instead of fitting them")
    p.add_argument("--against", metavar="DIR",
                   help="compare with the worst fault-free margin of campaign directory DIR "
                        "(default: run a plain Monte Carlo of the same budget)")


def cmd_falsify(args) -> int:
    from ..config import load_config
    from ..evidence.falsify import falsify

    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: must be ≥ 1 (local workers); fix: e.g. --jobs 2")
    if args.seed < 0:
        raise UsageError(f"--seed {args.seed}: must be ≥ 0; fix: e.g. --seed 0")
    config = load_config(args.campaign)
    check_writable(args.out, "--out", directory=True)
    try:
        result = falsify(config, args.detector, budget=args.budget, out=args.out,
                         jobs=args.jobs, seed=args.seed, scheduler=args.scheduler,
                         fitted_from=args.fitted_from, against=args.against, keep=args.keep)
    except KeyboardInterrupt:
        print("fdd-campaign: interrupted; nothing of the search is kept")
        return EXIT_INTERRUPTED
    w = result.worst
    out = Path(args.out)
    print(f"falsify {config.campaign.name!r}, {result.label}: {len(result.search)} runs "
          f"(budget {args.budget}) -> {out / 'search.parquet'}, {out / 'worst.toml'}")
    if result.errors:
        print(f"runs in error (not scored): {result.errors}")
    what = ("the distance to the alarm decision: ≥ 1 is an alarm"
            if result.margin_kind == "decision" else
            "the largest |r|/τ before the detector's confirmation: it gives no decision "
            "statistic, docs/write-a-detector.md")
    print(f"worst margin found by the search: {w['margin']:.6g} (run {w['run_id']}, "
          f"{w['manoeuvre']}, generation {int(w['generation'])}; {what})")
    above = int((result.search["margin"] >= 1.0).sum())
    print(f"false alarms raised by {result.label}: {result.false_alarms} of "
          f"{len(result.search)} searched runs"
          + ("  FALSE ALARM (the first runs of worst.toml)" if result.false_alarm else "")
          + (f"; {above - result.false_alarms} more above the threshold for less than the "
             "detector's confirmation" if above > result.false_alarms else ""))
    base = result.baseline_margin
    print(f"worst margin of {result.baseline_source}: "
          + (f"{base:.6g}" if math.isfinite(base) else "none scored"))
    replay = f"{out.parent / 'worst'}/"
    print(f"replay: fdd-campaign run {out / 'worst.toml'} --out {replay}, then fdd-campaign "
          f"gate {replay}")
    return EXIT_GATE if result.false_alarm else EXIT_OK
