"""Campaigns on the JSBSim plant ([plant] kind = "jsbsim", docs/aircraft.md §9): the
campaign-file keys, and a small campaign whose rows are the same at one and two workers."""

import pandas as pd
import pytest

from campaign.config import CampaignConfig, ConfigError


def _tiny(plant=None, **campaign):
    return CampaignConfig.from_dict({
        "campaign": {"name": "tiny-jsbsim", "seed": 5, "duration_s": 20.0,
                     "surface": "aileron", **campaign},
        "plant": {"kind": "jsbsim", **(plant or {})},
        "faults": {"onset_min_s": 4.0, "onset_before_end_s": 15.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "turn_coordination"],
             "count": 1},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": [{"name": "position-monitor"}],
        # the learning set on the plan's two manoeuvres (default: all six, 6 JSBSim runs)
        "learning": {"runs_per_manoeuvre": 1, "manoeuvres": ["cruise", "turn_coordination"]},
        "runner": {"chunk_size": 2},
    })


@pytest.mark.parametrize("plant, needle", [
    ({"aircraft": "A380"}, "plant.aircraft: unknown aircraft 'A380'; allowed: 737"),
    ({"kind": "aircraft", "aircraft": "B747"}, "plant.aircraft: unknown aircraft 'B747'"),
    ({"fmu": "servo.fmu"}, ("an FMU replaces the single actuator servo-loop, but [plant] kind "
                            "= \"jsbsim\"")),
])
def test_bad_jsbsim_plant_keys_are_reported(plant, needle):
    with pytest.raises(ConfigError) as info:
        _tiny(plant)
    assert needle in str(info.value)


def test_the_jsbsim_plant_is_built_from_its_section():
    pytest.importorskip("jsbsim")
    from campaign.plant_setup import plant_of, run_surface

    config = _tiny({"turbulence": "none"})
    plant = plant_of(config)
    assert (plant.kind, plant.aircraft, plant.turbulence) == ("jsbsim", "737", "none")
    assert run_surface(config, plant) == "left_inboard_aileron"
    assert plant.needs_processes


@pytest.mark.slow
def test_jsbsim_campaign_rows_are_the_same_at_one_and_two_workers(tmp_path):
    """Every run ok, and the result rows identical at --jobs 1 and 2 (an FDM per run, in
    worker processes): a run's rows are a function of its plan row only."""
    pytest.importorskip("jsbsim")
    from campaign import run

    one = run(_tiny(), tmp_path / "one", jobs=1, progress=False).results
    two = run(_tiny(), tmp_path / "two", jobs=2, progress=False).results
    assert (one["status"] == "ok").all() and len(one) == 4
    key = ["run_id", "detector"]
    pd.testing.assert_frame_equal(one.sort_values(key).reset_index(drop=True),
                                  two.sort_values(key).reset_index(drop=True))
    assert one.loc[one.fault == "runaway", "detected"].all()
    assert not one.loc[one.fault == "none", "false_alarm"].any()


def test_falsify_leaves_the_manoeuvre_start_to_the_pilot_model_on_jsbsim():
    """As on our aircraft, the pilot model places each manoeuvre: not a search variable."""
    from campaign.evidence.falsify import search_space

    assert "manoeuvre_start_s" not in search_space(_tiny()).bounds
    assert "manoeuvre_start_s" in search_space(_tiny({"kind": "actuator"})).bounds


def test_a_jsbsim_campaign_without_jsbsim_exits_2_naming_the_extra(tmp_path, monkeypatch,
                                                                    capsys):
    import sys

    from campaign.cli.commands import main

    monkeypatch.setitem(sys.modules, "jsbsim", None)          # as if not installed
    out = tmp_path / "out"
    assert main(["run", "jsbsim-mc", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert 'the jsbsim plant needs the JSBSim package' in err
    assert 'pip install -e ".[jsbsim]"' in err
