"""Campaigns at the aircraft plant level: the campaign-file keys, the plan, a small run
end to end and the command line."""

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.cli import main
from campaign.config import CampaignConfig, ConfigError
from campaign.design import build_plan


def _tiny(**campaign):
    data = {
        "campaign": {"name": "tiny-aircraft", "seed": 3, "duration_s": 20.0, **campaign},
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


def test_plant_defaults_to_actuator_and_aircraft_names_the_monitored_surface():
    assert _tiny().campaign.plant == "actuator"
    plan = build_plan(_tiny(plant="aircraft"))
    assert set(plan["surface"]) == {"left_elevator"}           # default: left of "elevator"
    plan_a = build_plan(_tiny(plant="aircraft", surface="aileron",
                              monitored_surface="right_outboard_aileron"))
    assert set(plan_a["surface"]) == {"right_outboard_aileron"}
    # another plant level never reuses the results of the first (run ids differ)
    assert not set(plan["run_id"]) & set(build_plan(_tiny())["run_id"])


@pytest.mark.parametrize("campaign, needle", [
    ({"monitored_surface": "left_elevator"}, "only used with plant = \"aircraft\""),
    ({"plant": "aircraft", "monitored_surface": "left_inbord_aileron"},
     "did you mean 'left_inboard_aileron'"),
    ({"plant": "airframe"}, "allowed: actuator, aircraft"),
])
def test_bad_plant_keys_are_reported(campaign, needle):
    with pytest.raises(ConfigError) as info:
        _tiny(**campaign)
    assert needle in str(info.value)


def test_aircraft_campaign_runs_end_to_end(tmp_path):
    """A small aircraft-level campaign: every run ok, the existing position monitor detects
    the runaways of the monitored left elevator and stays quiet on the fault-free runs."""
    res = run(_tiny(plant="aircraft"), tmp_path / "out", jobs=1, progress=False)
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
    from campaign.report import build_report

    out = tmp_path / "out"
    run(_tiny(plant="aircraft"), out, jobs=1, progress=False)
    page = build_report(out, jobs=1, log=lambda _: None).read_text()
    assert "reproduce the stored ones of all 4 runs (largest difference 0.0e+00)" in page
    assert 'class="warn"' not in page
