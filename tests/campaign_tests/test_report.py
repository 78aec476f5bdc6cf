"""The HTML campaign report, `show` (one run re-simulated from its id) and `compare`.

The page is checked as HTML and as PNG bytes, without a browser (the suite installs
nothing): its gate verdict comes first and agrees with `fdd-campaign gate`, one overview
row per detector in one order, no empty panel, figures that fit a laptop-width page, and a
size bound.
"""

import base64
import html
import io
import re
import shutil
from math import comb

import numpy as np
import pandas as pd
import pytest

from campaign import load, run
from campaign.cli.commands import main
from campaign.config import CampaignConfig
from campaign.report_build import ReportSettings, build_report
from detectors import registry
from reports.scoring.compare import compare_results
from reports.render.figures.report import SMALL_PT, bin_max, envelope_figure, fault_figure, pyplot
from reports.render.html import anchor, count_figures, show_command

FF_MANOEUVRES = ["cruise", "nose_up"]
FAULTS = ["liquid_jam", "runaway", "solid_jam"]


def small(**over) -> CampaignConfig:
    """8 fault-free runs in each of 2 manoeuvres, 8 liquid jams and 2 runs of 2 other fault
    types, 20 s each, simulated in one batch."""
    data = {
        "campaign": {"name": "report-test", "seed": 3, "duration_s": 20.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": FF_MANOEUVRES, "count": 8},
            {"name": "jam", "fault": "solid_jam", "manoeuvres": ["nose_up"], "count": 2},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
            {"name": "lj", "fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 8},
        ],
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 2},
        "runner": {"chunk_size": 64},
    }
    data.update(over)
    return CampaignConfig.from_dict(data)


#: A degraded version of the detector: thresholds at 4 × (instead of 1.5 ×) the largest
#: learned fault-free residual — blind to the small liquid jams.
#: A monitor with its surface check only: a liquid jam biases the COM acquisition alone
#: (docs/physics.md §5), while the surface sensor and the MON rod both see the true
#: position, so every liquid jam is missed, whatever the threshold.
DEGRADED = {"detector": [{"name": "position-monitor", "params": {"checks": ["surface"]}}]}
N_RUNS = {"liquid_jam": 8, "runaway": 2, "solid_jam": 2}

#: The report's campaign: the small one with a second detector that alarms from the first
#: sample on every run flown at a measured VCAS ≥ 250 kt (tests/plugin_detectors.py): its
#: false alarms fail the gate, which then names runs. Listed first, so the campaign file's
#: order (sm, position-monitor) differs from the summary's (position-monitor, sm).
SM = {"name": "schedule-margin", "label": "sm", "params": {"limit_kt": 250.0}}
TWO_DETECTORS = {"detector": [SM, {"name": "position-monitor"}]}
ORDER = ["position-monitor", "sm"]
#: Width of the page's content at a 1366 px laptop width [px]: body max-width 1300 px
#: less 2 × 1 em (16 px) of padding.
CONTENT_PX = 1300 - 32


@pytest.fixture(scope="module", autouse=True)
def _schedule_margin():
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(registry.BUILTIN, "schedule-margin", "plugin_detectors:ScheduleMargin")
        yield


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("camp") / "a"
    run(small(**TWO_DETECTORS), out, jobs=1, progress=False)
    return out


@pytest.fixture(scope="module")
def report(campaign_dir):
    path = build_report(campaign_dir, jobs=1, log=lambda _: None)
    return path, path.read_text()


def _alts(page: str) -> list[str]:
    return re.findall(r'<img class="fig" data-section="[^"]*" alt="([^"]*)"', page)


def test_report_has_the_verdict_first_and_every_figure(campaign_dir, report):
    path, page = report
    assert path == campaign_dir / "report.html"
    # verdict before any figure
    assert page.index('id="verdict"') < page.index('<img class="fig"')
    assert 'class="verdict faults"' in page and 'class="verdict faultfree"' in page
    camp = load(campaign_dir)
    s = camp.summary
    row = s[(s.fault == "none") & (s.manoeuvre == "all")
            & (s.detector == "position-monitor")].iloc[0]
    assert f"{int(row.fa_count)}/{int(row.n_runs)}" in page
    assert int(row.n_runs) == 16
    # the bound is spelled out (docs/design.md §5, Metrics): with k = 0 of 16, 1 − 0.05^(1/16)
    if row.fa_count == 0:
        bound = 100 * (1 - 0.05 ** (1 / 16))
        assert f"No false alarm in 16 fault-free runs: FA ≤ {bound:.2f} %" in page
    alts = set(_alts(page))
    # per detector: its envelopes (a panel per manoeuvre), its two maps and its detection
    # delay as survival data (docs/evidence.md; the certificate's figures only once
    # fdd-campaign certify has run); per fault type one figure across the detectors
    expected = {f"Detection of {f}" for f in FAULTS}
    # and its threshold trade-off (campaign/tradeoff.py, docs/thresholds.md)
    expected |= {f"Threshold trade-off — {f}" for f in FAULTS}
    for det in ORDER:
        expected |= {f"Residual envelopes — {det}", f"Margin to false alarm — {det}",
                     f"Detection time performance — {det}",
                     f"Detection delay (Kaplan–Meier) — {det}"}
    assert expected <= alts
    # example runs: the worst fault-free run and up to 3 per fault type
    examples = [a for a in alts if a.startswith("Example run")]
    assert len(examples) == 1 + sum(min(3, n) for n in N_RUNS.values())
    assert count_figures(page) == len(expected) + len(examples) == len(_alts(page))
    for data in re.findall(r'src="data:image/png;base64,([^"]+)"', page):
        assert base64.b64decode(data[:24])[:8] == b"\x89PNG\r\n\x1a\n"
    # self-contained: nothing fetched from anywhere
    assert not re.search(r'(src|href)="(https?:|//|file:)', page)


def test_every_link_reaches_the_runs_behind_its_row(campaign_dir, report):
    _, page = report
    ids = set(re.findall(r'id="([^"]+)"', page))
    targets = set(re.findall(r'href="#([^"]+)"', page))
    assert targets and targets <= ids
    for fault in ["none", *FAULTS]:
        assert anchor(fault) in targets
    assert anchor("none", "cruise") in targets and anchor("faulty") in targets
    assert {anchor("detector", d) for d in ORDER} <= targets
    # every run is listed once (a column per detector), and the command that re-simulates
    # any run is given once
    plan = pd.read_parquet(campaign_dir / "plan.parquet")
    for rid in plan["run_id"]:
        assert page.count(f"<code>{rid}</code>") == 1
    assert show_command("RUN_ID") in page
    # the cruise fault-free list holds exactly the 8 cruise fault-free runs
    start = page.index(f'id="{anchor("none", "cruise")}"')
    block = page[start:page.index("</table>", start)]
    cruise = plan[(plan.fault == "none") & (plan.manoeuvre == "cruise")]["run_id"]
    assert sorted(re.findall(r"<td><code>(\w+)</code></td>", block)) == sorted(cruise)


def test_resimulated_margins_reproduce_the_stored_ones(report):
    _, page = report
    # a run simulated alone or in any batch is bit for bit the same (docs/design.md §9,
    # Determinism), so the re-simulated margins equal the stored ones exactly
    assert "reproduce the stored ones of all 16 runs (largest difference 0.0e+00)" in page
    assert 'class="warn"' not in page


def test_subsampled_envelopes_keep_the_worst_run(campaign_dir, report, tmp_path):
    _, page = report
    small_page = build_report(campaign_dir, jobs=1, out=tmp_path / "r.html", log=lambda _: None,
                              settings=ReportSettings(envelope_runs=3, worst_kept=1,
                                                      examples_per_fault=0)).read_text()
    assert "6 of 16: per manoeuvre at most 3" in small_page
    # the worst run of each detector × manoeuvre, as named in the envelope captions
    pattern = r"worst run of each manoeuvre in red \(([^)]*); re-simulate"
    worst = re.findall(pattern, page)
    assert len(worst) == len(ORDER) and all(w.count(":") == 2 for w in worst)
    assert re.findall(pattern, small_page) == worst
    assert "Example run" not in small_page


def test_report_works_on_a_copied_directory(campaign_dir, report, tmp_path, capsys):
    copy = tmp_path / "elsewhere" / "copied"
    shutil.copytree(campaign_dir, copy)
    (copy / "report.html").unlink(missing_ok=True)
    hidden = campaign_dir.with_name("hidden-while-copied")
    campaign_dir.rename(hidden)        # nothing may be read from the original place
    try:
        assert main(["report", str(copy), "--jobs", "1"]) == 0
    finally:
        hidden.rename(campaign_dir)
    out = capsys.readouterr().out
    assert "Fault scenario" in out and "report.html" in out
    page = (copy / "report.html").read_text()
    assert str(copy) in page and count_figures(page) == count_figures(report[1]) > 0
    assert main(["report", str(copy), "--no-html", "--html", str(tmp_path / "x.html")]) == 0
    assert not (tmp_path / "x.html").exists()


def test_report_of_an_interrupted_campaign_says_so(campaign_dir, tmp_path):
    from campaign.runner import finalize
    from campaign.store.directory import CampaignDir

    copy = tmp_path / "partial"
    shutil.copytree(campaign_dir, copy)
    cdir = CampaignDir(copy)
    camp = load(copy)
    results = camp.results          # read now: the shards are removed below
    # as if the campaign had been stopped after its first runs
    for path in cdir.shard_paths():
        cdir.remove(path)
    first = camp.plan["run_id"].iloc[:20]
    cdir.write_shard(results[results["run_id"].isin(first)], camp.config.to_json())
    finalize(cdir, camp.config, camp.plan, False, 0.0)
    page = build_report(copy, jobs=1, log=lambda _: None,
                        settings=ReportSettings(examples_per_fault=0)).read_text()
    assert f"The campaign is incomplete: 20 of {len(camp.plan)} runs" in page
    # the runs that were not done are in no list
    missing = set(camp.plan["run_id"]) - set(load(copy).results["run_id"])
    assert missing and not any(f"<code>{rid}</code>" in page for rid in missing)


def test_show_resimulates_one_run_from_its_id(campaign_dir, tmp_path, capsys):
    camp = load(campaign_dir)
    res = camp.results
    row = res[(res.fault == "solid_jam") & (res.detector == "position-monitor")].iloc[0]
    png, pq = tmp_path / "run.png", tmp_path / "run.parquet"
    assert main(["show", str(campaign_dir), row.run_id, "--plot", str(png),
                 "--out", str(pq)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    frame = pd.read_parquet(pq)
    t = frame["time [s]"].to_numpy()
    res = frame["position-monitor |r|/tau [-]"].to_numpy()
    decision = frame["position-monitor decision [-]"].to_numpy()
    alarm = frame["position-monitor alarm"].to_numpy()
    onset = camp.plan.set_index("run_id").loc[row.run_id, "onset_s"]
    # bit-for-bit determinism: the stored margin (the largest decision statistic before
    # onset, the least |r|/τ of each confirmation window) and first alarm are reproduced
    assert np.nanmax(decision[t < onset]) == row.margin
    assert np.nanmax(decision[t < onset]) <= np.max(res[t < onset])
    assert t[np.argmax(alarm & (t >= onset))] == pytest.approx(row.first_alarm_s, abs=1e-12)
    # the run is scored again by the campaign's rules and printed beside the stored row
    out = capsys.readouterr().out
    stored, again = re.search(r"position-monitor: stored (.*)\n\s+re-simulated (.*)",
                              out).groups()
    assert stored == again and "detected True" in stored


def test_show_and_report_refuse_bad_input_with_exit_2(campaign_dir, tmp_path, capsys):
    assert main(["show", str(campaign_dir), "no-such-run"]) == 2
    assert "not in" in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "is not a campaign directory written by" in capsys.readouterr().err
    assert main(["compare", str(campaign_dir), str(tmp_path)]) == 2
    assert "not a campaign directory" in capsys.readouterr().err


def test_compare_flags_a_degraded_detector_and_not_an_identical_campaign(tmp_path, capsys):
    campaign_dir = tmp_path / "a"
    run(small(), campaign_dir, jobs=1, progress=False)
    same = tmp_path / "same"
    run(small(), same, jobs=1, progress=False)
    assert main(["compare", str(campaign_dir), str(same)]) == 0
    out = capsys.readouterr().out
    a, b = load(campaign_dir).results, load(same).results
    table = compare_results(a, b)
    # the cells of 8 runs and more are unchanged; those of 2 runs (runaway, solid jam) are
    # too few for the exact McNemar test to reach 0.01 (p ≥ 2·2⁻² = 0.5): said, not
    # called unchanged
    enough = table["n_a"] >= 8
    assert enough.any() and (~enough).any()
    assert (table.loc[enough, "flag"] == "unchanged").all(), out
    assert (table.loc[~enough, "flag"] == "too few runs").all(), out
    assert "0 worse" not in out and "unchanged" in out
    assert "cells of 2 shared runs (exact McNemar: p ≥ 0.5)" in out

    bad = tmp_path / "bad"
    run(small(**DEGRADED), bad, jobs=1, progress=False)
    assert main(["compare", str(campaign_dir), str(bad)]) == 0
    out = capsys.readouterr().out
    table = compare_results(a, load(bad).results)
    lj = table[(table.fault == "liquid_jam")].iloc[0]
    # the same 8 liquid jams: 0/8 vs 8/8 misses, exact McNemar p = 2·2⁻⁸ = 0.0078 < 0.01
    assert lj.flag == "worse" and lj.md_p < 0.01 and lj.md_rate_b > lj.md_rate_a, out
    # the fault-free runs are identical in both (same plan): no false alarm either way
    assert (table.loc[table.fault == "none", "flag"] == "unchanged").all()
    assert "liquid_jam / cruise: worse: MD rate" in out


def _compare_rows(detector, fault, manoeuvre, fa, n, dtp=None, ids="", missed=()):
    dtp = np.full(n, np.nan) if dtp is None else np.array(dtp, float)     # a copy
    dtp[list(missed)] = np.nan
    return pd.DataFrame({
        "run_id": [f"{ids}{fault}{i}" for i in range(n)], "detector": detector,
        "fault": fault, "manoeuvre": manoeuvre, "status": "ok",
        "false_alarm": np.arange(n) < fa, "detected": np.isfinite(dtp), "dtp": dtp})


def test_compare_counts_and_p_values():
    # two campaigns of other runs (other run ids): independent-sample tests
    rows = _compare_rows
    a = pd.concat([rows("d", "none", "cruise", 0, 20, ids="a"),
                   rows("d", "solid_jam", "cruise", 0, 7, np.linspace(0.1, 0.2, 7), ids="a")])
    b = pd.concat([rows("d", "none", "cruise", 10, 20, ids="b"),
                   rows("d", "solid_jam", "cruise", 0, 7, np.linspace(0.5, 0.6, 7), ids="b")])
    t = compare_results(a, b).set_index("fault")
    assert (t["test"] == "independent").all()
    # Fisher exact, 0/20 vs 10/20: the 10 alarms of 40 runs all in B or all in A are the
    # only tables as extreme, each of hypergeometric probability C(30,20)/C(40,20)
    assert t.loc["none", "fa_p"] == pytest.approx(2 * comb(30, 20) / comb(40, 20), rel=1e-9)
    assert t.loc["none", "flag"] == "worse"
    # DTP: every B value above every A value, 7 runs each without ties (scipy's exact
    # Mann–Whitney distribution): two-sided p = 2 / C(14, 7)
    assert t.loc["solid_jam", "dtp_p"] == pytest.approx(2 / comb(14, 7), rel=1e-9)
    assert t.loc["solid_jam", "dtp_shift"] == pytest.approx(0.4)
    assert t.loc["solid_jam", "flag"] == "worse"
    back = compare_results(b, a).set_index("fault")
    assert (back["flag"] == "better").all()
    with pytest.raises(ValueError, match="alpha"):
        compare_results(a, b, alpha=1.5)


def test_compare_pairs_the_runs_of_a_shared_plan():
    rows = _compare_rows
    # the same 300 runs in both (B's rows in another order); B misses 9 runs A detected and
    # detects none A missed: the exact McNemar test sees 9 discordant runs, all one way,
    # p = 2·2⁻⁹ ≈ 0.0039 < 0.01; with 6 B-only misses, p = 2·2⁻⁶ ≈ 0.031
    dtp = np.linspace(0.1, 0.9, 300)
    a = rows("d", "solid_jam", "cruise", 0, 300, dtp)
    b = rows("d", "solid_jam", "cruise", 0, 300, dtp, missed=range(9)).sample(frac=1.0,
                                                                             random_state=1)
    t = compare_results(a, b).iloc[0]
    assert t["test"] == "paired"
    assert t["md_p"] == pytest.approx(2 * 0.5 ** 9, rel=1e-12) and t["flag"] == "worse"
    assert t["dtp_p"] == 1.0               # every run detected in both has the same DTP
    b6 = rows("d", "solid_jam", "cruise", 0, 300, dtp, missed=range(6))
    assert compare_results(a, b6).iloc[0]["md_p"] == pytest.approx(2 * 0.5 ** 6)
    # DTP of the shared detected runs all 0.01 later in B: Wilcoxon signed-rank on 300
    # positive differences (normal approximation), p far below 1e-6
    later = rows("d", "solid_jam", "cruise", 0, 300, dtp + 0.01)
    t = compare_results(a, later).iloc[0]
    assert t["dtp_p"] < 1e-6 and t["flag"] == "worse" and t["md_p"] == 1.0


def test_compare_says_a_cell_of_too_few_runs_cannot_tell():
    # the largest difference a cell can show: every run of B misses where A detected
    from reports.scoring.compare import format_compare, p_floor

    rows = _compare_rows
    dtp = np.full(2, 0.3)
    # paired, 2 runs, both changed: McNemar p = 2·2⁻² = 0.5, the floor: "too few runs"
    t = compare_results(rows("d", "solid_jam", "cruise", 0, 2, dtp),
                        rows("d", "solid_jam", "cruise", 0, 2, dtp, missed=range(2))).iloc[0]
    assert t["md_p"] == pytest.approx(0.5) == p_floor(True, 2, 2)
    assert t["flag"] == "too few runs"
    assert "exact McNemar test on its 2 shared runs gives p ≥ 0.5" in t["reasons"]
    assert "power 0" in t["reasons"] and "needs ≥ 8 runs" in t["reasons"]
    # independent, 2 and 3 runs: Fisher p of [[2, 0], [0, 3]] = 1/C(5, 2) = 0.1
    t = compare_results(rows("d", "solid_jam", "cruise", 0, 2, dtp, ids="a"),
                        rows("d", "solid_jam", "cruise", 0, 3, np.full(3, 0.3), ids="b",
                             missed=range(3)))
    assert t.iloc[0]["md_p"] == pytest.approx(1 / comb(5, 2)) == p_floor(False, 2, 3)
    assert t.iloc[0]["flag"] == "too few runs"
    assert "Fisher exact: p ≥ 0.1" in format_compare(t)
    # 8 paired runs can reach 0.01 (2·2⁻⁸ = 0.0078): flagged by what they show
    same8 = rows("d", "solid_jam", "cruise", 0, 8, np.full(8, 0.3))
    assert compare_results(same8, same8).iloc[0]["flag"] == "unchanged"
    assert compare_results(same8, rows("d", "solid_jam", "cruise", 0, 8, np.full(8, 0.3),
                                       missed=range(8))).iloc[0]["flag"] == "worse"
    # at α = 0.1 the 2-and-3-run cell is tested, and worse
    assert compare_results(rows("d", "solid_jam", "cruise", 0, 2, dtp, ids="a"),
                           rows("d", "solid_jam", "cruise", 0, 3, np.full(3, 0.3), ids="b",
                                missed=range(3)), alpha=0.11).iloc[0]["flag"] == "worse"


def test_bin_max_keeps_every_peak_and_ignores_nan():
    x = np.zeros((2, 10))
    x[0, 7] = 5.0
    x[1, :3] = np.nan
    starts, b = bin_max(x, 4)
    assert starts.tolist() == [0, 3, 6, 9]
    assert b[0].tolist() == [0.0, 0.0, 5.0, 0.0]
    assert np.isnan(b[1, 0]) and b[1, 1:].tolist() == [0.0, 0.0, 0.0]



# ---- the verdict first, as `fdd-campaign gate` says it -------------------------------------
def _section(page: str, sid: str) -> str:
    start = page.index(f'<section id="{sid}">')
    return page[start:page.index("</section>", start)]


def test_the_page_opens_with_the_gate_verdict_of_the_gate_command(campaign_dir, report,
                                                                   capsys):
    _, page = report
    code = main(["gate", str(campaign_dir)])
    printed = capsys.readouterr().out.splitlines()
    # sm alarms on every run flown at ≥ 250 kt: the gate fails and names those runs
    assert code == 1
    body = page[page.index("<body>"):]
    first = body.index('<section id="gate">')
    # nothing of the verdict, no table, figure or badge comes before it
    assert first < min(body.index(x) for x in ("<table", "<img", 'class="badge'))
    gate = _section(page, "gate")
    # the same checks in the same words, line for line (the command adds a replay hint)
    lines = html.unescape(re.search(r'<pre class="gatelines">(.*?)</pre>', gate, re.S)
                          .group(1)).splitlines()
    assert lines == printed[:len(lines)] and printed[len(lines):][0].startswith("replay one")
    # the same verdict, said first
    verdict = lines[lines.index("") + 1]
    assert re.fullmatch(r"gate FAILED: \d+ of \d+ checks failed", verdict)
    assert gate.index(f'<p class="gateline fail">{verdict}</p>') < gate.index("<ul")
    # the same run ids: every run the command names, each with its show command
    plan_ids = set(load(campaign_dir).plan["run_id"])
    named = {r for r in plan_ids if r in "\n".join(printed)}
    assert named and named == {r for r in plan_ids if show_command(r) in gate}


def _overview_detectors(page: str) -> list[str]:
    table = _section(page, "requirements")
    body = table[table.index("<tbody>"):]
    return re.findall(r'<tr><td><a href="#runs-detector-[^"]*">([^<]*)</a>', body)


def test_one_overview_row_per_detector_and_one_order_everywhere(campaign_dir, report):
    _, page = report
    camp = load(campaign_dir)
    summary_order = list(dict.fromkeys(camp.summary["detector"]))
    # the summary's order (that of `run`, `report` and `gate`), not the campaign file's
    assert summary_order == ORDER != list(dict.fromkeys(camp.results["detector"]))
    assert _overview_detectors(page) == ORDER
    overview = _section(page, "requirements")
    # the "all requirements" verdict is labelled as such: here MD/DTP limits fail while
    # the gate's own checks fail for sm only
    assert "All requirements of the campaign file" in overview
    assert re.search(r"all requirements<br>\(--all-requirements\)", overview)
    # every section lists detectors in that order
    details = re.findall(r'<h3 class="det" id="[^"]*">([^ <]*) ', page)
    groups = {key: [g for g in re.findall(r"<h3>([^<]*)</h3>", _section(page, key))
                    if g in ORDER] for key in ("envelope", "map", "survival")}
    runs = page[page.index('<section id="runs">'):]
    head = re.search(r"<thead><tr>(.*?)</tr></thead>", runs).group(1)
    columns = [html.unescape(c.replace("<wbr>", ""))
               for c in re.findall(r"<th>([^<]*(?:<wbr>[^<]*)?)</th>", head)][6:]
    for order in [details, columns, *groups.values()]:
        assert order == ORDER, (order, groups)
    # every FAIL badge says which verdict it is, or sits in a column that says it
    for badge in re.findall(r'<span class="badge fail">([^<]*)</span>', page):
        assert badge in ("FAIL", "gate: FAIL", "all requirements: FAIL")
    for tbl in re.findall(r"<table[^>]*>.*?</table>", page, re.S):
        if 'class="badge fail">FAIL<' in tbl:
            assert "all requirements" in tbl or "fdd-campaign gate" in tbl


def _png_sizes(page: str) -> list[tuple[int, int, int]]:
    from PIL import Image

    out = []
    for data in re.findall(r'src="data:image/png;base64,([^"]+)"', page):
        raw = base64.b64decode(data)
        image = Image.open(io.BytesIO(raw))
        assert image.mode == "P"                    # palette-compressed
        out.append((len(raw), *image.size))
    return out


def test_the_page_is_small_and_its_figures_fit_a_laptop_screen(report):
    _, page = report
    sizes = _png_sizes(page)
    # 2 detectors: 2 envelope figures, 3 fault types (a detection and a trade-off figure
    # each), 4 maps, 2 survival curves, 8 example runs (1 fault-free, up to 3 per fault
    # type) = 22 figures, not one per detector × manoeuvre or detector × fault type
    assert len(sizes) == 22
    # no figure wider than the page's content at 1366 px: nothing is cut or scrolled
    assert max(w for _, w, _ in sizes) <= CONTENT_PX
    # measured: 9–56 kB per figure at 100 dpi in 256 colours (the example runs, dense noisy
    # traces, the largest), 0.45 MB of PNG and a 0.64 MB page in all. The bounds (0.8 MB of
    # PNG, a 1.1 MB page: 1.75× the measure) leave room for other noise draws and
    # matplotlib versions, and fail full-colour PNG (2.5–3× larger, measured on addsafe-mc),
    # a higher dpi or a figure per detector × manoeuvre again.
    assert sum(n for n, _, _ in sizes) <= 800_000
    assert len(page.encode()) <= 1_100_000


def test_no_figure_has_an_empty_panel_and_text_is_legible():
    plt = pyplot()
    rng = np.random.default_rng(0)
    # a detector that detected nothing has a bar, no box: every panel holds data
    fig = fault_figure([("a", rng.uniform(0.1, 2.0, 30), 2), ("b", np.array([]), 32)],
                       title="t", max_dtp=1.0)
    assert len(fig.axes) == 2 and all(ax.has_data() for ax in fig.axes)
    small_text = [t.get_text() for t in fig.findobj(lambda o: hasattr(o, "get_fontsize"))
                  if getattr(t, "get_text", lambda: "")() and t.get_fontsize() < SMALL_PT]
    assert small_text == []
    plt.close(fig)
    # no detector detected anything: only the bars are drawn
    fig = fault_figure([("a", np.array([]), 5)], title="t", max_dtp=1.0)
    assert len(fig.axes) == 1 and fig.axes[0].has_data()
    plt.close(fig)
    # 5 manoeuvres on a grid of 3 columns: 5 panels, the sixth removed
    t = np.arange(50) * 0.1
    panels = [(f"m{i}", rng.uniform(0, 0.8, (4, 50)).astype(np.float32), 0, "worst")
              for i in range(5)]
    fig = envelope_figure(t, panels, title="t")
    assert len(fig.axes) == 5 and all(ax.has_data() for ax in fig.axes)
    plt.close(fig)


def test_the_aircraft_plot_keeps_its_legends_off_the_curves():
    from reports.render.figures.aircraft import aircraft_run_figure

    t = np.arange(0, 10, 0.01)
    frame = pd.DataFrame({"command [mm]": np.sin(t), "rod_com [mm]": np.sin(t),
                          "true_rod [mm]": np.sin(t), "true_left_elevator [deg]": t,
                          "true_rudder [deg]": -t},
                         index=pd.Index(t, name="time [s]"))
    for name, unit in (("p", "deg/s"), ("q", "deg/s"), ("r", "deg/s"), ("phi", "deg"),
                       ("theta", "deg"), ("beta", "deg"), ("nz", "g"), ("ny", "g")):
        frame[f"{name} [{unit}]"] = np.cos(t)
    fig = aircraft_run_figure(frame, onset_s=5.0, title="t", monitored="left_elevator")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend().get_window_extent(renderer)
        # wholly right of the panel: it covers none of its curves
        assert legend.x0 >= ax.get_window_extent(renderer).x1
    pyplot().close(fig)


def test_overview_counts_each_run_in_error_once():
    from reports.scoring.gate import evaluate_gate
    from reports.render.html import render_report
    from reports.scoring.summary import summarize

    # detector d: 4 fault-free runs (1 in error) and 3 + 3 faulty runs of two fault types
    # (1 in error in each): 3 runs in error, whatever the aggregates over faults
    rows = []
    for i, (fault, man) in enumerate([("none", "cruise")] * 4 + [("runaway", "cruise")] * 3
                                     + [("solid_jam", "cruise")] * 3):
        err = i in (0, 4, 7)
        rows.append({"run_id": f"r{i}", "detector": "d", "fault": fault, "manoeuvre": man,
                     "status": "error" if err else "ok", "error": "boom" if err else "",
                     "false_alarm": False, "pre_onset_alarm": False,
                     "detected": fault != "none" and not err, "first_alarm_s": np.nan,
                     "delay_s": 0.1 if fault != "none" and not err else np.nan,
                     "dtp": 0.5 if fault != "none" and not err else np.nan, "margin": 0.4})
    results = pd.DataFrame(rows)
    summary = summarize(results)
    page = render_report(meta={"name": "x"}, summary=summary,
                         gate=evaluate_gate(summary, results=results), requirements={},
                         runs=results.assign(alt_ft=1e4, vcas_kt=250.0, mass_t=60.0,
                                             cg_pct=30.0, onset_s=5.0), figures=[])
    row = re.search(r'<tr><td><a href="#runs-detector-d">d</a></td>(.*?)</tr>',
                    _section(page, "requirements")).group(1)
    cells = re.findall(r"<td>(.*?)</td>", row)
    assert cells[6] == "3"                          # the "errors" column


# ---- a page that fits a laptop window --------------------------------------------------------
#: Longest line of text a cell that does not wrap may hold [characters]: about 420 px of
#: 13 px table text; longer prose goes in cells that wrap.
NOWRAP_CHARS = 60


def _visible(cell: str) -> list[str]:
    """The lines of text of a table cell (tags dropped, a line per <br>)."""
    return [html.unescape(re.sub(r"<[^>]+>", "", line)).strip()
            for line in re.split(r"<br\s*/?>", cell)]


def test_the_page_fits_a_laptop_window_and_every_unmet_mark_says_why(campaign_dir,
                                                                      tmp_path, capsys):
    copy = tmp_path / "certified"
    shutil.copytree(campaign_dir, copy)
    assert main(["certify", str(copy), "--jobs", "1"]) == 0
    capsys.readouterr()
    page = build_report(copy, jobs=1, log=lambda _: None,
                        settings=ReportSettings(examples_per_fault=0)).read_text()
    assert 'id="certificate-table"' in page
    style = re.search(r"<style>(.*?)</style>", page, re.S).group(1).replace("\n", "")
    # every table sits in a box no wider than the page, scrolled inside it if it must be:
    # its own (div.tablewrap) or the drill-down's (div.scroll)
    assert ".tablewrap{max-width:100%;overflow-x:auto}" in style
    assert re.search(r"\.scroll\{[^}]*max-width:100%[^}]*overflow:auto", style)
    body = page[page.index("<body>"):]
    tables = [m.start() for m in re.finditer(r"<table", body)]
    assert len(tables) > 10
    for at in tables:
        assert body[:at].endswith(('<div class="tablewrap">', '<div class="scroll">')), \
            body[max(0, at - 80):at + 40]
    # figures scale down to their box, never wider than the page
    assert re.search(r"figure img\{[^}]*max-width:100%", style)
    assert re.search(r"figure\{[^}]*max-width:100%", style)
    # prose wraps: the cells of text columns (the certificate's notes) and the gate's lines
    assert re.search(r"td\.text\{white-space:normal;overflow-wrap:anywhere", style)
    assert re.search(r"pre\.gatelines\{[^}]*white-space:pre-wrap", style)
    notes = re.findall(r'<table id="certificate-table">.*?</table>', body, re.S)[0]
    assert re.search(r'<td class="text">[^<]{30,}', notes)    # the notes column wraps
    # a cell that does not wrap holds short lines only (a reason beside a ✗ wraps itself)
    cells = re.findall(r"<td>(.*?)</td>", body, re.S)
    assert cells
    for cell in cells:
        cell = re.sub(r'<small class="why">.*?</small>', "", cell, flags=re.S)
        for line in _visible(cell):
            assert len(line) <= NOWRAP_CHARS, line
    # every ✗ is followed by its reason: the fault type or manoeuvre that fails the
    # requirement and its value against the limit
    marks = re.findall(r'<span class="unmet">(?:(?!</span>).)*?✗</span>(<br><small '
                       r'class="why">([^<]*)</small>)?', body, re.S)
    assert marks and body.count("✗") == len(marks) + body.count("✗ not met")
    faults = ["fault-free", *FAULTS, *FF_MANOEUVRES]
    for whole, reason in marks:
        assert whole, "a ✗ without its reason"
        for part in html.unescape(reason).split("; "):
            assert any(part.startswith(f) for f in faults), part
            assert " > " in part or part.endswith("no detected run"), part


def test_a_passing_value_beside_a_failure_names_the_failure():
    from reports.scoring.gate import requirements_gate
    from reports.render.html import render_report
    from reports.scoring.summary import summarize

    # detector d detects every runaway in time (DTP 0.5) and no liquid jam: its largest
    # DTP, 0.5, passes the limit 1 while the DTP requirement fails for the liquid jams
    rows = [{"run_id": f"{fault}{i}", "detector": "d", "fault": fault, "manoeuvre": "cruise",
             "status": "ok", "error": "", "false_alarm": False, "pre_onset_alarm": False,
             "detected": fault == "runaway", "first_alarm_s": np.nan,
             "delay_s": 0.25 if fault == "runaway" else np.nan,
             "dtp": 0.5 if fault == "runaway" else np.nan, "margin": 0.4}
            for fault in ("runaway", "liquid_jam") for i in range(3)]
    results = pd.DataFrame(rows)
    summary = summarize(results)
    req = {"max_fa_rate": 0.0, "max_md_rate": 0.0, "max_dtp": 1.0}
    page = render_report(meta={"name": "x"}, summary=summary,
                         gate=requirements_gate(summary, results, req), requirements=req,
                         all_requirements=requirements_gate(summary, results, req,
                                                            all_requirements=True),
                         runs=results.assign(alt_ft=1e4, vcas_kt=250.0, mass_t=60.0,
                                             cg_pct=30.0, onset_s=5.0), figures=[])
    row = re.search(r'<tr><td><a href="#runs-detector-d">d</a></td>(.*?)</tr>',
                    _section(page, "requirements")).group(1)
    cells = re.findall(r"<td>(.*?)</td>", row)
    assert cells[5] == ('<span class="unmet">0.5 ✗</span><br>'
                        '<small class="why">liquid_jam: no detected run</small>')
    # MD: 3 of 6 runs missed overall, all of them liquid jams
    assert cells[3].startswith('<span class="unmet">50.00')
    assert cells[3].endswith('<small class="why">liquid_jam: MD 100.00 % &gt; 0.00 %</small>')


@pytest.mark.slow
def test_workers_and_threads_make_the_page_one_process_makes(campaign_dir, report, tmp_path,
                                                             monkeypatch):
    import campaign.report_build as replay

    # batches of 5 runs: the 16 fault-free runs and the example runs re-simulated in 4
    # batches on 2 threads; the figures drawn in 2 worker processes
    monkeypatch.setattr(replay, "MAX_CHUNK", 5)
    parallel = build_report(campaign_dir, jobs=2, out=tmp_path / "p.html",
                            log=lambda _: None).read_text()
    alone = report[1]

    def figures(page):
        return re.findall(r'<figure>.*?</figure>', page, re.S)

    def text(page):
        page = re.sub(r"<figure>.*?</figure>", "", page, flags=re.S)
        page = re.sub(r"<td>report written \(UTC\)</td><td[^>]*>[^<]*</td>", "", page)
        return re.sub(r"<li>Report made with .*?</li>", "", page)

    # the same figures, bit for bit, in the same order, and the same page around them (19
    # and a threshold trade-off figure per fault type of the campaign: 3)
    assert len(figures(parallel)) == 22 and figures(parallel) == figures(alone)
    assert text(parallel) == text(alone)
    assert "Report made with 2 job(s)" in parallel
