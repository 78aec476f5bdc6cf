"""Fault injection pinned by value (docs/physics.md §2 time base, §5 faults).

Every expectation below is written from the documents and computed by hand here: the onset
step k0 = round(onset/Ts), the unit and sign of each magnitude, what the loop sees one step
before onset, at onset and after. The simulations use constructed orders and noise-free
sensors (quantisation 1e-9 mm instead of 0.01 mm), so that a value can be compared with the
hand computation to round-off instead of to the sensor noise, and run on both engines.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.faults import (NEVER, fault_arrays, liquid_jam_bias_mm, onset_steps,
                              solid_jam_offset_mm, solid_jam_variant)
from scenarios.params import AILERON, ELEVATOR, SensorParams
from scenarios.simulate import prepare, simulate, single_run

ENGINES = ("compiled", "numpy")
TS = 0.01
#: Sensors without noise, bias or scale error; a quantisation step far below every
#: tolerance used here (a step of 0 is not allowed: the acquisition divides by it).
EXACT = SensorParams(rod_noise_mm=0.0, rod_quant_mm=1e-9, rod_bias_mm=0.0, rod_scale=0.0,
                     surface_noise_deg=0.0, surface_quant_deg=1e-9, surface_bias_deg=0.0,
                     pressure_noise_frac=0.0)
#: round-off of one acquisition with EXACT: half the 1e-9 mm quantisation step plus the
#: rounding of sums of values of order 100 mm (1e-14 relative)
ACQ_TOL_MM = 1e-8


def rod_mm(act, deg):
    """x = r·sin δ (docs/physics.md §1) by hand."""
    return act.r_mm * math.sin(math.radians(deg))


def _arrays(fault, onset_s, magnitude, freq_hz, order, act=ELEVATOR, i_max=(10.0,)):
    order = np.atleast_2d(np.asarray(order, float))
    n = order.shape[0]
    return fault_arrays(np.array([fault] * n), np.full(n, onset_s), np.full(n, magnitude),
                        np.full(n, freq_hz), order, act, TS, np.asarray(i_max, float))


def _run(fault, engine, *, order_deg, onset_s=1.0, magnitude=None, freq_hz=None,
         surface="elevator", **point):
    duration = order_deg.shape[0] * TS
    runs = single_run(surface, "cruise", fault, onset_s=onset_s, magnitude=magnitude,
                      freq_hz=freq_hz, duration_s=duration, **point)
    return simulate(runs, ts=TS, sensors=EXACT, orders_deg=order_deg[None, :], engine=engine)


# ---- onset step ---------------------------------------------------------------------------
def test_onset_step_is_the_nearest_step():
    # docs/physics.md §2: k0 = round(onset/Ts); 1.004 s is 100.4 steps, 1.006 s is 100.6
    k = onset_steps([1.0, 1.004, 1.006, 0.0, np.nan], TS)
    assert list(k[:4]) == [100, 100, 101, 0]
    assert k[4] == NEVER          # a fault-free run never reaches its onset


# ---- the injection arrays, by hand --------------------------------------------------------
def test_runaway_ramps_the_loop_order_from_the_fault_free_order_at_onset():
    T, k0, rate = 300, 100, 5.0
    # a moving fault-free order, so that "from the order at t0" differs from "from 0" or
    # "from the order at t = 0"
    order = 2.0 + 0.5 * np.sin(np.arange(T) * TS * 3.0)
    fa = _arrays("runaway", 1.0, rate, np.nan, order)
    expected = [rod_mm(ELEVATOR, order[k] + (rate * (k - k0) * TS if k >= k0 else 0.0))
                for k in range(T)]
    # same formula, different order of operations: 1e-12 mm is 1e4 ulp of 10 mm
    np.testing.assert_allclose(fa.u_loop[0], expected, rtol=0, atol=1e-12)
    # one step before onset and at onset the loop sees the fault-free order exactly
    assert fa.u_loop[0, k0 - 1] == pytest.approx(rod_mm(ELEVATOR, order[k0 - 1]), abs=1e-12)
    assert fa.u_loop[0, k0] == pytest.approx(rod_mm(ELEVATOR, order[k0]), abs=1e-12)


@pytest.mark.parametrize("rate", [5.0, -7.0])
def test_runaway_slope_and_sign_and_clip_beyond_the_stops(rate):
    T = 1200
    fa = _arrays("runaway", 1.0, rate, np.nan, np.zeros(T))
    deg = np.degrees(np.arcsin(fa.u_loop[0] / ELEVATOR.r_mm))
    # slope of the corrupted order over the first second after onset: exactly ṙ deg/s
    # (arcsin of sin gives the angle back to 1e-12 deg)
    assert deg[200] - deg[100] == pytest.approx(rate * 1.0, abs=1e-9)
    # docs/physics.md §5: clipped 5° beyond the mechanical stops (+16.5 / −31.5 on the elevator)
    end = ELEVATOR.stop_max_deg + 5.0 if rate > 0 else ELEVATOR.stop_min_deg - 5.0
    assert deg[-1] == pytest.approx(end, abs=1e-9)
    assert end == pytest.approx(21.5 if rate > 0 else -36.5)


@pytest.mark.parametrize("magnitude, sign", [(1.0, 1.0), (-1.0, -1.0), (-0.3, -1.0), (2.0, 1.0),
                                             (0.0, 1.0), (np.nan, 1.0)])  # no sign: +i_max
def test_hardover_forces_plus_or_minus_imax_with_the_sign_of_the_magnitude(magnitude, sign):
    i_max = 8.5                      # a run's true saturation, not the nominal 10 mA
    fa = _arrays("hardover", 1.0, magnitude, np.nan, np.zeros(200), i_max=(i_max,))
    assert np.isnan(fa.cur_force[0, :100]).all()       # nothing forced before k0 = 100
    assert (fa.cur_force[0, 100:] == sign * i_max).all()


def test_liquid_jam_bias_is_a_share_of_the_deflection_range_in_mm():
    # docs/physics.md §5: 1.3 % of the range, r·sin(pct/100·range): elevator 45°, r 120 mm;
    # aileron 50°, r 70 mm; the documented values are 1.23 mm and 0.79 mm
    elev = 120.0 * math.sin(math.radians(0.013 * 45.0))
    ail = 70.0 * math.sin(math.radians(0.013 * 50.0))
    assert liquid_jam_bias_mm(ELEVATOR, 1.3) == pytest.approx(elev, rel=1e-12)
    assert liquid_jam_bias_mm(AILERON, 1.3) == pytest.approx(ail, rel=1e-12)
    # the table of docs/physics.md §5 rounds to 0.01 mm
    assert round(elev, 2) == 1.23 and round(ail, 2) == 0.79
    assert liquid_jam_bias_mm(ELEVATOR, 10.0) == pytest.approx(120 * math.sin(math.radians(4.5)),
                                                               rel=1e-12)


def test_liquid_jam_adds_its_bias_to_com_from_the_onset_step_only():
    f = -1.1
    fa = _arrays("liquid_jam", 1.0, f, np.nan, np.zeros(200))
    assert (fa.com_add[0, :100] == 0.0).all() and (fa.com_add[0, 100:] == f).all()
    assert fa.cur_add is None and fa.cur_force is None and fa.com_osc is None


@pytest.mark.parametrize("fault", ["ofc_liquid", "ofc_solid"])
def test_ofc_is_a_sine_of_period_one_over_f_hz_from_onset(fault):
    amp, f = 1.7, 2.5                 # 2.5 Hz: a period of 0.4 s = 40 steps
    fa = _arrays(fault, 1.0, amp, f, np.zeros(300))
    osc = fa.cur_add if fault == "ofc_liquid" else fa.com_osc
    j = np.arange(200)
    # A·sin(2πf·(t − t0)) with t − t0 = j·Ts; 1e-12 is round-off on values of order 1
    np.testing.assert_allclose(osc[0, 100:], amp * np.sin(2 * np.pi * f * j * TS), atol=1e-12)
    assert osc[0, 100] == 0.0                                  # starts at its zero
    assert osc[0, 110] == pytest.approx(amp, abs=1e-12)        # quarter period, 0.1 s
    assert osc[0, 140] == pytest.approx(0.0, abs=1e-12)        # one full period, 0.4 s
    before = osc[0, :100]
    assert (before == 0.0).all() if fault == "ofc_liquid" else np.isnan(before).all()
    if fault == "ofc_solid":
        assert fa.k_osc[0] == 100


@pytest.mark.parametrize("fault, field", [("solid_jam", "k_jam"), ("disconnection", "k_disc")])
def test_jam_and_disconnection_onsets_are_the_onset_step(fault, field):
    order = np.zeros((2, 200))
    fa = fault_arrays(np.array([fault, "none"]), np.array([1.004, np.nan]), np.full(2, np.nan),
                      np.full(2, np.nan), order, ELEVATOR, TS, np.full(2, 10.0))
    assert getattr(fa, field)[0] == 100 and getattr(fa, field)[1] == NEVER
    other = "k_disc" if field == "k_jam" else "k_jam"
    assert (getattr(fa, other) == NEVER).all() and (fa.k_osc == NEVER).all()


# ---- the simulated signals and truth ------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("rate", [5.0, -5.0])
def test_runaway_in_the_loop(engine, rate):
    T, k0, order = 400, 100, 1.0
    u = rod_mm(ELEVATOR, order)
    sig, truth = _run("runaway", engine, order_deg=np.full(T, order), magnitude=rate,
                      alt_ft=28000.0, vcas_kt=160.0)
    i = sig.current[0]
    # trimmed start on a constant order: no current before and at onset (the ramp is 0 at
    # k0); the noise-free acquisition leaves only its 1e-9 mm quantisation × K
    assert np.abs(i[:k0 + 1]).max() < 1e-8
    # one step after onset the rod has not moved yet (current one period late): the order
    # is the ramp's first step, K·r·(sin(δ + ṙ·Ts) − sin δ)
    assert i[k0 + 1] == pytest.approx(1.5 * (rod_mm(ELEVATOR, order + rate * TS) - u),
                                      abs=1e-8)
    # `command` keeps the fault-free order (docs/physics.md §4)
    assert np.all(sig.command[0] == u)
    # after the transient (5 τ = 0.33 s) the surface moves at ṙ: slope over 1 s within 1 %
    # (low q̄: the hinge load changes the loop's lag by far less than that)
    slope = truth.surface_deg[0, k0 + 250] - truth.surface_deg[0, k0 + 150]
    assert slope == pytest.approx(rate * 1.0, rel=0.01)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_hardover_in_the_loop(engine, direction):
    T, k0 = 200, 100
    sig, truth = _run("hardover", engine, order_deg=np.zeros(T), magnitude=direction)
    applied = truth.current_mA[0]
    assert np.abs(applied[:k0]).max() < 1e-8            # trimmed: nothing flows before
    assert (applied[k0:] == direction * 10.0).all()     # ±i_max from the onset step on
    # the rod leaves in the hardover's direction from k0 + 1 (it moves over [t_k0, t_k0+1))
    x = truth.rod_mm[0]
    assert x[k0] == pytest.approx(0.0, abs=1e-8)
    assert np.sign(x[k0 + 1]) == direction
    # saturated speed with the damping neighbour, no load would be 93 mm/s (docs/physics.md §3);
    # the rod moves at least 50 mm/s and at most Kci·i_max = 100 mm/s over 0.1 s
    travel = direction * (x[k0 + 11] - x[k0 + 1])
    assert 5.0 < travel <= 10.0 + 1e-9
    # the FCC's order saturates the other way as the loop error grows
    assert sig.current[0, -1] == pytest.approx(-direction * 10.0)


@pytest.mark.parametrize("engine", ENGINES)
def test_liquid_jam_in_the_loop(engine):
    T, k0, order = 500, 100, 3.0
    f = liquid_jam_bias_mm(ELEVATOR, 1.3)
    u = rod_mm(ELEVATOR, order)
    sig, truth = _run("liquid_jam", engine, order_deg=np.full(T, order), magnitude=f)
    com, mon, x = sig.rod_com[0], sig.rod_mon[0], truth.rod_mm[0]
    # one step before onset COM reads the rod; at onset it reads rod + f (the rod has not
    # moved yet: the current answers one period late)
    assert com[k0 - 1] - x[k0 - 1] == pytest.approx(0.0, abs=ACQ_TOL_MM)
    assert com[k0] - x[k0] == pytest.approx(f, abs=ACQ_TOL_MM)
    assert x[k0] == pytest.approx(u, abs=1e-8)
    # 4 s later (60 τ) the loop has brought COM back on the order and the rod to order − f;
    # MON (noise-free) shows the real rod; 1e-6 mm: the loop's residual error e^(−60)
    assert com[-1] == pytest.approx(u, abs=1e-6)
    assert x[-1] == pytest.approx(u - f, abs=1e-6)
    assert mon[-1] == pytest.approx(u - f, abs=1e-6)
    assert truth.surface_deg[0, -1] == pytest.approx(
        math.degrees(math.asin((u - f) / 120.0)), abs=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
def test_solid_jam_seizes_the_rod_where_it_is_at_onset(engine):
    T, k0 = 300, 100
    order = 2.0 + 4.0 * np.arange(T) * TS          # a ramp: the rod is moving at onset
    _, free = _run("none", engine, order_deg=order)
    sig, truth = _run("solid_jam", engine, order_deg=order)
    x = truth.rod_mm[0]
    # up to and including t0 the run is the fault-free one, bit for bit
    assert np.array_equal(x[:k0 + 1], free.rod_mm[0, :k0 + 1])
    assert x[k0] != x[k0 - 1]                                  # it was moving
    assert (x[k0:] == x[k0]).all()                             # and is frozen from k0
    assert (truth.surface_deg[0, k0:] == truth.surface_deg[0, k0]).all()
    assert x[k0 + 1] != free.rod_mm[0, k0 + 1]
    # the order runs away from the frozen rod: the current saturates at +i_max
    assert sig.current[0, -1] == pytest.approx(10.0)


def test_solid_jam_offset_is_the_stated_share_of_the_range_and_variant_follows_magnitude():
    # [CHEN] §6.2: 1.8 % of the aileron's 50° range = 0.9°, on the 70 mm lever: r·sin(0.9°)
    assert solid_jam_offset_mm(AILERON, 1.8) == pytest.approx(70.0 * math.sin(math.radians(0.9)),
                                                              rel=1e-12)
    assert solid_jam_offset_mm(AILERON, 1.8) == pytest.approx(1.0995, abs=1e-4)
    assert solid_jam_variant(np.nan) == "seized" and solid_jam_variant(-1.1) == "offset"
    fa = fault_arrays(np.array(["solid_jam", "solid_jam", "liquid_jam"]),
                      np.array([1.0, 1.0, 1.0]), np.array([np.nan, -1.1, 0.8]),
                      np.full(3, np.nan), np.zeros((3, 200)), AILERON, TS, np.full(3, 10.0))
    # seized: no offset; offset: the signed magnitude [mm]; another fault: none
    assert list(fa.jam_offset) == [0.0, -1.1, 0.0]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_solid_jam_offset_jumps_at_onset_then_seizes_and_the_sensors_read_it(engine, sign):
    T, k0 = 300, 100
    off = sign * solid_jam_offset_mm(AILERON, 1.8)           # [mm], signed
    order = 2.0 + 4.0 * np.arange(T) * TS                      # the rod is moving at onset
    _, free = _run("none", engine, order_deg=order, surface="aileron")
    sig, truth = _run("solid_jam", engine, order_deg=order, magnitude=off, surface="aileron")
    x, xf = truth.rod_mm[0], free.rod_mm[0]
    # one step before onset: the fault-free run, bit for bit
    assert np.array_equal(x[:k0], xf[:k0])
    # at onset: the fault-free position plus the offset, in mm on the rod, with its sign
    assert x[k0] == pytest.approx(xf[k0] + off, abs=1e-12)
    assert np.sign(x[k0] - xf[k0]) == sign
    # the surface is at the jammed rod's angle δ = asin(x/r) (docs/physics.md §1)
    assert truth.surface_deg[0, k0] == pytest.approx(
        math.degrees(math.asin(x[k0] / AILERON.r_mm)), abs=1e-12)
    # after: seized there, rod and surface
    assert (x[k0:] == x[k0]).all()
    assert (truth.surface_deg[0, k0:] == truth.surface_deg[0, k0]).all()
    # the rod sensors read the jammed rod from onset on ([CHEN] eq. 4: y = x + f_sol(x))
    np.testing.assert_allclose(sig.rod_com[0, k0:], x[k0], rtol=0, atol=ACQ_TOL_MM)
    np.testing.assert_allclose(sig.rod_mon[0, k0:], x[k0], rtol=0, atol=ACQ_TOL_MM)
    assert sig.rod_com[0, k0 - 1] == pytest.approx(xf[k0 - 1], abs=ACQ_TOL_MM)
    # the truth's additive fault of eq. 4: NaN before onset, y − (healthy rod) from onset:
    # the offset at onset (the healthy loop is the fault-free one on exact sensors)
    f = truth.rod_fault_mm[0]
    assert np.isnan(f[:k0]).all()
    assert f[k0] == pytest.approx(off, abs=1e-6)
    np.testing.assert_allclose(f[k0:], x[k0] - xf[k0:], rtol=0, atol=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
def test_solid_jam_offset_at_time_zero_and_at_the_stop(engine):
    # onset at 0 s: the jump applies to the trimmed start; an offset beyond the stop is
    # clipped at the stop
    T = 300
    order = np.full(T, AILERON.stop_max_deg - 0.2)
    _, truth = _run("solid_jam", engine, order_deg=order, onset_s=0.0, magnitude=5.0,
                    surface="aileron")
    x = truth.rod_mm[0]
    assert (x == x[0]).all()
    assert x[0] == pytest.approx(rod_mm(AILERON, AILERON.stop_max_deg), abs=1e-9)


@pytest.mark.parametrize("engine", ENGINES)
def test_liquid_jam_fault_signal_starts_at_the_bias(engine):
    # [CHEN] eq. 4, y = x + f_liq: at onset f is the bias; the loop then re-centres the
    # biased measurement on the order, and f (against the healthy loop) fades
    T, k0, bias = 400, 100, 0.8
    sig, truth = _run("liquid_jam", engine, order_deg=np.full(T, 1.0), magnitude=bias)
    f = truth.rod_fault_mm[0]
    assert np.isnan(f[:k0]).all()
    assert f[k0] == pytest.approx(bias, abs=1e-6)
    assert abs(f[-1]) < 0.1 * bias


@pytest.mark.parametrize("engine", ENGINES)
def test_disconnected_rod_is_unloaded(engine):
    # high q̄ (FL100, 330 kt) and an order step of −10° after the disconnection: the rod,
    # without aerodynamic load or damping neighbour, moves at exactly Kci·i_max·sqrt(S·ΔP /
    # S·ΔP_ref) = 100 mm/s (docs/physics.md §3); loaded it could not exceed 93 mm/s
    T = 300
    order = np.where(np.arange(T) >= 120, -10.0, 0.0)
    sig, truth = _run("disconnection", engine, order_deg=order, alt_ft=10000.0, vcas_kt=330.0)
    x = truth.rod_mm[0]
    # the current saturates from step 121 (acquired at 120, flowing one period later):
    # the rod then moves 1 mm per period, to round-off (constant rate, RK4 is exact)
    steps = np.diff(x[122:130])
    np.testing.assert_allclose(steps, -1.0, rtol=0, atol=1e-9)
    # the same run fault-free moves slower (load and damping neighbour)
    _, free = _run("none", engine, order_deg=order, alt_ft=10000.0, vcas_kt=330.0)
    assert np.diff(free.rod_mm[0, 122:130]).max() > -0.94
    # and the surface no longer follows the rod: it floats (checked in detail in
    # tests/scenarios_tests/test_reference_physics.py)
    assert abs(truth.surface_deg[0, -1] - math.degrees(math.asin(x[-1] / 120.0))) > 5.0


@pytest.mark.parametrize("engine", ENGINES)
def test_ofc_liquid_adds_the_sine_to_the_applied_current(engine):
    T, k0, amp, f = 400, 100, 1.5, 2.5
    sig, truth = _run("ofc_liquid", engine, order_deg=np.full(T, 1.0), magnitude=amp, freq_hz=f)
    k = np.arange(1, T)
    # applied over [t_k, t_k+1): the FCC's order of the previous period (docs/physics.md §2)
    # plus A·sin(2πf(t − t0)) from k0 (docs/physics.md §5); 1e-12 mA is round-off
    extra = truth.current_mA[0, 1:] - sig.current[0, :-1]
    expected = np.where(k >= k0, amp * np.sin(2 * np.pi * f * (k - k0) * TS), 0.0)
    np.testing.assert_allclose(extra, expected, rtol=0, atol=1e-12)
    # the surface oscillates at f: its deviation from the order changes sign every half
    # period (0.2 s) once the oscillation is established
    dev = truth.surface_deg[0, 200:] - 1.0
    crossings = np.flatnonzero(np.diff(np.sign(dev)) != 0)
    assert len(crossings) >= 7                   # 2 s at 2.5 Hz: ~10 sign changes
    assert np.median(np.diff(crossings)) == pytest.approx(20, abs=1)


@pytest.mark.parametrize("engine", ENGINES)
def test_ofc_solid_replaces_com_by_its_value_at_onset_plus_the_sine(engine):
    T, k0, amp, f = 400, 100, 0.8, 2.0
    order = 1.0 + 1.0 * np.arange(T) * TS             # moving, so COM at k0 is specific
    sig, truth = _run("ofc_solid", engine, order_deg=order, magnitude=amp, freq_hz=f)
    com, x = sig.rod_com[0], truth.rod_mm[0]
    assert com[k0 - 1] == pytest.approx(x[k0 - 1], abs=ACQ_TOL_MM)   # healthy one step before
    assert com[k0] == pytest.approx(x[k0], abs=ACQ_TOL_MM)           # the value held at t0
    j = np.arange(T - k0)
    np.testing.assert_allclose(com[k0:], com[k0] + amp * np.sin(2 * np.pi * f * j * TS),
                               rtol=0, atol=1e-12)
    # the real rod no longer follows the order: MON shows it drifting off (by more than the
    # 0.8 mm amplitude within 3 s)
    assert np.abs(sig.rod_mon[0, -1] - sig.command[0, -1]) > 1.0


def test_prepare_hands_the_loop_the_fault_arrays_of_the_run_table():
    runs = single_run("aileron", "cruise", "runaway", onset_s=0.5, magnitude=-3.0,
                      duration_s=2.0)
    p = prepare(runs, orders_deg=np.zeros((1, 200)))
    deg = np.degrees(np.arcsin(p.faults.u_loop[0] / AILERON.r_mm))
    assert deg[50] == 0.0 and deg[150] == pytest.approx(-3.0, abs=1e-9)
    np.testing.assert_array_equal(p.u, 0.0)              # the command stays fault-free


def test_single_run_default_magnitudes_are_the_documented_ones():
    """docs/physics.md §5, Default magnitudes, column "single run"."""
    from scenarios.faults import FAULT_DEFAULTS, default_magnitude
    from scenarios.params import RUDDER

    assert default_magnitude("runaway", ELEVATOR) == 5.0          # deg/s
    assert default_magnitude("hardover", ELEVATOR) == 1.0         # direction +1
    assert default_magnitude("ofc_liquid", ELEVATOR) == 1.0       # mA
    assert default_magnitude("ofc_solid", ELEVATOR) == 1.0        # mm
    assert FAULT_DEFAULTS.ofc_freq_hz == 1.0                      # Hz
    for fault in ("none", "solid_jam", "disconnection"):
        assert math.isnan(default_magnitude(fault, ELEVATOR))
    # 1.3 % of the deflection range, to the two decimals of the table [mm]
    for act, mm in ((ELEVATOR, 1.23), (AILERON, 0.79), (RUDDER, 1.50)):
        assert round(default_magnitude("liquid_jam", act), 2) == mm


def test_estimation_range_is_the_rod_travel_of_the_whole_deflection_range():
    from scenarios.faults import estimation_range_mm

    # r·Δδ with Δδ in rad (docs/physics.md §5), by hand
    expected = ELEVATOR.r_mm * ELEVATOR.deflection_range_deg * math.pi / 180.0
    assert estimation_range_mm(ELEVATOR) == pytest.approx(expected, rel=1e-12)


def test_offset_jam_of_one_millimetre_jumps_at_its_onset_step_only():
    from scenarios.faults import FAULT_DEFAULTS, jam_onset_position

    fa = _arrays("solid_jam", 1.0, 1.0, np.nan, np.zeros(200))
    x = np.array([2.0])
    assert jam_onset_position(x, 100, fa, -50.0, 50.0)[0] == 3.0   # k0 = 100: +1 mm
    assert jam_onset_position(x, 99, fa, -50.0, 50.0)[0] == 2.0
    assert FAULT_DEFAULTS.solid_jam_offset_pct_range == 1.8         # [CHEN] §6.2


def test_fault_descriptions_are_immutable():
    import dataclasses

    from scenarios.faults import FAULT_DEFAULTS

    fa = _arrays("liquid_jam", 1.0, 1.0, np.nan, np.zeros(200))
    for obj, name in ((FAULT_DEFAULTS, "ofc_freq_hz"), (fa, "k_jam")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, name, 0)


def test_fault_arrays_reuse_of_the_command_gives_the_same_bits():
    """``command_mm=`` (the fault-free rod order the caller computed) copies the loop's order
    only where it is the same bits: a runaway, a −0.0 order (the ramp's + 0 makes it +0.0)
    and an order beyond the stops are computed by the formula; every array is unchanged."""
    rng = np.random.default_rng(4)
    faults = np.array(["none", "runaway", "liquid_jam", "solid_jam", "disconnection",
                       "hardover", "ofc_liquid", "ofc_solid", "none", "none"])
    n, T = len(faults), 400
    order = rng.uniform(-20.0, 10.0, (n, T))
    order[8, 5] = -0.0                                  # the loop's order is +0.0 there
    order[9, 7] = ELEVATOR.stop_max_deg + 40.0          # beyond the stops: clipped
    onset = np.where(faults == "none", np.nan, 1.0)
    mag = np.array([np.nan, 5.0, 1.2, np.nan, np.nan, -1.0, 2.0, 0.5, np.nan, np.nan])
    freq = np.where(np.char.startswith(faults, "ofc"), 3.0, np.nan)
    i_max = np.full(n, 10.0)
    command = ELEVATOR.r_mm * np.sin(np.radians(order))
    plain = fault_arrays(faults, onset, mag, freq, order, ELEVATOR, TS, i_max)
    reused = fault_arrays(faults, onset, mag, freq, order, ELEVATOR, TS, i_max,
                          command_mm=command)
    for name in vars(plain):
        a, b = getattr(plain, name), getattr(reused, name)
        if a is None:
            assert b is None, name
            continue
        np.testing.assert_array_equal(a, b, err_msg=name)
        assert np.array_equal(np.signbit(a), np.signbit(b)), name
    assert np.signbit(plain.u_loop[8, 5]) != np.signbit(command[8, 5])


def test_the_blocked_pistons_pressure_gain_is_the_documented_half_milliampere():
    """docs/physics.md §4: once a solid jam seizes the rod, the valve drives the piston to
    ΔP·clip(i/0.5 mA, −1, 1). The pressure a jam shows is that gain's; the figure is an
    estimate, so it is pinned against the document rather than derived."""
    from pathlib import Path

    from scenarios.faults import FAULT_DEFAULTS

    assert FAULT_DEFAULTS.jam_pressure_gain_mA == 0.5
    physics = (Path(__file__).resolve().parents[2] / "docs" / "physics.md").read_text()
    assert "ΔP·clip(i/0.5 mA, −1, 1)" in physics
