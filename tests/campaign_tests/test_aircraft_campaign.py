"""Campaigns at the aircraft plant level: the campaign-file keys, the plan, a small run
end to end and the command line."""

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.cli.commands import main
from campaign.config import CampaignConfig, ConfigError
from campaign.plan import build_plan


def _tiny(plant_section=None, **campaign):
    data = {
        "campaign": {"name": "tiny-aircraft", "seed": 3, "duration_s": 20.0, **campaign},
        "plant": plant_section or {},
        "faults": {"onset_min_s": 8.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "turn_coordination"],
             "count": 2},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 2},
        "runner": {"chunk_size": 12},          # one batch per set: fast
    }
    return CampaignConfig.from_dict(data)


AIRCRAFT = {"kind": "aircraft"}


def test_plant_defaults_to_actuator_and_aircraft_names_the_monitored_surface():
    assert _tiny().plant.kind == "actuator"
    plan = build_plan(_tiny(AIRCRAFT))
    assert set(plan["surface"]) == {"left_elevator"}           # default: left of "elevator"
    plan_a = build_plan(_tiny({**AIRCRAFT, "monitored_surface": "right_outboard_aileron"},
                              surface="aileron"))
    assert set(plan_a["surface"]) == {"right_outboard_aileron"}
    # another plant level never reuses the results of the first (run ids differ)
    assert not set(plan["run_id"]) & set(build_plan(_tiny())["run_id"])


def test_old_spellings_of_the_plant_keys_still_work_with_a_note():
    """Campaign files written with [campaign] plant / monitored_surface keep working: the
    same configuration as the new [plant] spelling, and a one-line note naming it."""
    with pytest.warns(FutureWarning) as notes:
        old = _tiny(plant="aircraft", monitored_surface="rudder")
    assert old == _tiny({"kind": "aircraft", "monitored_surface": "rudder"})
    assert [str(n.message) for n in notes] == [
        "[campaign] plant is now [plant] kind; the old spelling still works",
        "[campaign] monitored_surface is now [plant] monitored_surface; the old spelling "
        "still works"]
    with pytest.raises(ConfigError, match="campaign.plant: old spelling of plant.kind"):
        _tiny({"kind": "actuator"}, plant="aircraft")


@pytest.mark.parametrize("plant, needle", [
    ({"monitored_surface": "left_elevator"}, "only used with kind = \"aircraft\""),
    ({**AIRCRAFT, "monitored_surface": "left_inbord_aileron"},
     "did you mean 'left_inboard_aileron'"),
    ({"kind": "airframe"}, "allowed: actuator, aircraft"),
    ({**AIRCRAFT, "fmu": "servo.fmu"}, "an FMU replaces the single actuator servo-loop"),
])
def test_bad_plant_keys_are_reported(plant, needle):
    with pytest.raises(ConfigError) as info:
        _tiny(plant)
    assert needle in str(info.value)


def test_plan_and_run_refuse_an_aircraft_detector_on_the_actuator_plant(tmp_path, capsys):
    """Compatibility is checked in one place: ``plan`` refuses what ``run`` refuses, with
    the same message, before anything is written."""
    path = tmp_path / "vanek-on-actuator.toml"
    path.write_text('''
[campaign]
name = "vanek-on-actuator"
duration_s = 20.0
[[group]]
fault = "none"
count = 1
[[detector]]
name = "vanek-geometric"
''')
    messages = []
    for command in ("plan", "run"):
        out = tmp_path / command
        assert main([command, str(path), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        messages.append(err)
        assert not out.exists()
    assert messages[0] == messages[1]
    assert ("detector[0].name: detector 'vanek-geometric' reads the aircraft sensors and "
            "every surface's rod, which the actuator plant does not simulate; fix: set "
            "[plant] kind = \"aircraft\"") in messages[0]


def test_aircraft_campaign_runs_end_to_end(tmp_path):
    """A small aircraft-level campaign: every run ok, the existing position monitor detects
    the runaways of the monitored left elevator and stays quiet on the fault-free runs."""
    res = run(_tiny(AIRCRAFT), tmp_path / "out", jobs=1, progress=False)
    r = res.results
    assert (r["status"] == "ok").all()
    assert not r.loc[r.fault == "none", "false_alarm"].any()
    assert r.loc[r.fault == "runaway", "detected"].all()


def test_simulate_command_aircraft_plant(tmp_path, capsys):
    out, png = tmp_path / "run.parquet", tmp_path / "run.png"
    assert main(["simulate", "--plant", "aircraft", "--surface", "aileron", "--fault",
                 "disconnection", "--duration", "20", "--out", str(out), "--plot", str(png)]) == 0
    frame = pd.read_parquet(out)
    assert {"p [deg/s]", "nz [g]", "true_rudder [deg]", "rod_left_elevator [mm]"} <= set(frame)
    assert np.isnan(frame["surface [deg]"]).all()        # no sensor on the inboard aileron
    assert png.stat().st_size > 10_000
    assert main(["simulate", "--surface", "left_elevator"]) == 2
    assert "--plant aircraft" in capsys.readouterr().err


def test_report_resimulates_an_aircraft_campaign_on_its_plant(tmp_path):
    """The report re-simulates runs on the campaign's plant level: on the actuator level
    instead, an aircraft campaign's margins would differ (other orders, other noise draws)."""
    from campaign.report_build import build_report

    out = tmp_path / "out"
    run(_tiny(AIRCRAFT), out, jobs=1, progress=False)
    page = build_report(out, jobs=1, log=lambda _: None).read_text()
    assert "reproduce the stored ones of all 4 runs (largest difference 0.0e+00)" in page
    assert 'class="warn"' not in page


def test_turbulence_option_of_plan_and_run(tmp_path, capsys):
    """``--turbulence none`` sets [plant] turbulence (docs/physics.md §7.2): written into the
    campaign the plan records; on the actuator plant it is refused before any work
    (exit code 2, the key and the fix named)."""
    from campaign.store.directory import read_metadata

    out = tmp_path / "calm"
    assert main(["plan", "chen-mc", "--turbulence", "none", "--out", str(out)]) == 0
    config = read_metadata(out / "plan.parquet")["config"]
    assert config["plant"]["turbulence"] == "none"
    bad = tmp_path / "bad"
    assert main(["plan", "smoke", "--turbulence", "none", "--out", str(bad)]) == 2
    assert ("plant.turbulence: only used with kind = \"aircraft\"; fix: remove it or set "
            "[plant] kind = \"aircraft\"") in capsys.readouterr().err
    assert not bad.exists()
