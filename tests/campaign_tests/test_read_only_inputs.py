"""Every detector reads the signals the plant produced, whatever another detector does:
``fit`` and ``detect`` receive them read-only (zero-copy views whose write flag is off, the
per-run mappings read-only), so a detector that writes into its input fails alone, its
rows recorded as its errors, and the others' rows are those of the campaign without it
(docs/write-a-detector.md, Signals and output)."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.cli.commands import main
from campaign.config import CampaignConfig
from detectors import registry
from detectors.base import FrozenMapping, read_only
from detectors.testing import DetectorCheckError, _batch, check_detector
from plugin_detectors import FitWriter, SignalWriter
from small_campaigns import campaign_toml, small_campaign
from scenarios.signals import SIGNAL_UNITS

WRITERS = {"signal-writer": "SignalWriter", "schedule-writer": "ScheduleWriter",
           "fit-writer": "FitWriter"}


@pytest.fixture
def writers(monkeypatch):
    """Register the writing detectors of tests/plugin_detectors.py (third-party: their
    module lies outside the detectors package)."""
    for name, cls in WRITERS.items():
        monkeypatch.setitem(registry.BUILTIN, name, f"plugin_detectors:{cls}")


def _config(*first) -> dict:
    """A small campaign: the position monitor (which reads command, both rod positions and
    the schedule) runs after the detectors *first* in every chunk."""
    return small_campaign("writers", 77123, first, pm_first=False)


def _results(cfg: dict, out) -> pd.DataFrame:
    return run(CampaignConfig.from_dict(cfg), out, jobs=1, progress=False,
               log=lambda m: None).results


def _rows(results: pd.DataFrame, label: str) -> pd.DataFrame:
    return results[results["detector"] == label].reset_index(drop=True)


# ---- the views ---------------------------------------------------------------------------
def test_read_only_views_share_memory_and_refuse_every_write():
    learn, _ = _batch("elevator", 20.0)
    ro = read_only(learn)
    for name in SIGNAL_UNITS:
        original, view = getattr(learn, name), getattr(ro, name)
        assert np.shares_memory(original, view)          # zero-copy: the same buffer
        assert not view.flags.writeable and original.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            view[0, 0] = 1.0
    assert isinstance(ro.schedule, FrozenMapping)
    for key, values in ro.schedule.items():
        assert np.shares_memory(values, learn.schedule[key])
        with pytest.raises(ValueError, match="read-only"):
            values *= 2.0
    with pytest.raises(TypeError):
        ro.schedule["qbar_pa"] = np.zeros(learn.n_runs)
    assert not ro.run_ids.flags.writeable
    # what a detector does with its input keeps working: sub-batches, truncation, copies
    # (a copy is the reader's own, writeable), pickling (workers receive signals pickled)
    part = ro.take([1]).truncate(50)
    assert part.n_runs == 1 and part.n_steps == 50
    again = pickle.loads(pickle.dumps(ro))
    assert np.array_equal(again.rod_com, learn.rod_com) and dict(again.schedule).keys() \
        == learn.schedule.keys()
    mine = copy.deepcopy(ro)
    mine.schedule["vcas_kt"][0] = 0.0
    mine.rod_com[0, 0] = 0.0
    assert learn.schedule["vcas_kt"][0] != 0.0 and learn.rod_com[0, 0] != 0.0


# ---- a writer among the detectors of a campaign ------------------------------------------
@pytest.fixture(scope="module")
def alone(tmp_path_factory) -> pd.DataFrame:
    """The position monitor's rows of the campaign without any writer (run once)."""
    return _rows(_results(_config(), tmp_path_factory.mktemp("alone")), "pm")


@pytest.mark.parametrize("writer", [
    {"name": "signal-writer", "label": "wr"},
    {"name": "schedule-writer", "label": "wr"},
    {"name": "schedule-writer", "label": "wr", "params": {"how": "assign"}},
], ids=["signals", "schedule-in-place", "schedule-entry"])
def test_a_writer_fails_alone_and_the_others_rows_are_unchanged(tmp_path, writers, writer,
                                                                 alone):
    both = _results(_config(writer), tmp_path / "both")
    # the position monitor, run after the writer on the same signals in every chunk: its
    # rows are those of the campaign without the writer, bit for bit
    pd.testing.assert_frame_equal(alone, _rows(both, "pm"))
    assert (_rows(both, "pm")["status"] == "ok").all()
    wrote = _rows(both, "wr")
    assert len(wrote) == both["run_id"].nunique()
    assert (wrote["status"] == "error").all()
    assert not wrote["false_alarm"].any() and not wrote["detected"].any()
    message = wrote["error"].iloc[0]
    assert "wrote into the signals it was given, which are read-only" in message
    assert "plugin_detectors.py" in message             # the line of the plugin that wrote


def test_without_read_only_inputs_the_writer_corrupts_its_neighbour(tmp_path, writers,
                                                                   monkeypatch, alone):
    """The test above can fail: handed writeable signals (the engine before read-only
    inputs), the same writer turns the position monitor's rows into false alarms."""
    import campaign.evaluate as evaluate

    monkeypatch.setattr(evaluate, "read_only", lambda signals: signals)
    both = _rows(_results(_config({"name": "signal-writer", "label": "wr"}),
                          tmp_path / "both"), "pm")
    free = both["fault"] == "none"
    assert not alone.loc[free, "false_alarm"].any()
    assert both.loc[free, "false_alarm"].all()


def test_a_fit_that_writes_into_the_learning_set_is_refused_naming_it(tmp_path, writers,
                                                                     capsys):
    path = tmp_path / "c.toml"
    path.write_text(campaign_toml(_config({"name": "fit-writer", "label": "fw"})))
    out = tmp_path / "out"
    assert main(["run", str(path), "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "detector 'fw' (FitWriter) failed while fitting on the learning set" in err
    assert "the learning signals are read-only" in err and "Traceback" not in err
    assert not out.exists()


# ---- check_detector ----------------------------------------------------------------------
@pytest.mark.parametrize("detector, check", [(SignalWriter(), "detect_leaves_signals"),
                                             (FitWriter(), "fit_leaves_signals")])
def test_check_detector_names_a_writer(detector, check):
    """check_detector hands the signals read-only; a writer is run again on a copy of its
    own, so the check names what it wrote (signal, run, step) and the other checks still
    judge its output (a writer that is otherwise sound fails this check only)."""
    with pytest.raises(DetectorCheckError) as info:
        check_detector(detector)
    failures = dict(info.value.failures)
    assert list(failures) == [check]
    assert "modified the" in failures[check] and "first at run 0" in failures[check]
    assert "a campaign hands them read-only" in failures[check]
