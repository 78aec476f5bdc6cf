"""docs/physics.md §8 sanity facts of the servo-loop, as quantitative checks.

Most checks drive the loop with a constructed order (``orders_deg``) and ideal sensors, so
the numbers compared are those of the plant and the loop, not of the noise.
"""

import dataclasses

import numpy as np
import pytest

from scenarios.params import AILERON, ELEVATOR, SENSORS
from scenarios.servo import plant_arrays
from scenarios.simulate import simulate, single_run

TS = 0.01
#: Ideal sensors: no noise, bias, scale error; a quantisation far below anything compared.
IDEAL = dataclasses.replace(SENSORS, rod_noise_mm=0.0, rod_quant_mm=1e-9, rod_bias_mm=0.0,
                            rod_scale=0.0, surface_noise_deg=0.0, surface_quant_deg=1e-9,
                            surface_bias_deg=0.0)
#: A low dynamic-pressure point (38 000 ft, 160 kt): the hinge load is a few % of S·ΔP.
LOW_Q = {"alt_ft": 38000.0, "vcas_kt": 160.0, "mass_t": 120.0, "cg_pct": 30.0}
#: A high dynamic-pressure point (8 000 ft, 300 kt).
HIGH_Q = {"alt_ft": 8000.0, "vcas_kt": 300.0, "mass_t": 180.0, "cg_pct": 30.0}
ACTS = {"elevator": ELEVATOR, "aileron": AILERON}


def run(surface, order_deg, fault="none", sensors=IDEAL, actuators=None, **kw):
    duration = order_deg.shape[-1] * TS
    runs = single_run(surface, "cruise", fault, duration_s=duration, **kw)
    return simulate(runs, orders_deg=np.atleast_2d(order_deg), sensors=sensors,
                    actuators=actuators)


def step_order(n, k0, level):
    o = np.zeros(n)
    o[k0:] = level
    return o


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_small_signal_time_constant(surface):
    act = ACTS[surface]
    k0, amp = 20, 0.3                                   # 0.3° step: far from saturation
    _, truth = run(surface, step_order(150, k0, amp), **LOW_Q)
    x = truth.rod_mm[0] - truth.rod_mm[0, 0]
    target = act.deg_to_mm(amp)
    # time from the step to 63.2 % of the final value; the one-period delay and the
    # zero-order hold shift it by about Ts against 1/(Kci·K): 10 % covers both (docs/physics.md §8).
    k63 = np.argmax(x >= (1 - np.exp(-1)) * target)
    tau = (k63 - k0) * TS
    assert tau == pytest.approx(act.tau_s, rel=0.10)
    assert x[-1] == pytest.approx(target, rel=1e-6)     # no static error


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_saturated_rate_without_load_is_kci_imax(surface):
    act = ACTS[surface]
    # "no load": no hinge moment (zero surface area) and no damping neighbour (Ka = 0)
    unloaded = act.replace(Sc_m2=0.0, Ka_N_per_mm_s2=0.0)
    _, truth = run(surface, step_order(200, 10, act.delta_max_deg - 1), **LOW_Q,
                   actuators={surface: unloaded})
    rate = np.max(np.diff(truth.rod_mm[0])) / TS
    assert rate == pytest.approx(act.rate_max_mm_s, rel=0.05)


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_saturated_rate_with_damping_neighbour_and_opposing_load(surface):
    act = ACTS[surface]
    no_aero = act.replace(Sc_m2=0.0)
    _, free = run(surface, step_order(200, 10, act.delta_max_deg - 1), **LOW_Q,
                  actuators={surface: no_aero})
    rate_free = np.max(np.diff(free.rod_mm[0])) / TS
    # [COMB] eq. 2 with F_aero = 0: Kci·i·sqrt(SΔP / (SΔP_ref + Ka·(Kci·i)²))
    v0 = act.rate_max_mm_s
    expected = v0 * np.sqrt(act.S_m2 * act.dP_Pa / (act.S_m2 * act.dP_ref_Pa
                                                    + act.Ka_N_per_mm_s2 * v0 ** 2))
    assert rate_free == pytest.approx(expected, rel=0.01)
    # the same stroke at high dynamic pressure, opening against the hinge moment, is slower
    _, loaded = run(surface, step_order(200, 10, act.delta_max_deg - 1), **HIGH_Q)
    x = loaded.rod_mm[0]
    rate_loaded = np.max(np.diff(x[x < act.deg_to_mm(act.delta_max_deg - 2)])) / TS
    assert rate_loaded < 0.97 * rate_free


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_steady_state_tracks_order_under_load(surface):
    act = ACTS[surface]
    level = 5.0      # docs/physics.md §3: at high q̄ and 5° the load is tens of % of S·ΔP
    _, truth = run(surface, step_order(400, 10, level), **HIGH_Q)
    # the hinge load at this point is a sizeable share of the stall force...
    p = plant_arrays(act, qbar_pa=truth.flight["qbar_pa"], alpha_deg=truth.flight["alpha_deg"],
                     mach=truth.flight["mach"])
    from scenarios.servo import aero_force
    share = abs(aero_force(act.deg_to_mm(level), p)[0]) / p.SdP[0]
    assert share > 0.1
    # ...and yet the rod settles on the order (the loop has integral action through ẋ ∝ i)
    assert truth.surface_deg[0, -1] == pytest.approx(level, abs=1e-6)


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_runaway_moves_at_its_rate_then_stops_at_the_stop(surface):
    act = ACTS[surface]
    onset, rate = 1.0, 5.0
    _, truth = run(surface, np.zeros(1200), "runaway", onset_s=onset, magnitude=rate, **LOW_Q)
    d = truth.surface_deg[0]
    t = np.arange(d.size) * TS
    window = (t > onset + 0.5) & (d < act.delta_max_deg - 2)   # ramp established, before stop
    slope = np.polyfit(t[window], d[window], 1)[0]
    assert slope == pytest.approx(rate, rel=0.05)
    assert d[-1] == pytest.approx(act.stop_max_deg, abs=1e-6)   # held at the mechanical stop


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_solid_jam_freezes_rod_and_surface(surface):
    act = ACTS[surface]
    order = 3.0 * np.sin(2 * np.pi * 0.3 * np.arange(800) * TS)
    sig, truth = run(surface, order, "solid_jam", onset_s=2.0, **HIGH_Q)
    k0 = 200
    assert np.ptp(truth.rod_mm[0, k0:]) == 0.0
    assert np.ptp(truth.surface_deg[0, k0:]) == 0.0
    # the loop error grows with the moving order until the current saturates
    assert np.max(np.abs(sig.current[0, k0:])) == pytest.approx(act.i_max_mA)


def test_liquid_jam_transient_and_offset():
    act = ELEVATOR
    bias = 1.2                                              # [mm] ≈ 1.3 % of the range
    order = np.full(600, 2.0)
    sig, truth = run("elevator", order, "liquid_jam", onset_s=1.0, magnitude=bias, **HIGH_Q)
    k0 = 100
    u = sig.command[0]
    err_com = sig.rod_com[0] - u
    k5tau = k0 + int(np.ceil(5 * act.tau_s / TS))
    assert np.max(np.abs(err_com[k0:k0 + 5])) > 0.8 * bias   # the transient appears on COM
    assert np.max(np.abs(err_com[k5tau:])) < 0.01 * bias     # ... and has died out by 5τ
    # the real rod (and MON) settle at order − bias
    assert truth.rod_mm[0, -1] == pytest.approx(u[-1] - bias, abs=1e-4)
    assert sig.rod_mon[0, -1] == pytest.approx(u[-1] - bias, abs=1e-4)


def test_disconnection_surface_floats_while_rod_tracks():
    act = ELEVATOR
    order = np.full(400, -8.0)
    order[250:] = -6.0                                       # the order moves after onset
    sig, truth = run("elevator", order, "disconnection", onset_s=1.0, **HIGH_Q)
    p = plant_arrays(act, qbar_pa=truth.flight["qbar_pa"], alpha_deg=truth.flight["alpha_deg"],
                     mach=truth.flight["mach"])
    d_float = np.degrees(p.delta_float_rad[0])
    assert truth.surface_deg[0, -1] == pytest.approx(d_float, abs=0.01)
    assert abs(d_float - (-8.0)) > 3.0                        # it really went somewhere
    # the rod keeps tracking the order, now unloaded
    assert truth.rod_mm[0, -1] == pytest.approx(act.deg_to_mm(-6.0), abs=1e-5)
    # the surface sensor shows the float, the rod sensors do not
    assert sig.surface[0, -1] == pytest.approx(d_float, abs=0.01)
