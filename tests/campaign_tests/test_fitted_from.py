"""Separating a detector from its learning set: ``fdd-campaign run … --fitted-from DIR``
evaluates the detectors fitted in DIR without learning again, records their SHA-256 in the
summary's metadata and copies their files; ``compare`` says whether two campaigns share
fitted detectors and, when not, which thresholds were re-learned (docs/thresholds.md)."""

from __future__ import annotations

import json

import pytest

from campaign import run
from campaign.cli.commands import main
from campaign.config import load_config
from campaign.runner import CampaignSetupError
from campaign.store.directory import CampaignDir, read_metadata


@pytest.fixture(scope="module")
def smoke_dirs(tmp_path_factory):
    """Three smoke campaigns: A (seed 0), B (seed 1, fitted on its own learning set) and C
    (seed 1, the detectors fitted in A)."""
    root = tmp_path_factory.mktemp("fitted")
    a, b, c = root / "A", root / "B", root / "C"
    assert main(["run", "smoke", "--out", str(a), "--quiet", "--jobs", "1"]) == 0
    assert main(["run", "smoke", "--seed", "1", "--out", str(b), "--quiet", "--jobs", "1"]) == 0
    assert main(["run", "smoke", "--seed", "1", "--fitted-from", str(a), "--out", str(c),
                 "--quiet", "--jobs", "1"]) == 0
    return a, b, c


def _thresholds(path):
    doc = json.loads((path / "fitted" / "position-monitor.json").read_text())
    return doc["learned"]["thresholds_mm_"]


def test_fitted_from_copies_the_fitted_files_and_records_their_hash(smoke_dirs):
    a, b, c = smoke_dirs
    labels = ["position-monitor"]
    sha_a, sha_c = CampaignDir(a).fitted_sha256(labels), CampaignDir(c).fitted_sha256(labels)
    assert sha_a == sha_c != CampaignDir(b).fitted_sha256(labels)
    for d, sha in ((a, sha_a), (c, sha_c)):
        meta = read_metadata(d / "summary.parquet")
        assert meta["fitted_sha256"] == sha
    assert read_metadata(c / "summary.parquet")["fitted_from"] == str(a.resolve())
    assert read_metadata(a / "summary.parquet")["fitted_from"] is None
    assert (c / "fitted" / "position-monitor.npz").read_bytes() == \
        (a / "fitted" / "position-monitor.npz").read_bytes()
    assert (c / "learning.parquet").read_bytes() == (a / "learning.parquet").read_bytes()
    assert CampaignDir(c).verify() == []          # self-contained and in its manifest
    assert _thresholds(c) == _thresholds(a) != _thresholds(b)


def test_compare_names_relearned_thresholds_or_the_shared_state(smoke_dirs, capsys):
    a, b, c = smoke_dirs
    assert main(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "fitted detectors: not shared" in out and "thresholds were re-learned" in out
    ta, tb = _thresholds(a), _thresholds(b)
    for check in ta:
        assert f"thresholds_mm_['{check}']: {ta[check]:.6g} → {tb[check]:.6g}" in out
    assert main(["compare", str(a), str(c)]) == 0
    out = capsys.readouterr().out
    assert "fitted detectors: shared" in out and "re-learned" not in out
    assert "thresholds_mm_ = {" + ", ".join(f"{k}: {v:.6g}" for k, v in ta.items()) + "}" in out


def test_fitted_from_refuses_other_detectors(smoke_dirs, tmp_path, capsys):
    a, _, _ = smoke_dirs
    other = tmp_path / "other.toml"
    data = load_config("smoke").to_dict()
    data["detector"] = [{"name": "position-monitor", "params": {"safety": 2.0}}]
    from campaign.config import CampaignConfig

    config = CampaignConfig.from_dict(data)
    with pytest.raises(CampaignSetupError, match=r"detector\[0\]\.params"):
        run(config, tmp_path / "out", jobs=1, progress=False, log=lambda m: None,
            fitted_from=a)
    assert not (tmp_path / "out").exists()          # nothing left behind
    other.write_text('[campaign]\nname = "x"\nduration_s = 30.0\n'
                     '[[group]]\nfault = "none"\nmanoeuvres = ["cruise"]\ncount = 1\n'
                     '[[detector]]\nname = "position-monitor"\nlabel = "pm"\n')
    assert main(["run", str(other), "--fitted-from", str(a), "--out",
                 str(tmp_path / "out2"), "--quiet"]) == 2
    assert "not this campaign's [[detector]] entries" in capsys.readouterr().err
    assert main(["run", "smoke", "--fitted-from", str(tmp_path), "--out",
                 str(tmp_path / "out3"), "--quiet"]) == 2
    assert "not a campaign directory" in capsys.readouterr().err


def test_a_resumed_directory_keeps_the_adopted_detectors(smoke_dirs, tmp_path):
    a, b, c = smoke_dirs
    # rerunning C without --fitted-from resumes it with A's detectors (nothing to do)
    assert main(["run", "smoke", "--seed", "1", "--out", str(c), "--quiet"]) == 0
    assert _thresholds(c) == _thresholds(a)
    # B holds its own fitted detectors: adopting A's into it is refused
    assert main(["run", "smoke", "--seed", "1", "--fitted-from", str(a), "--out", str(b),
                 "--quiet"]) == 2
