"""The census of the control laws' surface activity (campaign.tools.studies.saturation,
``fdd-campaign study saturation``, docs/aircraft.md §5)."""

import numpy as np
import pandas as pd
import pytest

from campaign.cli.commands import main
from campaign.tools.studies import saturation
from scenarios.aircraft.loop import AircraftPlant
from scenarios.simulate import single_run


def test_run_statistics_counts_saturated_samples_and_the_rms_rate():
    """A run whose current sits at +i_max for 6 of its 100 samples saturates, more than 5 %
    of the time; one at 0.999·i_max does not. A surface ramping at 2 deg/s has an RMS rate
    of 2 deg/s and its extreme deflections at the ends of the ramp."""
    current = np.zeros((2, 100))
    current[0, 10:16] = 10.0
    current[1, :] = 9.99
    delta = np.tile(np.arange(100) * 0.02 - 1.0, (2, 1))       # 2 deg/s at ts = 0.01 s
    stats = saturation.run_statistics(current, 10.0, delta, 0.01)
    assert list(stats["sat_any"]) == [True, False]
    assert stats["sat_share"].tolist() == [0.06, 0.0]
    assert stats["sat_share"][0] > saturation.LONG_SATURATION
    np.testing.assert_allclose(np.sqrt(stats["rate_sq"] / stats["rate_n"]), 2.0, rtol=1e-12)
    np.testing.assert_allclose(stats["delta_min_deg"], -1.0)
    np.testing.assert_allclose(stats["delta_max_deg"], 0.98)


def test_no_saturation_in_cruise_at_the_corner_where_the_fixed_law_saturated():
    """The low-q̄, light, aft-CG corner (160 kt at 8 000 ft, 120 t, CG 41 %), fault-free
    cruise in moderate turbulence, eight turbulence and noise streams: no sample of the
    monitored left elevator's current order at ±i_max. Under the laws of model servo-4
    (ω_sp fixed at 2 rad/s: 101 °/g of load-factor gain there, no filter, no rate limit) all
    eight saturated, 19–23 % of their samples, the elevator swinging over −20…+13°; now it
    stays inside −10…+7°."""
    rows = [single_run("elevator", "cruise", "none", duration_s=40.0, seed=5, alt_ft=8000.0,
                       vcas_kt=160.0, mass_t=120.0, cg_pct=41.0) for _ in range(8)]
    runs = pd.concat(rows, ignore_index=True)
    runs["surface"] = "left_elevator"
    runs["stream"] = np.arange(8)
    runs["run_id"] = [f"corner-{i}" for i in range(8)]
    stats = saturation._simulate_runs(runs, AircraftPlant())
    assert not stats["sat_any"].any()
    assert stats["delta_min_deg"].min() > -12.0 and stats["delta_max_deg"].max() < 9.0


def test_census_table_has_one_row_per_surface_manoeuvre_and_seed():
    table = saturation.census(seeds=(3,), surfaces=("rudder",), runs=2, duration_s=20.0,
                              manoeuvres=("cruise", "yaw_angle_mode"))
    assert list(table.columns) == list(saturation.COLUMNS)
    assert table[["surface", "manoeuvre", "seed", "runs"]].values.tolist() == [
        ["rudder", "cruise", 3, 2], ["rudder", "yaw_angle_mode", 3, 2]]
    assert table[["sat_any", "sat_over_5pct"]].isin([0.0, 0.5, 1.0]).all().all()
    assert (table["rms_rate_deg_s"] > 0).all()
    assert (table["max_rms_rate_deg_s"] >= table["rms_rate_deg_s"]).all()
    assert (table["delta_min_deg"] < table["delta_max_deg"]).all()


def test_census_plan_is_a_campaign_plan_of_fault_free_runs():
    plan = saturation.census_plan("left_inboard_aileron", seed=9, runs=3, duration_s=20.0)
    assert len(plan) == 18 and (plan["fault"] == "none").all()
    assert (plan["surface"] == "left_inboard_aileron").all()
    assert plan.groupby("manoeuvre").size().tolist() == [3] * 6
    assert plan["realistic"].all()
    with pytest.raises(ValueError, match="unknown aircraft surface 'aileron'"):
        saturation.census_plan("aileron", seed=9)


def test_study_saturation_command(capsys):
    assert main(["study", "saturation", "--seeds", "3", "--runs", "1", "--duration", "20",
                 "--surfaces", "rudder", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "sat_any" in out and out.count("rudder") == 6
    assert main(["study", "saturation", "--runs", "0"]) == 2
    assert main(["study", "saturation", "--surfaces", "left_elevatr"]) == 2
    assert "unknown aircraft surface(s) left_elevatr" in capsys.readouterr().err
