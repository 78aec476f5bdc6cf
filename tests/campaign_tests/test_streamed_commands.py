"""certify, compare and report read the result rows a batch of runs at a time: none of them
reads every row at once, and what they compute is, to the bit, what the whole table gives
(issue 35: memory independent of the number of runs)."""

import shutil

import pandas as pd
import pytest

from campaign import load, run
from campaign.cli.commands import main
from campaign.compare import compare_dirs
from campaign.config import CampaignConfig
from campaign.evidence.certify import certificate
from campaign.evidence.certify.levels import DEFAULT_LEVELS, level_table
from campaign.evidence.certify.rows import CertifyRows
from campaign.evidence.hazard import hazard_table
from campaign.report_build import POINT_COLUMNS, runs_table
from campaign.store.directory import CampaignDir
from reports.scoring.compare import compare_results
from reports.scoring.summary import detector_order
from small_campaigns import small_campaign

#: Runs per batch in these tests: the campaign's 12 runs come in 6 batches, and its
#: 3 shards (chunks of 4 runs) are cut across batches.
BATCH_RUNS = 2


@pytest.fixture(scope="module")
def camp_dir(tmp_path_factory):
    """10 fault-free runs and 2 runaways, 20 s each, of the position monitor and the
    interval detector (five variants): 72 result rows in three shards."""
    out = tmp_path_factory.mktemp("streamed") / "c"
    cfg = small_campaign("streamed", 404, [{"name": "comb-interval"}], free=5)
    run(CampaignConfig.from_dict(cfg), out, jobs=1, progress=False)
    return out


@pytest.fixture
def small_batches(monkeypatch):
    """Every reader of result rows gets batches of BATCH_RUNS runs."""
    whole = CampaignDir.result_batches

    def batches(self, *args, **kwargs):
        kwargs["batch_runs"] = BATCH_RUNS
        return whole(self, *args, **kwargs)

    monkeypatch.setattr(CampaignDir, "result_batches", batches)


def test_the_batches_are_the_results_in_their_order(camp_dir, small_batches):
    camp = load(camp_dir)
    whole = camp.results
    parts = list(camp.result_batches())
    assert len(parts) == 12 // BATCH_RUNS and len(whole) == 12 * 6
    pd.testing.assert_frame_equal(pd.concat(parts, ignore_index=True), whole,
                                  check_exact=True)


def test_certify_tables_from_batches_equal_those_of_every_row(camp_dir):
    camp = load(camp_dir)
    rows = CertifyRows.of_campaign(camp, batch_runs=BATCH_RUNS)
    curve = level_table(rows, DEFAULT_LEVELS)
    pd.testing.assert_frame_equal(curve, level_table(camp.results, DEFAULT_LEVELS),
                                  check_exact=True)
    cert = certificate(rows, None, 0.95, curve)
    pd.testing.assert_frame_equal(cert, certificate(camp.results, camp.plan, 0.95),
                                  check_exact=True)
    rates = dict(camp.config.requirements.fault_rate_per_fh)
    hazard = hazard_table(rows, None, rates)
    pd.testing.assert_frame_equal(hazard, hazard_table(camp.results, camp.plan, rates),
                                  check_exact=True)
    # not vacuous: 10 fault-free runs of 20 s per detector variant, the detectors in the
    # one order of every output (by name, numbers by value), and the runaways counted on
    # the hazard's side
    assert list(cert["detector"]) == detector_order(camp.results["detector"])
    assert list(cert["detector"]) != list(dict.fromkeys(camp.results["detector"]))
    assert (cert["n_runs"] == 10).all()
    assert cert["exposure_h"].tolist() == pytest.approx([10 * 20.0 / 3600.0] * 6,
                                                        rel=1e-12)   # sums of 20.0 s
    assert (hazard.loc[hazard["fault"] == "runaway", "n_runs"] == 2).all()


def test_compare_from_batches_equals_compare_of_every_row(camp_dir, small_batches):
    camp = load(camp_dir)
    table = compare_dirs(camp_dir, camp_dir, log=lambda _: None)
    whole = compare_results(camp.results, camp.results)
    pd.testing.assert_frame_equal(table.drop(columns="fitted"), whole, check_exact=True)
    assert (table["test"] == "paired").all() and len(table) == 6 * 4   # none, runaway ×
    # 2 manoeuvres + all: only the 10 fault-free runs of "all" can show a change at
    # α = 0.01 (paired, 2·2⁻¹⁰); 5 runs (2·2⁻⁵ = 0.0625), 2 and 1 run are too few
    enough = (table["fault"] == "none") & (table["manoeuvre"] == "all")
    assert (table.loc[enough, "flag"] == "unchanged").all()
    assert (table.loc[~enough, "flag"] == "too few runs").all()


def test_runs_table_from_batches_is_the_merge_of_every_row(camp_dir, small_batches):
    camp = load(camp_dir)
    runs = runs_table(camp)
    point = camp.plan[["run_id", *POINT_COLUMNS]]
    whole = camp.results.merge(point, on="run_id", how="left", validate="many_to_one")
    pd.testing.assert_frame_equal(runs, whole[list(runs.columns)], check_exact=True)


def test_no_command_reads_every_result_row(camp_dir, tmp_path, small_batches, monkeypatch,
                                           capsys):
    camp = load(camp_dir)
    rates = dict(camp.config.requirements.fault_rate_per_fh)
    expected = (level_table(camp.results, DEFAULT_LEVELS),
                certificate(camp.results, camp.plan, 0.95),
                hazard_table(camp.results, camp.plan, rates))
    here = tmp_path / "c"
    shutil.copytree(camp_dir, here)

    def refuse(self):
        raise AssertionError("a command read every result row at once")

    monkeypatch.setattr(CampaignDir, "read_results", refuse)
    assert main(["certify", str(here)]) == 0
    done = load(here).certificate
    for got, want in zip((done.levels, done.table, done.hazard), expected):
        pd.testing.assert_frame_equal(got, want, check_exact=True)
    assert main(["compare", str(here), str(camp_dir)]) == 0
    assert "24 cells: 6 unchanged, 18 too few runs" in capsys.readouterr().out
    assert main(["report", str(here), "--jobs", "1", "--envelope-runs", "2"]) == 0
    assert (here / "report.html").stat().st_size > 0


def test_plan_rows_are_the_rows_of_the_plan(camp_dir, monkeypatch):
    """A few rows of the plan read a row group at a time (groups of 5 rows here, so that
    the rows asked for fall in several) are those of the plan read whole."""
    import campaign.store.directory as store

    monkeypatch.setattr(store, "PLAN_ROW_GROUP_ROWS", 5)
    whole = load(camp_dir).plan
    for positions in ([0], [1, 5, 6, 11], [], list(range(12))):
        got = load(camp_dir).plan_rows(positions)
        pd.testing.assert_frame_equal(got, whole.loc[positions], check_exact=True)
