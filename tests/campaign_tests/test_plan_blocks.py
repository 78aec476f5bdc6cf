"""The run table made and written block by block (campaign.plan.PlanBlocks,
CampaignDir.write_plan): the same rows, run ids, streams and file as the table made whole,
whatever the block size, so that a plan of 10⁶ runs is written with one block in memory
(docs/execution.md, "Memory independent of the number of runs")."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import ConfigError
from campaign.plan import (PLAN_COLUMNS, PlanBlocks, _unit_sample_stream, _unit_samples,
                             build_plan)
from campaign.store.directory import PLAN_ROW_GROUP_ROWS, CampaignDir

from test_design_values import ALL_FAULTS, RUNS, _sliver, config

GRID = {"campaign": {"design": "grid"}}


def _cases():
    """Campaigns whose plans take every path of the design: Monte Carlo cells (Sobol and
    plain random), fixed group keys, a grid, explicit runs after the groups, a rare
    realistic region that needs doublings of a cell's draw."""
    fixed = {"name": "fx", "fault": "runaway", "manoeuvres": ["nose_up"], "count": 9,
             "onset_s": 10.0, "magnitude": 2.0, "alt_ft": 20000.0}
    return {
        "mc": config(ALL_FAULTS + [fixed]),
        "random": config(ALL_FAULTS[:3], campaign={"sampler": "random"}),
        "grid": config([{"name": "g", "fault": "runaway", "manoeuvres": ["cruise"]}], **GRID),
        "runs": config(ALL_FAULTS[:2], run=[RUNS[0], RUNS[1]]),
        "sliver": _sliver(252.0, 3, 1),
    }


#: (case, block rows): every case at 1, 7 and 64 rows, but the rare region at 7 and 64 only:
#: its one run is the 890th point of the cell's sequence, so blocks of one row draw 890 times
#: (13 s) what blocks of 7 draw 128 times, in pieces as far from a power of two.
BLOCK_CASES = [(name, rows) for rows in (1, 7, 64) for name in _cases()
               if (name, rows) != ("sliver", 1)]


@pytest.mark.parametrize("name, block_rows", BLOCK_CASES)
def test_the_blocks_are_the_plan_whatever_their_size(name, block_rows):
    cfg = _cases()[name]
    whole = build_plan(cfg)
    blocks = PlanBlocks(resolve(cfg), block_rows=block_rows)
    assert blocks.rows == len(whole)                      # known before any block
    parts = list(blocks)
    assert all(0 < len(p) <= block_rows for p in parts)
    assert [p.index[0] for p in parts] == list(np.cumsum([0] + [len(p) for p in parts])[:-1])
    pd.testing.assert_frame_equal(pd.concat(parts), whole, check_exact=True)
    blocks.check()                                        # no duplicate: nothing raised


@pytest.mark.parametrize("sampler", ["sobol", "random"])
def test_a_cell_sequence_drawn_piece_by_piece_is_its_prefix(sampler):
    # the Monte Carlo cells draw their sequence in pieces: the same numbers as the first
    # points of one draw of a power of two (what a cell drew before it drew in blocks)
    from scipy.stats import qmc

    from campaign.plan import _DESIGN_KEY, _DIMS

    cfg = config(ALL_FAULTS[:1], campaign={"sampler": sampler})
    draw = _unit_sample_stream(cfg, 3)
    pieces = np.concatenate([draw(k) for k in (5, 11, 16, 100)])
    rng = np.random.default_rng(np.random.SeedSequence(5, spawn_key=(_DESIGN_KEY, 3)))
    whole = (qmc.Sobol(d=len(_DIMS), scramble=True, seed=rng).random_base2(8)
             if sampler == "sobol" else rng.random((256, len(_DIMS))))
    np.testing.assert_array_equal(pieces, whole[:132])
    np.testing.assert_array_equal(_unit_samples(132, cfg, 3), whole[:132])


def test_a_plan_written_block_by_block_is_the_file_of_the_whole_plan(tmp_path):
    cfg = config(ALL_FAULTS)
    whole = build_plan(cfg)
    a, b = CampaignDir(tmp_path / "a"), CampaignDir(tmp_path / "b")
    assert a.write_plan(whole, cfg.to_json(), "servo-4") == len(whole)
    blocks = PlanBlocks(resolve(cfg), block_rows=3)
    assert b.write_plan(blocks, cfg.to_json(), "servo-4") == len(whole)
    pd.testing.assert_frame_equal(b.read_plan(), a.read_plan(), check_exact=True)
    fa, fb = pq.ParquetFile(a.plan_path), pq.ParquetFile(b.plan_path)
    groups = [fb.metadata.row_group(i).num_rows for i in range(fb.num_row_groups)]
    assert groups == [fa.metadata.row_group(i).num_rows for i in range(fa.num_row_groups)]
    assert fa.schema_arrow.metadata == fb.schema_arrow.metadata   # rows, config, version
    assert b.planned_runs() == len(whole)
    assert list(b.read_plan().columns) == list(PLAN_COLUMNS)


def test_row_groups_of_a_streamed_plan_keep_their_size_across_blocks(tmp_path):
    # blocks of 1000 rows make row groups of PLAN_ROW_GROUP_ROWS all the same, the last
    # one the remainder, as a whole-table write cuts them
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 5000}])
    cdir = CampaignDir(tmp_path / "c")
    cdir.write_plan(PlanBlocks(resolve(cfg), block_rows=1000), cfg.to_json(), "servo-4")
    f = pq.ParquetFile(cdir.plan_path)
    sizes = [f.metadata.row_group(i).num_rows for i in range(f.num_row_groups)]
    full, rest = divmod(5000, PLAN_ROW_GROUP_ROWS)
    assert sizes == [PLAN_ROW_GROUP_ROWS] * full + ([rest] if rest else [])


def test_two_equal_runs_refuse_the_streamed_plan_and_leave_no_file(tmp_path):
    cfg = config(ALL_FAULTS[:1], run=[RUNS[1], RUNS[1]])
    cdir = CampaignDir(tmp_path / "d")
    with pytest.raises(ConfigError, match="duplicate runs in group 'worst'"):
        cdir.write_plan(PlanBlocks(resolve(cfg), block_rows=2), cfg.to_json(), "servo-4")
    assert not cdir.has_plan()
    assert not any(p.name.startswith("plan") for p in (tmp_path / "d").rglob("*"))


def test_the_plan_command_leaves_nothing_when_the_plan_is_refused(tmp_path, capsys):
    # a box without enough realistic points is refused while the plan is written: the
    # directory the command created is removed (exit 2, the fix named)
    box = tmp_path / "box.toml"
    box.write_text(
        '[campaign]\nname = "box"\nseed = 1\nduration_s = 40.0\n'
        '[envelope]\nalt_ft = [40000.0, 41000.0]\nvcas_kt = [180.0, 185.0]\n'
        'mass_t = [240.0, 242.0]\n'
        '[[group]]\nname = "ff"\nfault = "none"\nmanoeuvres = ["cruise"]\ncount = 3\n'
        '[[detector]]\nname = "position-monitor"\n')
    out = tmp_path / "out"
    assert main(["plan", str(box), "--out", str(out)]) == 2
    assert "fewer than 3 realistic flight points" in capsys.readouterr().err
    assert not out.exists()


def test_plan_counts_of_the_plan_read_in_batches_are_those_of_the_whole_plan(tmp_path):
    # fdd-campaign plan counts the written plan batch by batch: the same table, in the
    # order of the groups' first rows, whatever the batch cuts
    from campaign.plan import plan_counts

    cfg = config(ALL_FAULTS, run=[RUNS[0]])
    whole = build_plan(cfg)
    cdir = CampaignDir(tmp_path / "e")
    cdir.write_plan(whole, cfg.to_json(), "servo-4")
    expected = (whole.groupby(["group", "fault", "manoeuvre"], sort=False).size()
                .rename("runs").reset_index())
    for batch_rows in (3, 1000):
        got = plan_counts(cdir.plan_batches(batch_rows, columns=["group", "fault", "manoeuvre"]))
        pd.testing.assert_frame_equal(got, expected)


def test_run_ids_are_read_as_bytes_from_the_arrow_buffer_when_they_have_one_length():
    # the run ids of a plan (20 hex characters) go from plan.parquet to the run index
    # without a Python string each; anything else takes the general path, same bytes
    import pyarrow as pa

    from campaign.store.directory import _as_bytes, _fixed_width_bytes

    ids = [f"{i:020x}" for i in range(1000)]
    column = pa.chunked_array([pa.array(ids[:300]), pa.array(ids[300:])])
    for col in (column, pa.array(ids).slice(7, 500), pa.array(ids, pa.large_string())):
        got = _fixed_width_bytes(col)
        assert got is not None and got.dtype == np.dtype("S20")
        np.testing.assert_array_equal(got, np.array(col.to_pylist(), dtype="S"))
    for other in (pa.array(["ab", "abc"]), pa.array(["ab", None]), pa.array(["a\x00", "bc"]),
                  pa.array([1, 2]), pa.array([], pa.string())):
        assert _fixed_width_bytes(other) is None
    np.testing.assert_array_equal(_as_bytes(pa.array(["ab", "abc", "é"])),
                                  np.array([b"ab", b"abc", "é".encode()]))


def test_whether_onsets_are_fixed_is_decided_alike_from_parts_of_the_plan():
    # finalize decides it from plan.parquet batch by batch: the verdict of the whole plan
    from campaign.config import load_config
    from reports.scoring.detection_times import fixed_onset_campaign

    # (parts of one row on the two small plans: on addsafe-mc's 2400 rows they cost 7 s)
    for preset, fixed in (("comb-table1", True), ("addsafe-mc", False), ("smoke", False)):
        plan = build_plan(load_config(preset))
        assert fixed_onset_campaign(plan) is fixed
        for size in (1, 7, 500) if len(plan) <= 100 else (7, 500):
            parts = (plan.iloc[i:i + size] for i in range(0, len(plan), size))
            assert fixed_onset_campaign(parts) is fixed
    # a faulty group whose onsets are all NaN has none: not fixed, in parts too
    plan = build_plan(load_config("comb-table1"))
    plan.loc[plan["fault"] != "none", "onset_s"] = np.nan
    assert not fixed_onset_campaign(plan)
    assert not fixed_onset_campaign(plan.iloc[i:i + 3] for i in range(0, len(plan), 3))


def test_duplicate_runs_name_the_group_of_the_first_repeated_row_across_blocks():
    # the repeated row is the first of a block: its own group is named, not the group of
    # the block before (explicit runs of two groups, blocks of two rows)
    first = {**RUNS[0], "group": "first"}
    cfg = config(ALL_FAULTS[:1], run=[first, RUNS[1], RUNS[1]])
    blocks = PlanBlocks(resolve(cfg), block_rows=2)
    parts = list(blocks)
    assert parts[-1]["group"].tolist() == ["worst"] and len(parts[-1]) == 1
    with pytest.raises(ConfigError, match="duplicate runs in group 'worst'"):
        blocks.check()


def test_run_ids_differing_in_their_last_character_are_two_runs():
    from campaign.plan import RUN_ID_CHARS, DuplicateRuns

    ids = ["a" * (RUN_ID_CHARS - 1) + c for c in "xy"]
    runs = DuplicateRuns(2)
    runs.add(pd.DataFrame({"run_id": ids, "group": ["g", "g"]}))
    runs.check()                                          # nothing raised
    same = DuplicateRuns(3)
    same.add(pd.DataFrame({"run_id": ids + ids[:1], "group": ["g", "g", "h"]}))
    with pytest.raises(ConfigError, match="group 'h'"):
        same.check()
