"""``fdd-campaign gate DIR --worst-case N``: its options and its checks, one per gated detector
(the search and the corpus: :mod:`campaign.evidence.worst_case`; docs/evidence.md,
"Worst-case gate"). Registered on the ``gate`` parser by :mod:`campaign.cli.commands`."""

from __future__ import annotations

__all__ = ["add_worst_case_options", "check_worst_case_options", "replay_command",
           "worst_case_checks"]


def add_worst_case_options(p) -> None:
    """The ``--worst-case`` options of the ``gate`` parser, and the worst-case gate's
    arguments they give (``check_budget(budget)``, ``gated_names(…, only)``,
    ``worst_case(…, seed=…)``)."""
    from ..evidence.worst_case import DEFAULT_SEED
    from .common import argument_flags

    argument_flags(p, {"budget": "--worst-case", "only": "--worst-case-detector",
                       "seed": "--worst-case-seed"})

    p.add_argument("--worst-case", metavar="N",
                   help="also search each gated detector's fault-free envelope for a false "
                        "alarm with N runs (fdd-campaign falsify with the campaign's fitted "
                        "detectors), after replaying the worst runs of earlier searches stored "
                        "in DIR/worst-case/; a stored search of the same N and seed is reused "
                        "(docs/evidence.md)")
    p.add_argument("--worst-case-seed", type=int, default=DEFAULT_SEED, metavar="S",
                   help=f"seed of the worst-case searches (default {DEFAULT_SEED}; same seed → "
                        "same search)")
    p.add_argument("--worst-case-detector", action="append", metavar="NAME",
                   help="search only this detector (result-row name, e.g. position-monitor or "
                        "comb-interval[a=0.9]; repeat for more; default every gated one)")
    p.add_argument("--jobs", type=int, default=2,
                   help="local workers of the worst-case search (default 2)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="evaluate the worst-case runs on this dask.distributed scheduler's "
                        "workers")


def check_worst_case_options(args) -> None:
    """Refuse bad ``--worst-case`` options before any work (exit 2, naming the flag and the
    fix); ``args.worst_case`` becomes the number of runs."""
    from ..evidence.worst_case import DEFAULT_SEED, WorstCaseError, check_budget

    used = [flag for flag, value in (("--worst-case-seed", args.worst_case_seed != DEFAULT_SEED),
                                     ("--worst-case-detector", args.worst_case_detector),
                                     ("--scheduler", args.scheduler)) if value]
    if args.worst_case is None:
        if used:
            raise WorstCaseError(f"{used[0]} applies to the worst-case search: give "
                                 "--worst-case N too, e.g. --worst-case 300")
        return
    args.worst_case = check_budget(args.worst_case)
    if args.worst_case_seed < 0:
        raise WorstCaseError(f"--worst-case-seed {args.worst_case_seed}: must be ≥ 0; fix: "
                             f"e.g. --worst-case-seed {DEFAULT_SEED}")
    if args.jobs < 1:
        raise WorstCaseError(f"--jobs {args.jobs}: must be ≥ 1 (local workers); fix: e.g. "
                             "--jobs 2")


def replay_command(root, alarm, name: str) -> str:
    """The commands that replay *alarm* (a :class:`campaign.evidence.worst_case.Alarm` of
    detector *name* in the campaign directory *root*) with the campaign's fitted detectors,
    then gate the replay."""
    safe = "".join(ch if ch.isalnum() or ch in "-_.=" else "_" for ch in name)
    out = f"{str(root).rstrip('/')}-worst-{safe}/"
    return (f"fdd-campaign run {alarm.worst_toml} --fitted-from {root} --out {out}, then "
            f"fdd-campaign gate {out}")


def _check(camp, found):
    """The gate's ``worst_case`` check of one :class:`campaign.evidence.worst_case.WorstCase`."""
    from reports.scoring.gate import Check

    search = (f"a {found.budget}-run search at seed {found.seed}"
              + (" (stored, reused)" if found.reused else ""))
    if found.passed:
        worst = (f"; worst margin {found.worst_margin:.4g} (run {found.worst_run}, "
                 f"{found.worst_manoeuvre})" if found.worst_run else "")
        corpus = (f"the {found.corpus_runs} corpus runs replayed first and "
                  if found.corpus_runs else "")
        message = (f"PASS worst case: {found.name}: no false alarm in {corpus}{search}"
                   f"{worst}; a search bounds nothing (docs/evidence.md)")
    else:
        first = found.alarms[0]
        in_corpus = sum(a.source == "corpus" for a in found.alarms)
        corpus = (f"{in_corpus} in the {found.corpus_runs} corpus runs replayed first, "
                  if found.corpus_runs else "")
        message = (f"FAIL worst case: {found.name}: {len(found.alarms)} false alarm(s) "
                   f"({corpus}{len(found.alarms) - in_corpus} new in {search}): "
                   f"{first.describe()}; replay: {replay_command(camp.root, first, found.name)}")
    return Check("worst_case", found.name, "none", "all", float(len(found.alarms)), 0.0,
                 found.passed, message)


def _report(camp, found) -> list[str]:
    """What the worst case of one detector found, in lines: the corpus, the search, and each
    false alarm (at most five) with the command that replays it."""
    lines = [f"worst case {found.name}:"]
    if found.corpus_runs:
        corpus_alarms = sum(a.source == "corpus" for a in found.alarms)
        lines.append(f"  corpus: {found.corpus_runs} runs of {found.corpus_files} stored "
                     f"search(es) replayed first: {corpus_alarms} false alarm(s)")
    state = "stored, reused" if found.reused else "run now"
    worst = (f", worst margin {found.worst_margin:.4g} (run {found.worst_run}, "
             f"{found.worst_manoeuvre})" if found.worst_run else "")
    lines.append(f"  search ({state}): {found.searched} runs, seed {found.seed}{worst}, "
                 f"{found.search_alarms} false alarm(s) -> {found.search_dir}")
    shown = found.alarms[:5]
    lines += [f"  FALSE ALARM ({alarm.source}): {alarm.describe()}" for alarm in shown]
    if len(found.alarms) > len(shown):
        lines.append(f"  … and {len(found.alarms) - len(shown)} more")
    firsts = {alarm.worst_toml: alarm for alarm in reversed(shown)}   # one per file
    lines += [f"  replay (the runs above of {path.name}): "
              f"{replay_command(camp.root, alarm, found.name)}"
              for path, alarm in reversed(firsts.items())]
    return lines


def worst_case_checks(camp, limits: dict, args) -> list:
    """The ``gate --worst-case`` checks of campaign *camp* (:class:`campaign.result.Campaign`)
    under the gate's false-alarm *limits* (the requirements' JSON form), one per gated
    detector; what each found is printed first."""
    from reports.scoring.gate import fa_limits

    from ..evidence.worst_case import gated_names, worst_case

    names, left = gated_names(camp.summary, fa_limits(camp.summary, limits),
                              args.worst_case_detector)
    for why in left:
        print(f"worst case: not searched: {why}")
    found = worst_case(camp, args.worst_case, names, seed=args.worst_case_seed,
                       jobs=args.jobs, scheduler=args.scheduler)
    for outcome in found:
        print("\n".join(_report(camp, outcome)))
    return [_check(camp, outcome) for outcome in found]
