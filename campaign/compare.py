"""``fdd-campaign compare DIR_A DIR_B``: what changed between two campaign directories.

Both directories are read back as campaigns (:func:`campaign.result.load`: files checked
against their manifest, fitted detectors as data); nothing is simulated.
"""

from __future__ import annotations

import pandas as pd

from reports.compare import compare_results, differing_keys, format_compare
from reports.table import error_lines

from .store.fitted import compare_fitted

__all__ = ["compare_dirs"]


def compare_dirs(dir_a, dir_b, *, alpha: float = 0.01, log=print) -> pd.DataFrame:
    """Compare two campaign directories cell by cell (:func:`reports.compare.compare_results`)
    and print the table; returns it."""
    from .result import load

    a, b = load(dir_a), load(dir_b)
    ca, cb = a.config.to_dict(), b.config.to_dict()
    differ = differing_keys(ca, cb)
    log(f"A: {a.root} ({a.config.campaign.name}, {a.results['run_id'].nunique()} runs)")
    log(f"B: {b.root} ({b.config.campaign.name}, {b.results['run_id'].nunique()} runs)")
    log("the campaign files differ in: " + ("; ".join(differ) if differ else "nothing"))
    for side, camp in (("A", a), ("B", b)):
        for line in error_lines(camp.results):
            log(f"{side}: {line}")
    notes = compare_fitted(a, b, log)
    table = compare_results(a.results, b.results, alpha=alpha)
    labels = {str(d): str(d).split("[", 1)[0] for d in table["detector"]}
    table["fitted"] = [("re-learned" if labels[str(d)] in notes else "shared")
                       for d in table["detector"]]
    log(format_compare(table, alpha=alpha, notes=notes))
    return table
