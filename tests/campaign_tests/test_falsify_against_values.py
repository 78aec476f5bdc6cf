"""``fdd-campaign falsify --against DIR`` by value (campaign/evidence/falsify.py,
docs/evidence.md "Worst-case search (falsify)"): the worst fault-free margin of a campaign
directory and its worst runs, in order, as the baseline and the warm start of the search.
The directory is a campaign of 12 fault-free runs whose margin is a closed-form function of
the run (tests/plugin_detectors.py, ScheduleMargin); the search's own runs are evaluated by
the recorder of test_falsify_values.py."""

import numpy as np
import pandas as pd
import pytest

from campaign.config.schema import CampaignConfig
from campaign.evidence.falsify import FalsifyOptionError, _against, falsify
from campaign.store.directory import CampaignDir

from test_falsify_values import install_pipeline


@pytest.fixture
def pipeline(monkeypatch):
    """The runner's pipeline replaced by the recorder of test_falsify_values.py."""
    return install_pipeline(monkeypatch)

def _against_config():
    return CampaignConfig.from_dict({
        "campaign": {"name": "against", "seed": 11, "duration_s": 20.0, "ts_s": 0.05,
                     "sampler": "random", "realistic_only": False},
        "envelope": {"vcas_kt": [160.0, 300.0]},
        "group": [{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
                  {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"],
                   "count": 6}],
        "detector": [{"name": "schedule-margin", "label": "sm",
                      "params": {"limit_kt": 280.0}},
                     {"name": "schedule-margin", "label": "twice",
                      "params": {"limit_kt": 140.0}}],
        "learning": {"runs_per_manoeuvre": 2, "manoeuvres": ["cruise"]},
    })


@pytest.fixture(scope="module")
def against(tmp_path_factory):
    """A campaign of 2 runaways, then 12 fault-free runs (a few seconds), whose margin is
    measured VCAS / 280 kt (tests/plugin_detectors.py, ScheduleMargin), and twice that of a
    second detector."""
    from campaign.runner import run
    from detectors import registry

    out = tmp_path_factory.mktemp("against") / "c"
    with pytest.MonkeyPatch.context() as mp:       # the plugin registered for the module
        mp.setitem(registry.BUILTIN, "schedule-margin", "plugin_detectors:ScheduleMargin")
        run(_against_config(), out, jobs=1, progress=False, log=lambda m: None)
        yield out


def test_against_gives_the_worst_fault_free_margin_and_the_worst_runs_in_order(against):
    config = _against_config()
    results = CampaignDir(against).read_results()
    plan = CampaignDir(against).read_plan()
    mine = results[(results["detector"] == "sm") & (results["fault"] == "none")]
    # margin = VCAS·(1 + d_vcas) / 280 of each run
    merged = mine.merge(plan[["run_id", "vcas_kt", "d_vcas"]], on="run_id")
    np.testing.assert_allclose(merged["margin"], merged["vcas_kt"] * (1 + merged["d_vcas"])
                               / 280.0, rtol=1e-12)
    baseline, rows = _against(against, config, "sm", 3)
    assert baseline == (mine["margin"].max(), 12,
                        f"the 12 fault-free runs of {against} (campaign 'against')")
    worst = mine.sort_values("margin", ascending=False, kind="stable").head(3)
    assert list(rows["run_id"]) == list(worst["run_id"])
    assert list(rows.index) == [0, 1, 2]
    want = plan.set_index("run_id").loc[list(worst["run_id"])].reset_index()
    assert list(rows.columns) == list(want.columns)          # the plan's, no index column
    pd.testing.assert_frame_equal(rows, want, check_dtype=False)
    # keep larger than the runs: every fault-free run, worst first
    _, rows = _against(against, config, "sm", 50)
    assert list(rows["run_id"]) == list(
        mine.sort_values("margin", ascending=False, kind="stable")["run_id"])


def test_against_reads_the_results_a_batch_at_a_time(against, monkeypatch):
    # batches of two runs: the first holds only the runaways, the worst runs of the others
    # are gathered over the batches
    from campaign.result import Campaign

    config = _against_config()
    whole = _against(against, config, "sm", 3)
    read = Campaign.result_batches
    monkeypatch.setattr(Campaign, "result_batches",
                        lambda self, columns=None, batch_runs=0, positions=False: read(
                            self, columns=columns, batch_runs=2, positions=positions))
    small = _against(against, config, "sm", 3)
    assert small[0] == whole[0]
    pd.testing.assert_frame_equal(small[1], whole[1])


def test_against_refuses_a_directory_without_the_detector(against):
    with pytest.raises(FalsifyOptionError, match=f"against='{against}': its results hold no "
                                                 "detector 'pm'; they hold: sm, twice"):
        _against(against, _against_config(), "pm", 3)


def test_the_search_against_a_campaign_opens_with_its_worst_runs(against, tmp_path, pipeline):
    config = _against_config()
    out = tmp_path / "s"
    res = falsify(config, "sm", budget=12, out=out, jobs=1, seed=0, keep=3, against=against,
                  log=lambda m: None, progress=False)
    baseline, rows = _against(against, config, "sm", 3)
    assert (res.baseline_margin, res.baseline_runs, res.baseline_source) == baseline
    first = res.search.iloc[:3]
    assert list(first["stream"]) == list(rows["stream"])
    assert list(first["manoeuvre"]) == list(rows["manoeuvre"])
    np.testing.assert_array_equal(first["vcas_kt"], rows["vcas_kt"])
    assert first["manoeuvre_start_s"].isna().all()
    assert not (out / "monte-carlo.parquet").exists() and len(pipeline.batches) == 2


def test_a_worst_run_the_plan_lacks_counts_but_is_not_replayed(against, tmp_path):
    # a result row of a run id outside the plan (plan position = the plan's run count)
    import shutil

    from campaign.result import load

    copy = tmp_path / "c"
    shutil.copytree(against, copy)
    cdir = CampaignDir(copy)
    row = pd.read_parquet(cdir.shard_paths()[-1])
    row = row[(row["detector"] == "sm") & (row["fault"] == "none")].head(1)
    cdir.write_shard(row.assign(run_id="outside-the-plan", margin=9.0),
                     load(copy).config.to_json())
    config = _against_config()
    (top, n_free, _), rows = _against(copy, config, "sm", 3)
    _, whole = _against(against, config, "sm", 3)
    assert (top, n_free) == (9.0, 13)
    # the two worst runs of the plan, in order; the outside run left out
    assert list(rows["run_id"]) == list(whole["run_id"].iloc[:2])
