"""The worst-case gate: ``fdd-campaign gate DIR --worst-case N`` (docs/evidence.md,
"Worst-case gate").

For each gated detector of a campaign directory (each result-row name, variants apart, whose
accepted false-alarm rate is 0 and that has fault-free runs), in this order:

1. **the corpus first**: the runs of every ``worst.toml`` stored under ``DIR/worst-case/``
   for that name (the worst runs of the searches of earlier gates, any budget and seed) are
   evaluated again, with the campaign's own fitted detectors, through the runner's pipeline
   (:func:`campaign.runner.evaluate_rows`): a regression on a run found before is caught even
   when the new search misses it;
2. **the search**: an N-run worst-case search (:func:`campaign.evidence.falsify.falsify`) over
   the campaign's fault-free envelope and uncertainty box, with the detectors the campaign
   scored (``fitted_from`` the directory) and its worst fault-free runs opening the screening
   (``against`` the directory), into ``DIR/worst-case/NAME-nN-seedS/``
   (:meth:`campaign.store.directory.CampaignDir.worst_case_search_dir`). A finished search of
   the same name, N and seed stored there is reused, not run again: a killed gate run again
   goes on with the searches it had not finished.

A detector fails on a **false alarm**: the ``false_alarm`` of the scored run (the detector's
own decision, with its confirmation), never a margin ≥ 1 alone. The false alarms are those of
the corpus replay, then those of the search that the corpus did not hold (a reused search's
as it stored them: its worst runs, false alarms first, are in the corpus and were evaluated
again above). Each is named with its run id, manoeuvre,
flight point and the ``worst.toml`` that replays it. A search is a falsification attempt of N
runs, not a proof: finding none bounds nothing by itself.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from scenarios.envelope import FLIGHT_COLUMNS
from scenarios.errors import ArgumentError, InputError

from .falsify import MIN_BUDGET, FalsifyError, falsify, scores

__all__ = ["DEFAULT_SEED", "KEEP", "Alarm", "WorstCase", "WorstCaseError",
           "WorstCaseOptionError", "check_budget", "gated_names", "replay_corpus",
           "search_detector", "worst_case"]

#: Seed of the searches when the gate is not given one (``--worst-case-seed``).
DEFAULT_SEED: int = 0
#: Worst runs of each search kept in its ``worst.toml`` (the corpus), false alarms first.
KEEP: int = 10


class WorstCaseError(InputError, ValueError):
    """The worst-case gate cannot start (a bad budget, an unknown detector …): exit 2."""


class WorstCaseOptionError(WorstCaseError, ArgumentError):
    """An argument of the worst-case gate it cannot take (*budget*, *only*, *seed*), named
    as Python names it; ``fdd-campaign gate`` names its option
    (:class:`scenarios.errors.ArgumentError`)."""


@dataclass(frozen=True)
class Alarm:
    """One fault-free run in which a detector raised a false alarm, and how to replay it."""

    run_id: str
    manoeuvre: str
    point: dict                # alt_ft, vcas_kt, mass_t, cg_pct
    margin: float
    worst_toml: Path           # the campaign file whose [[run]] entries replay it
    source: str                # "corpus" (replayed first), "search" (found now) or
                               # "stored search" (found by the reused search, not replayed)

    def describe(self) -> str:
        """``run ID (manoeuvre, alt … ft, … kt, … t, cg … %), margin …``."""
        p = self.point
        return (f"run {self.run_id} ({self.manoeuvre}, {p['alt_ft']:.0f} ft, "
                f"{p['vcas_kt']:.1f} kt, {p['mass_t']:.1f} t, cg {p['cg_pct']:.1f} %), "
                f"margin {self.margin:.4g}")


@dataclass
class WorstCase:
    """The worst-case outcome of one detector name."""

    name: str
    budget: int
    seed: int
    search_dir: Path
    reused: bool = False             # the search was stored already: not run again
    searched: int = 0                # runs of the search
    search_alarms: int = 0           # its false alarms (of the search run now, or stored)
    worst_margin: float = float("nan")
    worst_run: str = ""
    worst_manoeuvre: str = ""
    corpus_files: int = 0            # stored searches whose worst.toml was replayed
    corpus_runs: int = 0             # distinct runs replayed
    alarms: list[Alarm] = field(default_factory=list)   # corpus first, then the search

    @property
    def passed(self) -> bool:
        return not self.alarms


def check_budget(budget) -> int:
    """The runs of each search, *budget* (a number or its text), as a number;
    :class:`WorstCaseOptionError` naming the argument and the fix when it is not a whole
    number ≥ :data:`MIN_BUDGET`."""
    text = str(budget).strip()
    try:
        n = int(text)
    except ValueError:
        raise WorstCaseOptionError.said(
            "{budget} {given}: not a whole number of runs; fix: the runs each detector's "
            "worst-case search spends, e.g. {budget} 300", given=repr(budget)) from None
    if n < MIN_BUDGET:
        raise WorstCaseOptionError.of("budget", n, f"the search needs at least {MIN_BUDGET} "
                                      "runs (screening, then the worst cell)", 300,
                                      f"or any other ≥ {MIN_BUDGET}")
    return n


def gated_names(summary: pd.DataFrame, limits: dict, only=None) -> tuple[list[str], list[str]]:
    """(names searched, names left out with the reason) of the detectors of *summary*: every
    result-row name with fault-free runs whose accepted false-alarm rate (*limits*, name →
    rate, :func:`reports.scoring.gate.fa_limits`) is 0; *only*: the names asked for
    (``--worst-case-detector``), each of which must be one of them."""
    free = summary[(summary["fault"] == "none") & (summary["n_runs"] > 0)]
    with_runs = list(dict.fromkeys(free["detector"].astype(str)))
    names = list(dict.fromkeys(summary["detector"].astype(str)))
    unknown = [n for n in (only or ()) if n not in names]
    if unknown:
        raise WorstCaseOptionError.of("only", unknown[0], f"not a detector of these results; "
                                      f"choose among {', '.join(names)} (a variant is named "
                                      "as in the results, e.g. comb-interval[a=0.9])")
    chosen = [n for n in names if not only or n in only]
    searched, left = [], []
    for name in chosen:
        if name not in with_runs:
            left.append(f"{name}: no fault-free run scored, nothing to search around")
        elif limits.get(name, 0.0) > 0.0:
            left.append(f"{name}: its false alarms are allowed up to a rate of "
                        f"{limits[name]:g} (detector_max_fa_rate), not gated at zero")
        else:
            searched.append(name)
    return searched, left


def _owner(name: str, labels) -> str:
    """The detector label whose results *name* is (itself, or a variant ``LABEL[…]``)."""
    return next(lb for lb in labels if name == lb or name.startswith(f"{lb}["))


def _alarms(rows: pd.DataFrame, flags: np.ndarray, margin: np.ndarray, files, source: str):
    """The :class:`Alarm` s of the rows flagged, worst margin first; *files*: per row, the
    ``worst.toml`` that replays it."""
    picked = pd.DataFrame({"i": np.flatnonzero(flags), "m": margin[flags]})
    picked = picked.sort_values("m", ascending=False, kind="stable")
    out = []
    for i in picked["i"]:
        r = rows.iloc[int(i)]
        out.append(Alarm(str(r["run_id"]), str(r["manoeuvre"]),
                         {c: float(r[c]) for c in FLIGHT_COLUMNS}, float(margin[i]),
                         Path(files[int(i)]), source))
    return out


def _corpus_rows(config, paths) -> tuple[pd.DataFrame, list[Path]]:
    """The run-table rows of the ``[[run]]`` entries of the corpus files *paths* (a run held
    by several once, at its first file) and, per row, the file that holds it."""
    from ..config import load_config
    from ..plan import explicit_plan
    from ..plant_setup import as_resolved

    campaign = as_resolved(config)       # resolved once for every file of the corpus
    frames, files = [], []
    for path in paths:
        rows = explicit_plan(campaign, load_config(Path(path)).runs)
        frames.append(rows)
        files += [path] * len(rows)
    rows = pd.concat(frames, ignore_index=True)
    first = ~rows["run_id"].duplicated().to_numpy()
    return rows[first].reset_index(drop=True), [f for f, k in zip(files, first) if k]


def replay_corpus(camp, outcomes: dict, *, jobs: int, scheduler=None, tls=None, log) -> None:
    """Evaluate again the corpus of every name of *outcomes* (name → :class:`WorstCase`) with
    the fitted detectors of campaign *camp*, on *jobs* local workers or the dask cluster
    *scheduler*; fills each outcome's ``corpus_*`` counts and its corpus false alarms."""
    from ..runner import evaluate_rows, prepare
    from ..store.directory import CampaignDir

    cdir = CampaignDir(camp.root)
    corpora = {name: cdir.worst_case_corpus(name) for name in outcomes}
    if not any(corpora.values()):
        return
    setup, detectors = prepare(camp.config, cdir.worst_case_replay_dir(), jobs=jobs,
                               scheduler=scheduler, tls=tls, fitted_from=camp.root, log=log)
    try:
        for name, paths in corpora.items():
            if not paths:
                continue
            rows, files = _corpus_rows(camp.config, paths)
            label = _owner(name, detectors)
            log(f"worst case {name}: replaying the corpus first, {len(rows)} runs of "
                f"{len(paths)} stored search(es)")
            results = evaluate_rows(setup, rows, {label: detectors[label]}, log=log)
            margin, flags = scores(results, rows, name)
            found = outcomes[name]
            found.corpus_files, found.corpus_runs = len(paths), len(rows)
            found.alarms += _alarms(rows, flags, margin, files, "corpus")
    finally:
        setup.close()


def search_detector(camp, found: WorstCase, *, jobs: int, scheduler=None, tls=None,
                    log) -> None:
    """The search of *found* (its name, budget and seed) on campaign *camp*: read back when
    a finished one is stored, else run and stored (module docstring); fills its search
    fields and adds its false alarms that the corpus replay did not name."""
    from ..store.directory import CampaignDir, SearchDir

    cdir, stored = CampaignDir(camp.root), SearchDir(found.search_dir)
    config = camp.config
    found.reused = cdir.finished_search(found.name, found.budget, found.seed, config.to_json())
    if found.reused:
        log(f"worst case {found.name}: the search of {found.budget} runs at seed {found.seed} "
            f"is stored in {found.search_dir}: reused, not run again")
        search = pd.read_parquet(stored.search_path)
    else:
        log(f"worst case {found.name}: searching {found.budget} fault-free runs (seed "
            f"{found.seed}) -> {found.search_dir}")
        try:
            search = falsify(config, found.name, budget=found.budget, out=found.search_dir,
                             jobs=jobs, seed=found.seed, scheduler=scheduler, tls=tls,
                             fitted_from=camp.root, against=camp.root, keep=KEEP,
                             log=log).search
        except FalsifyError as exc:
            raise WorstCaseError(f"worst case {found.name}: {exc}") from None
    flags = search["false_alarm"].fillna(False).to_numpy(bool)
    margin = search["margin"].to_numpy(float)
    found.searched, found.search_alarms = len(search), int(flags.sum())
    if np.isfinite(margin).any():
        worst = int(np.nanargmax(margin))
        found.worst_margin = float(margin[worst])
        found.worst_run = str(search["run_id"].iloc[worst])
        found.worst_manoeuvre = str(search["manoeuvre"].iloc[worst])
    # its false alarms that the corpus replay did not name already (a reused search's
    # worst runs are in the corpus: replayed there; the rest as the search stored them)
    known = {a.run_id for a in found.alarms}
    new = flags & ~search["run_id"].isin(known).to_numpy()
    found.alarms += _alarms(search, new, margin, [stored.worst_path] * len(search),
                            "stored search" if found.reused else "search")


def worst_case(camp, budget, names, *, seed: int = DEFAULT_SEED, jobs: int = 2,
               scheduler=None, tls=None, log=None) -> list[WorstCase]:
    """The worst-case gate of campaign *camp* (:class:`campaign.result.Campaign`) for the
    detector *names* (:func:`gated_names`) with *budget* runs per search at *seed*: the
    corpus replayed first, then the searches (module docstring). Returns one
    :class:`WorstCase` per name, in order."""
    from ..store.directory import CampaignDir

    from .falsify import search_space

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    budget = check_budget(budget)
    if isinstance(seed, bool) or int(seed) < 0:
        raise WorstCaseOptionError.of("seed", seed, "must be a whole number ≥ 0", DEFAULT_SEED)
    try:
        search_space(camp.config)          # a campaign the search cannot cover: before work
    except FalsifyError as exc:
        raise WorstCaseError(f"worst-case search of {camp.root}: {exc}") from None
    cdir = CampaignDir(camp.root)
    outcomes = {name: WorstCase(name, budget, int(seed),
                                cdir.worst_case_search_dir(name, budget, seed))
                for name in names}
    replay_corpus(camp, outcomes, jobs=jobs, scheduler=scheduler, tls=tls, log=log)
    for found in outcomes.values():
        search_detector(camp, found, jobs=jobs, scheduler=scheduler, tls=tls, log=log)
    return list(outcomes.values())
