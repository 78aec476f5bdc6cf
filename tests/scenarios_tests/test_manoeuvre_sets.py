"""Manoeuvre sets (docs/physics.md §7): ``normal`` and ``stress`` at both plant levels, in
the campaign file, the run table and the run id."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.plant_setup import resolve
from campaign.config import ConfigError, load_config, with_overrides
from campaign.plan import build_learning_plan, build_plan, run_id
from scenarios.aircraft.data import PILOT
from scenarios.aircraft.pilot import PILOT_STRESS, set_params
from scenarios.plants import simulate
from scenarios.runs import RunSpecError, validate_runs
from scenarios.simulate import prepare


def _turns(manoeuvre_set: str, plant: str, n: int = 4):
    """*n* fault-free turns (aileron, realistic envelope) in *manoeuvre_set*: of the chen-mc
    plan on the aircraft plant, of chen-local on the actuator plant."""
    preset = "chen-mc" if plant == "aircraft" else "chen-local"
    config = with_overrides(load_config(preset), values={"manoeuvres.set": manoeuvre_set})
    plan = build_plan(config)
    return plan[(plan["manoeuvre"] == "turn_coordination") & (plan["fault"] == "none")].head(n)


def _roll_in_rate(phi: np.ndarray, ts: float) -> float:
    """Mean roll rate [deg/s] of the roll-in, from the bank-angle record *phi* [deg]: the bank
    change between 20 % and 80 % of the peak bank over the time it takes (the steady part of
    the roll-in; the smoothed edges lie outside it)."""
    sign = np.sign(phi[np.argmax(np.abs(phi))])
    x = sign * phi
    peak = x.max()
    i20 = int(np.flatnonzero(x >= 0.2 * peak)[0])
    i80 = int(np.flatnonzero(x >= 0.8 * peak)[0])
    return (x[i80] - x[i20]) / ((i80 - i20) * ts)


@pytest.mark.parametrize("manoeuvre_set, rate, above, median", [("normal", 7.5, 0.25, 0.15),
                                                                ("stress", 15.0, 0.30, 0.30)])
def test_aircraft_turn_rolls_in_at_the_set_rate(manoeuvre_set, rate, above, median):
    """The aircraft-level roll-in, measured on the simulated bank-angle sensor, is the set's
    roll-rate order: each of four turns within −10 % and +*above*, their median within
    *median* (the roll law tracks p_c with a 3-rad/s bandwidth, a lag and no rate error;
    moderate turbulence and the bank-hold gain add roll over the 1–3 s of the measurement:
    measured 7.6–9.1 °/s for 7.5 °/s, median 7.9). At 15 °/s over 0.5-s edges the roll law
    asks the ailerons for their whole 25° authority within about 0.5 s; rate-limited at
    28 °/s (docs/aircraft.md §4.4) and then held at that authority, the aircraft lags the
    order and the bank hold, whose reference integrates p_c, makes the lag up within the
    measurement: measured 16.7–19.2 °/s, median 18.8 (16.1–17.9 °/s, median 16.6, under the
    laws of model servo-4, without rate limits), hence +30 % and a median within 30 % for
    the stress set (+25 % and 15 % before)."""
    assert set_params(manoeuvre_set).turn_rate_deg_s == rate
    sig, _ = simulate(_turns(manoeuvre_set, "aircraft"), plant="aircraft")
    rates = np.array([_roll_in_rate(phi, sig.ts) for phi in sig.aircraft["phi"]])
    assert np.all((0.9 * rate <= rates) & (rates <= (1.0 + above) * rate)), rates
    assert np.median(rates) == pytest.approx(rate, rel=median), rates


def test_stress_pilot_table_is_the_aggressive_end_of_the_normal_one():
    assert PILOT_STRESS.turn_rate_deg_s == 15.0 and PILOT_STRESS.turn_smooth_s == PILOT.smooth_s
    for name in ("nose_up_g", "aoa_g", "pitch_g", "yaw_beta_deg", "turn_bank_deg"):
        assert getattr(PILOT_STRESS, name) == (getattr(PILOT, name)[1],) * 2, name
    assert PILOT_STRESS.aoa_ramp_s == (PILOT.aoa_ramp_s[0],) * 2
    assert PILOT_STRESS.turn_hold_s == PILOT.turn_hold_s and PILOT_STRESS.start_s == PILOT.start_s


@pytest.mark.parametrize("manoeuvre_set, rate", [("normal", 7.5), ("stress", 15.0)])
def test_actuator_turn_aileron_pulse_gives_the_set_rate(manoeuvre_set, rate):
    """At the actuator level the roll-in is an aileron pulse held for bank/rate (bank drawn
    in 25–33°; 33° in the stress set): its width at half amplitude, measured on the orders
    of the run table's runs, is that to within 0.05 s below (the gust reaction, ≤ 0.5°,
    moves each half-amplitude crossing by ≤ 20 ms) and 0.2 s above (a pulse clipped at the
    hinge-load authority is measured at half of its clipped peak, which widens it)."""
    banks = (33.0, 33.0) if manoeuvre_set == "stress" else (25.0, 33.0)
    for order in prepare(_turns(manoeuvre_set, "actuator", n=8)).order_deg:
        sign = np.sign(order[np.flatnonzero(np.abs(order - order[0]) > 2.0)[0]])
        x = sign * (order - order[0])
        pulse = x[: int(np.flatnonzero(x < -2.0)[0])]            # up to the opposite pulse
        width = np.count_nonzero(pulse > 0.5 * pulse.max()) * 0.01
        assert banks[0] / rate - 0.05 <= width <= banks[1] / rate + 0.2, width


def test_the_set_is_in_the_run_table_and_the_run_id():
    normal = build_plan(load_config("chen-local"))
    stress = build_plan(with_overrides(load_config("chen-local"),
                                       values={"manoeuvres.set": "stress"}))
    assert ((normal["manoeuvre_set"] == "normal").all()
            and (stress["manoeuvre_set"] == "stress").all())
    # normal runs keep the ids they had before the column existed
    row = normal.iloc[0].to_dict()
    assert run_id({k: v for k, v in row.items() if k != "manoeuvre_set"}) == row["run_id"]
    # the same draws under the other set are other runs: never mixed up on resume
    assert set(normal["run_id"]).isdisjoint(stress["run_id"])
    cols = [c for c in normal.columns if c not in ("run_id", "manoeuvre_set")]
    assert normal[cols].equals(stress[cols])


def test_learning_set_follows_the_set_unless_given():
    config = with_overrides(load_config("chen-local"), values={"manoeuvres.set": "stress"})
    assert (build_learning_plan(resolve(config))["manoeuvre_set"] == "stress").all()
    config = with_overrides(config, values={"manoeuvres.learning_set": "normal"})
    assert (build_learning_plan(resolve(config))["manoeuvre_set"] == "normal").all()
    assert (build_plan(config)["manoeuvre_set"] == "stress").all()


def test_unknown_set_is_refused_with_the_allowed_names():
    with pytest.raises(ConfigError) as err:
        with_overrides(load_config("smoke"), values={"manoeuvres.set": "agressive"})
    assert any("manoeuvres.set" in e and "normal, stress" in e for e in err.value.errors)
    runs = build_plan(load_config("smoke")).head(2).copy()
    runs["manoeuvre_set"] = "hard"
    with pytest.raises(RunSpecError, match="manoeuvre_set: unknown value 'hard'"):
        validate_runs(runs)
