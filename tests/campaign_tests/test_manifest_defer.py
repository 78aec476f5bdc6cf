"""The runner records its shards in the manifest a few seconds at a time
(campaign/store/directory.py, ``MANIFEST_DEFER_S``): the manifest is rewritten whole, so a
rewrite per shard grows with the square of the shards. The manifest still never claims a
shard that is not there; a shard a crash leaves out of it is removed on resume and its runs
are run again, with the same rows."""

from __future__ import annotations

import json

import pandas as pd

from campaign import run
from campaign.config import CampaignConfig
from campaign.store import directory
from campaign.store.directory import CampaignDir
from small_campaigns import small_campaign


def config(chunk_size: int = 1) -> CampaignConfig:
    # 8 runs (3 fault-free in each of two manoeuvres, 2 runaways) in chunks of one run: 8 shards
    return CampaignConfig.from_dict(small_campaign("defer", 31, [], runner={"chunk_size":
                                                                             chunk_size}))


def rows(out) -> pd.DataFrame:
    frame = pd.read_parquet(out / "runs")
    return frame.sort_values(["run_id", "detector"]).reset_index(drop=True)


def test_a_campaign_rewrites_its_manifest_once_for_its_shards(tmp_path, monkeypatch):
    monkeypatch.setattr(directory, "MANIFEST_DEFER_S", 1e9)
    writes = []
    original = CampaignDir._write_manifest

    def counted(self):
        writes.append(sorted(r for r in self._manifest["files"] if r.startswith("runs/")))
        original(self)

    monkeypatch.setattr(CampaignDir, "_write_manifest", counted)
    out = tmp_path / "out"
    run(config(), out, jobs=1, progress=False)
    shards = sorted(f"runs/{p.name}" for p in (out / "runs").glob("part-*.parquet"))
    assert len(shards) == 8
    with_shards = [w for w in writes if w]
    assert with_shards[0] == shards            # the first rewrite that has shards has all 8
    assert CampaignDir(out).verify() == []
    assert set(json.loads((out / "manifest.json").read_text())["files"]) >= set(shards)


def test_shards_a_crash_left_out_of_the_manifest_are_run_again(tmp_path, monkeypatch):
    straight = tmp_path / "straight"
    run(config(), straight, jobs=1, progress=False)
    # a campaign killed before its manifest took its last shards: the shards are on disk,
    # the manifest lists only the first three
    out = tmp_path / "out"
    run(config(), out, jobs=1, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    late = sorted(r for r in manifest["files"] if r.startswith("runs/"))[3:]
    for rel in late:
        del manifest["files"][rel]
    for name in ("summary.parquet",):
        manifest["files"].pop(name, None)
        (out / name).unlink()
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    notes = []
    resumed = run(config(), out, jobs=1, progress=False, log=notes.append)
    assert sum("was written but not recorded" in n for n in notes) == len(late) == 5
    assert CampaignDir(out).verify() == []
    pd.testing.assert_frame_equal(rows(out), rows(straight), check_exact=True)
    assert resumed.summary.equals(pd.read_parquet(straight / "summary.parquet"))
