"""Manoeuvre orders: shapes, flight-point scaling, limits, rate, timing, batch invariance."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from scenarios.catalog import MANOEUVRES, SURFACES
from scenarios.manoeuvres import (
    FLIGHT_KEYS,
    MANOEUVRE_PARAMS,
    REFERENCE_FLIGHT,
    STRESS_MANOEUVRE_PARAMS,
    amplitude_scale,
    elevator_trim_deg,
    orders_for_runs,
    set_params,
    surface_order_deg,
)
from scenarios.params import ACTUATORS, AILERON, ELEVATOR, parameter_table

TS = 0.01
P = MANOEUVRE_PARAMS
#: Gust reaction switched off: the pure manoeuvre, for exact shape checks.
CALM = dataclasses.replace(P, gust_gain_elevator=0.0, gust_gain_aileron=0.0)

REF = dict(REFERENCE_FLIGHT)
#: Corners of the envelope: slow and low (lowest q̄, strongest turbulence, aft CG, high α),
#: fast and low (highest q̄), high and slow-ish.
SLOW_LOW = {"qbar_pa": 3400.0, "tas_ms": 80.0, "alt_ft": 8000.0, "alpha_deg": 9.0,
            "cg_pct": 41.0, "mach": 0.24}
FAST_LOW = {"qbar_pa": 18000.0, "tas_ms": 190.0, "alt_ft": 8000.0, "alpha_deg": 0.5,
            "cg_pct": 17.0, "mach": 0.58}
HIGH = {"qbar_pa": 6000.0, "tas_ms": 250.0, "alt_ft": 41000.0, "alpha_deg": 5.0,
        "cg_pct": 30.0, "mach": 0.85}
FLIGHTS = [REF, SLOW_LOW, FAST_LOW, HIGH]

#: (manoeuvre, surface) pairs with a manoeuvre profile; the others are trim + gust reaction.
ACTIVE = {("nose_up", "elevator"), ("aoa_protection", "elevator"),
          ("pitch_protection", "elevator"), ("yaw_angle_mode", "aileron"),
          ("turn_coordination", "aileron"), ("turn_coordination", "elevator")}


def times(seconds: float) -> np.ndarray:
    return np.arange(int(round(seconds / TS))) * TS


def order(manoeuvre, surface, flight=REF, seed=0, seconds=60.0, params=P):
    return surface_order_deg(manoeuvre, surface, times(seconds), flight,
                             np.random.default_rng(seed), ACTUATORS[surface], params=params)


def trim(surface, flight=REF):
    if surface == "aileron":
        return 0.0
    return elevator_trim_deg(flight["alpha_deg"], flight["cg_pct"], ELEVATOR)


def half_width_s(x: np.ndarray) -> float:
    """Time spent beyond half of the peak excursion of x (x ≥ 0 outside one pulse)."""
    return np.count_nonzero(x > 0.5 * x.max()) * TS


# ---- tables ----------------------------------------------------------------------------
def test_every_parameter_has_unit_and_source():
    for row in parameter_table(P):
        assert row["unit"] and row["source"], row["name"]


@pytest.mark.parametrize("changes", [
    {"nose_up_amp_deg": (5.0, 2.0)},
    {"qbar_ref_pa": 0.0},
    {"manoeuvre_rate_deg_s": 40.0},
    {"scale_min": float("nan")},
])
def test_invalid_params_are_rejected(changes):
    with pytest.raises(ValueError, match="ManoeuvreParams"):
        dataclasses.replace(P, **changes)


# ---- every manoeuvre × surface -----------------------------------------------------------
@pytest.mark.parametrize("surface", SURFACES)
@pytest.mark.parametrize("manoeuvre", MANOEUVRES)
def test_finite_within_limits_and_rate_limited(manoeuvre, surface):
    act = ACTUATORS[surface]
    for flight in FLIGHTS:
        for seed in range(8):
            o = order(manoeuvre, surface, flight, seed)
            assert o.shape == (6000,)
            assert np.all(np.isfinite(o))
            assert o.min() >= act.delta_min_deg and o.max() <= act.delta_max_deg
            # rate bound of the whole order, including the gust reaction at SLOW_LOW
            # (the most turbulent point: ≈ 1 °/s RMS on top of the 25 °/s transitions)
            assert np.abs(np.diff(o)).max() / TS <= P.rate_max_deg_s


def test_rate_bound_holds_over_many_turbulent_runs():
    # the gust reaction is Gaussian: check its rate tail on 200 runs at the most turbulent,
    # slowest point during the fastest transitions (pitch protection at factor 3)
    t = times(30.0)
    for surface, manoeuvre in [("elevator", "pitch_protection"), ("aileron", "turn_coordination")]:
        n = 100
        o = orders_for_runs([manoeuvre] * n, surface, t,
                            {k: np.full(n, v) for k, v in SLOW_LOW.items()},
                            [np.random.default_rng(s) for s in range(n)], ACTUATORS[surface])
        assert np.abs(np.diff(o, axis=1)).max() / TS <= P.rate_max_deg_s


# ---- shapes --------------------------------------------------------------------------------
def test_nose_up_elevator_is_a_held_negative_step():
    for seed in range(20):
        x = order("nose_up", "elevator", seed=seed, params=CALM) - trim("elevator")
        assert 2.0 - 1e-9 <= -x.min() <= 5.0 + 1e-9        # docs/physics.md §7 at q_ref
        assert x.max() <= 1e-12                            # one-sided: nose up only
        # held 5–10 s (width at half amplitude; ± one sample of quantisation)
        assert 5.0 - TS <= half_width_s(-x) <= 10.0 + TS
    # with the gust reaction (≈ 0.13° RMS at q_ref), a 1-s average keeps the step depth
    # within 0.6° (> 4σ of the averaged reaction) of the 2–5° range
    kernel = np.ones(100) / 100
    for seed in range(20):
        x = order("nose_up", "elevator", seed=seed) - trim("elevator")
        depth = -np.convolve(x, kernel, mode="valid").min()
        assert 2.0 - 0.6 <= depth <= 5.0 + 0.6


def test_nose_up_step_scales_with_qbar():
    half_q = {**REF, "qbar_pa": REF["qbar_pa"] / 2}
    for seed in range(10):
        ref = order("nose_up", "elevator", seed=seed, params=CALM) - trim("elevator")
        low = order("nose_up", "elevator", half_q, seed=seed, params=CALM) - trim("elevator")
        assert 4.0 - 1e-9 <= -low.min() <= 10.0 + 1e-9
        assert low.min() == pytest.approx(2.0 * ref.min(), rel=1e-12)


@pytest.mark.parametrize("manoeuvre, surface", sorted(ACTIVE))
def test_amplitude_grows_when_qbar_decreases(manoeuvre, surface):
    qbars = [1.5 * P.qbar_ref_pa, P.qbar_ref_pa, 0.7 * P.qbar_ref_pa, 0.4 * P.qbar_ref_pa]
    for seed in range(5):
        peaks = np.array([np.abs(order(manoeuvre, surface, {**REF, "qbar_pa": q}, seed, params=CALM)
                                 - trim(surface)).max() for q in qbars])
        # strictly growing until the deflection reaches the electrical limit (pitch
        # protection at low q̄), then held there
        act = ACTUATORS[surface]
        authority = max(act.delta_max_deg - trim(surface), trim(surface) - act.delta_min_deg)
        grows = np.diff(peaks) > 0
        at_limit = np.isclose(peaks[1:], peaks[:-1]) & np.isclose(
            np.abs(order(manoeuvre, surface, {**REF, "qbar_pa": qbars[-1]}, seed, params=CALM)
                   - trim(surface)).max(), authority)
        assert np.all(grows | at_limit), peaks
        assert peaks[1] > peaks[0]


def test_amplitude_scale_law():
    assert amplitude_scale(P.qbar_ref_pa) == 1.0
    assert amplitude_scale(P.qbar_ref_pa / 2) == pytest.approx(2.0)
    assert amplitude_scale(1.0) == P.scale_max            # clipped
    assert amplitude_scale(1e9) == P.scale_min


def test_aoa_protection_is_a_slow_excursion():
    for seed in range(10):
        x = order("aoa_protection", "elevator", seed=seed, params=CALM) - trim("elevator")
        assert 5.0 - 1e-9 <= -x.min() <= 15.0 + 1e-9
        # slow: ramps of at least 2 s, so the peak rate is ≤ π·15/(2·2) ≈ 11.8 °/s
        assert np.abs(np.diff(x)).max() / TS <= math.pi * 15.0 / 4.0 + 1e-6


def test_pitch_protection_reaches_the_limits_at_low_qbar():
    low = {**REF, "qbar_pa": P.qbar_ref_pa / 2}          # factor 2: 85–100 % × 2 ≥ authority
    for seed in range(10):
        o = order("pitch_protection", "elevator", low, seed=seed, params=CALM)
        assert o.min() == pytest.approx(ELEVATOR.delta_min_deg)
        assert o.max() == pytest.approx(ELEVATOR.delta_max_deg)
        o = order("pitch_protection", "elevator", seed=seed, params=CALM)   # at q_ref
        tr = trim("elevator")
        assert 0.85 - 1e-9 <= (tr - o.min()) / (tr - ELEVATOR.delta_min_deg) <= 1.0 + 1e-9
        assert 0.85 - 1e-9 <= (o.max() - tr) / (ELEVATOR.delta_max_deg - tr) <= 1.0 + 1e-9
        assert np.argmin(o) < np.argmax(o)                 # nose-up transient first


def test_yaw_angle_mode_aileron_is_held():
    signs = set()
    for seed in range(20):
        x = order("yaw_angle_mode", "aileron", seed=seed, params=CALM)
        peak = x[np.argmax(np.abs(x))]
        signs.add(np.sign(peak))
        assert 2.0 - 1e-9 <= abs(peak) <= 5.0 + 1e-9
        assert 5.0 - TS <= half_width_s(np.sign(peak) * x) <= 10.0 + TS
    assert signs == {-1.0, 1.0}


def test_turn_coordination_aileron_pulses():
    # rate ≤ the documented bound and peaks of 5–10° at q_ref, both signs in each turn
    for seed in range(20):
        x = order("turn_coordination", "aileron", seed=seed, params=CALM)
        assert np.abs(np.diff(x)).max() / TS <= P.manoeuvre_rate_deg_s + 1e-6
        assert 5.0 - 1e-9 <= x.max() <= 10.0 + 1e-9
        assert x.max() == pytest.approx(-x.min())
        # roll-in pulse lasts bank/roll-rate = 25–33°/(7.5 °/s) at half amplitude (normal set)
        first = x if x[np.argmax(np.abs(x))] > 0 else -x
        pulse = first[: int(np.flatnonzero(first < -0.5 * first.max())[0])]
        assert P.turn_roll_rate_deg_s == 7.5
        assert 25 / 7.5 - TS <= half_width_s(pulse) <= 33 / 7.5 + TS
    for seed in range(20):                 # with the gust reaction: peaks within ±0.6° (> 4σ)
        x = order("turn_coordination", "aileron", seed=seed)
        assert np.abs(np.diff(x)).max() / TS <= P.rate_max_deg_s
        assert 5.0 - 0.6 <= np.abs(x).max() <= 10.0 + 0.6


def test_stress_set_rolls_in_at_full_stick_with_the_largest_amplitudes():
    """The stress turn's aileron pulse is 33°/(15 °/s) = 2.2 s wide (half the normal one at
    the same bank: twice the roll rate) and 10° high at q_ref; the pitch manoeuvres reach the
    high end of their ranges. Widths are measured at half amplitude (± one sample)."""
    calm = dataclasses.replace(STRESS_MANOEUVRE_PARAMS, gust_gain_elevator=0.0,
                               gust_gain_aileron=0.0)
    assert set_params("stress") is STRESS_MANOEUVRE_PARAMS and set_params("normal") is P
    for seed in range(10):
        x = order("turn_coordination", "aileron", seed=seed, params=calm)
        assert x.max() == pytest.approx(10.0) and x.min() == pytest.approx(-10.0)
        first = x if x[np.argmax(np.abs(x))] > 0 else -x
        pulse = first[: int(np.flatnonzero(first < -0.5 * first.max())[0])]
        assert 33 / 15 - TS <= half_width_s(pulse) <= 33 / 15 + TS
        normal = order("turn_coordination", "aileron", seed=seed, params=CALM)
        first = normal if normal[np.argmax(np.abs(normal))] > 0 else -normal
        wide = first[: int(np.flatnonzero(first < -0.5 * first.max())[0])]
        assert half_width_s(wide) >= 25 / 7.5 - TS > half_width_s(pulse)
        nose = order("nose_up", "elevator", seed=seed, params=calm) - trim("elevator")
        assert -nose.min() == pytest.approx(5.0)
    with pytest.raises(ValueError, match="unknown manoeuvre set 'stres'.*did you mean 'stress'"):
        set_params("stres")


def test_lateral_manoeuvres_give_small_elevator_activity_and_vice_versa():
    for seed in range(10):
        # turn: load factor 1/cos φ ≤ 1.19 g → pull ≤ 4 °/g · 0.19 ≈ 0.77° at q_ref
        x = order("turn_coordination", "elevator", seed=seed, params=CALM) - trim("elevator")
        assert -0.8 <= x.min() <= -0.4 and x.max() <= 1e-12
        assert np.all(order("yaw_angle_mode", "elevator", seed=seed, params=CALM)
                      == trim("elevator"))
        for m in ("nose_up", "aoa_protection", "pitch_protection"):
            assert np.all(order(m, "aileron", seed=seed, params=CALM) == 0.0)


def test_cruise_activity_at_reference():
    # docs/physics.md §7: cruise ±0.2–0.5°; the gust reaction's std is ≈ 0.13° at q_ref
    for surface in SURFACES:
        stds = [order("cruise", surface, seed=s).std() for s in range(20)]
        assert 0.05 <= np.median(stds) <= 0.5
        assert 0.02 <= min(stds) and max(stds) <= 0.5
        means = [order("cruise", surface, seed=s).mean() - trim(surface) for s in range(20)]
        assert abs(np.mean(means)) < 0.1     # centred on the trim


def test_gust_reaction_grows_with_turbulence_and_slowness():
    # σ/V: 3.0/80 at SLOW_LOW against 1.45/242 at the reference, ≈ 6×
    ref = np.median([order("cruise", "elevator", seed=s).std() for s in range(10)])
    slow = np.median([order("cruise", "elevator", SLOW_LOW, seed=s).std() for s in range(10)])
    assert 3.0 < slow / ref < 12.0


def test_elevator_trim_law():
    assert elevator_trim_deg(0.0, P.cg_ref_pct, ELEVATOR) == pytest.approx(P.trim_k0_deg)
    assert elevator_trim_deg(5.0, 40.0, ELEVATOR) == pytest.approx(
        P.trim_k0_deg + 5.0 * P.trim_k_alpha + 10.0 * P.trim_k_cg_deg_per_pct)
    assert elevator_trim_deg(100.0, 30.0, ELEVATOR) == P.trim_min_deg       # clipped
    assert elevator_trim_deg(-100.0, 30.0, ELEVATOR) == P.trim_max_deg
    narrow = ELEVATOR.replace(delta_min_deg=-4.0)
    assert elevator_trim_deg(100.0, 30.0, narrow) == -4.0                   # electrical limit
    # more α → more nose-up (negative) elevator; the order's calm level is the trim
    o = order("cruise", "elevator", SLOW_LOW, params=CALM)
    assert np.all(o == trim("elevator", SLOW_LOW))
    assert trim("elevator", SLOW_LOW) < trim("elevator", REF)


# ---- timing ---------------------------------------------------------------------------------
@pytest.mark.parametrize("seconds", [20.0, 30.0, 60.0])
@pytest.mark.parametrize("manoeuvre, surface", sorted(ACTIVE))
def test_manoeuvre_happens_inside_the_record(manoeuvre, surface, seconds):
    # at the lowest q̄ the transitions are longest; the manoeuvre is at rest for the
    # first lead_s and the last tail_s seconds and present in between. Exception (module
    # docstring): the normal set's longest turns (≤ 17.7 s) do not fit a 20-s record; they
    # start at lead_s and the end of the record cuts their roll-out.
    n_lead, n_tail = int(P.lead_s / TS), int(P.tail_s / TS)
    starts, cut = [], 0
    for flight in (SLOW_LOW, REF):
        for seed in range(15):
            x = (order(manoeuvre, surface, flight, seed, seconds, params=CALM)
                 - trim(surface, flight))
            assert np.all(x[:n_lead] == 0.0)
            active = np.flatnonzero(x != 0.0)
            assert active.size > 0
            starts.append(active[0] * TS)
            if not np.all(x[-n_tail:] == 0.0):
                assert manoeuvre == "turn_coordination" and seconds < 23.0
                assert active[0] * TS <= P.lead_s + 1.5 * TS    # started as early as allowed
                cut += 1
    assert np.std(starts) > (0.5 if seconds > 20 else 0.0)   # randomised start
    if seconds >= 23.0:
        assert cut == 0


def test_same_seed_same_turbulence_whatever_the_manoeuvre():
    # fixed draw order: before the manoeuvre starts, every manoeuvre's order is the same
    n_lead = int(P.lead_s / TS)
    for surface in SURFACES:
        base = order("cruise", surface, seed=9)
        for m in MANOEUVRES:
            np.testing.assert_array_equal(order(m, surface, seed=9)[:n_lead], base[:n_lead])


def test_deterministic_for_a_seed():
    a = order("turn_coordination", "aileron", seed=5)
    np.testing.assert_array_equal(a, order("turn_coordination", "aileron", seed=5))
    assert not np.array_equal(a, order("turn_coordination", "aileron", seed=6))


# ---- batch -----------------------------------------------------------------------------------
def test_orders_for_runs_equals_individual_calls():
    rng = np.random.default_rng(0)
    n = 12
    manoeuvres = [MANOEUVRES[i % len(MANOEUVRES)] for i in range(n)]
    flight = {
        "qbar_pa": rng.uniform(3400, 18000, n), "tas_ms": rng.uniform(80, 260, n),
        "alt_ft": rng.uniform(8000, 38000, n), "alpha_deg": rng.uniform(0, 9, n),
        "cg_pct": rng.uniform(17, 41, n), "mach": rng.uniform(0.2, 0.86, n),
    }
    t = times(30.0)
    for surface in SURFACES:
        batch = orders_for_runs(manoeuvres, surface, t, flight,
                                [np.random.default_rng(100 + i) for i in range(n)],
                                ACTUATORS[surface])
        assert batch.shape == (n, t.size)
        for i in range(n):
            single = surface_order_deg(manoeuvres[i], surface, t,
                                       {k: v[i] for k, v in flight.items()},
                                       np.random.default_rng(100 + i), ACTUATORS[surface])
            np.testing.assert_array_equal(batch[i], single)
        # a run's order does not depend on the other runs: reverse the batch
        rev = orders_for_runs(manoeuvres[::-1], surface, t, {k: v[::-1] for k, v in flight.items()},
                              [np.random.default_rng(100 + i) for i in reversed(range(n))],
                              ACTUATORS[surface])
        np.testing.assert_array_equal(rev[::-1], batch)


# ---- errors ------------------------------------------------------------------------------------
def test_unknown_names_are_clear_errors():
    t = times(20.0)
    with pytest.raises(ValueError, match=r"unknown manoeuvre 'nose_upp' \(did you mean "
                                         r"'nose_up'\?\); allowed: cruise"):
        surface_order_deg("nose_upp", "elevator", t, REF, np.random.default_rng(0), ELEVATOR)
    with pytest.raises(ValueError, match="unknown surface 'rudder'.*allowed: elevator, aileron"):
        surface_order_deg("cruise", "rudder", t, REF, np.random.default_rng(0), ELEVATOR)
    with pytest.raises(ValueError, match="actuator is for surface 'aileron'"):
        surface_order_deg("cruise", "elevator", t, REF, np.random.default_rng(0), AILERON)


@pytest.mark.parametrize("key, value, message", [
    ("qbar_pa", 0.0, r"flight\['qbar_pa'\] must be > 0"),
    ("qbar_pa", -5.0, r"flight\['qbar_pa'\] must be > 0"),
    ("tas_ms", float("nan"), r"flight\['tas_ms'\] must be finite"),
    ("alpha_deg", float("inf"), r"flight\['alpha_deg'\] must be finite"),
    ("cg_pct", "aft", r"flight\['cg_pct'\] must be a number"),
    ("mach", None, r"flight\['mach'\] must be a number"),
])
def test_invalid_flight_values_name_the_key(key, value, message):
    with pytest.raises(ValueError, match=message):
        surface_order_deg("cruise", "elevator", times(20.0), {**REF, key: value},
                          np.random.default_rng(0), ELEVATOR)


def test_missing_flight_key_and_bad_times():
    rng = np.random.default_rng(0)
    flight = {k: v for k, v in REF.items() if k != "alt_ft"}
    with pytest.raises(ValueError, match="missing 'alt_ft'"):
        surface_order_deg("cruise", "elevator", times(20.0), flight, rng, ELEVATOR)
    with pytest.raises(ValueError, match="at least 20 s"):
        surface_order_deg("cruise", "elevator", times(10.0), REF, rng, ELEVATOR)
    t = times(30.0)
    t[100] += 0.005
    with pytest.raises(ValueError, match="uniform"):
        surface_order_deg("cruise", "elevator", t, REF, rng, ELEVATOR)
    with pytest.raises(TypeError, match="Generator"):
        surface_order_deg("cruise", "elevator", times(20.0), REF, 0, ELEVATOR)


def test_orders_for_runs_errors_name_the_run():
    t = times(20.0)
    flight = {k: np.full(3, v) for k, v in REF.items()}
    rngs = [np.random.default_rng(i) for i in range(3)]
    with pytest.raises(ValueError, match="run 1: unknown manoeuvre 'loop'"):
        orders_for_runs(["cruise", "loop", "cruise"], "aileron", t, flight, rngs, AILERON)
    bad = {**flight, "qbar_pa": np.array([1e4, 1e4, -1.0])}
    with pytest.raises(ValueError, match=r"run 2: flight\['qbar_pa'\] must be > 0"):
        orders_for_runs(["cruise"] * 3, "aileron", t, bad, rngs, AILERON)
    with pytest.raises(ValueError, match="one per run"):
        orders_for_runs(["cruise"] * 2, "aileron", t, flight, rngs, AILERON)
    with pytest.raises(ValueError, match="single string"):
        orders_for_runs("cruise", "aileron", t, flight, rngs, AILERON)
    with pytest.raises(ValueError, match=r"flight\['mach'\] must have shape \(3,\)"):
        orders_for_runs(["cruise"] * 3, "aileron", t, {**flight, "mach": np.ones(2)}, rngs, AILERON)
    assert set(FLIGHT_KEYS) == set(REF)
