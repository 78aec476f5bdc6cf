"""Reading a campaign directory never loads native code it names: ``report`` and ``show`` on
an FMU-plant campaign re-simulate only on an FMU named on the command line (``--fmu``)
whose SHA-256 is the one recorded at run time, and otherwise show what needs no simulation
and say how to get the rest (docs/security.md)."""

from __future__ import annotations

import shutil
import sys

import pytest

from campaign import run
from campaign.cli.commands import main
from campaign.config import load_config, with_overrides
from campaign.store.files import sha256_of
from campaign.plant_setup import replay_plant
from campaign.store.directory import CampaignDir
from scenarios.fmu_files import FmuError
from scenarios.plants import get_plant

#: (event, first argument) of the audit events "open" and "ctypes.dlopen" while recording
#: (None: not recording). Audit hooks cannot be removed, so one is added once per session.
_EVENTS: list | None = None
_HOOKED = False


def _hook(event, args):
    if _EVENTS is not None and event in ("open", "ctypes.dlopen") and args:
        _EVENTS.append((event, str(args[0])))


class _Recording:
    """Every file opened and every shared library loaded inside the ``with`` block."""

    def __enter__(self):
        global _EVENTS, _HOOKED
        if not _HOOKED:
            sys.addaudithook(_hook)
            _HOOKED = True
        _EVENTS = []
        return self

    def __exit__(self, *exc):
        global _EVENTS
        self.events, _EVENTS = _EVENTS, None

    def touched(self, *needles) -> list:
        """The events whose path holds one of *needles*, or is a shared library of an
        FMU (its ``binaries/`` folder, where fmpy loads the model's code from)."""
        return [(e, p) for e, p in self.events
                if any(n in p for n in needles) or (e == "ctypes.dlopen" and "binaries" in p)]


@pytest.fixture(scope="module")
def fmu_campaign(servo_fmu, tmp_path_factory):
    """The smoke campaign run on a copy of the servo FMU at plant/servo.fmu; then a
    *different* FMU (the aileron's parameter table: another file, another SHA-256) is
    planted at that recorded path."""
    root = tmp_path_factory.mktemp("replay")
    from scenarios.fmu_build import build_servo_fmu

    other = build_servo_fmu(root / "other.fmu", surface="aileron")
    recorded = root / "plant" / "servo.fmu"
    recorded.parent.mkdir()
    shutil.copy(servo_fmu, recorded)
    config = with_overrides(load_config("smoke"), values={"plant.fmu": str(recorded)})
    out = root / "out"
    result = run(config, out, jobs=1, progress=False, log=lambda m: None)
    assert result.complete and (result.results["status"] == "ok").all()
    shutil.copy(other, recorded)                       # the planted FMU
    assert sha256_of(recorded) != sha256_of(servo_fmu)
    return {"out": out, "planted": recorded, "servo": servo_fmu, "result": result}


def test_the_run_records_the_digest_of_its_fmu(fmu_campaign):
    _, meta = CampaignDir(fmu_campaign["out"]).read_summary()
    assert meta["fmu_sha256"] == sha256_of(fmu_campaign["servo"])


def test_report_and_show_without_fmu_load_nothing_and_say_how(fmu_campaign, capsys,
                                                              tmp_path):
    out, planted = fmu_campaign["out"], str(fmu_campaign["planted"])
    run_id = str(fmu_campaign["result"].plan["run_id"].iloc[0])
    html = tmp_path / "report.html"
    with _Recording() as rec:
        assert main(["report", str(out), "--jobs", "1", "--html", str(html)]) == 0
        assert main(["show", str(out), run_id]) == 0
    assert rec.touched(planted) == []
    captured = capsys.readouterr()
    page = html.read_text()
    assert "--fmu FILE" in page and "Residual envelope" not in page
    assert "Margin to false alarm" in page               # what needs no simulation is there
    assert "position-monitor: stored margin" in captured.out
    assert "--fmu FILE" in captured.out and sha256_of(fmu_campaign["servo"]) in captured.out
    # traces cannot be written without re-simulating: refused before any work
    plot = tmp_path / "run.png"
    assert main(["show", str(out), run_id, "--plot", str(plot)]) == 2
    assert "--plot and --out need the run's traces" in capsys.readouterr().err
    assert not plot.exists()


def test_a_named_fmu_is_checked_against_the_recorded_digest(fmu_campaign, capsys):
    out, planted = fmu_campaign["out"], str(fmu_campaign["planted"])
    run_id = str(fmu_campaign["result"].plan["run_id"].iloc[0])
    with _Recording() as rec:
        assert main(["show", str(out), run_id, "--fmu", planted]) == 2
    err = capsys.readouterr().err
    assert "is not that of the FMU" in err and sha256_of(fmu_campaign["servo"]) in err
    assert [e for e, _ in rec.touched(planted) if e == "ctypes.dlopen"] == []


def test_the_recorded_fmu_named_on_the_command_line_re_simulates(fmu_campaign, capsys,
                                                                  tmp_path):
    """The FMU the campaign ran on, named with --fmu: loaded (the recording sees its shared
    library, which shows the recording would see the planted one), and the re-simulated
    run and envelopes reproduce the stored margins. A fresh copy (same bytes, same digest)
    is named, so that no FMU an earlier test left loaded in this process stands in for it."""
    out = fmu_campaign["out"]
    servo = str(shutil.copy(fmu_campaign["servo"], tmp_path / "servo-copy.fmu"))
    run_id = str(fmu_campaign["result"].plan["run_id"].iloc[0])
    with _Recording() as rec:
        assert main(["show", str(out), run_id, "--fmu", servo]) == 0
    assert any(e == "ctypes.dlopen" for e, _ in rec.touched(servo))
    assert "re-simulated margin" in capsys.readouterr().out
    html = tmp_path / "report.html"
    assert main(["report", str(out), "--jobs", "1", "--html", str(html), "--fmu", servo]) == 0
    page = html.read_text()
    assert "Residual envelope" in page and "reproduce the stored ones" in page


def test_fmu_option_on_a_built_in_plant_is_refused():
    with pytest.raises(FmuError, match="built-in actuator plant, not on an FMU"):
        replay_plant(get_plant("actuator"), None, "servo.fmu")
    plant = get_plant("actuator")
    assert replay_plant(plant, None, None) == (plant, "")
