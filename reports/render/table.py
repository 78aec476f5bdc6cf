"""Plain-text terminal table of a summary, laid out like [CHEN] Tables 3–4.

Per detector: one row per fault type with FA (%), MD (%), Min/Mean/Max DTP ([CHEN] §5),
each rate followed by its exact one-sided 95 % upper bound (docs/design.md §5, Metrics), then the
fault-free false alarms per manoeuvre as ``k/n, FA ≤ x %``.
"""

from __future__ import annotations

import math

import pandas as pd

from ..scoring.metrics import FAULT_FREE
from .paper import CHEN_ESTIMATOR, PAPER_TABLES
from ..scoring.summary import ALL_FAULTS, ALL_MANOEUVRES, detector_order
from ..scoring.text import number_text

__all__ = ["error_lines", "format_paper_table", "format_table", "late_text", "number_text",
           "percent_text"]


def percent_text(x, missing: str = "-") -> str:
    """A rate in [0, 1] as a percentage with two decimals."""
    return number_text(100 * x if x is not None else None, ".2f", missing)


def _dtp(row) -> str:
    parts = [number_text(row.dtp_min, ".4g"), number_text(row.dtp_mean, ".4g"),
             number_text(row.dtp_max, ".4g")]
    return "-" if parts == ["-", "-", "-"] else "/".join(parts)


def _delays(row) -> str:
    """Min/mean/max delay [s] of a summary row; '-' when missing (summaries written before
    ``delay_min_s``/``delay_max_s`` existed, or nothing detected)."""
    parts = [number_text(getattr(row, c, None), ".3g")
             for c in ("delay_min_s", "delay_mean_s", "delay_max_s")]
    return "-" if "-" in parts else "/".join(parts)


def late_text(row) -> str:
    """Late detections (DTP > 1) of a summary row; '-' for summaries written before the
    column existed."""
    late = getattr(row, "late_count", None)
    return "-" if late is None or late != late else str(int(late))


def _fault_label(fault: str) -> str:
    return "all faults" if fault == ALL_FAULTS else fault


def _render(header: list[str], rows: list[list[str]], align: str) -> list[str]:
    """Fixed-width lines; ``align`` has one 'l' or 'r' per column."""
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows)]

    def line(cells):
        out = [c.ljust(w) if a == "l" else c.rjust(w) for c, w, a in zip(cells, widths, align)]
        return "  ".join(out).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return [line(header), rule] + [line(r) for r in rows]


def format_table(summary: pd.DataFrame) -> str:
    """Render a summary (:func:`reports.scoring.summary.summarize`) as fixed-width text.

    Rates are in %; ``≤95`` columns are exact one-sided 95 % upper bounds; for faulty runs FA
    counts alarms before onset. ``DTP≤1`` is the share of faulty runs detected within the
    required time (misses count as not within).
    """
    if summary is None or len(summary) == 0:
        return "no results"
    lines: list[str] = []
    for detector in detector_order(summary["detector"]):
        det = summary[summary["detector"] == detector]
        if lines:
            lines.append("")
        lines.append(f"Detector: {detector}")
        lines.append("")

        faults = det[(det["manoeuvre"] == ALL_MANOEUVRES) & (det["fault"] != FAULT_FREE)]
        if len(faults):
            header = ["Fault scenario", "n", "err", "FA (%)", "FA ≤95 (%)", "MD (%)",
                      "MD ≤95 (%)", "late", "MD in T (%)", "Min/Mean/Max DTP", "DTP≤1 (%)"]
            body = [[_fault_label(r.fault), str(int(r.n_runs)), str(int(r.n_errors)),
                     percent_text(r.fa_rate), percent_text(r.fa_upper95), percent_text(r.md_rate),
                     percent_text(r.md_upper95),
                     late_text(r), percent_text(getattr(r, "md_req_rate", math.nan)), _dtp(r),
                     number_text(100 * r.dtp_within, ".1f")]
                    for r in faults.itertuples(index=False)]
            lines += _render(header, body, "lrrrrrrrrlr")
            lines.append("(FA of faulty runs: alarms before onset. MD: never detected in the "
                         "detection window; late: detected after the required time T (DTP > "
                         "1); MD in T: not detected within T, missed or late)")
            lines.append("")

        free = det[det["fault"] == FAULT_FREE]
        if len(free):
            header = ["Fault-free manoeuvre", "n", "err", "FA (%)", "False alarms (95 % bound)",
                      "Worst margin"]
            body = []
            for r in free.itertuples(index=False):
                n = int(r.n_runs)
                bound = (f"{int(r.fa_count)}/{n}, FA ≤ {percent_text(r.fa_upper95)} %" if n
                         else "no scored runs")
                label = "all manoeuvres" if r.manoeuvre == ALL_MANOEUVRES else r.manoeuvre
                body.append([label, str(n), str(int(r.n_errors)), percent_text(r.fa_rate), bound,
                             number_text(r.worst_margin, ".3f")])
            lines += _render(header, body, "lrrrlr")
    return "\n".join(lines)


def error_lines(results: pd.DataFrame, per_detector: int = 3) -> list[str]:
    """One warning per detector with runs that did not finish (``status != "ok"``): how
    many, with which status, and its first distinct messages with a run id each."""
    bad = results[results["status"].astype(str) != "ok"]
    out = []
    for detector in detector_order(bad["detector"]):
        g = bad[bad["detector"] == detector]
        counts = ", ".join(f"{n} {status}" for status, n in
                           g["status"].astype(str).value_counts().sort_index().items())
        first = g.drop_duplicates("error").head(per_detector)
        more = g["error"].nunique() - len(first)
        msgs = "; ".join(f"run {r.run_id}: {r.error}" for r in first.itertuples(index=False))
        out.append(f"{detector}: {g['run_id'].nunique()} run(s) did not finish ({counts}); "
                   "they are in the 'err' column and left out of every rate. "
                   f"{msgs}{f' (and {more} other messages)' if more > 0 else ''}")
    return out


def _sci(x) -> str:
    return number_text(x, ".4g")


def format_paper_table(summary: pd.DataFrame, reference: str,
                       required_time_s: dict | None = None) -> str:
    """The campaign's figures beside a published table (:data:`reports.render.paper.PAPER_TABLES`),
    two rows per fault: ``ours`` (the fault read on its estimator's row,
    :data:`reports.render.paper.CHEN_ESTIMATOR`) then the paper's.

    Columns: FA (%) — ours over the estimator's fault-free runs of every manoeuvre (their
    count given) and, after ``/``, before onset in the fault's runs; MD (%) — never detected
    in the run; MD in T (%) — not detected within our required time (missed or late);
    Min/Mean/Max delay [s] after onset — ours measured, the paper's its DTP × its inferred
    denominator (:meth:`reports.render.paper.PaperTable.delays_s`); Min/Mean/Max DTP, each over its
    own required time; the mean and variance of the fault-estimation error f̂ − f
    normalised by the deflection range (pooled over the post-onset samples,
    ``reports.scoring.summary``). *required_time_s*: fault → our required time [s] (the campaign's
    ``[requirements] detection_time_s``), named in the notes when given.
    """
    table = PAPER_TABLES[reference]
    if summary is None or len(summary) == 0:
        return "no results"
    header = ["Fault scenario", "source", "FA (%) free / pre-onset", "MD (%)", "MD in T (%)",
              "Min/Mean/Max delay (s)", "Min/Mean/Max DTP", "error mean", "error variance"]
    body = []
    for fault, paper in table.rows.items():
        name = CHEN_ESTIMATOR[fault]
        det = summary[(summary["detector"] == name) & (summary["manoeuvre"] == ALL_MANOEUVRES)]
        row = det[det["fault"] == fault]
        free = det[det["fault"] == FAULT_FREE]
        if len(row):
            r = row.iloc[0]
            fa_free = (f"{percent_text(free.iloc[0].fa_rate)} (n={int(free.iloc[0].n_runs)})"
                       if len(free) else "-")
            body.append([fault, f"ours: {name}", f"{fa_free} / {percent_text(r.fa_rate)}",
                         percent_text(r.md_rate), percent_text(r.get("md_req_rate", math.nan)),
                         _delays(r),
                         _dtp(r), _sci(r.get("est_err_mean", math.nan)),
                         _sci(r.get("est_err_var", math.nan))])
        else:
            body.append([fault, f"ours: {name}", "not in this campaign", "", "", "", "", "",
                         ""])
        delays = table.delays_s(fault)
        body.append(["", table.cite.split(" (")[0], f"{paper.fa_pct:g}", f"{paper.md_pct:g}",
                     "-", "-" if delays is None else "/".join(f"{v:g}" for v in delays),
                     "/".join(f"{v:g}" for v in paper.dtp),
                     "-" if paper.err_mean is None else f"{paper.err_mean:g}",
                     "-" if paper.err_var is None else f"{paper.err_var:g}"])
    ours_t = ("our required times " + ", ".join(
        f"{f} {float(required_time_s[f]):g} s" for f in table.rows if f in required_time_s)
        if required_time_s else "our required times (the campaign's [requirements])")
    paper_t = (f"{table.dtp_denominator_s:g} s" if table.dtp_denominator_s is not None
               else "its own, not known")
    lines = [f"Beside {table.cite}:", ""]
    lines += _render(header, body, "llrrrllrr")
    lines += [
        "(ours: each fault on the row of its estimator. FA free: false alarms of that "
        "estimator on every fault-free run; pre-onset: alarms before onset in the fault's "
        "runs. MD: never detected; MD in T: not detected within our required time (missed "
        "or late); the paper gives MD only. Delay: seconds from onset to the first alarm, "
        "the unit to compare. DTP = delay / required time: ours over " + ours_t + ", the "
        "paper's over " + paper_t + ", so the two DTP columns are not comparable)",
    ]
    if table.denominator_note:
        lines.append(f"({table.denominator_note})")
    lines.append(
        "(error: f̂ − f after onset, f the jam's additive effect on the rod measurement "
        "([CHEN] eq. 4), normalised by the rod travel of the deflection range, variance in "
        "its square; ours pooled over all post-onset samples of the fault's runs. The paper "
        "does not state its normalisation; '-': not given, the disconnection's cannot be "
        "computed without a surface sensor ([CHEN] §6.2))")
    return "\n".join(lines)
