"""The report's section "Hazard per flight hour" (docs/evidence.md): the table that
``fdd-campaign certify`` writes to ``certificate-hazard.parquet`` (one row per detector ×
fault type, the undetected faults of every type, the false alarms), each upper bound set
against the AMC 25.1309 budgets, and the assumptions it rests on. An HTML fragment that
the report page places among its sections; it knows nothing of how the table was made
(the budgets and assumptions are passed in)."""

from __future__ import annotations

import html
import math
from typing import Mapping, Sequence

import pandas as pd

__all__ = ["hazard_section", "insert_section"]


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _g(x) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3g}"


def hazard_section(hazard: pd.DataFrame, budgets: Mapping[str, float],
                   assumptions: Sequence[str]) -> str:
    """``<section id="hazard">`` with the hazard table *hazard* (the columns of
    ``campaign.hazard.HAZARD_COLUMNS``), the *budgets* (category → rate per flight hour)
    and the *assumptions* (sentences) listed under it."""
    level = f"{100 * float(hazard['level'].iloc[0]):g} %" if len(hazard) else "95 %"
    head = ["detector", "fault", "runs", "missed / FA", f"P per run ≤ ({level})",
            "rate [1/FH]", "per FH", f"per FH ≤ ({level})", "meets",
            "per FH ≤, late = undetected"]
    rows = []
    for r in hazard.to_dict(orient="records"):
        fault = {"none": "false alarm", "all": "all faults (undetected)"}.get(r["fault"],
                                                                            r["fault"])
        cells = [_e(r["detector"]), _e(fault), str(int(r["n_runs"])), str(int(r["events"])),
                 _g(r["p_run_upper95"]), _g(r["rate_per_fh"]), _g(r["per_fh"]),
                 _g(r["per_fh_upper95"]), _e(r["meets"]), _g(r["in_time_per_fh_upper95"])]
        style = ' style="font-weight:bold"' if r["fault"] in ("all", "none") else ""
        rows.append(f"<tr{style}>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    budget_text = ", ".join(f"{_e(k)} ≤ {v:g}" for k, v in budgets.items())
    table = ("<table id=\"hazard-table\"><thead><tr>"
             + "".join(f"<th>{_e(h)}</th>" for h in head) + "</tr></thead><tbody>\n"
             + "\n".join(rows) + "\n</tbody></table>")
    return ('<section id="hazard"><h2>Hazard per flight hour</h2>'
            "<p>Both sides of each detector (Hu and Seiler's combination, docs/evidence.md): "
            "the rate of undetected actuator faults per flight hour, each fault mode's "
            "occurrence rate times its missed-detection probability (exact one-sided "
            f"Clopper–Pearson bound at {level}; the total's bound Bonferroni-adjusted over "
            "the fault types), and the false-alarm rate per flight hour of the fault-free "
            f"runs. AMC 25.1309 budgets per flight hour: {budget_text}; <i>meets</i> names the "
            "most severe category whose budget the bound does not exceed.</p>" + table
            + "<p>Assumptions:</p><ul>" + "".join(f"<li>{_e(a)}</li>" for a in assumptions)
            + "</ul></section>")


def insert_section(page: str, section: str) -> str:
    """*page* with *section* placed before the runs' drill-down (``<section id="runs">``),
    or before ``</body>`` without one; *page* itself when *section* is empty."""
    if not section:
        return page
    anchor = '<section id="runs">'
    if anchor in page:
        return page.replace(anchor, section + anchor, 1)
    return page.replace("</body>", section + "</body>", 1)
