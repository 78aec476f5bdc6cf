"""The campaign report as one self-contained HTML page (figures embedded, no script, no
network).

Layout: the verdict first — per detector, FA / MD with exact 95 % Clopper–Pearson intervals
and DTP statistics in the layout of [CHEN] Tables 3–4, pass/fail against the campaign's
requirements (:mod:`reports.gate`) — then the residual envelopes, the per-fault detection
behaviour with example runs, the envelope maps, and the drill-down lists: every table row
links to the runs behind it, each with the command that re-simulates it.

This module only formats what it is given (DataFrames, PNG bytes); it reads no file.
"""

from __future__ import annotations

import base64
import html
import math
import re
from dataclasses import dataclass

import pandas as pd

from . import table
from .gate import GateResult
from .metrics import FAULT_FREE, clopper_pearson
from .summary import ALL_FAULTS, ALL_MANOEUVRES

__all__ = ["ReportFigure", "anchor", "count_figures", "render_report", "show_command"]

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
    return table._num(x, fmt, missing="–")


def _pct(x) -> str:
    return table._pct(x, missing="–")


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


def _table(header: list[str], rows: list[list[str]], cls: str = "", tid: str = "") -> str:
    head = "".join(f"<th>{h}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    attrs = (f' class="{cls}"' if cls else "") + (f' id="{tid}"' if tid else "")
    return f"<table{attrs}><thead><tr>{head}</tr></thead><tbody>\n{body}\n</tbody></table>"


def _img(fig: ReportFigure) -> str:
    data = base64.b64encode(fig.png).decode("ascii")
    cap = f"<figcaption><b>{_e(fig.title)}</b>" + (f" — {_e(fig.caption)}" if fig.caption
                                                    else "") + "</figcaption>"
    return (f'<figure><img class="fig" data-section="{_e(fig.section)}" alt="{_e(fig.title)}" '
            f'src="data:image/png;base64,{data}">{cap}</figure>')


# ---- verdict -------------------------------------------------------------------------------
def _row_passed(gate: GateResult | None, detector: str, fault: str, manoeuvre: str):
    """Pass/fail of a summary row: the gate checks that concern exactly its runs."""
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
    if not rel:
        return None
    return all(c.passed for c in rel)


def _verdict(summary: pd.DataFrame, gate: GateResult | None, requirements: dict) -> str:
    out = ['<section id="verdict"><h2>Verdict</h2>']
    req = ", ".join(f"{k} = {v}" for k, v in requirements.items())
    out.append(f'<p class="req">Requirements of the campaign: {_e(req) or "none stored"}. '
               "Rates in %; intervals are exact two-sided 95 % Clopper–Pearson intervals, "
               "“≤95” the one-sided 95 % upper bound; DTP = detection delay / required "
               "detection time ([CHEN] §5), over detected runs only — misses are counted "
               "in MD beside it. Each row links to the runs behind it.</p>")
    for detector, det in summary.groupby("detector", sort=True):
        checks = [c for c in (gate.checks if gate else []) if c.detector == detector]
        passed = all(c.passed for c in checks) if checks else None
        out.append(f'<h3 class="det">{_e(detector)} {_badge(passed)}</h3>')
        faults = det[(det["manoeuvre"] == ALL_MANOEUVRES) & (det["fault"] != FAULT_FREE)]
        if len(faults):
            rows = []
            for r in faults.itertuples(index=False):
                label = "all faults" if r.fault == ALL_FAULTS else r.fault
                link = anchor(detector, "faulty" if r.fault == ALL_FAULTS else r.fault)
                n = int(r.n_runs)
                rows.append([
                    f'<a href="#{link}">{_e(label)}</a>', str(n), str(int(r.n_errors)),
                    _pct(r.fa_rate), _ci(r.fa_count, n), _pct(r.md_rate), _ci(r.md_count, n),
                    _pct(r.md_upper95), table.late_text(r),
                    _pct(getattr(r, "md_req_rate", math.nan)),
                    f"{_num(r.dtp_min, '.4g')}/{_num(r.dtp_mean, '.4g')}/"
                    f"{_num(r.dtp_max, '.4g')}", _num(r.dtp_p95, ".4g"),
                    _num(100 * r.dtp_within, ".1f"),
                    _badge(_row_passed(gate, detector, r.fault, r.manoeuvre)),
                    f'<a href="#{link}">{n + int(r.n_errors)} runs</a>'])
            out.append(_table(
                ["Fault scenario", "n", "err", "FA (%)", "FA 95 % CI", "MD (%)", "MD 95 % CI",
                 "MD ≤95 (%)", "late", "MD in T (%)", "Min/Mean/Max DTP", "DTP p95",
                 "DTP ≤ 1 (%)", "verdict",
                 "drill-down"], rows, cls="verdict faults"))
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
                link = anchor(detector, FAULT_FREE) if allm else anchor(detector, FAULT_FREE,
                                                                        r.manoeuvre)
                margin = _num(r.worst_margin, ".3f")
                if math.isfinite(float(r.worst_margin)) and float(r.worst_margin) >= 1.0:
                    margin = f'<span class="bad">{margin}</span>'
                rows.append([
                    f'<a href="#{link}">{"all manoeuvres" if allm else _e(r.manoeuvre)}</a>',
                    str(n), str(int(r.n_errors)), f"{int(r.fa_count)}/{n}", _pct(r.fa_rate),
                    _ci(r.fa_count, n), _pct(r.fa_upper95), margin,
                    _badge(_row_passed(gate, detector, FAULT_FREE, r.manoeuvre)),
                    f'<a href="#{link}">{n + int(r.n_errors)} runs</a>'])
            out.append(_table(
                ["Fault-free manoeuvre", "n", "err", "false alarms", "FA (%)", "FA 95 % CI",
                 "FA ≤95 (%)", "worst margin max |r|/τ", "verdict", "drill-down"], rows,
                cls="verdict faultfree"))
            tot = free[free["manoeuvre"] == ALL_MANOEUVRES]
            if len(tot) and int(tot["n_runs"].iloc[0]):
                r = tot.iloc[0]
                k, n = int(r.fa_count), int(r.n_runs)
                words = "No false alarm" if k == 0 else f"{k} false alarm{'s' * (k > 1)}"
                out.append(f'<p class="bound">{words} in {n} fault-free runs: FA ≤ '
                           f"{_pct(r.fa_upper95)} % at 95 % confidence (exact one-sided "
                           "Clopper–Pearson bound).</p>")
        failed = [c for c in checks if not c.passed]
        if failed:
            items = "".join(f"<li>{_e(c.message)}</li>" for c in failed)
            out.append(f'<details class="fails" open><summary>{len(failed)} failed '
                       f"check(s)</summary><ul>{items}</ul></details>")
    out.append("</section>")
    return "\n".join(out)


# ---- drill-down ----------------------------------------------------------------------------
_RUN_HEADER = ["run id", "alt [ft]", "VCAS [kt]", "mass [t]", "CG [% MAC]",
               "onset [s]", "status", "false alarm", "detected", "margin max |r|/τ",
               "delay [s]", "DTP", "re-simulate (in the campaign directory)"]


def _run_rows(runs: pd.DataFrame) -> list[list[str]]:
    rows = []
    for r in runs.itertuples(index=False):
        ok = r.status == "ok"
        fa = bool(r.false_alarm) if ok else False
        det = bool(r.detected) if ok else False
        faulty = r.fault != FAULT_FREE
        margin = _num(r.margin, ".3f")
        if ok and math.isfinite(float(r.margin)) and float(r.margin) >= 1.0:
            margin = f'<span class="bad">{margin}</span>'
        detected = ("–" if not faulty or not ok else
                    ("yes" if det else '<span class="bad">missed</span>'))
        status = _e(r.status) if ok else f'<span class="bad" title="{_e(r.error)}">' \
                                          f"{_e(r.status)}</span>"
        rows.append([
            f"<code>{_e(r.run_id)}</code>", _num(r.alt_ft, ".0f"),
            _num(r.vcas_kt, ".0f"), _num(r.mass_t, ".1f"), _num(r.cg_pct, ".1f"),
            _num(r.onset_s, ".2f"), status, '<span class="bad">yes</span>' if fa else "no",
            detected, margin, _num(r.delay_s, ".3f"), _num(r.dtp, ".4g"),
            f"<code>{_e(show_command(r.run_id))}</code>"])
    return rows


def _order(runs: pd.DataFrame) -> pd.DataFrame:
    """Most worrying runs first: errors, false alarms, misses, then by margin / DTP."""
    ok = runs["status"].eq("ok")
    key = pd.DataFrame({
        "err": ~ok,
        "fa": ok & runs["false_alarm"].astype("boolean").fillna(False).astype(bool),
        "miss": ok & runs["fault"].ne(FAULT_FREE)
        & ~runs["detected"].astype("boolean").fillna(False).astype(bool),
        "dtp": pd.to_numeric(runs["dtp"], errors="coerce").fillna(-1.0),
        "margin": pd.to_numeric(runs["margin"], errors="coerce").fillna(-1.0),
    }, index=runs.index)
    idx = key.sort_values(["err", "fa", "miss", "dtp", "margin"], ascending=False,
                          kind="stable").index
    return runs.loc[idx]


def _drilldown(runs: pd.DataFrame) -> str:
    out = ['<section id="runs"><h2>Runs behind each row (drill-down)</h2>',
           "<p>Every run of the campaign, most worrying first (errors, false alarms, misses, "
           "then the largest DTP or margin). A run's signals, residuals and alarms are "
           "re-simulated from its run id and seed by the command beside it, run in the "
           "directory that holds this report (add <code>--out RUN.parquet</code> for the "
           "traces).</p>"]
    for detector, det in runs.groupby("detector", sort=True):
        out.append(f'<section id="{anchor(detector)}"><h3>{_e(detector)}</h3>')
        faults = [f for f in sorted(det["fault"].unique()) if f != FAULT_FREE]
        order = ([FAULT_FREE] if (det["fault"] == FAULT_FREE).any() else []) + faults
        opened_faulty = False
        for fault in order:
            if fault != FAULT_FREE and not opened_faulty:
                out.append(f'<section id="{anchor(detector, "faulty")}">')
                opened_faulty = True
            sub = det[det["fault"] == fault]
            label = "fault-free" if fault == FAULT_FREE else fault
            out.append(f'<section id="{anchor(detector, fault)}"><h4>{_e(detector)} — '
                       f"{_e(label)} ({len(sub)} runs)</h4>")
            for man, cell in sub.groupby("manoeuvre", sort=True):
                out.append(f'<div class="runs" id="{anchor(detector, fault, man)}">'
                           f"<h5>{_e(label)} × {_e(man)}: {len(cell)} runs</h5>")
                out.append('<div class="scroll">' + _table(_RUN_HEADER, _run_rows(_order(cell)),
                                                           cls="runlist") + "</div></div>")
            out.append("</section>")
        if opened_faulty:
            out.append("</section>")
        out.append("</section>")
    out.append("</section>")
    return "\n".join(out)


# ---- page ----------------------------------------------------------------------------------
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:1.5em auto;
max-width:1300px;padding:0 1em;color:#222;line-height:1.35}
h1{margin-bottom:.2em}h2{border-bottom:2px solid #ccd;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0 1em 0;font-size:13px}
th,td{border:1px solid #ccd;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eef;position:sticky;top:0}td:first-child,th:first-child{text-align:left}
table.runlist td:last-child{text-align:left}
.badge{display:inline-block;padding:1px 8px;border-radius:4px;font-weight:bold;color:#fff;
font-size:12px}.pass{background:#2a8a3a}.fail{background:#c62828}.na{background:#999}
.bad{color:#c62828;font-weight:bold}.note,.req{font-size:13px;color:#444}
.bound{font-weight:bold}
.scroll{max-height:360px;overflow:auto;border:1px solid #ddd;margin-bottom:1em}
figure{display:inline-block;width:min-content;margin:.4em .8em .8em 0;vertical-align:top}
figure img{border:1px solid #ddd}figcaption{font-size:12px}
nav a{margin-right:1em}code{font-size:12px}.meta td{text-align:left}
.warn{background:#fff3cd;border:1px solid #e0c060;padding:.4em .8em}
"""


def render_report(*, meta: dict, summary: pd.DataFrame, gate: GateResult | None,
                  requirements: dict, runs: pd.DataFrame, figures: list[ReportFigure],
                  notes: list[str] = (), warnings: list[str] = (),
                  certificate: pd.DataFrame | None = None) -> str:
    """The report page.

    Parameters
    ----------
    meta : campaign facts shown in the header (name, description, directory, counts, …)
    summary : :func:`reports.summary.summarize` output
    gate : :func:`reports.gate.evaluate_gate` on *summary* with the campaign's requirements
    requirements : the limits used, shown above the verdict
    runs : one row per run × detector: result columns (:data:`reports.metrics.RESULT_COLUMNS`)
        and the flight point ``alt_ft, vcas_kt, mass_t, cg_pct, onset_s``
    figures : embedded figures, shown in :data:`SECTIONS` order, grouped by ``group``
    notes : sentences on how the figures were made (sampling rules, re-simulation checks)
    warnings : shown in a highlighted box at the top
    certificate : ``certificate.parquet`` of ``fdd-campaign certify`` (None: no such
        section unless it has figures)
    """
    unknown = sorted({f.section for f in figures} - set(SECTIONS))
    if unknown:
        raise ValueError(f"unknown figure section(s) {unknown}; use one of {list(SECTIONS)}")
    name = meta.get("name", "campaign")
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>fdd-campaign report — {_e(name)}</title>",
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             f"<style>{_CSS}</style></head><body>",
             f"<h1>Campaign report — {_e(name)}</h1>"]
    if meta.get("description"):
        parts.append(f"<p>{_e(meta['description'])}</p>")
    facts = [[_e(k), _e(v)] for k, v in meta.items() if k not in ("name", "description")]
    parts.append(_table(["", ""], facts, cls="meta"))
    links = ['<a href="#verdict">Verdict</a>'] + [
        f'<a href="#{key}">{_e(title)}</a>' for key, title in SECTIONS.items()
        if any(f.section == key for f in figures)
        or (key == "certificate" and certificate is not None)] + ['<a href="#runs">Runs</a>']
    parts.append("<nav>" + "".join(links) + "</nav>")
    for w in warnings:
        parts.append(f'<p class="warn">{_e(w)}</p>')
    parts.append(_verdict(summary, gate, requirements))
    for key, title in SECTIONS.items():
        figs = [f for f in figures if f.section == key]
        table_here = key == "certificate" and certificate is not None
        if not figs and not table_here:
            continue
        parts.append(f'<section id="{key}"><h2>{_e(title)}</h2>')
        if table_here:
            parts.append(_certificate_table(certificate))
        for group in dict.fromkeys(f.group for f in figs):
            parts.append(f"<h3>{_e(group)}</h3>")
            parts += [_img(f) for f in figs if f.group == group]
        parts.append("</section>")
    if notes:
        parts.append('<section id="notes"><h2>How the figures were made</h2><ul>'
                     + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul></section>")
    parts.append(_drilldown(runs))
    parts.append("</body></html>")
    return "\n".join(parts)


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
            f"exposure (Poisson model).</p>" + _table(head, rows, tid="certificate-table"))


def count_figures(page: str) -> int:
    """Number of embedded figures of a rendered page."""
    return len(re.findall(r'<img class="fig"', page))
