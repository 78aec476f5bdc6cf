"""scenarios.aircraft.loop by value: what ``prepare_aircraft`` computes before the time loop,
for a batch formed as a campaign forms it (``single_run`` rows, one monitored surface),
recomputed from the module docstring: the plant at the run's true flight point, the orders'
limits and trim, the exact discretisation, and each run's draws from its own streams in the
documented order — the manoeuvre stream gives the pilot's eight uniforms then the Dryden
turbulence; the sensor stream gives the monitored surface's sensor errors (as at the
actuator level), then the other six surfaces' COM errors, then the aircraft sensor noise.

Every comparison is exact: the same functions on the same inputs give the same floating-point
numbers; a value taken from the wrong stream, position, surface or run differs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from scenarios import acquisition, envelope
from scenarios.aircraft import laws, loop, lpv, pilot
from scenarios.aircraft.data import AIRCRAFT_ACTUATORS, AIRCRAFT_SENSORS, LAYOUT
from scenarios.faults import fault_arrays
from scenarios.manoeuvres import elevator_trim_deg
from scenarios.params import ELEVATOR, SENSORS
from scenarios.runs import flight_of, run_streams
from scenarios.servo import authority_limits, plant_arrays
from scenarios.simulate import servo_provides, single_run
from scenarios.turbulence import MODERATE, dryden_gusts

from test_aircraft_kernel import needs_kernel

MONITORED = "left_inboard_aileron"
CASES = (("turn_coordination", "none"), ("nose_up", "runaway"), ("cruise", "solid_jam"))


def _runs(duration_s=10.0):
    rows = [single_run("aileron", man, fault, duration_s=duration_s,
                       onset_s=min(5.0, duration_s / 2), seed=11 + i,
                       alt_ft=12000.0 + 6000.0 * i, mass_t=150.0 + 30.0 * i)
            for i, (man, fault) in enumerate(CASES)]
    runs = pd.concat(rows, ignore_index=True)
    runs["surface"] = MONITORED
    runs["stream"] = [5, 9, 2]
    runs["run_id"] = [f"v{i}" for i in range(len(runs))]
    return runs


@pytest.fixture(scope="module")
def batch():
    runs = _runs()
    return runs, loop.prepare_aircraft(runs)


def _columns(runs):
    return {c: runs[c].to_numpy(float) for c in runs.columns
            if runs[c].dtype.kind in "fi" and c not in ("seed", "stream")}


def test_the_batch_shape_and_the_monitored_surface(batch):
    runs, p = batch
    assert (p.n, p.T, p.ts, p.monitored) == (3, 1000, 0.01, 2)
    assert p.acts == tuple(AIRCRAFT_ACTUATORS[k] for k in LAYOUT.actuator)
    assert p.airframe == "aircraft"


def test_the_plant_limits_and_trim_of_every_surface(batch):
    """Each surface's plant at the run's true flight point with the run's draws, stacked
    surface-major (index s·n + i); its order limits where the hinge load stays below the
    laws' 0.9 of the stall force; the elevators trimmed (δ_trim of the true α and CG), the
    other surfaces at 0, each inside its limits."""
    runs, p = batch
    f = _columns(runs)
    flight, schedule = flight_of(f)
    draws = {c: f[c] for c in ("d_ch0", "d_cha", "d_chd", "d_supply", "d_kci")}
    for s, act in enumerate(p.acts):
        pl = plant_arrays(act, qbar_pa=flight["qbar_pa"], alpha_deg=flight["alpha_deg"],
                          mach=flight["mach"], **draws)
        for i in range(3):
            assert p.plant.K[s * 3 + i] == pl.K[i] and p.plant.r_mm[s * 3 + i] == pl.r_mm[i]
            assert p.plant.i_max[s * 3 + i] == pl.i_max[i]
        limit = laws.LAWS.hinge_load_limit
        lo, hi = authority_limits(pl, act.replace(order_load_limit=limit))
        np.testing.assert_array_equal(p.lo_deg[s], lo)
        np.testing.assert_array_equal(p.hi_deg[s], hi)
        trim = ([elevator_trim_deg(a, c, ELEVATOR) for a, c in zip(flight["alpha_deg"],
                                                                    f["cg_pct"])]
                if LAYOUT.actuator[s] == "elevator" else np.zeros(3))
        np.testing.assert_array_equal(p.trim_deg[s], np.clip(trim, lo, hi))
        if s == 2:
            np.testing.assert_array_equal(p.plant_m.K, pl.K)
    assert (p.trim_deg[:2] != 0).all() and (p.trim_deg[2:] == 0).all()
    for k in ("mach", "qbar_pa", "alpha_deg"):
        np.testing.assert_array_equal(p.flight_true[k], flight[k])
    for k in ("mach", "qbar_pa", "mass_t", "cg_pct"):
        np.testing.assert_array_equal(p.schedule[k], schedule[k])


def test_the_aircraft_flown_is_the_true_point_discretised_with_the_ramp(batch):
    runs, p = batch
    f = _columns(runs)
    flight, _ = flight_of(f)
    model = lpv.run_models(flight, {c: f[f"d_{c}"] for c in envelope.AERO_COEFFICIENTS})
    phi, gam, ramp = lpv.discretise_ramp(model, 0.01)
    np.testing.assert_array_equal(p.step_matrix, np.concatenate([phi, gam, ramp], axis=2))
    np.testing.assert_array_equal(p.load_matrix, np.concatenate([model.C, model.D], axis=2))
    assert p.law_params is laws.LAWS


def _streams(runs):
    return [run_streams(s, k) for s, k in zip(runs["seed"], runs["stream"])]


def test_the_manoeuvre_stream_gives_the_pilot_then_the_turbulence(batch):
    """Pilot inputs of the run's eight uniforms; then Dryden gusts (u_g, v_g, w_g) at the
    true TAS and altitude, as gust angles α_g = −w_g/V and β_g = −v_g/V."""
    runs, p = batch
    f = _columns(runs)
    flight, _ = flight_of(f)
    t = np.arange(1000) * 0.01
    for i, (man_gen, _) in enumerate(_streams(runs)):
        u = man_gen.uniform(size=8)
        want = pilot.pilot_inputs(CASES[i][0], t, u, pilot.PILOT)
        for got, w in zip((p.nz_c[i], p.p_c[i], p.beta_c[i]), want):
            np.testing.assert_array_equal(got, w)
        V = flight["tas_ms"][i]
        g = dryden_gusts(1000, 0.01, V, f["alt_ft"][i], man_gen, MODERATE)
        np.testing.assert_array_equal(p.gust_alpha[i], -g[2] / V)
        np.testing.assert_array_equal(p.gust_beta[i], -g[1] / V)
    assert np.abs(p.p_c[0]).max() > 0 and np.abs(p.nz_c[1]).max() > 0


def test_calm_air_has_no_gust():
    p = loop.prepare_aircraft(_runs(), turbulence=None)
    assert not p.gust_alpha.any() and not p.gust_beta.any()


def test_the_sensor_stream_gives_the_monitored_errors_then_the_others_then_the_aircraft(batch):
    runs, p = batch
    n, T, m = 3, 1000, 2
    others = [0, 1, 3, 4, 5, 6]
    sig = np.radians([0.02, 0.02, 0.02, 0.02, 0.02, 0, 0, 0.1, 0.1])
    sig[5:7] = 0.003
    np.testing.assert_array_equal(loop._aircraft_noise_sigmas(AIRCRAFT_SENSORS), sig)
    bias, scale = p.com_bias.reshape(7, n), p.com_scale.reshape(7, n)
    noise = p.com_noise.reshape(7, n, T)
    for i, (_, sens) in enumerate(_streams(runs)):
        d = [x[0] for x in acquisition.sensor_draws([sens], T, SENSORS,
                                                    AIRCRAFT_ACTUATORS["aileron"].dP_Pa)]
        assert (bias[m, i], scale[m, i]) == (d[0], d[1])
        np.testing.assert_array_equal(noise[m, i], d[2])
        assert (p.mon_bias[i], p.mon_scale[i], p.surf_bias[i]) == (d[3], d[4], d[6])
        np.testing.assert_array_equal(p.mon_noise[i], d[5])
        np.testing.assert_array_equal(p.surf_noise[i], d[7])
        np.testing.assert_array_equal(p.pres_noise[i], d[8])
        u = sens.uniform(-1.0, 1.0, size=(6, 2))
        z = sens.standard_normal((6, T))
        np.testing.assert_array_equal(bias[others, i], u[:, 0] * SENSORS.rod_bias_mm)
        np.testing.assert_array_equal(scale[others, i], u[:, 1] * SENSORS.rod_scale)
        np.testing.assert_array_equal(noise[others, i], z * SENSORS.rod_noise_mm)
        np.testing.assert_array_equal(p.ac_noise[:, i],
                                      sens.standard_normal((9, T)) * sig[:, None])


def test_the_monitored_surface_carries_the_run_faults(batch):
    """The actuator-level fault arrays of the monitored surface, its runaway as a ramp of the
    order in degrees: asin(u/r) of the rod ramp, clipped to the stroke's ±r."""
    runs, p = batch
    act = AIRCRAFT_ACTUATORS["aileron"]
    col = {c: runs[c].to_numpy() for c in ("fault", "onset_s", "magnitude", "freq_hz")}
    fa = fault_arrays(col["fault"], col["onset_s"], col["magnitude"], col["freq_hz"],
                      np.zeros((3, 1000)), act, 0.01, p.plant_m.i_max)
    np.testing.assert_array_equal(p.faults.k_jam, fa.k_jam)
    np.testing.assert_array_equal(p.ramp_deg, np.degrees(np.arcsin(np.clip(
        fa.u_loop / act.r_mm, -1.0, 1.0))))
    assert p.ramp_deg[1, -1] != 0 and not p.ramp_deg[0].any()
    assert p.faults.k_jam[2] == 500 and p.faults.k_jam[0] > 1000


def test_the_servos_start_at_the_trim(batch):
    _, p = batch
    x, delta = loop.servo_start(p)
    r = p.plant.r_mm
    want = np.clip(r * np.sin(np.radians(p.trim_deg).ravel()), p.plant.x_min, p.plant.x_max)
    np.testing.assert_array_equal(x, want)
    np.testing.assert_array_equal(delta, np.arcsin(want / r))
    assert x[0] != 0 and x[6] == 0


def test_each_law_moves_its_own_surfaces():
    """The pitch order drives the two elevators, the yaw order the rudder, the roll order the
    ailerons with the laws' antisymmetric distribution (docs/aircraft.md §4)."""
    np.testing.assert_array_equal(loop._PITCH, [1, 1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(loop._YAW, [0, 0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(loop._ELEVATORS, [True, True, False, False, False, False,
                                                    False])
    np.testing.assert_array_equal(loop._ROLL, laws.ROLL_DISTRIBUTION[:7])


def test_the_engine_runs_the_kernel_only_when_asked_and_available(batch, monkeypatch):
    """integrate_aircraft: the compiled kernel with engine "compiled" where it can run bit for
    bit, the NumPy reference otherwise (engine "numpy", or the kernel unavailable)."""
    _, p = batch
    monkeypatch.setattr(loop, "_integrate_compiled", lambda p, s: "compiled")
    monkeypatch.setattr(loop, "integrate_reference", lambda p, s: "reference")
    monkeypatch.setattr(loop.kernel, "available", lambda: True)
    assert loop.integrate_aircraft(p, engine="compiled") == "compiled"
    assert loop.integrate_aircraft(p, engine="numpy") == "reference"
    monkeypatch.setattr(loop.kernel, "available", lambda: False)
    assert loop.integrate_aircraft(p, engine="compiled") == "reference"


def test_the_plant_s_options_are_keyword_only():
    """ts, sensors and the pressure sensor are named (a period passed by position would be
    taken for the sensors)."""
    plant = loop.AircraftPlant()
    runs = _runs(1.0)
    with pytest.raises(TypeError, match="positional"):
        plant.simulate_signals(runs, 0.01)
    with pytest.raises(TypeError, match="positional"):
        plant.simulate(runs, 0.01)


def test_the_plant_names_its_surfaces_and_signals():
    plant = loop.AircraftPlant()
    assert plant.run_surface("elevator") == "left_elevator"
    assert plant.run_surface("aileron") == "left_inboard_aileron"
    assert plant.run_surface("aileron", "right_outboard_aileron") == "right_outboard_aileron"
    act = plant.actuator("rudder")
    for pressure in (False, True):
        want = servo_provides(act, pressure) | {"aircraft"}
        assert plant.provides("rudder", pressure_sensor=pressure) == want
        assert "aircraft" in want and len(want) > 1


@needs_kernel
def test_an_offset_jam_and_a_runaway_past_the_stop_in_the_kernel_and_the_reference():
    """The two paths a campaign's default faults rarely take, the kernel against the NumPy
    reference bit for bit: an "offset" solid jam (the rod jumps by −1.1 mm at onset, [CHEN]
    eq. 4) and a runaway at −60 °/s, whose order passes the lower stop and is clipped 5°
    beyond it (docs/physics.md §5), so the rod ends on its stop; the same upwards at 160 kt
    and 10 000 ft, where the hinge load lets the rod reach its upper stop (at 300 kt it
    stalls half-way, where any order beyond saturates the current alike)."""
    runs = _runs(3.0)
    runs.loc[2, ["alt_ft", "vcas_kt"]] = [10000.0, 160.0]
    runs["fault"] = ["solid_jam", "runaway", "runaway"]
    runs["onset_s"] = [1.0, 0.5, 0.5]
    runs["magnitude"] = [-1.1, -60.0, 60.0]
    p = loop.prepare_aircraft(runs)
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    k0 = 100
    # the jump plus the rod's own motion over one period (0.07 mm here, under 0.1 mm)
    assert ref.x[0, k0] - ref.x[0, k0 - 1] == pytest.approx(-1.1, abs=0.1)
    assert (ref.x[0, k0:] == ref.x[0, k0]).all()
    assert ref.x[1, -1] == pytest.approx(p.plant_m.x_min[1], abs=1e-6)
    assert ref.x[2, -1] == pytest.approx(p.plant_m.x_max[2], abs=1e-6)


@needs_kernel
def test_an_elevator_sensor_reading_past_the_rod_s_reach_is_read_at_the_end_of_its_arc():
    """Decision boundary of the elevator angle the laws read from the COM rods (asin of y/r
    clipped to ±1): a monitored elevator's COM acquisition off by ±200 mm (beyond its
    r = 120 mm) is read as ±90° in both engines, bit for bit."""
    runs = _runs(1.0).iloc[:2].copy()
    runs["surface"] = "left_elevator"
    runs["fault"] = "none"
    p = loop.prepare_aircraft(runs, turbulence=None)
    add = np.empty((2, p.T))
    add[0], add[1] = 200.0, -200.0
    p = dataclasses.replace(p, faults=dataclasses.replace(p.faults, com_add=add))
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    assert np.isfinite(ref.states).all()
    assert ref.y_com[0, 0] > 120.0 and ref.y_com[1, 0] < -120.0


def test_prepared_batches_and_plants_are_frozen_and_simulate_aircraft_s_options_named(batch):
    _, p = batch
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.n = 4
    with pytest.raises(dataclasses.FrozenInstanceError):
        loop.AircraftPlant().turbulence = "none"
    with pytest.raises(TypeError, match="positional"):
        loop.simulate_aircraft(_runs(1.0), 0.01)
    with pytest.raises(TypeError, match="positional"):
        loop.prepare_aircraft(_runs(1.0), 0.01)
    traj = loop.integrate_reference(loop.prepare_aircraft(_runs(1.0)))
    with pytest.raises(dataclasses.FrozenInstanceError):
        traj.x = traj.x


def test_the_plant_has_no_pressure_sensor_unless_asked():
    runs = _runs(1.0)
    plant = loop.AircraftPlant(turbulence="none")
    assert np.isnan(plant.simulate(runs)[0].pressure).all()
    assert np.isfinite(plant.simulate(runs, pressure_sensor=True)[0].pressure).all()


def test_the_options_of_the_block_functions_and_of_the_plant_are_named(batch):
    runs, p = batch
    plant = loop.AircraftPlant()
    with pytest.raises(TypeError, match="positional"):
        plant.simulate(runs, 0.01)
    with pytest.raises(TypeError, match="positional"):
        plant.provides("rudder", False)
    with pytest.raises(TypeError, match="positional"):
        loop._simulate_block(runs, 0.01, SENSORS, False, None, laws.LAWS, AIRCRAFT_SENSORS,
                             True)
    small = _runs(1.0)
    q = loop.prepare_aircraft(small)
    traj = loop.integrate_reference(q)
    with pytest.raises(TypeError, match="positional"):
        loop.trajectory_signals(traj, q, small, 0.01, SENSORS, False, True)


def test_blocks_that_all_have_a_jam_keep_every_rod_fault(monkeypatch):
    """rod_fault_mm of a batch cut into blocks each with a solid jam: every block's series
    (none is NaN-filled or dropped), as the batch simulated whole gives them."""
    runs = _runs(1.0).iloc[:2].copy()
    runs["fault"] = "solid_jam"
    runs["onset_s"] = 0.5
    runs["magnitude"] = np.nan
    _, whole = loop.simulate_aircraft(runs, turbulence=None)
    monkeypatch.setattr(loop.AircraftPlant, "batch_runs", 1)
    _, cut = loop.simulate_aircraft(runs, turbulence=None)
    assert cut.rod_fault_mm is not None and np.isfinite(cut.rod_fault_mm[:, -1]).all()
    np.testing.assert_array_equal(cut.rod_fault_mm, whole.rod_fault_mm)
