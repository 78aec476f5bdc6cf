"""The HTML campaign report, `show` (one run re-simulated from its id) and `compare`.

The report is also rendered in a real browser (headless Chromium, no network). Chromium
comes from the Debian packages; the fixture installs it when it is missing (as root, with
apt-get) and skips with the reason when that is impossible.
"""

import base64
import os
import re
import shutil
import subprocess
from math import comb
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.cli import main
from campaign.config import CampaignConfig
from campaign.report import ReportSettings, build_report, load_campaign
from reports.compare import compare_results
from reports.figures import bin_max
from reports.html import anchor, count_figures, show_command

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


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("camp") / "a"
    run(small(), out, jobs=1, progress=False)
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
    camp = load_campaign(campaign_dir)
    s = camp.summary
    row = s[(s.fault == "none") & (s.manoeuvre == "all")].iloc[0]
    assert f"{int(row.fa_count)}/{int(row.n_runs)}" in page
    assert int(row.n_runs) == 16
    # the bound is spelled out (docs/design.md §5, Metrics): with k = 0 of 16, 1 − 0.05^(1/16)
    if row.fa_count == 0:
        bound = 100 * (1 - 0.05 ** (1 / 16))
        assert f"No false alarm in 16 fault-free runs: FA ≤ {bound:.2f} %" in page
    alts = set(_alts(page))
    det = "position-monitor"
    expected = {f"Residual envelope — {det} — {m}" for m in FF_MANOEUVRES}
    expected |= {f"Detection of {f} — {det}" for f in FAULTS}
    expected |= {f"Margin to false alarm — {det}", f"Detection time performance — {det}"}
    # detection time as survival data (docs/evidence.md); the certificate's figures only
    # once fdd-campaign certify has run
    expected |= {f"Detection delay (Kaplan–Meier) — {det}"}
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
    det = "position-monitor"
    for fault in ["none", *FAULTS]:
        assert anchor(det, fault) in targets
    assert anchor(det, "none", "cruise") in targets
    # every run is listed once per detector, with the command that re-simulates it
    plan = pd.read_parquet(campaign_dir / "plan.parquet")
    for rid in plan["run_id"]:
        assert page.count(f"<code>{rid}</code>") == 1
        assert show_command(rid) in page
    # the cruise fault-free list holds exactly the 8 cruise fault-free runs
    start = page.index(f'id="{anchor(det, "none", "cruise")}"')
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
    worst = re.findall(r"worst run (\w+) \(fdd-campaign", page)
    assert len(worst) == 2 and re.findall(r"worst run (\w+) \(fdd-campaign", small_page) == worst
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
    # 15 figures and the Kaplan–Meier curve of the detection delays
    assert str(copy) in page and count_figures(page) == count_figures(report[1]) == 16
    assert main(["report", str(copy), "--no-html", "--html", str(tmp_path / "x.html")]) == 0
    assert not (tmp_path / "x.html").exists()


def test_report_of_an_interrupted_campaign_says_so(campaign_dir, tmp_path):
    from campaign.runner import finalize
    from campaign.storage import CampaignDir

    copy = tmp_path / "partial"
    shutil.copytree(campaign_dir, copy)
    cdir = CampaignDir(copy)
    camp = load_campaign(copy)
    # as if the campaign had been stopped after its first runs
    for path in cdir.shard_paths():
        cdir.remove(path)
    first = camp.plan["run_id"].iloc[:20]
    cdir.write_shard(camp.results[camp.results["run_id"].isin(first)], camp.config.to_json())
    finalize(cdir, camp.config, camp.plan, False, 0.0)
    page = build_report(copy, jobs=1, log=lambda _: None,
                        settings=ReportSettings(examples_per_fault=0)).read_text()
    assert f"The campaign is incomplete: 20 of {len(camp.plan)} runs" in page
    # the runs that were not done are in no list
    missing = set(camp.plan["run_id"]) - set(load_campaign(copy).results["run_id"])
    assert missing and not any(f"<code>{rid}</code>" in page for rid in missing)


def test_show_resimulates_one_run_from_its_id(campaign_dir, tmp_path, capsys):
    camp = load_campaign(campaign_dir)
    row = camp.results[camp.results.fault == "solid_jam"].iloc[0]
    png, pq = tmp_path / "run.png", tmp_path / "run.parquet"
    assert main(["show", str(campaign_dir), row.run_id, "--plot", str(png),
                 "--out", str(pq)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    frame = pd.read_parquet(pq)
    t = frame["time [s]"].to_numpy()
    res = frame["position-monitor |r|/tau [-]"].to_numpy()
    alarm = frame["position-monitor alarm"].to_numpy()
    onset = camp.plan.set_index("run_id").loc[row.run_id, "onset_s"]
    # bit-for-bit determinism: the stored margin (max |r|/τ before onset) and first alarm
    # are reproduced exactly
    assert np.max(res[t < onset]) == row.margin
    assert t[np.argmax(alarm & (t >= onset))] == pytest.approx(row.first_alarm_s, abs=1e-12)
    # the run is scored again by the campaign's rules and printed beside the stored row
    out = capsys.readouterr().out
    stored = re.search(r"position-monitor: stored (.*)", out).group(1)
    again = re.search(r"re-simulated (.*)", out).group(1)
    assert stored == again and "detected True" in stored


def test_show_and_report_refuse_bad_input_with_exit_2(campaign_dir, tmp_path, capsys):
    assert main(["show", str(campaign_dir), "no-such-run"]) == 2
    assert "not in" in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "is not a campaign directory written by" in capsys.readouterr().err
    assert main(["compare", str(campaign_dir), str(tmp_path)]) == 2
    assert "not a campaign directory" in capsys.readouterr().err


def test_compare_flags_a_degraded_detector_and_not_an_identical_campaign(
        campaign_dir, tmp_path, capsys):
    same = tmp_path / "same"
    run(small(), same, jobs=1, progress=False)
    assert main(["compare", str(campaign_dir), str(same)]) == 0
    out = capsys.readouterr().out
    a, b = load_campaign(campaign_dir).results, load_campaign(same).results
    table = compare_results(a, b)
    assert (table["flag"] == "unchanged").all(), out
    assert "0 worse" not in out and "unchanged" in out

    bad = tmp_path / "bad"
    run(small(**DEGRADED), bad, jobs=1, progress=False)
    assert main(["compare", str(campaign_dir), str(bad)]) == 0
    out = capsys.readouterr().out
    table = compare_results(a, load_campaign(bad).results)
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


def test_bin_max_keeps_every_peak_and_ignores_nan():
    x = np.zeros((2, 10))
    x[0, 7] = 5.0
    x[1, :3] = np.nan
    starts, b = bin_max(x, 4)
    assert starts.tolist() == [0, 3, 6, 9]
    assert b[0].tolist() == [0.0, 0.0, 5.0, 0.0]
    assert np.isnan(b[1, 0]) and b[1, 1:].tolist() == [0.0, 0.0, 0.0]


# ---- in a browser --------------------------------------------------------------------------
CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="session")
def chromium():
    if CHROMIUM.exists():
        return CHROMIUM
    if not shutil.which("apt-get"):
        pytest.skip("chromium is not installed and apt-get is not available to install it")
    if hasattr(os, "geteuid") and os.geteuid() != 0:
        pytest.skip("chromium is not installed and installing it with apt-get needs root")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    try:
        for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "chromium"]):
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
            if done.returncode != 0:
                pytest.skip(f"could not install chromium ({' '.join(cmd)} failed: "
                            f"{done.stderr.strip()[-300:]})")
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"could not install chromium: {exc}")
    if not CHROMIUM.exists():
        pytest.skip("apt-get installed chromium but /usr/bin/chromium is missing")
    return CHROMIUM


def _chromium(binary, profile, *args, timeout=120):
    return subprocess.run([str(binary), *FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=timeout)


def test_report_dom_has_the_verdict_table_and_every_figure(chromium, report, tmp_path):
    page_path, html = report
    done = _chromium(chromium, tmp_path / "profile", "--dump-dom", page_path.as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    dom = done.stdout
    assert re.search(r'<section id="verdict">.*?<table class="verdict faults">', dom, re.S)
    assert "position-monitor" in dom and "Fault scenario" in dom
    # 15 figures and the Kaplan–Meier curve of the detection delays
    assert count_figures(dom) == count_figures(html) == 16
    # every image is an embedded PNG (data URI), nothing to fetch
    srcs = re.findall(r'<img [^>]*src="([^"]{0,30})', dom)
    assert len(srcs) == 16 and all(s.startswith("data:image/png;base64,") for s in srcs)


def test_report_screenshot_shows_a_rendered_page(chromium, report, tmp_path):
    page_path = report[0]
    shot = tmp_path / "report.png"
    done = _chromium(chromium, tmp_path / "profile", f"--screenshot={shot}",
                     "--window-size=1400,3000", page_path.as_uri())
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)
    assert img.shape[:2] == (3000, 1400)
    # a blank or unstyled page is almost uniform; the rendered report has text, tables,
    # the green/red verdict badges and figures: many distinct colours and dark pixels
    rgb = (img[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    assert len(np.unique(rgb, axis=0)) > 500
    assert np.mean(rgb.mean(axis=1) < 128) > 0.005
