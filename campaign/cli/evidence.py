"""The command line of the evidence beyond counting (docs/evidence.md): ``fdd-campaign
certify`` and the ``gate --max-fa-prob`` checks. Registered by :mod:`campaign.cli.commands`."""

from __future__ import annotations

from pathlib import Path

#: The options of ``certify --validate`` by the arguments of
#: :func:`campaign.evidence.certify.validate.validate` they give (*seed* is certify's own
#: ``--seed`` elsewhere).
VALIDATE_FLAGS = {"n": "--validate", "seed": "--validate-seed"}

__all__ = ["VALIDATE_FLAGS", "add_evidence_parsers", "cmd_certify", "fa_probability_checks",
           "format_certificate", "format_hazard", "format_levels", "format_sampling"]


def cmd_certify(args) -> int:
    """``fdd-campaign certify DIR``: write DIR/certificate.parquet and
    DIR/certificate-levels.parquet and print them; with ``--validate N``, run and report
    the brute-force validation of the curve."""
    from scenarios.errors import ArgumentError

    from ..evidence.certify import CertifyError, certify
    from .common import EXIT_INTERRUPTED, UsageError
    from ..store.directory import CampaignDir

    if args.validate is not None:               # bad validation options: before any work
        from ..evidence.certify.validate import check_validation
        from ..config import CampaignConfig

        cdir = CampaignDir(args.dir)
        if not cdir.is_campaign():
            raise CertifyError(f"{args.dir}: not a campaign directory (no campaign.json); give "
                               "the --out directory of a finished 'fdd-campaign run'")
        try:
            check_validation(CampaignConfig.from_dict(cdir.read_config()), args.validate,
                             args.validate_seed)
        except ArgumentError as exc:
            raise UsageError(exc.for_command_line(VALIDATE_FLAGS)) from None
    try:
        cert = certify(args.dir, level=args.level, sampling=args.sampling, jobs=args.jobs,
                       seed=args.seed, detectors=args.detector, scheduler=args.scheduler,
                       log=lambda msg: print(msg, flush=True), max_levels=args.max_levels,
                       levels=args.levels)
    except KeyboardInterrupt:
        print(f"fdd-campaign: interrupted; the sampled batches done so far are kept under "
              f"{Path(args.dir) / 'sampling'}/: the same command goes on from them")
        return EXIT_INTERRUPTED
    print(format_certificate(cert.table))
    note = residual_margin_note(CampaignDir(args.dir).read_config())
    if note:
        print(note)
    print(format_levels(cert.levels))
    print(format_sampling(cert.table))
    print(format_hazard(cert.hazard))
    print(f"certificate written to {Path(args.dir) / 'certificate.parquet'} and "
          f"{Path(args.dir) / 'certificate-levels.parquet'}; the report shows it: "
          f"fdd-campaign report {args.dir}")
    if args.validate is not None:
        from ..evidence.certify.validate import summarise, validate

        try:
            table = validate(args.dir, int(args.validate), seed=args.validate_seed,
                             jobs=args.jobs, scheduler=args.scheduler,
                             log=lambda msg: print(msg, flush=True))
        except ArgumentError as exc:
            raise UsageError(exc.for_command_line(VALIDATE_FLAGS)) from None
        except KeyboardInterrupt:
            print(f"fdd-campaign: interrupted; the validation runs done so far are kept under "
                  f"{args.dir}/validation/: the same command goes on from them")
            return EXIT_INTERRUPTED
        print(summarise(table))
    return 0


def _g(x) -> str:
    return "n/a" if x != x else f"{x:.3g}"


def format_certificate(cert) -> str:
    """The certificate as a terminal table (probabilities per run, rates per hour). A tail
    estimate below the limit of the runs is printed as "< limit", never as a number; a
    detector that was not sampled shows "—" in the sampled columns. Each bound is named:
    "count ≤" the counting bound, "tail ≤" the curve's at margin 1 marked by what it is
    (:func:`reports.scoring.gate.curve_method`), "sampled" subset simulation."""
    from reports.scoring.gate import curve_method

    lines = [f"{'detector':24s} {'runs':>6s} {'FA':>4s} {'count ≤':>9s} {'tail est':>10s} "
             f"{'tail ≤':>10s} {'sampled':>9s} {'sampled bounds':>19s} {'per hour':>9s}"]
    tag = {"counted": "c", "counted per manoeuvre": "c", "limit of the runs": "*"}
    for r in cert.to_dict(orient="records"):
        sampled = (f"[{_g(r['sampling_lower95'])}, {_g(r['sampling_upper95'])}]"
                   if r["sampling_runs"] else "—")
        est = r["fa_prob_evt"]
        if est != est and "limit" in str(r["evt_note"]):
            est_text = f"<{r['fa_upper95_cp'] / 100:.2g}"
        else:
            est_text = _g(est)
        lines.append(f"{r['detector']:24s} {r['n_runs']:6d} {r['fa_count']:4d} "
                     f"{_g(r['fa_upper95_cp']):>9s} {est_text:>10s} "
                     f"{_g(r['fa_prob_evt_upper95']) + tag.get(curve_method(r), ''):>10s} "
                     f"{_g(r['sampling_prob']) if r['sampling_runs'] else '—':>9s} "
                     f"{sampled:>19s} {_g(r['fa_per_hour_upper95']):>9s}")
    level = float(cert["level"].iloc[0]) if len(cert) else 0.95
    lines.append(f"bounds one-sided at {100 * level:g} %; per-run probabilities of a run of "
                 f"the campaign's duration. count ≤: counting bound (exact Clopper–Pearson) "
                 f"of the false alarms; tail ≤: tail fit (the manoeuvres' generalised Pareto "
                 f"tails at margin 1), or, marked c, the counting bound (Clopper–Pearson) of "
                 f"the margins ≥ 1 (pooled where it is the smaller, or per manoeuvre where "
                 f"the runs are too few for a tail fit), or, marked *, the limit of the "
                 f"runs (the counting bound / 100; the tail fit claims less); sampled: subset "
                 f"simulation; per hour from the counting bound (Poisson exposure model, "
                 f"docs/evidence.md); \"<x\": the tail's estimate lies below the limit of the "
                 f"runs, not given; \"—\": not sampled (--sampling N)")
    return "\n".join(lines)



def residual_margin_note(config: dict) -> str:
    """A line naming the detectors of the campaign (*config*, its stored dict) whose margin
    is their residual before confirmation, not the distance to the alarm decision (no
    ``Capabilities.threshold_scale``): for them P(margin ≥ 1) bounds more than their false
    alarms (docs/design.md §5, Metrics); empty when every detector gives a decision."""
    from detectors import load_detector_class

    from ..config import CampaignConfig

    labels = [d.label for d in CampaignConfig.from_dict(config).detectors
              if not getattr(load_detector_class(d.name).capabilities, "threshold_scale",
                             False)]
    if not labels:
        return ""
    return (f"margins of {', '.join(labels)}: the largest |r|/τ before the detector's "
            "confirmation (it gives no decision statistic, docs/write-a-detector.md), so "
            "P(margin ≥ 1) bounds more than its false alarms")


def format_levels(curve) -> str:
    """The exceedance curve as a terminal table: per detector, the bound P(margin ≥ level)
    ≤ p_upper95 at each level (and how it was obtained)."""
    if curve is None or curve.empty:
        return ""
    levels = sorted(curve["level"].unique())
    head = f"{'P(margin ≥ level) ≤':24s} " + " ".join(f"{v:>9g}" for v in levels)
    lines = [head]
    tag = {"counted": "c", "mixture": "", "limit of the runs": "*", "tail": ""}

    def mark(row) -> str:
        if row["method"] == "mixture" and not row.get("tail_class", "x"):
            return "c"                  # a mixture of the manoeuvres' counts, no tail fit
        return tag.get(row["method"], "?")

    for name, g in curve.groupby("detector", sort=False):
        by = g.set_index("level")
        cells = [f"{_g(by.loc[v, 'p_upper95'])}{mark(by.loc[v])}"
                 if v in by.index else "" for v in levels]
        lines.append(f"{name:24s} " + " ".join(f"{c:>9s}" for c in cells))
    lines.append("c: counted (exact Clopper–Pearson bound of the runs at or above the level, "
                 "pooled or per manoeuvre mixed by their shares); *: the limit of the runs "
                 "(the tail model claims less: see the note in certificate-levels.parquet); "
                 "unmarked: tail fit (mixture of the manoeuvres' tails)")
    return "\n".join(lines)


def fa_probability_checks(camp, limit: float) -> list:
    """The ``gate --max-fa-prob`` checks of campaign *camp* (:class:`campaign.result.Campaign`)
    from its certificate (:func:`reports.scoring.gate.fa_probability_checks`); a CertifyError (exit
    2) naming the command that makes it when the directory has none."""
    from reports.scoring.gate import fa_probability_checks as checks

    from ..evidence.certify import CertifyError

    if camp.certificate is None:
        raise CertifyError(f"--max-fa-prob: {camp.root} has no certificate.parquet; make it "
                           f"first with: fdd-campaign certify {camp.root} (add --sampling "
                           "500 for the sampled cross-check)")
    return checks(camp.certificate.table, limit)


def add_evidence_parsers(subs) -> None:
    """Sub-command ``certify``."""
    from ..evidence.certify.levels import DEFAULT_LEVELS
    from .common import add_command, argument_flags

    p = add_command(subs, "certify", "per-run false-alarm probability of each detector beyond "
            "counting: exact binomial bound, generalised Pareto tail of the fault-free margins, "
            "optionally subset simulation (resumable: its batches are kept under DIR/sampling/); "
            "writes DIR/certificate.parquet (docs/evidence.md)",
            "fdd-campaign certify results/ --sampling 500", cmd_certify)
    argument_flags(p, {"detectors": "--detector"})      # certify(dir, detectors=…)
    p.add_argument("dir", help="finished campaign directory written by 'fdd-campaign run'")
    p.add_argument("--level", type=float, default=0.95,
                   help="confidence of the one-sided bounds (default 0.95)")
    p.add_argument("--sampling", type=int, metavar="N",
                   help="also estimate P(margin ≥ 1) by subset simulation with N runs per "
                        "level (a multiple of 10, ≥ 20; e.g. 500)")
    p.add_argument("--jobs", type=int, default=2,
                   help="threads fitting the manoeuvres' tails, and local workers "
                        "simulating the sampled runs (default 2)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="simulate the sampled runs on this dask.distributed scheduler's "
                        "workers")
    p.add_argument("--detector", action="append", metavar="NAME",
                   help="sample only this detector (result-row name, e.g. position-monitor; "
                        "repeat for more; default all)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the subset simulation (default 0)")
    p.add_argument("--max-levels", type=int, default=12, metavar="L",
                   help="levels of the subset simulation after the first before it reports "
                        "the highest level reached instead of margin 1 (default 12: down to "
                        "about 1e-12 per run; raising it goes on from the stored batches)")
    p.add_argument("--levels", default=",".join(f"{v:g}" for v in DEFAULT_LEVELS),
                   metavar="X,Y,…",
                   help="margins of the exceedance curve written to "
                        "DIR/certificate-levels.parquet (1.0, the false alarm, always "
                        "included; default %(default)s)")
    p.add_argument("--validate", type=int, metavar="N",
                   help="validate the curve by brute force: N fault-free runs of the "
                        "campaign's distribution with its fitted detectors, into "
                        "DIR/validation/ (resumable), and the coverage at every level with "
                        "≥ 5 exceedances (e.g. 60000; about 500 runs/s on 2 idle cores)")
    p.add_argument("--validate-seed", type=int, metavar="S",
                   help="campaign seed of the validation runs (default: the campaign's seed "
                        "+ 1; never the campaign's own seed, whose runs are those certified)")



# ---- the subset simulations' outcome and the hazard table (docs/evidence.md) ----------------
def format_sampling(cert) -> str:
    """One paragraph per sampled detector: what its subset simulation estimated and its
    chains' diagnostics (the certificate's ``sampling_note``); empty without --sampling."""
    rows = [r for r in cert.to_dict(orient="records") if r["sampling_runs"]]
    return "\n".join(f"{r['detector']}: {r['sampling_note']}" for r in rows)


def format_hazard(hazard) -> str:
    """The hazard per flight hour as a terminal table: per detector, each fault type's
    missed detections, the undetected rate per flight hour without the detector (the fault
    rate, "(est.)" when a placeholder) and with it (the bound), the category credited to
    the detector and why (:func:`campaign.evidence.hazard.credit`), their total, and the
    false alarms; then what the columns mean and the assumptions. '' for None (no hazard
    table)."""
    from ..evidence.hazard import (AMC_25_1309_BUDGETS_PER_FH, ASSUMPTIONS, RATE_GIVEN,
                                   RATE_PLACEHOLDER, WIDEST_CREDITED_BOUND, with_claims)

    if hazard is None:
        return ""
    hazard = with_claims(hazard)
    budgets = ", ".join(f"{k} ≤ {v:g}" for k, v in AMC_25_1309_BUDGETS_PER_FH.items())
    level = float(hazard["level"].iloc[0]) if len(hazard) else 0.95
    lines = [f"Hazard per flight hour (both sides; AMC 25.1309 budgets /FH: {budgets})",
             f"{'detector':24s} {'fault':14s} {'runs':>5s} {'missed':>6s} {'P ≤ (CP)':>9s} "
             f"{'without /FH':>14s} {'with ≤ /FH':>10s} {'credited':>12s} "
             f"{'in time ≤':>9s} {'credited':>12s}  claim"]
    for r in hazard.to_dict(orient="records"):
        free = r["fault"] == "none"
        fault = "false alarm" if free else r["fault"]
        src = str(r["rate_source"])
        mark = "" if free or src == RATE_GIVEN else " (est.)"
        without = "—" if free else f"{_g(r['without_per_fh'])}{mark}"
        lines.append(f"{r['detector']:24s} {fault:14s} {r['n_runs']:5d} {r['events']:6d} "
                     f"{_g(r['p_run_upper95']):>9s} {without:>14s} "
                     f"{_g(r['per_fh_upper95']):>10s} {r['credited']:>12s} "
                     f"{_g(r['in_time_per_fh_upper95']):>9s} {r['credited_in_time']:>12s}  "
                     f"{r['claim']}")
    lines.append(
        f"bounds one-sided at {100 * level:g} %, all counting bounds: P ≤ (CP) is the exact "
        "Clopper–Pearson bound of the missed share (of the false alarms per run on the false-"
        "alarm row); 'all': undetected faults of every type, its bound Bonferroni-adjusted over "
        "the types. without: the undetected rate with no detector, the fault rate; with: the "
        "fault rate × P ≤; 'in time': the same when a detection after the required time counts "
        "as undetected. credited: the most severe category whose budget the rate with the "
        f"detector meets and the fault rate alone does not — none when the detector detected "
        f"none of the runs, when P ≤ is above {WIDEST_CREDITED_BOUND:g} or when the bound "
        "leaves the rate in its category without the detector ('not shown'); n/a: false "
        "alarms are a cost of the detector, not a credit.")
    if any(s != RATE_GIVEN for s in hazard.loc[hazard["fault"] != "none", "rate_source"]):
        lines.append(f"(est.): {RATE_PLACEHOLDER.replace('placeholder (est.)', 'a placeholder')}"
                     "; the default rates are estimates with no cited source, and a category "
                     "resting on them is a placeholder too")
    lines.append("Assumptions:")
    lines.extend(f"  - {a}" for a in ASSUMPTIONS)
    return "\n".join(lines)
