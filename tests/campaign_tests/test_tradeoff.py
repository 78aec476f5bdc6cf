"""A campaign's results at other thresholds from its stored runs (campaign/tradeoff.py,
docs/thresholds.md): what ``tradeoff`` predicts at a stored scale is what the same campaign
run with ``threshold_scale`` at that scale (and ``--fitted-from`` the first) gives, row for
row and count for count; at scale 1 it is the campaign's own summary; ``gate
--threshold-scale`` is the gate of that campaign; a directory written before the column
says so; a detector without a threshold scale is refused the key (exit 2)."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from campaign import load, run
from campaign.cli.commands import main
from campaign.config import CampaignConfig, ConfigError
from campaign.store.directory import CampaignDir
from campaign.tradeoff import (TRADEOFF_COLUMNS, TradeoffError, _at_scale, _plan_runs,
                               at_threshold_scales, operating_points, tradeoff)
from detectors import registry
from reports.scoring.alarm_steps import ALARM_STEPS_COLUMN
from small_campaigns import campaign_toml, small_campaign

SCALES = (0.8, 1.25)
COUNTS = ("fa_count", "md_count", "late_count", "dtp_max")
SCORED = ("false_alarm", "pre_onset_alarm", "detected", "first_alarm_s", "delay_s", "dtp",
          "margin")


def _config(scale: float | None = None, seed: int = 21) -> dict:
    """6 fault-free runs, 3 runaways, 3 solid jams and 3 disconnections of 20 s, the
    position monitor (``pm``) and the interval detector (five variants), every detector at
    threshold × *scale*."""
    cfg = small_campaign("tradeoff", seed, [{"name": "comb-interval", "label": "ci"}])
    cfg["group"] = [cfg["group"][0]] + [
        {"name": f, "fault": f, "manoeuvres": ["cruise"], "count": 3}
        for f in ("runaway", "solid_jam", "disconnection")]
    if scale is not None:
        for d in cfg["detector"]:
            d["threshold_scale"] = scale
    return cfg


@pytest.fixture(scope="module")
def dirs(tmp_path_factory):
    """The campaign at its own thresholds, then at each of SCALES with its fitted
    detectors."""
    root = tmp_path_factory.mktemp("tradeoff")
    run(CampaignConfig.from_dict(_config()), root / "base", jobs=1, progress=False)
    for s in SCALES:
        run(CampaignConfig.from_dict(_config(s)), root / f"s{s:g}", jobs=1, progress=False,
            fitted_from=root / "base")
    return root


def _all(summary: pd.DataFrame) -> pd.DataFrame:
    return summary[summary["manoeuvre"] == "all"].set_index(["detector", "fault"])


def test_the_reruns_reused_the_fitted_detectors(dirs):
    sha = CampaignDir(dirs / "base").fitted_sha256(["pm", "ci"])
    for s in SCALES:
        assert CampaignDir(dirs / f"s{s:g}").fitted_sha256(["pm", "ci"]) == sha


@pytest.mark.parametrize("scale", SCALES)
def test_predicted_counts_are_those_of_the_campaign_at_that_scale(dirs, scale):
    table = tradeoff(dirs / "base", (scale,)).table.set_index(["detector", "fault"])
    rerun = _all(load(dirs / f"s{scale:g}").summary)
    assert sorted(table.index) == sorted(rerun.index)
    for key, row in table.iterrows():
        for column in COUNTS:
            want = rerun.loc[key, column]
            assert row[column] == want or (np.isnan(want) and np.isnan(row[column])), (
                key, column)


@pytest.mark.parametrize("scale", SCALES)
def test_predicted_rows_are_those_of_the_campaign_at_that_scale_to_the_bit(dirs, scale):
    base = load(dirs / "base")
    cdir = CampaignDir(dirs / "base")
    runs = _plan_runs(cdir, base.config)
    got = pd.concat([_at_scale(b, runs, scale, base.config.campaign.ts_s)
                     for b in cdir.result_batches(positions=True)], ignore_index=True)
    want = load(dirs / f"s{scale:g}").results
    both = got.merge(want, on=["run_id", "detector"], suffixes=("", "_rerun"))
    assert len(both) == len(want) == len(got) and got["known"].all()
    faulty = both["fault"] != "none"
    for column in SCORED:
        a, b = both[column], both[f"{column}_rerun"]
        if column == "first_alarm_s":                  # not stored for fault-free runs
            a, b = a[faulty], b[faulty]
        pd.testing.assert_series_equal(a.reset_index(drop=True), b.reset_index(drop=True),
                                       check_names=False, check_exact=True)
    # the scale changed some first alarms: the comparison above had something to see
    moved = (both.loc[faulty, "first_alarm_s"]
             != base.results.set_index(["run_id", "detector"]).loc[
                 list(zip(both.loc[faulty, "run_id"], both.loc[faulty, "detector"])),
                 "first_alarm_s"].to_numpy())
    assert moved.sum() >= 5


def test_at_scale_one_the_table_is_the_campaign_s_summary(dirs):
    table = tradeoff(dirs / "base", (1.0,)).table
    assert tuple(table.columns) == TRADEOFF_COLUMNS
    summary = _all(load(dirs / "base").summary)
    for key, row in table.set_index(["detector", "fault"]).iterrows():
        for column in (*COUNTS, "n_runs", "delay_max_s"):
            want = summary.loc[key, column]
            assert row[column] == want or (np.isnan(want) and np.isnan(row[column]))


def test_the_command_writes_the_table_and_an_operating_point(dirs, tmp_path, capsys):
    work = tmp_path / "c"
    shutil.copytree(dirs / "base", work)
    assert main(["tradeoff", str(work), "--scales", "0.8,1,1.25", "--max-fa-prob",
                 "0.5"]) == 0
    out = capsys.readouterr().out
    stored = CampaignDir(work).read_tradeoff()
    assert sorted(set(stored["scale"])) == [0.8, 1.0, 1.25]
    assert set(stored["detector"]) >= {"pm", "ci[a=0.9]"}
    assert "Detector: pm" in out and "Operating points" in out
    assert main(["verify", str(work)]) == 0              # recorded in the manifest
    points = operating_points(stored, max_fa_prob=0.5)
    assert set(points["scale"].dropna()) <= {0.8, 1.0, 1.25} and points["scale"].notna().all()
    # a target no scale meets: no operating point
    assert operating_points(stored, max_fa_prob=1e-9)["scale"].isna().all()


def _gate_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(("PASS", "FAIL"))]


def test_gate_at_a_threshold_scale_is_the_gate_of_the_campaign_at_that_scale(dirs, capsys):
    for s in SCALES:
        code = main(["gate", str(dirs / "base"), "--all-requirements",
                     "--threshold-scale", f"pm={s:g},ci={s:g}"])
        predicted = _gate_lines(capsys.readouterr().out)
        assert main(["gate", str(dirs / f"s{s:g}"), "--all-requirements"]) == code
        assert _gate_lines(capsys.readouterr().out) == predicted and predicted
    camp = at_threshold_scales(load(dirs / "base"), {"ci": 1.25})
    pd.testing.assert_frame_equal(
        camp.summary[camp.summary["detector"] == "pm"].reset_index(drop=True),
        load(dirs / "base").summary.query("detector == 'pm'").reset_index(drop=True))


@pytest.mark.parametrize("option, message", [
    ("pm=1.1", "1.1 is not a stored threshold scale"),
    ("nope=0.8", "'nope' is no detector"),
    ("pm", "give DETECTOR=SCALE"),
])
def test_gate_at_a_scale_refuses_what_it_cannot_give(dirs, capsys, option, message):
    assert main(["gate", str(dirs / "base"), "--threshold-scale", option]) == 2
    assert message in capsys.readouterr().err


def test_a_directory_written_before_the_column_says_so(tmp_path, monkeypatch, capsys):
    """A campaign whose shards hold no first alarms at other scales (as an older version
    writes them): false alarms at every scale from the margins, detections not given, and
    the note says how to get them; the gate at another scale is refused."""
    import campaign.evaluate as ev

    def none(decision, **kw):
        return np.full(len(kw["fault"]), None, dtype=object)

    monkeypatch.setattr(ev, "alarm_steps", none)
    out = tmp_path / "old"
    run(CampaignConfig.from_dict(_config(seed=22)), out, jobs=1, progress=False)
    monkeypatch.undo()
    assert all(ALARM_STEPS_COLUMN not in pd.read_parquet(p).columns
               for p in CampaignDir(out).shard_paths())
    result = tradeoff(out, (0.8, 1.0))
    assert any("predates" in note and "--fitted-from" in note for note in result.notes)
    t = result.table.set_index(["detector", "fault", "scale"])
    assert np.isnan(t.loc[("pm", "runaway", 0.8), "dtp_max"])
    assert t.loc[("pm", "runaway", 0.8), "n_unknown"] == 3
    assert t.loc[("pm", "none", 0.8), "n_runs"] == 6                 # margins: known
    assert not np.isnan(t.loc[("pm", "runaway", 1.0), "dtp_max"])    # its own rows
    assert main(["gate", str(out), "--threshold-scale", "pm=0.8"]) == 2
    assert "predates" in capsys.readouterr().err
    with pytest.raises(TradeoffError, match="predates"):
        at_threshold_scales(load(out), {"pm": 0.8})


def test_the_key_is_refused_for_a_detector_without_threshold_scale(monkeypatch, tmp_path,
                                                                   capsys):
    monkeypatch.setitem(registry.BUILTIN, "subsampled", "plugin_detectors:Subsampled")
    cfg = small_campaign("noscale", 5, [{"name": "subsampled", "threshold_scale": 0.8}])
    with pytest.raises(ConfigError, match=r"detector\[1\].threshold_scale: detector "
                                          r"'subsampled' has no threshold scale"):
        CampaignConfig.from_dict(cfg)
    file = tmp_path / "c.toml"
    file.write_text(campaign_toml(cfg))
    assert main(["plan", str(file), "--out", str(tmp_path / "p")]) == 2
    assert "has no threshold scale" in capsys.readouterr().err
    # scale 1 is the default, allowed for every detector, and not in the canonical form
    cfg["detector"][1]["threshold_scale"] = 1
    assert "threshold_scale" not in CampaignConfig.from_dict(cfg).to_json()


def test_the_report_gets_one_trade_off_figure_per_fault_type(dirs):
    from PIL import Image
    import io

    from campaign.tradeoff import report_figures

    notes: list = []
    figures = report_figures(load(dirs / "base"), {"max_dtp": 1.0}, notes)
    assert [f.group for f in figures] == ["disconnection", "runaway", "solid_jam"]
    assert all(f.section == "fault" and f.title.startswith("Threshold trade-off") for f in figures)
    for f in figures:
        width, height = Image.open(io.BytesIO(f.png)).size
        assert 400 < width <= 1100 and 250 < height < 700       # within the page's width
    assert notes == []                                          # nothing predates here


def test_false_alarms_per_flight_hour_and_their_operating_point(dirs):
    table = tradeoff(dirs / "base", (0.8, 1.0)).table
    free = table[table["fault"] == "none"]
    hours = 20.0 / 3600.0                              # the runs' duration
    np.testing.assert_allclose(free["fa_per_hour_upper95"],
                               -np.log1p(-free["fa_upper95"]) / hours, rtol=1e-12)
    assert table.loc[table["fault"] != "none", "fa_per_hour_upper95"].isna().all()
    rate = float(free["fa_per_hour_upper95"].max())    # every scale meets it
    points = operating_points(table, max_fa_per_hour=rate)
    assert points["scale"].notna().all()
    assert operating_points(table, max_fa_per_hour=rate / 1e6)["scale"].isna().all()
    with pytest.raises(TradeoffError, match="one false-alarm target"):
        operating_points(table, max_fa_prob=0.1, max_fa_per_hour=rate)


def test_a_detector_without_threshold_scale_is_listed_with_no_curve(monkeypatch, tmp_path):
    monkeypatch.setitem(registry.BUILTIN, "subsampled", "plugin_detectors:Subsampled")
    cfg = small_campaign("noscale", 23, [{"name": "subsampled", "label": "sub"}])
    run(CampaignConfig.from_dict(cfg), tmp_path / "c", jobs=1, progress=False)
    result = tradeoff(tmp_path / "c", (0.8, 1.0, 1.25))
    assert result.unscaled == ["sub"]
    assert any("no threshold scale" in note and "sub" in note for note in result.notes)
    sub = result.table[result.table["detector"] == "sub"]
    assert set(sub["scale"]) == {1.0} and not sub["threshold_scale"].any()
    pm = result.table[result.table["detector"] == "pm"]
    assert set(pm["scale"]) == {0.8, 1.0, 1.25} and pm["threshold_scale"].all()
    with pytest.raises(TradeoffError, match="sub has no threshold scale"):
        at_threshold_scales(load(tmp_path / "c"), {"sub": 0.8})


def test_a_threshold_scale_is_a_mark_on_the_detector_not_a_learned_value():
    from detectors.base import set_threshold_scale, set_threshold_scales, threshold_scale_of
    from detectors.builtin.position_monitor import PositionMonitor
    from plugin_detectors import Subsampled

    pm = PositionMonitor()
    assert threshold_scale_of(pm) == 1.0
    assert threshold_scale_of(set_threshold_scale(pm, 1.25)) == 1.25
    assert "_threshold_scale" not in pm.fitted_state() and "threshold_scale" not in str(
        pm.get_params())
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="finite number > 0"):
            set_threshold_scale(pm, bad)
    set_threshold_scale(Subsampled(), 1.0)                 # 1: every detector takes it
    with pytest.raises(ValueError, match="'sub'.*has no threshold scale"):
        set_threshold_scales({"sub": Subsampled()}, {"sub": 0.8})
