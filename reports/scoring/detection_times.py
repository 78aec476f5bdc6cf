"""Detection times per scenario and detector variant, laid out like [COMB] Table 1.

For campaigns of fixed scenarios (every faulty group has a fixed onset, as the [COMB] §4
reproduction ``comb-table1``), the first alarm time of each group matters more than rates:
one row per group (fault, onset), one column per detector variant (e.g. one per residual
filter pole a), the time [s] of the first alarm. A fault-free group shows its first alarm
(a false alarm) or "none". With several runs per group the median first alarm is shown
and the number of runs without alarm is counted.

Only result rows and the run table are read (``reports`` does not import the engine).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .metrics import FAULT_FREE
from .summary import natural_key

__all__ = ["DETECTION_TIME_COLUMNS", "detection_time_table", "format_detection_times",
           "fixed_onset_campaign"]

#: Columns of the long-form table.
DETECTION_TIME_COLUMNS: tuple[str, ...] = (
    "group", "fault", "onset_s", "detector", "n_runs", "n_alarmed", "first_alarm_s",
    "delay_s",
)


def fixed_onset_campaign(plan) -> bool:
    """Whether every faulty group of *plan* has one onset (the Table-1 view applies).
    *plan*: the run table (columns ``group``, ``fault``, ``onset_s`` at least), or
    consecutive parts of it (an iterable of DataFrames, read one at a time)."""
    parts = [plan] if isinstance(plan, pd.DataFrame) else plan
    onsets: dict = {}                 # faulty group -> its distinct onsets (NaN left out)
    for part in parts:
        faulty = part[part["fault"] != FAULT_FREE]
        for group, values in faulty.groupby("group", sort=False)["onset_s"]:
            seen = onsets.setdefault(group, set())
            if len(seen) < 2:         # two already decide it
                seen.update(values.dropna().unique().tolist())
    return bool(onsets) and all(len(seen) == 1 for seen in onsets.values())


def detection_time_table(plan: pd.DataFrame, results: pd.DataFrame) -> pd.DataFrame:
    """Long form: one row per group × detector variant (columns
    :data:`DETECTION_TIME_COLUMNS`); ``first_alarm_s`` is the median over the group's runs
    that alarmed (NaN when none did), ``delay_s`` = first_alarm_s − onset_s."""
    ok = results[results["status"] == "ok"]
    groups = plan[["run_id", "group", "fault", "onset_s"]]
    merged = ok.drop(columns=["fault"]).merge(groups, on="run_id", how="inner")
    order = {g: i for i, g in enumerate(pd.unique(plan["group"]))}
    rows = []
    for (group, detector), part in merged.groupby(["group", "detector"], sort=False):
        first = part["first_alarm_s"].to_numpy(float)
        alarmed = np.isfinite(first)
        onset = float(part["onset_s"].iloc[0]) if part["onset_s"].notna().any() else math.nan
        t = float(np.median(first[alarmed])) if alarmed.any() else math.nan
        rows.append({"group": group, "fault": str(part["fault"].iloc[0]), "onset_s": onset,
                     "detector": detector, "n_runs": int(len(part)),
                     "n_alarmed": int(alarmed.sum()), "first_alarm_s": t,
                     "delay_s": t - onset if math.isfinite(onset) else math.nan})
    table = pd.DataFrame(rows, columns=list(DETECTION_TIME_COLUMNS))
    if table.empty:
        return table
    table["_o"] = table["group"].map(order)
    return table.sort_values("_o", kind="stable").drop(columns="_o").reset_index(drop=True)


def _short_names(detectors: list[str]) -> dict[str, str]:
    """Column headers: the variant part ("a=0.9") when all columns share one detector."""
    bases = {d.split("[", 1)[0] for d in detectors}
    if len(bases) == 1 and all("[" in d for d in detectors):
        return {d: d.split("[", 1)[1].rstrip("]") for d in detectors}
    return {d: d for d in detectors}


def format_detection_times(table: pd.DataFrame) -> str:
    """Plain text, one line per group and one column per variant, like [COMB] Table 1."""
    if table.empty:
        return "detection times: no result rows"
    lines = []
    for base in pd.unique(table["detector"].str.split("[", n=1).str[0]):
        part = table[table["detector"].str.split("[", n=1).str[0] == base]
        detectors = sorted(pd.unique(part["detector"]), key=natural_key)
        heads = _short_names(detectors)
        wide = part.pivot_table(index="group", columns="detector", values="first_alarm_s",
                                aggfunc="first", dropna=False, sort=False)
        meta = part.drop_duplicates("group").set_index("group")
        label_w = max(len(_row_label(g, meta.loc[g])) for g in meta.index)
        col_w = max(8, *(len(h) for h in heads.values()))
        lines.append(f"Detection times (s) of {base}" + (" wrt residual filter pole a"
                     if any(h.startswith("a=") for h in heads.values()) else ""))
        lines.append(" " * label_w + "  " + "  ".join(heads[d].rjust(col_w) for d in detectors))
        for g in meta.index:
            cells = []
            for d in detectors:
                v = wide.loc[g, d] if d in wide.columns else math.nan
                cells.append(("none" if not np.isfinite(v) else f"{v:.2f}").rjust(col_w))
            lines.append(_row_label(g, meta.loc[g]).ljust(label_w) + "  " + "  ".join(cells))
        lines.append("")
    return "\n".join(lines).rstrip()


def _row_label(group: str, row) -> str:
    if row["fault"] == FAULT_FREE:
        return f"{group}: fault-free"
    return f"{group}: {row['fault']} t = {row['onset_s']:g} s"
