"""The command line of the threshold trade-off (docs/thresholds.md, "Other thresholds from
one campaign: tradeoff"): ``fdd-campaign tradeoff DIR`` and the ``gate --threshold-scale``
option. Registered by :mod:`campaign.cli.commands`."""

from __future__ import annotations

import math

__all__ = ["add_threshold_scale_option", "add_tradeoff_parser", "cmd_tradeoff",
           "format_operating_points", "format_tradeoff", "gated_at_scales"]


def cmd_tradeoff(args) -> int:
    """``fdd-campaign tradeoff DIR``: write DIR/tradeoff.parquet and print it; with a
    false-alarm target, the operating point of each detector."""
    from ..tradeoff import (SCALES, TradeoffError, operating_points, parse_scales, tradeoff,
                            write_tradeoff)

    scales = parse_scales(args.scales) if args.scales else SCALES
    if args.max_fa_prob is not None and args.max_fa_per_hour is not None:
        raise TradeoffError("give one false-alarm target: --max-fa-prob P (per run) or "
                            "--max-fa-per-hour R (per flight hour), not both")
    for flag, value in (("--max-fa-prob", args.max_fa_prob),
                        ("--max-fa-per-hour", args.max_fa_per_hour)):
        if value is not None and not (math.isfinite(value) and value > 0 and (
                flag != "--max-fa-prob" or value < 1)):
            raise TradeoffError(f"{flag} {value!r}: give a target > 0"
                                + (" and < 1 (a probability per run, e.g. 1e-3)"
                                   if flag == "--max-fa-prob" else " [1/FH], e.g. 1e-5"))
    result = tradeoff(args.dir, scales)
    path = write_tradeoff(args.dir, result)
    print(format_tradeoff(result))
    for note in result.notes:
        print(f"note: {note}")
    example = _gate_example(result.table)
    if args.max_fa_prob is not None or args.max_fa_per_hour is not None:
        points = operating_points(result.table, max_fa_prob=args.max_fa_prob,
                                  max_fa_per_hour=args.max_fa_per_hour)
        print(format_operating_points(points, args.max_fa_prob, args.max_fa_per_hour))
        met = points.dropna(subset="scale")
        if len(met):
            example = (str(met["detector"].iloc[0]), float(met["scale"].iloc[0]))
    print(f"trade-off written to {path}" + ("" if example is None else
          f"; gate a detector at a scale: fdd-campaign gate {args.dir} --threshold-scale "
          f"{example[0]}={example[1]:g}"))
    return 0


def _gate_example(table):
    """(detector, scale) of a ``gate --threshold-scale`` hint: the first detector with a
    threshold scale, at the largest scale of the table other than 1 (None: none)."""
    scaled = table[table["threshold_scale"] & (table["scale"] != 1.0)]
    if scaled.empty:
        return None
    name = str(scaled["detector"].iloc[0])
    return name, float(scaled.loc[scaled["detector"] == name, "scale"].max())


def _g(x, fmt: str = ".3g") -> str:
    return "—" if x != x else format(x, fmt)


def _pct(x) -> str:
    return "—" if x != x else f"{100 * x:.3g} %"


def format_tradeoff(result) -> str:
    """The trade-off as terminal tables: per detector one line per scale, the false alarms
    of the fault-free runs (count, Clopper–Pearson bound, certified bound and its level),
    then per fault type misses · late · largest DTP (``?`` where the detections at that
    scale are not stored)."""
    from reports.scoring.metrics import FAULT_FREE
    from reports.scoring.summary import ALL_FAULTS

    table = result.table
    lines = []
    for name, g in table.groupby("detector", sort=False):
        faults = [f for f in dict.fromkeys(g["fault"]) if f != FAULT_FREE]
        faults = [f for f in faults if f != ALL_FAULTS] + [f for f in faults if f == ALL_FAULTS]
        head = (f"{'scale':>5s}  {'FA':>9s} {'FA ≤95':>8s} {'certified ≤95':>15s}  "
                + "  ".join(f"{f[:16]:>16s}" for f in faults))
        scaled = bool(g["threshold_scale"].iloc[0])
        lines += ["", f"Detector: {name}" + ("" if scaled else " (no threshold scale: "
                                             "scale 1 only)"), head, "-" * len(head)]
        for scale in sorted(set(g["scale"])):
            at = g[g["scale"] == scale].set_index("fault")
            if FAULT_FREE in at.index:
                r = at.loc[FAULT_FREE]
                fa = f"{int(r['fa_count'])}/{int(r['n_runs'])}"
                cert = ("—" if r["certified_level"] != r["certified_level"] else
                        f"{_g(r['fa_prob_certified_upper95'], '.2g')} @{r['certified_level']:g}")
                left = f"{scale:5g}  {fa:>9s} {_pct(r['fa_upper95']):>8s} {cert:>15s}  "
            else:
                left = f"{scale:5g}  {'':>9s} {'':>8s} {'':>15s}  "
            cells = []
            for f in faults:
                if f not in at.index:
                    cells.append(f"{'':>16s}")
                    continue
                r = at.loc[f]
                if r["md_rate"] != r["md_rate"] and r["n_runs"] > 0:
                    cells.append(f"{'?':>16s}")
                else:
                    cells.append(f"{int(r['md_count'])} · {int(r['late_count'])} · "
                                 f"{_g(r['dtp_max'], '.3g')}".rjust(16))
            lines.append(left + "  ".join(cells))
    lines.append("")
    lines.append("FA: false alarms of the fault-free runs; FA ≤95: their one-sided 95 % "
                 "Clopper–Pearson bound; certified ≤95: certify's bound of P(margin ≥ scale) "
                 "from its curve at the level shown (≤ the scale: a valid bound); per fault "
                 "type: missed · late (DTP > 1) · largest DTP of the detected runs. Exact at "
                 "the stored scales: the counts a campaign run at that scale gives.")
    return "\n".join(lines)


def format_operating_points(points, max_fa_prob, max_fa_per_hour) -> str:
    """The chosen scale of each detector for the false-alarm target."""
    target = (f"per-run false-alarm probability ≤ {max_fa_prob:g}" if max_fa_prob is not None
              else f"false alarms ≤ {max_fa_per_hour:g} per flight hour")
    lines = ["", f"Operating points for {target} (the bound: certified where certify's curve "
                 "gives one, else counted; then fewest misses, shortest worst-case DTP):"]
    best = None
    for r in points.to_dict(orient="records"):
        if r["scale"] != r["scale"]:
            lines.append(f"  {r['detector']}: no stored scale meets it")
            continue
        lines.append(f"  {r['detector']}: threshold_scale = {r['scale']:g} (FA bound "
                     f"{_g(r['fa_bound'], '.2g')}, {r['fa_bound_kind']}; missed "
                     f"{r['md_count']}; worst DTP {_g(r['dtp_max'])})")
        key = (r["md_count"], r["dtp_max"] if r["dtp_max"] == r["dtp_max"] else math.inf)
        if best is None or key < best[0]:
            best = (key, r)
    if best is not None:
        r = best[1]
        lines.append(f"best: {r['detector']} at threshold_scale = {r['scale']:g}")
    return "\n".join(lines)


def add_tradeoff_parser(subs) -> None:
    """Sub-command ``tradeoff``."""
    from .common import add_command
    from ..tradeoff import SCALES

    p = add_command(subs, "tradeoff", "a campaign's false alarms, misses and DTP at other "
                    "threshold scales, from its stored runs (no simulation); writes "
                    "DIR/tradeoff.parquet", "fdd-campaign tradeoff results/ --scales 0.8,1,1.25 "
                    "--max-fa-prob 1e-3", cmd_tradeoff)
    p.add_argument("dir", help="campaign directory written by 'fdd-campaign run'")
    p.add_argument("--scales", metavar="S,S,…",
                   help="threshold scales (every threshold × S), among the stored "
                        f"{', '.join(f'{s:g}' for s in SCALES)} (default: all)")
    p.add_argument("--max-fa-prob", type=float, metavar="P",
                   help="print each detector's operating point: the scale whose per-run "
                        "false-alarm bound is ≤ P with the fewest misses, then the shortest "
                        "worst-case DTP")
    p.add_argument("--max-fa-per-hour", type=float, metavar="R",
                   help="the same with a bound on false alarms per flight hour (the runs' "
                        "durations as exposure, the Poisson model of certify)")


def add_threshold_scale_option(p) -> None:
    """``gate --threshold-scale D=s``: the *scales* of
    :func:`campaign.tradeoff.at_threshold_scales`."""
    from .common import argument_flags

    argument_flags(p, {"scales": "--threshold-scale"})
    p.add_argument("--threshold-scale", action="append", metavar="D=S",
                   help="gate detector D (result name or [[detector]] label: all its "
                        "variants) as if every threshold were × S, from the stored runs (a "
                        "stored scale, see 'fdd-campaign tradeoff'); repeatable")


def gated_at_scales(camp, args):
    """*camp* with the detectors of ``--threshold-scale`` at their scales
    (:func:`campaign.tradeoff.at_threshold_scales`); *camp* itself without the option."""
    from ..tradeoff import TradeoffError, at_threshold_scales, parse_scale_options

    scales = parse_scale_options(getattr(args, "threshold_scale", None))
    if not scales:
        return camp
    if args.max_fa_prob is not None or args.worst_case is not None:
        raise TradeoffError("--threshold-scale gates the stored runs at another scale; "
                            "--max-fa-prob and --worst-case read evidence made at the "
                            "campaign's own thresholds: give them without --threshold-scale")
    print("threshold scales: " + ", ".join(f"{k} × {v:g}" for k, v in scales.items())
          + " (from the stored runs)")
    return at_threshold_scales(camp, scales)
