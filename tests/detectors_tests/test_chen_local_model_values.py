"""The quasi-LPV actuator model of chen-local (detectors/synthesis/chen_local_model.py,
docs/chen-estimator.md §1) pinned by value, in a few seconds: the scheduling vector and the
affine coefficients, the gain of [CHEN] eq. 13, the current saturation and the damping factor
with their coefficients from the actuator table, the linearised physical coefficients, the
bilinear step, the discrete model against a plain-Python recursion and its sensitivities
against central differences, the excitation orders by their formula, and the output-error
identification on a noise-free record made by a known model (it must find that model).

Expected values are written out from the documented formulas, never taken from the
function under test.
"""

from __future__ import annotations

import math
from dataclasses import FrozenInstanceError

import numpy as np
import pytest

from detectors.synthesis import chen_local_model as lm
from scenarios.params import ACTUATORS
from scenarios.servo import authority_limits, plant_arrays

ACT = ACTUATORS["elevator"]
AIL = ACTUATORS["aileron"]
TS = 0.01
#: hand-built coefficients of C0 [1/s], C1 [1/(s·mm)], C2 [mm] on [1, q̄/10⁴ Pa, M, α/10°]
THETA = np.array([[14.0, 1.2, -3.0, 2.0],
                  [-0.02, -0.03, 0.01, 0.015],
                  [4.0, 1.5, -2.0, 6.0]])
SCHEDULE = {"qbar_pa": np.array([12000.0, 25000.0, 6000.0]),
            "mach": np.array([0.55, 0.8, 0.35]),
            "alpha_deg": np.array([2.5, 1.0, 6.0])}


def _rho(schedule):
    """ρ = (q̄/10 kPa, Mach, α/10°) (docs/chen-estimator.md §1), one row per run."""
    return np.array([[q / 1e4, m, a / 10.0] for q, m, a in zip(schedule["qbar_pa"],
                                                                schedule["mach"],
                                                                schedule["alpha_deg"])])


def _coeffs(theta, rho_row):
    return [theta[m, 0] + sum(theta[m, j + 1] * rho_row[j] for j in range(len(rho_row)))
            for m in range(3)]


def _simulate(theta, rho, u, x0, delay, e_sat=math.inf, kappa=0.0):
    """The discrete model of the module docstring, plain Python: x_{k+1} = v + (x − v)·φ(K̃),
    v = u_{k−d}, K̃ = K·σ·D, φ(a) = (1 − a·Ts/2)/(1 + a·Ts/2)."""
    n, T = u.shape
    out = np.empty((n, T))
    for r in range(n):
        c0, c1, c2 = _coeffs(theta, rho[r])
        x = float(x0[r])
        for k in range(T):
            out[r, k] = x
            v = float(u[r, max(k - delay, 0)])
            e = v - x
            s = 1.0 if e > 0.0 else (-1.0 if e < 0.0 else 0.0)
            K = c0 + c1 * s * (x + c2)
            sig = min(1.0, e_sat / abs(e)) if e != 0.0 else 1.0
            D = 1.0 / math.sqrt(1.0 + kappa * (c0 * sig * e) ** 2)
            a = K * sig * D
            x = v + (x - v) * (1.0 - 0.5 * TS * a) / (1.0 + 0.5 * TS * a)
    return out


def _orders(T=300):
    """Three runs: a step far beyond e_sat and back, a slow ramp, a sine (orders [mm])."""
    t = np.arange(T) * TS
    return np.stack([np.where(t < 0.5, 0.0, 30.0) - np.where(t < 1.8, 0.0, 45.0),
                     -20.0 + 9.0 * t,
                     8.0 * np.sin(2.0 * np.pi * 0.9 * t)])


# ---- scheduling and coefficients ---------------------------------------------------------
def test_scheduling_vector_basis_and_coefficients():
    rho = lm.scheduling_vector(SCHEDULE)
    np.testing.assert_array_equal(rho, _rho(SCHEDULE))
    np.testing.assert_array_equal(lm.basis(rho), np.hstack([np.ones((3, 1)), _rho(SCHEDULE)]))
    c = lm.coefficients(THETA, rho)
    for r in range(3):
        np.testing.assert_allclose([c[m][r] for m in range(3)], _coeffs(THETA, rho[r]),
                                   rtol=1e-14)
    # a run's coefficients do not depend on the batch
    c1 = lm.coefficients(THETA, rho[1:2])
    assert [float(c1[m][0]) for m in range(3)] == [float(c[m][1]) for m in range(3)]


def test_basis_keeps_any_leading_shape():
    """φ(ρ) = [1, ρ] on the last axis, whatever the leading dimensions (…, n_ρ)."""
    rho = np.arange(12.0).reshape(2, 2, 3)
    out = lm.basis(rho)
    assert out.shape == (2, 2, 4)
    np.testing.assert_array_equal(out[..., 0], 1.0)
    np.testing.assert_array_equal(out[..., 1:], rho)
    np.testing.assert_array_equal(lm.basis([0.5, 2.0, 3.0]), [1.0, 0.5, 2.0, 3.0])


def test_one_flight_point_given_as_scalars():
    """Scalars (one flight point) give one ρ vector and one (C0, C1, C2)."""
    point = {k: float(v[0]) for k, v in SCHEDULE.items()}
    np.testing.assert_array_equal(lm.scheduling_vector(point), _rho(SCHEDULE)[0])
    np.testing.assert_allclose(lm.physical_coefficients(ACT, point),
                               lm.physical_coefficients(ACT, SCHEDULE)[0], rtol=1e-15)


def test_scheduling_vector_names_missing_data():
    with pytest.raises(ValueError, match=r"needs the scheduling data \['mach'\]"):
        lm.scheduling_vector({"qbar_pa": [1.0], "alpha_deg": [1.0]})


def test_gain_of_eq_13():
    assert lm.gain(10.0, 0.5, 3.0, 4.0, 1.0) == 10.0 + 0.5 * 7.0
    assert lm.gain(10.0, 0.5, 3.0, 4.0, -1.0) == 10.0 - 0.5 * 7.0
    assert lm.gain(10.0, 0.5, 3.0, 4.0, 0.0) == 10.0


def test_saturation_and_damping_from_the_actuator_table():
    # docs/chen-estimator.md §1: e_sat = i_max/K_s, 6.7 mm on the elevator, 4 mm on the aileron
    assert lm.saturation_mm(ACT) == pytest.approx(ACT.i_max_mA / ACT.K_mA_per_mm, rel=1e-15)
    assert lm.saturation_mm(ACT) == pytest.approx(6.67, abs=0.01)
    assert lm.saturation_mm(AIL) == pytest.approx(4.0, abs=0.01)
    kappa = ACT.Ka_N_per_mm_s2 / (ACT.S_m2 * ACT.dP_ref_Pa)
    assert lm.damping_coefficient(ACT) == pytest.approx(kappa, rel=1e-15)
    # D at the saturated no-load speed: the rod slowed by a few per cent (§1: about 5 %)
    v0 = ACT.bandwidth_per_s * lm.saturation_mm(ACT)
    assert lm.damping_factor(v0, kappa) == pytest.approx(1.0 / math.sqrt(1.0 + kappa * v0 ** 2),
                                                         rel=1e-15)
    assert 0.9 < lm.damping_factor(v0, kappa) < 0.99
    e = np.array([-9.0, -2.0, 0.0, 1.5, 2.0, 2.0000001, 8.0])
    np.testing.assert_array_equal(lm.saturation_factor(e, 2.0),
                                  [2.0 / 9.0, 1.0, 1.0, 1.0, 1.0, 2.0 / 2.0000001, 0.25])


def test_physical_coefficients_linearise_the_load_law():
    """C0 = Kci·K_s, C1 = Kci·K_s·q̄·S_c·c_c·PG(M)·Chδ/(2·r[m]·r[mm]·S·ΔP), C2 =
    r·Chα·α_s/Chδ with α_s = α·(1 − dε/dα) (docs/chen-estimator.md §1, docs/physics.md §3):
    PG held at the compressibility cap above it."""
    out = lm.physical_coefficients(ACT, SCHEDULE)
    bw = ACT.Kci_mm_s_per_mA * ACT.K_mA_per_mm
    for r in range(3):
        q, m, a = (float(SCHEDULE[k][r]) for k in ("qbar_pa", "mach", "alpha_deg"))
        pg = 1.0 / math.sqrt(1.0 - min(m, ACT.mach_compress_cap) ** 2)
        c1 = (bw * q * ACT.Sc_m2 * ACT.cc_m * pg * ACT.Ch_delta
              / (2.0 * (ACT.r_mm / 1000.0) * ACT.r_mm * ACT.S_m2 * ACT.dP_Pa))
        c2 = ACT.r_mm * ACT.Ch_alpha * math.radians(a) * (1.0 - ACT.downwash) / ACT.Ch_delta
        np.testing.assert_allclose(out[r], [bw, c1, c2], rtol=1e-13)
    assert SCHEDULE["mach"][1] > ACT.mach_compress_cap        # the cap is exercised


def test_tustin_pole():
    assert lm.tustin_pole(20.0, 0.01) == (1.0 - 0.1) / (1.0 + 0.1)
    assert lm.tustin_pole(0.0, 0.01) == 1.0
    assert lm.tustin_pole(400.0, 0.01) == -1.0 / 3.0


# ---- the discrete model ------------------------------------------------------------------
@pytest.mark.parametrize("delay", [0, 1, 2])
def test_simulate_model_follows_the_recursion(delay):
    u = _orders()
    rho = _rho(SCHEDULE)
    x0 = np.array([0.5, -19.0, 1.0])
    e_sat, kappa = 6.0, 2e-4
    x = lm.simulate_model(THETA, rho, u, TS, x0, delay, e_sat=e_sat, kappa=kappa)
    np.testing.assert_allclose(x, _simulate(THETA, rho, u, x0, delay, e_sat, kappa),
                               rtol=1e-12, atol=1e-12)
    # no saturation, no damping (the defaults)
    np.testing.assert_allclose(lm.simulate_model(THETA, rho, u, TS, x0, delay),
                               _simulate(THETA, rho, u, x0, delay), rtol=1e-12, atol=1e-12)
    x2, dx = lm.simulate_model(THETA, rho, u, TS, x0, delay, sensitivities=True, e_sat=e_sat,
                               kappa=kappa)
    np.testing.assert_array_equal(x2, x)
    assert dx.shape == (3, u.shape[1], 12)


@pytest.mark.parametrize("e_sat, kappa", [(math.inf, 0.0), (6.0, 2e-4), (6.0, 0.0)])
def test_sensitivities_match_central_differences(e_sat, kappa):
    """dx/dθ of the recursion against (x(θ + h) − x(θ − h))/2h, h = 1e-6 of each
    coefficient's scale: the model is smooth between sign and saturation changes, which
    only kink it (σ, D and (x − v)·φ are continuous), so the difference quotient agrees to
    the truncation and rounding error, 1e-5 of the largest sensitivity."""
    u = _orders(200)
    rho = _rho(SCHEDULE)
    x0 = np.array([0.5, -19.0, 1.0])
    _, dx = lm.simulate_model(THETA, rho, u, TS, x0, 1, sensitivities=True, e_sat=e_sat,
                              kappa=kappa)
    th = THETA.ravel()
    for i in range(th.size):
        h = 1e-6 * max(abs(th[i]), 1e-2)
        plus, minus = th.copy(), th.copy()
        plus[i] += h
        minus[i] -= h
        fd = (_simulate(plus.reshape(3, -1), rho, u, x0, 1, e_sat, kappa)
              - _simulate(minus.reshape(3, -1), rho, u, x0, 1, e_sat, kappa)) / (2.0 * h)
        scale = max(np.abs(fd).max(), 1e-9)
        np.testing.assert_allclose(dx[:, :, i], fd, rtol=0, atol=1e-5 * scale,
                                   err_msg=f"coefficient {i}")
    assert np.abs(dx[:, 0]).max() == 0.0           # x0 does not depend on θ


# ---- the excitation ----------------------------------------------------------------------
def test_schedule_moves_and_excitation_orders_by_formula():
    s = lm.IdentificationSettings(levels=(0.5, 0.9, 0.1, 0.5), rates_deg_s=(10.0, 200.0),
                                  holds_s=(0.3, 0.2), sine_amp_frac=0.02, sine_hz=2.0,
                                  input_delay_steps=1, max_nfev=5)
    span = 40.0
    moves, duration = s.schedule_moves(span)
    # move j from level j to j + 1 at the rate j mod 2, lasting π·|Δ|·span/(2·rate) (a
    # raised cosine of that peak rate), at least 0.05 s; holds cycle (0.3, 0.2) starting
    # with the first
    d0 = math.pi * 0.4 * span / 20.0
    d1 = max(math.pi * 0.8 * span / 400.0, 0.05)
    d2 = math.pi * 0.4 * span / 20.0
    expected = [(0.3, 0.5, 0.9, d0), (0.3 + d0 + 0.2, 0.9, 0.1, d1),
                (0.3 + d0 + 0.2 + d1 + 0.3, 0.1, 0.5, d2)]
    assert len(moves) == 3
    np.testing.assert_allclose(moves, expected, rtol=1e-14)
    assert duration == pytest.approx(0.3 + d0 + 0.2 + d1 + 0.3 + d2 + 0.2, rel=1e-14)
    short = lm.IdentificationSettings(levels=(0.0, 0.01), rates_deg_s=(100.0,), holds_s=(0.1,),
                                      sine_amp_frac=0.0, sine_hz=1.0, input_delay_steps=1,
                                      max_nfev=5)
    assert short.schedule_moves(10.0)[0][0][3] == 0.05       # the shortest move

    lo, hi = np.array([-20.0, -10.0]), np.array([20.0, 10.0])
    orders = lm.excitation_orders(lo, hi, TS, s)
    T = int(round(duration / TS))
    assert orders.shape == (2, T)
    t = np.arange(T) * TS
    for k in (0, 10, 45, int((0.3 + d0 / 2) / TS), int((0.5 + d0 + d1 / 2) / TS), T - 1):
        frac = 0.5
        for start, a, b, dur in expected:
            if t[k] >= start:
                xi = min(max((t[k] - start) / dur, 0.0), 1.0)
                frac = a + (b - a) * 0.5 * (1.0 - math.cos(math.pi * xi))
        frac = min(max(frac + 0.02 * math.sin(2.0 * math.pi * 2.0 * t[k]), 0.0), 1.0)
        np.testing.assert_allclose(orders[:, k], lo + (hi - lo) * frac, rtol=1e-12,
                                   atol=1e-12)


def test_excitation_orders_stay_inside_the_authority():
    s = lm.IdentificationSettings(levels=(0.5, 1.0, 0.0), rates_deg_s=(50.0,), holds_s=(0.2,),
                                  sine_amp_frac=0.05, sine_hz=3.0, input_delay_steps=1,
                                  max_nfev=5)
    orders = lm.excitation_orders(np.array([-5.0]), np.array([15.0]), TS, s)
    assert orders.min() == -5.0 and orders.max() == 15.0    # clipped at both limits


# ---- the identification ------------------------------------------------------------------
def test_identification_recovers_the_model_of_a_noise_free_record(monkeypatch):
    """Rod positions made by the discrete model itself from known coefficients (start:
    the physical ones, moved by 10–30 %): the output-error fit finds them again and its
    RMS is at rounding level; the initial RMS is the physical start's."""
    schedule = {"qbar_pa": np.array([4000.0, 9000.0, 15000.0, 22000.0, 30000.0, 12000.0]),
                "mach": np.array([0.3, 0.45, 0.6, 0.7, 0.82, 0.5]),
                "alpha_deg": np.array([7.0, 4.0, 2.5, 1.5, 0.8, 5.0])}
    rho = _rho(schedule)
    phi = np.hstack([np.ones((6, 1)), rho])
    phys = lm.physical_coefficients(ACT, schedule)
    theta0 = np.linalg.lstsq(phi, phys, rcond=None)[0].T
    truth = theta0 * np.array([[1.1], [0.8], [1.3]]) + np.array([[0.5], [0.0], [0.2]])
    t = np.arange(400) * TS
    u = np.stack([15.0 * np.sin(2.0 * np.pi * (0.4 + 0.15 * r) * t) - 10.0
                  + np.where(t > 2.0, 20.0, 0.0) for r in range(6)])
    e_sat, kappa = lm.saturation_mm(ACT), lm.damping_coefficient(ACT)
    x_true = _simulate(truth, rho, u, u[:, 0] - 1.0, 1, e_sat, kappa)
    monkeypatch.setattr(lm, "identification_runs",
                        lambda act, ts, settings: (schedule, u, x_true))
    fit = lm.fit_local_model.__wrapped__(ACT, TS)        # not the per-actuator cache
    np.testing.assert_allclose(fit.theta, truth, rtol=1e-6, atol=1e-8)
    assert fit.rms_mm < 1e-8 and fit.max_abs_mm < 1e-7
    r0 = _simulate(theta0, rho, u, u[:, 0] - 1.0, 1, e_sat, kappa) - x_true
    assert fit.rms_initial_mm == pytest.approx(math.sqrt(np.mean(r0 ** 2)), rel=1e-9)
    assert fit.rms_initial_mm > 0.1
    assert (fit.e_sat_mm, fit.kappa) == (e_sat, kappa)
    np.testing.assert_array_equal(fit.rho_min, rho.min(axis=0))
    np.testing.assert_array_equal(fit.rho_max, rho.max(axis=0))
    assert (fit.x_min_mm, fit.x_max_mm) == (x_true.min(), x_true.max())
    assert (fit.n_points, fit.ts, fit.delay) == (6, TS, 1)
    with pytest.raises(FrozenInstanceError):
        fit.rms_mm = 0.0
    d = fit.as_dict()
    assert d["theta"] == fit.theta.tolist() and d["rho_names"] == ["qbar_pa", "mach",
                                                                   "alpha_deg"]
    assert (d["e_sat_mm"], d["kappa"], d["rms_mm"], d["max_abs_mm"], d["rms_initial_mm"],
            d["n_points"]) == (e_sat, kappa, fit.rms_mm, fit.max_abs_mm, fit.rms_initial_mm, 6)


def test_identification_settings_and_a_surface_without_servo_loop():
    assert lm.SETTINGS.input_delay_steps == 1           # docs/physics.md §2: one Ts
    assert max(lm.SETTINGS.rates_deg_s[:9]) <= 25.0     # slow moves: the manoeuvres' rates
    assert min(lm.SETTINGS.rates_deg_s[9:]) >= 80.0     # fast moves: 80–300 °/s (§1)
    with pytest.raises(FrozenInstanceError):
        lm.SETTINGS.max_nfev = 1
    with pytest.raises(ValueError, match="no servo-loop to identify for surface 'rudder_x'"):
        lm.identification_runs(ACT.replace(surface="rudder_x"), TS)


def test_the_excitation_settings_as_designed():
    """The identification's excitation (docs/chen-estimator.md §1): seventeen levels across
    the authority, nine slow moves at the manoeuvres' rates then seven fast ones that
    saturate the current, the holds, a 1 % sine at 1.5 Hz, one period of delay, 60
    evaluations of least_squares (all est.; the identified model below depends on each)."""
    assert lm.SETTINGS == lm.IdentificationSettings(
        levels=(0.5, 0.7, 0.35, 0.9, 0.1, 0.6, 0.02, 0.45, 0.98, 0.5,
                0.95, 0.05, 0.7, 0.02, 0.98, 0.3, 0.5),
        rates_deg_s=(20.0, 5.0, 25.0, 10.0, 15.0, 3.0, 22.0, 8.0, 18.0,
                     150.0, 80.0, 300.0, 120.0, 200.0, 100.0, 250.0),
        holds_s=(0.5, 0.8, 0.4, 1.0), sine_amp_frac=0.01, sine_hz=1.5,
        input_delay_steps=1, max_nfev=60)


@pytest.mark.parametrize("surface, rms, largest, start", [
    ("elevator", 0.128, 0.98, 0.24),
    ("aileron", 0.118, 1.15, 0.40),
])
def test_the_identification_gives_the_documented_fit(surface, rms, largest, start):
    """docs/chen-estimator.md §1's table at Ts = 10 ms: output-error RMS, largest error and
    RMS of the physical start, 53 realistic points (within the table's rounding)."""
    fit = lm.fit_local_model(ACTUATORS[surface], TS)
    assert fit.rms_mm == pytest.approx(rms, abs=5e-4)
    assert fit.max_abs_mm == pytest.approx(largest, abs=5e-3)
    assert fit.rms_initial_mm == pytest.approx(start, abs=5e-3)
    assert (fit.n_points, fit.delay, fit.ts) == (53, 1, TS)
    if surface == "elevator":
        # the levels reach 2 % from each point's authority limits; the widest authority
        # comes within 20 % of the electrical limits (the load limits the nose-down side)
        assert fit.x_min_mm < 0.8 * ACT.u_min_mm and fit.x_max_mm > 0.9 * ACT.u_max_mm


def test_an_aircraft_surface_is_identified_on_the_servo_loop_of_its_kind(monkeypatch):
    """left_inboard_aileron has no servo-loop table of its own: the fault-free cruise runs
    (seed 0, one per realistic point, as long as the excitation) are simulated on the
    aileron's loop with the surface's parameters, driven by the excitation orders inside
    each point's authority; the identification reads the measured schedule, the order and
    the true rod position."""
    import types

    from scenarios import envelope
    from scenarios import simulate as simulation

    seen = {}

    def fake_simulate(rows, ts, actuators, orders_deg):
        seen.update(rows=rows, ts=ts, actuators=actuators, orders=orders_deg)
        n, T = orders_deg.shape
        return (types.SimpleNamespace(schedule={"mark": 1}, command=np.full((n, T), 2.0)),
                types.SimpleNamespace(rod_mm=np.full((n, T), 3.0)))

    monkeypatch.setattr(simulation, "simulate", fake_simulate)
    act = AIL.replace(surface="left_inboard_aileron", i_max_mA=9.0)
    schedule, u, x = lm.identification_runs(act, TS)
    assert schedule == {"mark": 1} and (u == 2.0).all() and (x == 3.0).all()
    assert seen["ts"] == TS and seen["actuators"] == {"aileron": act.replace(surface="aileron")}
    rows, orders = seen["rows"], seen["orders"]
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]]
    assert len(rows) == len(pts) == orders.shape[0] == 53
    for c in ("alt_ft", "vcas_kt", "mass_t", "cg_pct"):
        np.testing.assert_array_equal(rows[c].to_numpy(float), pts[c].to_numpy(float))
    assert set(rows["surface"]) == {"aileron"} and set(rows["manoeuvre"]) == {"cruise"}
    assert set(rows["fault"]) == {"none"} and set(rows["seed"]) == {0}
    assert rows["stream"].tolist() == list(range(53)) and rows["run_id"].is_unique
    assert rows.index.tolist() == list(range(53))       # one run table, not 53 stacked
    np.testing.assert_allclose(rows["duration_s"], orders.shape[1] * TS, rtol=1e-12)
    # orders [deg] inside each point's authority (the surface's own parameters), reaching
    # within 2 % of it at both ends (levels 0.02 and 0.98, the 1 % sine)
    fc = envelope.flight_condition(*(pts[c].to_numpy(float) for c in ("alt_ft", "vcas_kt",
                                                                      "mass_t", "cg_pct")))
    lo, hi = authority_limits(plant_arrays(act, qbar_pa=fc["qbar_pa"],
                                           alpha_deg=fc["alpha_deg"], mach=fc["mach"]), act)
    width = hi - lo
    assert (orders.min(axis=1) >= lo).all() and (orders.max(axis=1) <= hi).all()
    assert (orders.min(axis=1) <= lo + 0.02 * width).all()
    assert (orders.max(axis=1) >= hi - 0.02 * width).all()
