"""The campaign report as one self-contained HTML page (figures embedded, no script, no
network).

Layout: the gate's verdict first — the checks of ``fdd-campaign gate DIR``, in its words,
with the run ids it names (:mod:`reports.scoring.gate`, evaluated by the caller with the command's
arguments) — then one overview table across detectors (FA, MD, MD in T, DTP, each
requirement of the campaign file met or not: the verdict of ``gate --all-requirements``),
then the detail: per detector FA / MD with exact 95 % Clopper–Pearson intervals and DTP
statistics in the layout of [CHEN] Tables 3–4, the residual envelopes, the per-fault
detection behaviour with example runs, the envelope maps, and the drill-down lists: every
table row links to the runs behind it. Detectors appear in one order everywhere (the
caller's, by default the summary's).

This module only formats what it is given (DataFrames, PNG bytes); it reads no file.
"""

from __future__ import annotations

import base64
import html
import math
import re
from dataclasses import dataclass
from typing import Mapping, Sequence

import pandas as pd

from . import table
from ..scoring.gate import GateResult
from ..scoring.metrics import FAULT_FREE, clopper_pearson
from ..scoring.summary import ALL_FAULTS, ALL_MANOEUVRES

__all__ = ["ReportFigure", "anchor", "count_figures", "drilldown_section", "hazard_section",
           "render_report", "show_command"]

#: Sections of the page that hold figures, in page order: key → heading.
SECTIONS = {
    "envelope": "Residual envelopes of the fault-free runs",
    "fault": "Detection per fault type",
    "map": "Envelope maps",
    "certificate": "False-alarm probability certificates (certify)",
    "survival": "Detection time as survival data",
}


@dataclass(frozen=True)
class ReportFigure:
    """One embedded figure.

    section : a key of :data:`SECTIONS`
    group : sub-heading it is shown under (e.g. the detector, the fault type)
    title : alt text and caption heading
    png : the PNG bytes
    caption : one sentence under the figure
    """

    section: str
    group: str
    title: str
    png: bytes
    caption: str = ""


def anchor(*parts: str) -> str:
    """HTML id of a drill-down list: ``runs-`` and the parts, made id-safe."""
    slug = "-".join(re.sub(r"[^A-Za-z0-9_.]+", "_", str(p)) for p in parts)
    return f"runs-{slug}"


def show_command(run_id: str) -> str:
    """Command that re-simulates one run, to be run in the campaign directory."""
    return f"fdd-campaign show . {run_id} --plot {run_id}.png"


# ---- formatting ----------------------------------------------------------------------------
def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _num(x, fmt: str = ".3g") -> str:
    return table.number_text(x, fmt, missing="–")


def _pct(x) -> str:
    return table.percent_text(x, missing="–")


def _ci(k, n) -> str:
    if not n:
        return "–"
    lo, hi = clopper_pearson(int(k), int(n))
    return f"[{100 * lo:.2f}, {100 * hi:.2f}]"


def _badge(passed: bool | None) -> str:
    if passed is None:
        return '<span class="badge na">–</span>'
    return ('<span class="badge pass">PASS</span>' if passed
            else '<span class="badge fail">FAIL</span>')


def _table(header: list[str], rows: list[list[str]], cls: str = "", tid: str = "",
           text_columns=(), wrap: bool = True) -> str:
    """A table; the cells of *text_columns* (indices) hold prose that wraps, the others
    stay on one line. With *wrap* the table sits in a box as wide as the page at most,
    scrolled sideways inside it if it must (``div.tablewrap``): the page never gets wider
    than its window. The drill-down's tables have their own scroll box (*wrap* False)."""
    head = "".join(f"<th>{h}</th>" for h in header)
    text = set(text_columns)
    body = "\n".join("<tr>" + "".join(f'<td class="text">{c}</td>' if i in text
                                       else f"<td>{c}</td>" for i, c in enumerate(r))
                     + "</tr>" for r in rows)
    attrs = (f' class="{cls}"' if cls else "") + (f' id="{tid}"' if tid else "")
    table = f"<table{attrs}><thead><tr>{head}</tr></thead><tbody>\n{body}\n</tbody></table>"
    return f'<div class="tablewrap">{table}</div>' if wrap else table


def _img(fig: ReportFigure) -> str:
    data = base64.b64encode(fig.png).decode("ascii")
    cap = f"<figcaption><b>{_e(fig.title)}</b>" + (f" — {_e(fig.caption)}" if fig.caption
                                                    else "") + "</figcaption>"
    return (f'<figure><img class="fig" data-section="{_e(fig.section)}" alt="{_e(fig.title)}" '
            f'src="data:image/png;base64,{data}">{cap}</figure>')


# ---- verdict -------------------------------------------------------------------------------
def _passed(checks) -> bool | None:
    """All of *checks* passed (None: there is none)."""
    checks = list(checks)
    return all(c.passed for c in checks) if checks else None


def _row_passed(gate: GateResult | None, detector: str, fault: str, manoeuvre: str):
    """Pass/fail of a summary row: the checks that concern exactly its runs."""
    if gate is None:
        return None
    mine = [c for c in gate.checks if c.detector == detector]
    if fault == ALL_FAULTS:
        rel = [c for c in mine if c.fault not in (FAULT_FREE, "all")]
    elif manoeuvre == ALL_MANOEUVRES:
        rel = [c for c in mine if c.fault == fault]
    else:
        rel = [c for c in mine if c.fault == fault and c.manoeuvre in (manoeuvre,
                                                                        ALL_MANOEUVRES)]
    return _passed(rel)


def _labelled_badge(label: str, passed: bool | None) -> str:
    """A PASS/FAIL badge that says which verdict it is (the gate, all requirements)."""
    if passed is None:
        return f'<span class="badge na">{_e(label)}: –</span>'
    return (f'<span class="badge {"pass" if passed else "fail"}">{_e(label)}: '
            f'{"PASS" if passed else "FAIL"}</span>')


def _gate_section(gate: GateResult | None, requirements: dict) -> str:
    """The verdict of ``fdd-campaign gate DIR``: its verdict line, its failed checks with
    the runs they name, every line it prints (folded)."""
    out = ['<section id="gate"><h2>Gate verdict (<code>fdd-campaign gate</code>)</h2>']
    if gate is None:
        out.append("<p>No gate was evaluated.</p></section>")
        return "\n".join(out)
    out.append(f'<p class="gateline {"pass" if gate.passed else "fail"}">'
               f'{_e(gate.verdict)}</p>')
    allow = requirements.get("detector_max_fa_rate") or {}
    out.append(
        '<p class="note">What <code>fdd-campaign gate DIR</code> prints for this directory, in '
        "its words. It checks that the campaign has finished its plan, that no detector "
        f"exceeds the false-alarm limit max_fa_rate = {_e(requirements.get('max_fa_rate'))}"
        + (f" (per-detector allowances {_e(allow)})" if allow else "")
        + " in any fault-free manoeuvre or before any fault onset, that every run "
        "finished, and that a detector declared to isolate one surface's faults stays silent "
        "on another surface's (isolation). The campaign file's missed-detection and "
        "detection-time limits are not part "
        'of it: they are in the overview below, under <a href="#requirements">all '
        "requirements</a> "
        "(<code>fdd-campaign gate --all-requirements</code>).</p>")
    failures = gate.failures
    if failures:
        items = []
        for c in failures:
            runs = "".join(f"<li><code>{_e(show_command(r))}</code></li>" for r in c.run_ids)
            items.append(f"<li>{_e(c.message)}" + (f"<ul>{runs}</ul>" if runs else "")
                         + "</li>")
        out.append(f'<ul class="fails">{"".join(items)}</ul>')
    out.append(f"<details><summary>every line of <code>fdd-campaign gate</code> "
               f"({len(gate.checks)} checks)</summary><pre class=\"gatelines\">"
               + _e(gate.format()) + "</pre></details>")
    out.append("</section>")
    return "\n".join(out)


def _mark(text: str, checks) -> str:
    """A value with its requirement met (✓), not met (✗, followed by the reason: which
    check fails and by how much, as the value shown may be the one that passes, e.g. the
    largest DTP of the detected runs beside a fault type with none detected) or not
    required (no check)."""
    checks = list(checks)
    if not checks:
        return text
    failed = [c for c in checks if not c.passed]
    if not failed:
        return f'<span class="met">{text} ✓</span>'
    why = "; ".join(_e(_reason(c)) for c in failed)
    return f'<span class="unmet">{text} ✗</span><br><small class="why">{why}</small>'


def _reason(check) -> str:
    """Why a failed requirement check fails, in a few words: where and the value against
    the limit (:class:`reports.scoring.gate.Check`; rates as fractions, shown in %)."""
    where = "fault-free" if check.fault == FAULT_FREE else check.fault
    if check.manoeuvre not in (ALL_MANOEUVRES, "all"):
        where = f"{where} {check.manoeuvre}"
    value, limit = float(check.value), float(check.limit)
    if check.name == "dtp":
        if math.isnan(value):
            return f"{where}: no detected run"
        return f"{where}: DTP {value:.3g} > {limit:g}"
    if check.name == "missed_detection":
        return f"{where}: MD {_pct(value)} % > {_pct(limit)} %"
    if check.name == "false_alarm":
        return f"{where}: FA {_pct(value)} % > {_pct(limit)} %"
    return re.sub(r"^FAIL\s+", "", check.message)


def _overview(summary: pd.DataFrame, gate: GateResult | None, full: GateResult | None,
              requirements: dict, detectors: list[str]) -> str:
    """One row per detector: FA, MD, MD in T, DTP with each requirement met or not."""
    full_checks = full.checks if full is not None else []

    def checks(det, name):
        return [c for c in full_checks if c.detector == det and c.name == name]

    rows = []
    for det in detectors:
        s = summary[summary["detector"] == det]
        free = s[(s["fault"] == FAULT_FREE) & (s["manoeuvre"] == ALL_MANOEUVRES)]
        faulty = s[(s["fault"] == ALL_FAULTS) & (s["manoeuvre"] == ALL_MANOEUVRES)]
        per_fault = s[(s["manoeuvre"] == ALL_MANOEUVRES)
                      & ~s["fault"].isin([FAULT_FREE, ALL_FAULTS])]
        fa_checks = checks(det, "false_alarm")
        cells = [f'<a href="#{anchor("detector", det)}">{_e(det)}</a>',
                 _badge(_passed(c for c in (gate.checks if gate else [])
                                if c.detector == det))]
        if len(free):
            r = free.iloc[0]
            fa = f"{int(r.fa_count)}/{int(r.n_runs)} (≤ {_pct(r.fa_upper95)} %)"
            cells.append(_mark(fa, (c for c in fa_checks if c.fault == FAULT_FREE)))
        else:
            cells.append("–")
        if len(faulty):
            r = faulty.iloc[0]
            cells.append(_mark(f"{int(r.fa_count)}/{int(r.n_runs)}",
                               (c for c in fa_checks if c.fault != FAULT_FREE)))
            worst = per_fault.sort_values("md_rate", ascending=False, kind="stable").iloc[0] \
                if len(per_fault) > 1 else None
            md = _pct(r.md_rate) + (f'<br><small>worst: {_e(worst.fault)} '
                                    f"{_pct(worst.md_rate)}</small>" if worst is not None
                                    else "")
            md += _informative_note([c for c in full_checks if c.detector == det
                                     and c.informative], per_fault)
            cells.append(_mark(md, checks(det, "missed_detection")))
            cells.append(_pct(getattr(r, "md_req_rate", math.nan)))
            cells.append(_mark(_num(r.dtp_max, ".4g"), checks(det, "dtp")))
        else:
            cells += ["–"] * 4
        # runs in error: the fault-free aggregate and the all-faults one (no run twice)
        cells.append(str(int(free["n_errors"].sum() + faulty["n_errors"].sum())))
        cells.append(_badge(_passed(c for c in full_checks if c.detector == det)))
        rows.append(cells)
    req = requirements

    def lim(key, fmt):
        v = req.get(key)
        return "not required" if v is None else fmt(v)

    head = ["detector", "gate<br>(fdd-campaign gate)",
            f"FA fault-free<br>(limit {lim('max_fa_rate', _pct)} %)",
            "FA before onset", f"MD (%)<br>(limit {lim('max_md_rate', _pct)} %)",
            "MD in T (%)", f"max DTP<br>(limit {lim('max_dtp', lambda v: f'{v:g}')})",
            "errors", "all requirements<br>(--all-requirements)"]
    verdict = ("" if full is None else
               f'<p class="gateline {"pass" if full.passed else "fail"}">All requirements '
               f"of the campaign file (<code>fdd-campaign gate --all-requirements</code>): "
               + ("met" if full.passed else f"not met, {len(full.failures)} of "
                  f"{sum(not c.informative for c in full.checks)} checks fail") + "</p>")
    return ('<section id="requirements"><h2>Overview across detectors</h2>' + verdict
            + _table(head, rows, cls="overview", tid="overview")
            + '<p class="note">✓ requirement of the campaign file met, ✗ not met, with the '
            "fault type (or manoeuvre) that fails it and its value against the limit; a value "
            "without a mark has no requirement. FA fault-free: false alarms / fault-free "
            "runs with the exact one-sided 95 % bound; FA before onset: faulty runs alarmed "
            "before the fault; MD: never detected (over every faulty run; the requirement "
            "holds per fault type); MD in T: not detected within the required time, missed "
            "or late (no limit of its own: a late run fails the DTP requirement); max DTP: "
            "the largest detection delay / required time. “gate” is the verdict of "
            "<code>fdd-campaign gate</code> above (false alarms, run errors, isolation); “all "
            "requirements” adds the MD and DTP limits, which hold a detector on the fault "
            "types it is designed for and a detection system's members not at all (the "
            "system holds them): the MD cell names the fault types reported for information "
            "only (docs/design.md §5, Declared coverage, Detection systems).</p></section>")


def _informative_note(checks: list, per_fault: pd.DataFrame) -> str:
    """The MD cell's note of the fault types a detector is not held to (its informative
    checks, :func:`reports.scoring.gate.evaluate_gate`): not designed for them, with what it
    detected of each (its per-fault summary rows *per_fault*), or a detection system's
    member (the system named by the check's message, ``INFO member of SYSTEM: …``)."""
    if not checks:
        return ""
    member = [c for c in checks if c.name == "member"]
    if member:
        system = member[0].message.removeprefix("INFO member of ").split(":", 1)[0]
        return (f"<br><small>member of {_e(system)}: its MD and DTP are the system's "
                "requirement, reported for information</small>")
    rows = per_fault.set_index("fault")
    parts = []
    for c in checks:
        n = int(rows.loc[c.fault, "n_runs"])
        parts.append(f"{_e(c.fault)} ({n - int(rows.loc[c.fault, 'md_count'])}/{n} detected)")
    return "<br><small>not designed for: " + ", ".join(parts) + "</small>"


def _details(summary: pd.DataFrame, gate: GateResult | None, full: GateResult | None,
             requirements: dict, detectors: list[str]) -> str:
    out = ['<section id="verdict"><h2>Per detector</h2>']
    req = ", ".join(f"{k} = {v}" for k, v in requirements.items())
    out.append(f'<p class="req">Requirements of the campaign: {_e(req) or "none stored"}. '
               "Rates in %; intervals are exact two-sided 95 % Clopper–Pearson intervals, "
               "“≤95” the one-sided 95 % upper bound; DTP = detection delay / required "
               "detection time ([CHEN] §5), over detected runs only — misses are counted "
               "in MD beside it. The column “all requirements” checks every limit of the "
               "campaign file (<code>fdd-campaign gate --all-requirements</code>). Each row "
               "links to the runs behind it.</p>")
    for detector in detectors:
        det = summary[summary["detector"] == detector]
        mine = [c for c in (full.checks if full else []) if c.detector == detector]
        in_gate = _passed(c for c in (gate.checks if gate else []) if c.detector == detector)
        out.append(f'<h3 class="det" id="{anchor("detector", detector)}">{_e(detector)} '
                   f'{_labelled_badge("gate", in_gate)} '
                   f'{_labelled_badge("all requirements", _passed(mine))}</h3>')
        faults = det[(det["manoeuvre"] == ALL_MANOEUVRES) & (det["fault"] != FAULT_FREE)]
        if len(faults):
            rows = []
            for r in faults.itertuples(index=False):
                label = "all faults" if r.fault == ALL_FAULTS else r.fault
                link = anchor("faulty" if r.fault == ALL_FAULTS else r.fault)
                n = int(r.n_runs)
                rows.append([
                    f'<a href="#{link}">{_e(label)}</a>', str(n), str(int(r.n_errors)),
                    _pct(r.fa_rate), _ci(r.fa_count, n), _pct(r.md_rate), _ci(r.md_count, n),
                    _pct(r.md_upper95), table.late_text(r),
                    _pct(getattr(r, "md_req_rate", math.nan)),
                    f"{_num(r.dtp_min, '.4g')}/{_num(r.dtp_mean, '.4g')}/"
                    f"{_num(r.dtp_max, '.4g')}", _num(r.dtp_p95, ".4g"),
                    _num(100 * r.dtp_within, ".1f"),
                    _badge(_row_passed(full, detector, r.fault, r.manoeuvre))])
            out.append(_table(
                ["Fault scenario", "n", "err", "FA (%)", "FA 95 % CI", "MD (%)", "MD 95 % CI",
                 "MD ≤95 (%)", "late", "MD in T (%)", "Min/Mean/Max DTP", "DTP p95",
                 "DTP ≤ 1 (%)", "all requirements"], rows, cls="verdict faults"))
            out.append('<p class="note">FA of faulty runs: alarms before onset. MD: never '
                       'detected in the detection window; late: detected after the required '
                       'time T (DTP &gt; 1); MD in T: not detected within T, missed or late '
                       '(the reading of [CHEN] Tables 3–4, whose MD and DTP say “in time”).'
                       '</p>')
        free = det[det["fault"] == FAULT_FREE]
        if len(free):
            rows = []
            for r in free.itertuples(index=False):
                n = int(r.n_runs)
                allm = r.manoeuvre == ALL_MANOEUVRES
                link = anchor(FAULT_FREE) if allm else anchor(FAULT_FREE, r.manoeuvre)
                margin = _num(r.worst_margin, ".3f")
                if math.isfinite(float(r.worst_margin)) and float(r.worst_margin) >= 1.0:
                    margin = f'<span class="bad">{margin}</span>'
                rows.append([
                    f'<a href="#{link}">{"all manoeuvres" if allm else _e(r.manoeuvre)}</a>',
                    str(n), str(int(r.n_errors)), f"{int(r.fa_count)}/{n}", _pct(r.fa_rate),
                    _ci(r.fa_count, n), _pct(r.fa_upper95), margin,
                    _badge(_row_passed(full, detector, FAULT_FREE, r.manoeuvre))])
            out.append(_table(
                ["Fault-free manoeuvre", "n", "err", "false alarms", "FA (%)", "FA 95 % CI",
                 "FA ≤95 (%)", "worst margin max |r|/τ", "all requirements"], rows,
                cls="verdict faultfree"))
            tot = free[free["manoeuvre"] == ALL_MANOEUVRES]
            if len(tot) and int(tot["n_runs"].iloc[0]):
                r = tot.iloc[0]
                k, n = int(r.fa_count), int(r.n_runs)
                words = "No false alarm" if k == 0 else f"{k} false alarm{'s' * (k > 1)}"
                out.append(f'<p class="bound">{words} in {n} fault-free runs: FA ≤ '
                           f"{_pct(r.fa_upper95)} % at 95 % confidence (exact one-sided "
                           "Clopper–Pearson bound).</p>")
        failed = [c for c in mine if not c.passed]
        if failed:
            items = "".join(f"<li>{_e(c.message)}</li>" for c in failed)
            out.append(f'<details class="fails"><summary>{len(failed)} check(s) of all '
                       f"requirements not met</summary><ul>{items}</ul></details>")
    out.append("</section>")
    return "\n".join(out)


# ---- drill-down ----------------------------------------------------------------------------
_POINT_HEADER = ["run id", "alt [ft]", "VCAS [kt]", "mass [t]", "CG [% MAC]", "onset [s]"]


def _outcome(r, faulty: bool) -> str:
    """One detector's outcome of one run: margin (fault-free) or DTP and delay (faulty),
    false alarms, misses and errors in red, late detections in orange."""
    if r.status != "ok":
        return f'<span class="bad" title="{_e(r.error)}">{_e(r.status)}</span>'
    fa = '<span class="bad">FA</span> ' if bool(r.false_alarm) else ""
    if not faulty:
        margin = _num(r.margin, ".3f")
        return fa + (f'<span class="bad">{margin}</span>' if fa else margin)
    if not bool(r.detected):
        return fa + '<span class="bad">missed</span>'
    text = f"{_num(r.dtp, '.3g')} / {_num(r.delay_s, '.3g')} s"
    late = math.isfinite(float(r.dtp)) and float(r.dtp) > 1.0
    return fa + (f'<span class="late">{text}</span>' if late else text)


def _worry(cell: pd.DataFrame) -> pd.Series:
    """Run id → sort key, most worrying first: errors, false alarms, misses, then the
    largest DTP or margin over the detectors."""
    ok = cell["status"].eq("ok")
    key = pd.DataFrame({
        "run_id": cell["run_id"],
        "err": ~ok,
        "fa": ok & cell["false_alarm"].astype("boolean").fillna(False).astype(bool),
        "miss": ok & cell["fault"].ne(FAULT_FREE)
        & ~cell["detected"].astype("boolean").fillna(False).astype(bool),
        "dtp": pd.to_numeric(cell["dtp"], errors="coerce").fillna(-1.0),
        "margin": pd.to_numeric(cell["margin"], errors="coerce").fillna(-1.0),
    }).groupby("run_id", sort=False).max()
    return key.sort_values(["err", "fa", "miss", "dtp", "margin"], ascending=False,
                           kind="stable").index


def _cell_table(cell: pd.DataFrame, detectors: list[str]) -> str:
    """The runs of one fault × manoeuvre cell: a row per run, a column per detector."""
    faulty = cell["fault"].iloc[0] != FAULT_FREE
    dets = [d for d in detectors if (cell["detector"] == d).any()]
    by = {(r.run_id, r.detector): r for r in cell.itertuples(index=False)}
    rows = []
    for rid in _worry(cell):
        first = next(by[(rid, d)] for d in dets if (rid, d) in by)
        rows.append([f"<code>{_e(rid)}</code>", _num(first.alt_ft, ".0f"),
                     _num(first.vcas_kt, ".0f"), _num(first.mass_t, ".1f"),
                     _num(first.cg_pct, ".1f"), _num(first.onset_s, ".2f")]
                    + [_outcome(by[(rid, d)], faulty) if (rid, d) in by else "–"
                       for d in dets])
    # a long detector name may break before its parameters
    return _table(_POINT_HEADER + [_e(d).replace("[", "<wbr>[") for d in dets], rows,
                  cls="runlist", wrap=False)


def drilldown_section(runs: pd.DataFrame, detectors: list[str]) -> str:
    """``<section id="runs">``: every run of *runs* (one row per run × detector, with the
    flight point) in a table per fault type × manoeuvre, a column per detector in the order
    of *detectors*."""
    out = ['<section id="runs"><h2>Runs behind each row (drill-down)</h2>',
           "<p>Every run of the campaign, a row per run and a column per detector, most "
           "worrying first (errors, false alarms, misses, then the largest DTP or margin). "
           "Fault-free runs: the margin max |r|/τ (a false alarm in red); faulty runs: DTP / "
           "detection delay, <span class=\"late\">late</span> (DTP &gt; 1) in orange, "
           '<span class="bad">missed</span> and alarms before onset (FA) in red. A run\'s '
           "signals, residuals and alarms are re-simulated from its run id and seed, in the "
           f"directory that holds this report, by <code>{_e(show_command('RUN_ID'))}</code> "
           "(add <code>--out RUN_ID.parquet</code> for the traces).</p>"]
    faults = sorted(f for f in runs["fault"].unique() if f != FAULT_FREE)
    order = ([FAULT_FREE] if (runs["fault"] == FAULT_FREE).any() else []) + faults
    by_fault = runs.groupby("fault", sort=False).indices     # row positions: no copy of
    opened_faulty = False                                     # a fault's rows but a cell's
    for fault in order:
        if fault != FAULT_FREE and not opened_faulty:
            out.append(f'<section id="{anchor("faulty")}">')
            opened_faulty = True
        at = by_fault[fault]
        label = "fault-free" if fault == FAULT_FREE else fault
        out.append(f'<section id="{anchor(fault)}"><h3>{_e(label)} '
                   f"({runs['run_id'].iloc[at].nunique()} runs)</h3>")
        manoeuvres = runs["manoeuvre"].to_numpy()[at]
        cells = pd.Series(manoeuvres).groupby(manoeuvres).indices
        for man in sorted(cells):
            cell = runs.iloc[at[cells[man]]]
            out.append(f'<div class="runs" id="{anchor(fault, man)}">'
                       f"<h4>{_e(label)} × {_e(man)}: {cell['run_id'].nunique()} runs</h4>")
            out.append('<div class="scroll">' + _cell_table(cell, detectors) + "</div></div>")
        out.append("</section>")
    if opened_faulty:
        out.append("</section>")
    out.append("</section>")
    return "\n".join(out)


# ---- page ----------------------------------------------------------------------------------
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:1.5em auto;
max-width:1300px;padding:0 1em;color:#222;line-height:1.35}
h1{margin-bottom:.2em}h2{border-bottom:2px solid #ccd;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0 1em 0;font-size:13px}
.tablewrap{max-width:100%;overflow-x:auto}.tablewrap table{margin-bottom:.4em}
th,td{border:1px solid #ccd;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eef;position:sticky;top:0}td:first-child,th:first-child{text-align:left}
td.text{white-space:normal;overflow-wrap:anywhere;text-align:left;min-width:14em;
max-width:40em}
table.runlist th{white-space:normal;vertical-align:bottom}
.badge{display:inline-block;padding:1px 8px;border-radius:4px;font-weight:bold;color:#fff;
font-size:12px}.pass{background:#2a8a3a}.fail{background:#c62828}.na{background:#999}
.bad{color:#c62828;font-weight:bold}.note,.req{font-size:13px;color:#444}
.bound{font-weight:bold}
.scroll{max-height:360px;max-width:100%;overflow:auto;border:1px solid #ddd;margin-bottom:1em}
figure{display:inline-block;width:min-content;max-width:100%;margin:.4em .8em .8em 0;
vertical-align:top}
figure img{border:1px solid #ddd;max-width:100%;height:auto}figcaption{font-size:12px}
nav a{margin-right:1em}code{font-size:12px;overflow-wrap:anywhere}
.warn{background:#fff3cd;border:1px solid #e0c060;padding:.4em .8em;overflow-wrap:anywhere}
.late{color:#b35900;font-weight:bold}.met{color:#1e6b2b}.unmet{color:#c62828;font-weight:bold}
.why{display:inline-block;white-space:normal;max-width:18em;color:#a51d1d}
table.overview th{white-space:normal;vertical-align:bottom}
table.overview td{vertical-align:top}small{font-size:11px;font-weight:normal}
.gateline{font-size:17px;font-weight:bold;padding:.3em .6em;border-radius:4px;
overflow-wrap:anywhere}
.gateline.pass{background:#e3f3e6;color:#1e6b2b}.gateline.fail{background:#fbe3e3;color:#a51d1d}
pre.gatelines{font-size:12px;max-height:360px;overflow:auto;background:#f7f7fa;padding:.5em;
white-space:pre-wrap;overflow-wrap:anywhere}
li{overflow-wrap:anywhere}
"""


def render_report(*, meta: dict, summary: pd.DataFrame, gate: GateResult | None,
                  requirements: dict, runs: pd.DataFrame, figures: list[ReportFigure],
                  notes: list[str] = (), warnings: list[str] = (),
                  certificate: pd.DataFrame | None = None,
                  all_requirements: GateResult | None = None,
                  detectors: list[str] | None = None,
                  hazard: tuple | None = None, drilldown: str | None = None) -> str:
    """The report page.

    Parameters
    ----------
    meta : campaign facts shown in the header (name, description, directory, counts, …)
    summary : :func:`reports.scoring.summary.summarize` output
    gate : the checks of ``fdd-campaign gate DIR`` (:func:`reports.scoring.gate.evaluate_gate` with
        that command's arguments), shown first, line for line
    requirements : the limits of the campaign file, shown with the verdicts
    all_requirements : the checks of ``fdd-campaign gate DIR --all-requirements`` (every
        limit of the campaign file); the overview's and the detail's marks (None: none)
    detectors : the order of the detectors on the whole page (default: the summary's)
    runs : one row per run × detector: result columns
    (:data:`reports.scoring.metrics.RESULT_COLUMNS`)
        and the flight point ``alt_ft, vcas_kt, mass_t, cg_pct, onset_s``
    figures : embedded figures, shown in :data:`SECTIONS` order, grouped by ``group``
    notes : sentences on how the figures were made (sampling rules, re-simulation checks)
    warnings : shown in a highlighted box at the top
    hazard : (table, budgets, assumptions) of ``certify``'s hazard per flight hour
        (``certificate-hazard.parquet``, ``campaign.evidence.hazard``), shown before the runs; None:
        ``certify`` has not made one
    certificate : ``certificate.parquet`` of ``fdd-campaign certify`` (None: no such
        section unless it has figures)
    drilldown : the drill-down section as :func:`drilldown_section` renders it for *runs*
        and the same detectors (given: made beforehand, e.g. while the figures are drawn;
        None: rendered here)
    """
    unknown = sorted({f.section for f in figures} - set(SECTIONS))
    if unknown:
        raise ValueError(f"unknown figure section(s) {unknown}; use one of {list(SECTIONS)}")
    detectors = list(detectors) if detectors is not None else list(
        dict.fromkeys(summary["detector"].astype(str)))
    name = meta.get("name", "campaign")
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>fdd-campaign report — {_e(name)}</title>",
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             f"<style>{_CSS}</style></head><body>",
             f"<h1>Campaign report — {_e(name)}</h1>"]
    if meta.get("description"):
        parts.append(f"<p>{_e(meta['description'])}</p>")
    links = ['<a href="#gate">Gate verdict</a>', '<a href="#requirements">Overview</a>',
             '<a href="#campaign">Campaign</a>', '<a href="#verdict">Per detector</a>'] + [
        f'<a href="#{key}">{_e(title)}</a>' for key, title in SECTIONS.items()
        if any(f.section == key for f in figures)
        or (key == "certificate" and certificate is not None)] + (
        ['<a href="#hazard">Hazard per flight hour</a>'] if hazard is not None else []) + [
        '<a href="#runs">Runs</a>']
    parts.append("<nav>" + "".join(links) + "</nav>")
    for w in warnings:
        parts.append(f'<p class="warn">{_e(w)}</p>')
    parts.append(_gate_section(gate, requirements))
    parts.append(_overview(summary, gate, all_requirements, requirements, detectors))
    facts = [[_e(k), _e(v)] for k, v in meta.items() if k not in ("name", "description")]
    parts.append('<section id="campaign"><h2>Campaign</h2>'
                 + _table(["", ""], facts, cls="meta", text_columns=(1,)) + "</section>")
    parts.append(_details(summary, gate, all_requirements, requirements, detectors))
    rank = {d: i for i, d in enumerate(detectors)}
    for key, title in SECTIONS.items():
        figs = [f for f in figures if f.section == key]
        table_here = key == "certificate" and certificate is not None
        if not figs and not table_here:
            continue
        parts.append(f'<section id="{key}"><h2>{_e(title)}</h2>')
        if table_here:
            parts.append(_certificate_table(certificate))
        # detector groups in the page's detector order; other groups as given
        for group in sorted(dict.fromkeys(f.group for f in figs),
                            key=lambda g: rank.get(g, len(rank))):
            parts.append(f"<h3>{_e(group)}</h3>")
            parts += [_img(f) for f in figs if f.group == group]
        parts.append("</section>")
    if notes:
        parts.append('<section id="notes"><h2>How the figures were made</h2><ul>'
                     + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul></section>")
    if hazard is not None:
        parts.append(hazard_section(*hazard))
    parts.append(drilldown_section(runs, detectors) if drilldown is None else drilldown)
    parts.append("</body></html>")
    return "\n".join(parts)



def hazard_section(hazard: pd.DataFrame, budgets: Mapping[str, float],
                   assumptions: Sequence[str]) -> str:
    """``<section id="hazard">``: the hazard table *hazard* (the columns of
    ``campaign.evidence.hazard.HAZARD_COLUMNS``, one row per detector × fault type, the undetected
    faults of every type, the false alarms), the *budgets* (AMC 25.1309 category → rate per
    flight hour) and the *assumptions* (sentences) it rests on (docs/evidence.md): per row the
    undetected rate without and with the detector, the category credited to the detector and
    the claim in words; a placeholder fault rate is marked (est.)."""
    level = f"{100 * float(hazard['level'].iloc[0]):g} %" if len(hazard) else "95 %"
    head = ["detector", "fault", "runs", "missed / FA", f"P per run ≤ ({level}, counting)",
            "fault rate [1/FH]", "without detector [1/FH]", f"with detector ≤ [1/FH] ({level})",
            "credited to the detector", "claim", "with ≤, late = undetected",
            "credited, late = undetected"]
    names = {"none": "false alarm", "all": "all faults (undetected)"}

    def rate(r) -> str:
        if r["fault"] == "none":
            return "–"
        src = str(r["rate_source"])
        mark = (" (est.)" if src.startswith("placeholder")
                else " (partly est.)" if src.startswith("partly") else "")
        return f'<span title="{_e(src)}">{_num(r["rate_per_fh"])}{mark}</span>'

    rows = [[_e(r["detector"]), _e(names.get(r["fault"], r["fault"])), str(int(r["n_runs"])),
             str(int(r["events"])), _num(r["p_run_upper95"]), rate(r),
             _num(r["without_per_fh"]), _num(r["per_fh_upper95"]), _e(r["credited"]),
             _e(r["claim"]), _num(r["in_time_per_fh_upper95"]), _e(r["credited_in_time"])]
            for r in hazard.to_dict(orient="records")]
    budget_text = ", ".join(f"{_e(k)} ≤ {v:g}" for k, v in budgets.items())
    placeholder = any(str(s).startswith(("placeholder", "partly"))
                      for s in hazard.get("rate_source", ()))
    return ('<section id="hazard"><h2>Hazard per flight hour</h2>'
            "<p>Both sides of each detector (Hu and Seiler's combination, docs/evidence.md): "
            "the rate of undetected actuator faults per flight hour without the detector (the "
            "fault mode's occurrence rate: every fault undetected) and with it (the occurrence "
            "rate times the counting bound — exact one-sided Clopper–Pearson at "
            f"{level} — of its missed-detection probability; the total's bound "
            "Bonferroni-adjusted over the fault types), and the false-alarm rate per flight "
            "hour of the fault-free runs (counting bound). AMC 25.1309 budgets per flight "
            f"hour: {budget_text}. A category is <i>credited to the detector</i> only where "
            "the bound with it is under the category's budget and the fault rate alone is "
            "not; a detector that detected none of the runs is credited nothing; a bound "
            "above 0.5, or one that leaves the rate in the category it has without the "
            "detector, shows nothing (<i>not shown</i>).</p>"
            + ("<p><b>(est.)</b>: a placeholder fault rate (the default of "
               "campaign.evidence.hazard.DEFAULT_FAULT_RATES_PER_FH, an estimate with no "
               "cited source): set [requirements] fault_rate_per_fh from your safety "
               "assessment; a category resting on it is a placeholder too.</p>"
               if placeholder else "")
            + _table([_e(h) for h in head], rows, tid="hazard-table",
                     text_columns=(head.index("claim"),))
            + "<p>Assumptions:</p><ul>" + "".join(f"<li>{_e(a)}</li>" for a in assumptions)
            + "</ul></section>")

def _certificate_table(cert: pd.DataFrame) -> str:
    """The certificate as a table: counts, the three estimates side by side, the fit."""
    level = f"{100 * float(cert['level'].iloc[0]):g} %" if len(cert) else "95 %"
    rows = []
    for r in cert.to_dict(orient="records"):
        sampled = (f"{_num(r['sampling_prob'])} [{_num(r['sampling_lower95'])}, "
                   f"{_num(r['sampling_upper95'])}] ({int(r['sampling_runs'])} runs)"
                   if r["sampling_runs"] else "—")
        rows.append([_e(r["detector"]), f"{r['fa_count']}/{r['n_runs']}",
                     _num(r["exposure_h"], ".4g"), _num(r["fa_upper95_cp"]),
                     f"{_num(r['fa_prob_evt'])} (≤ {_num(r['fa_prob_evt_upper95'])})", sampled,
                     _num(r["fa_per_hour_upper95"]), _e(r["evt_note"] or "")
                     + (f"; {_e(r['sampling_note'])}" if r["sampling_note"] else "")])
    head = ["detector", "FA / runs", "exposure [h]", f"CP bound ({level})",
            f"tail fit (bound at {level})", "subset simulation [bounds]",
            "FA per hour ≤", "tail fit / sampling"]
    return (f"<p>Per-run false-alarm probability beyond counting (docs/evidence.md): the "
            f"exact one-sided Clopper–Pearson bound of the count, the generalised Pareto "
            f"tail of the fault-free margins with its profile-likelihood bound, and, when "
            f"run, subset simulation over the run variables; bounds one-sided at {level}. "
            f"Per hour: from the counting bound, a run of duration d being d hours of "
            f"exposure (Poisson model).</p>"
            + _table(head, rows, tid="certificate-table", text_columns=(len(head) - 1,)))


def count_figures(page: str) -> int:
    """Number of embedded figures of a rendered page."""
    return len(re.findall(r'<img class="fig"', page))
