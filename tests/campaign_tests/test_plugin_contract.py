"""What the engine does with a third-party detector that breaks its contract: the output
of every ``detect`` is checked (shape, dtype, ±inf, NaN only as warm-up) and a breach
becomes ``status="error"`` rows, never scored; ``check_detector`` and scoring agree on NaN
warm-up samples; a batch-dependent detector is refused at campaign start; a non-causal
one is refused; a ``fit`` or a plant that fails on the learning set ends with exit 2
naming it and leaves nothing that looks like a campaign (docs/write-a-detector.md)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.cli.commands import main
from campaign.config import CampaignConfig, ConfigError
from campaign.plan import build_plan
from campaign.runner import CampaignSetupError
from campaign.store.directory import CampaignDir
from detectors import Detection, detection_problems, registry
from detectors.testing import check_detector
from plugin_detectors import BadResidual, BatchMean
from small_campaigns import campaign_toml, small_campaign

PLUGINS = ("Subsampled", "BadResidual", "BatchMean", "Offline", "FitFails", "FitFailsLate",
           "FitsTogether", "NaNLater")


@pytest.fixture
def plugins(monkeypatch):
    """Register the detectors of tests/plugin_detectors.py (kebab-case names)."""
    for cls in PLUGINS:
        name = "".join(f"-{c.lower()}" if c.isupper() else c for c in cls).lstrip("-")
        monkeypatch.setitem(registry.BUILTIN, name, f"plugin_detectors:{cls}")


def _config(*detectors, chunk_size=4) -> dict:
    return small_campaign("plugins", 5, detectors, runner={"chunk_size": chunk_size})


# ---- the rule itself -----------------------------------------------------------------------
def test_detection_problems_rule():
    ok = np.zeros((2, 10), bool)
    res = np.full((2, 10), 0.5)
    assert detection_problems(Detection(ok, res), 2, 10) == []
    warm = res.copy()
    warm[:, :3] = np.nan
    warm[1, :] = np.nan                    # a run still warming up at its end: allowed
    assert detection_problems(Detection(ok, warm), 2, 10) == []
    short = detection_problems(Detection(ok[:, :9], res[:, :9]), 2, 10)
    assert any("(2, 10), got (2, 9)" in p for p in short)
    late = warm.copy()
    late[0, 6] = np.nan
    (msg,) = detection_problems(Detection(ok, late), 2, 10)
    assert "NaN is allowed only before the first non-NaN sample" in msg and "step 6" in msg
    inf = res.copy()
    inf[1, 4] = -np.inf
    (msg,) = detection_problems(Detection(ok, inf), 2, 10)
    assert "±inf" in msg and "run 1, step 4" in msg
    (msg,) = detection_problems(Detection(ok, np.zeros((2, 10), int)), 2, 10)
    assert "float" in msg


def test_check_detector_and_scoring_agree_on_warm_up_nan():
    """NaN warm-up samples pass check_detector (as scoring accepts them); ±inf and a NaN
    after the warm-up fail its output_types check."""
    check_detector(BadResidual(warm_up=5))
    for value in (np.inf, np.nan):
        with pytest.raises(AssertionError, match="output_types"):
            check_detector(BadResidual(warm_up=5, value=value, step=50))


# ---- breaches in a campaign ----------------------------------------------------------------
def test_contract_breaches_become_error_rows(tmp_path, plugins):
    cfg = _config()
    plan = build_plan(CampaignConfig.from_dict(cfg))
    bad_runs = list(plan["run_id"].iloc[[1, 4]])
    cfg["detector"] += [
        {"name": "subsampled", "label": "short", "params": {"cut": 1}},
        {"name": "subsampled", "label": "tenth", "params": {"every": 10}},
        {"name": "bad-residual", "label": "inf", "params": {"value": "inf",
                                                            "runs": bad_runs}},
        {"name": "bad-residual", "label": "late-nan", "params": {"warm_up": 3,
                                                                 "value": "nan"}},
        {"name": "bad-residual", "label": "warm-up", "params": {"warm_up": 20}},
    ]
    result = run(CampaignConfig.from_dict(cfg), tmp_path / "out", jobs=1, progress=False,
                 log=lambda m: None)
    rows = result.results.set_index(["detector", "run_id"])
    n = len(plan)
    for label, rule in (("short", "(1, 2000), got (1, 1999)"), ("tenth", "got (1, 200)"),
                        ("late-nan", "NaN is allowed only before")):
        got = rows.loc[label]
        assert (got["status"] == "error").all() and len(got) == n, label
        msg = got["error"].iloc[0]
        assert f"detector {label!r}" in msg and rule in msg
        assert "check_detector" in msg and "seen: alarm" in msg
    inf = rows.loc["inf"]
    assert set(inf.index[inf["status"] == "error"]) == set(bad_runs)
    assert "±inf" in inf.loc[bad_runs[0], "error"]
    assert (rows.loc["warm-up", "status"] == "ok").all()     # warm-up NaN: scored
    assert (rows.loc["pm", "status"] == "ok").all()
    # never scored: no false alarm, no detection on a breached run
    bad = result.results[result.results["status"] == "error"]
    assert not bad["false_alarm"].any() and not bad["detected"].any()


def test_a_residual_that_turns_nan_mid_run_gets_no_ok_row_and_fails_the_gate(tmp_path,
                                                                            plugins, capsys):
    """A detector whose residual blows up to NaN half-way through every run, in every batch
    of the campaign (not only the few runs of the start-up checks), has every row an error
    naming the breach, never an ok row without alarm; the zero-false-alarm gate fails."""
    cfg = _config({"name": "na-n-later", "label": "blow-up"}, chunk_size=2)
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(cfg))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "2", "--quiet", "--out", str(out)]) in (0, 1)
    rows = CampaignDir(out).read_results()
    mine = rows[rows["detector"] == "blow-up"]
    assert len(mine) == len(build_plan(CampaignConfig.from_dict(cfg)))
    assert (mine["status"] == "error").all()
    assert mine["error"].str.contains("NaN is allowed only before").all()
    assert (rows.loc[rows["detector"] == "pm", "status"] == "ok").all()
    capsys.readouterr()
    assert main(["gate", str(out), "--max-fa", "0"]) == 1
    assert "blow-up" in capsys.readouterr().out


def test_well_behaved_results_unchanged_by_the_check(tmp_path, plugins):
    """The built-in detector's rows are the same with and without a breaching neighbour."""
    alone = run(CampaignConfig.from_dict(_config()), tmp_path / "a", jobs=1, progress=False,
                log=lambda m: None).results
    cfg = _config({"name": "subsampled", "label": "short", "params": {"cut": 1}})
    both = run(CampaignConfig.from_dict(cfg), tmp_path / "b", jobs=1, progress=False,
               log=lambda m: None).results
    pd.testing.assert_frame_equal(alone.reset_index(drop=True),
                                  both[both["detector"] == "pm"].reset_index(drop=True))


# ---- refused before any run ----------------------------------------------------------------
def test_batch_dependent_detector_refused_at_start(tmp_path, plugins, capsys):
    from campaign.config import load_config  # noqa: F401  (the CLI path below)

    cfg = _config({"name": "batch-mean", "label": "bm"})
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(cfg))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "detector 'bm' (BatchMean) is not batch-invariant" in err
    assert "--chunk-size" in err and "check_detector" in err
    assert not out.exists()


def test_batch_check_skips_built_in_detectors(plugins):
    from campaign.runner import third_party
    from detectors import make_detector

    assert not third_party(make_detector("position-monitor"))
    assert third_party(BatchMean())


def test_offline_detector_refused(plugins):
    with pytest.raises(ConfigError, match=r"causal=False.*online detection"):
        CampaignConfig.from_dict(_config({"name": "offline"}))


def test_fit_failure_exit_2_and_nothing_left(tmp_path, plugins, capsys):
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(_config({"name": "fit-fails", "label": "ff-det"})))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "detector 'ff-det' (FitFails) failed while fitting on the learning set" in err
    assert "RuntimeError: singular matrix" in err and "Traceback" not in err
    assert not out.exists()
    empty = tmp_path / "empty"           # an empty directory given: emptied again
    empty.mkdir()
    assert main(["run", str(path), "--jobs", "1", "--quiet", "--out", str(empty)]) == 2
    assert empty.is_dir() and not any(empty.iterdir())


def test_the_fit_failure_reported_is_the_first_in_the_campaign_order(tmp_path, plugins, capsys):
    # 'late' fits on a worker thread and fails after 'soon', fitted here, has failed: the
    # error still names 'late', the first in the campaign's order, as one fit at a time would
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(_config({"name": "fit-fails-late", "label": "late"},
                                          {"name": "fit-fails", "label": "soon"})))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "2", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "detector 'late' (FitFailsLate) failed while fitting" in err
    assert "'soon'" not in err
    assert not out.exists()


def test_detectors_that_say_so_fit_at_the_same_time(tmp_path, plugins):
    # each fit waits for the other at a barrier: the campaign runs only if both fit at once
    import plugin_detectors

    plugin_detectors.FIT_BARRIER.reset()
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(_config({"name": "fits-together", "label": "a"},
                                          {"name": "fits-together", "label": "b"})))
    assert main(["run", str(path), "--jobs", "2", "--quiet", "--out", str(tmp_path / "o")]) == 0


def test_plant_failure_in_learning_names_the_plant(tmp_path, monkeypatch, capsys):
    import campaign.runner as runner

    def broken(*args, **kwargs):
        raise RuntimeError("solver diverged")

    monkeypatch.setattr(runner, "simulate_chunks", broken)
    out = tmp_path / "out"
    assert main(["run", "smoke", "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "the actuator plant failed while simulating the learning set" in err
    assert "RuntimeError: solver diverged" in err
    assert not out.exists()


def test_setup_error_in_a_resumable_campaign_keeps_it(tmp_path, monkeypatch):
    """A campaign directory that already holds this campaign is left as it was."""
    import campaign.runner as runner

    cfg = CampaignConfig.from_dict(_config())
    out = tmp_path / "out"
    run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    monkeypatch.setattr(runner, "_learn", lambda *a, **k: (_ for _ in ()).throw(
        CampaignSetupError("learning failed")))
    with pytest.raises(CampaignSetupError):
        run(cfg, out, jobs=1, progress=False, log=lambda m: None)
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_plugin_whose_module_fails_on_import_is_named_exit_2(tmp_path, monkeypatch, capsys):
    """A third-party detector whose module raises on import (here a parameter declaration
    the contract refuses) is the plugin's failure, named with exit 2 before any run, not an
    internal error of the engine."""
    (tmp_path / "broken_plugin.py").write_text(
        "from detectors import Detector, Param\n"
        "class Broken(Detector):\n"
        "    parameters = (Param('gain', 'float', gt=0.0, choices=('a',)),)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_entry_point_specs", lambda: {"broken": "broken_plugin:Broken"})
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(_config({"name": "broken"})))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "detector 'broken' (broken_plugin:Broken, a third-party detector) fails when its " \
           "module is imported: ValueError: Param 'gain'" in err
    assert "internal error" not in err and not out.exists()


def test_certify_names_the_detectors_whose_margin_is_a_residual(plugins):
    """A plugin without a decision statistic (no threshold_scale) has the margin of its
    residual before confirmation: certify names it; the built-in monitor it does not."""
    from campaign.cli.evidence import residual_margin_note

    assert residual_margin_note(_config()) == ""
    note = residual_margin_note(_config({"name": "bad-residual", "label": "plug"}))
    assert note.startswith("margins of plug:") and "pm" not in note.split(":")[0]
    assert "no decision statistic" in note
