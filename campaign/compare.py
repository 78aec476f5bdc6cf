"""``fdd-campaign compare DIR_A DIR_B``: what changed between two campaign directories.

Both directories are read back as campaigns (:func:`campaign.result.load`: files checked
against their manifest, fitted detectors as data); nothing is simulated.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from reports.scoring.compare import ScoredRows, compare_scored, differing_keys, format_compare
from reports.render.table import error_lines

from .store.directory import CampaignDir
from .store.fitted import compare_fitted

__all__ = ["compare_dirs"]

#: Result columns compare reads.
COMPARE_READ_COLUMNS = ["fault", "manoeuvre", "status", "error", "false_alarm", "detected",
                        "dtp"]


def _read_side(camp, index, outside: dict) -> tuple[int, list, ScoredRows]:
    """(runs with result rows, the rows that did not finish ``ok``, the scored rows) of
    campaign *camp*, read a batch of runs at a time; each run keyed by its row in the plan
    of campaign A (*index*, :meth:`campaign.store.directory.CampaignDir.run_index`), a run
    that plan lacks by a key past its end (*outside*: run id → key, shared by A and B)."""
    runs, bad, scored = 0, [], ScoredRows()
    n = len(index)
    for batch in camp.result_batches(columns=COMPARE_READ_COLUMNS):
        runs += batch["run_id"].nunique()        # a run's rows are all in one batch
        bad.append(batch[batch["status"].astype(str) != "ok"])
        keys = index.positions(batch["run_id"])
        for i in np.flatnonzero(keys == n):
            keys[i] = outside.setdefault(str(batch["run_id"].iat[i]), n + len(outside))
        scored.add(batch, keys)
    bad = (pd.concat(bad, ignore_index=True) if bad
           else pd.DataFrame(columns=["run_id", "detector", "status", "error"]))
    return runs, bad, scored


def compare_dirs(dir_a, dir_b, *, alpha: float = 0.01, log=print) -> pd.DataFrame:
    """Compare two campaign directories cell by cell
    (:func:`reports.scoring.compare.compare_results`) and print the table; returns it. The result
    rows are read a batch of runs at a time and only what the tests need is kept of each run
    (:class:`reports.scoring.compare.ScoredRows`)."""
    from .result import load

    a, b = load(dir_a), load(dir_b)
    ca, cb = a.config.to_dict(), b.config.to_dict()
    differ = differing_keys(ca, cb)
    index, outside = CampaignDir(a.root).run_index(), {}
    runs_a, bad_a, scored_a = _read_side(a, index, outside)
    runs_b, bad_b, scored_b = _read_side(b, index, outside)
    del index
    log(f"A: {a.root} ({a.config.campaign.name}, {runs_a} runs)")
    log(f"B: {b.root} ({b.config.campaign.name}, {runs_b} runs)")
    log("the campaign files differ in: " + ("; ".join(differ) if differ else "nothing"))
    for side, bad in (("A", bad_a), ("B", bad_b)):
        for line in error_lines(bad):
            log(f"{side}: {line}")
    notes = compare_fitted(a, b, log)
    table = compare_scored(scored_a.table(), scored_b.table(), alpha=alpha)
    labels = {str(d): str(d).split("[", 1)[0] for d in table["detector"]}
    table["fitted"] = [("re-learned" if labels[str(d)] in notes else "shared")
                       for d in table["detector"]]
    log(format_compare(table, alpha=alpha, notes=notes))
    return table
