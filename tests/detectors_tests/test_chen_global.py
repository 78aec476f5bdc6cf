"""The global level of [CHEN] (chen-global): lateral LPV model affine in the scheduling
vector, vertex-LMI gains of eq. 20–23, unit static gain on the design model, and detection
of the left inboard aileron's disconnection on simulated aircraft runs."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from detectors.builtin.chen_global import (INPUT_SURFACES, OUTPUTS, ChenGlobalEstimator,
                                   lateral_models, output_matrix, scheduling_vector,
                                   table2_error_bounds)
from detectors.synthesis.chen_global_uncertainty import (CHANNELS, SIGNALS, error_bounds,
                                                         signal_matrices,
                                               uncertainty_matrix)
from detectors.synthesis.lpv_synthesis import discretise, hinf_sweep
from scenarios.signals import Signals
from scenarios.plants import simulate
from scenarios.simulate import single_run

MONITORED = "left_inboard_aileron"
#: Flight points of the simulated runs (realistic points of the [CHEN] Table-1 grid).
POINTS = {
    "high_fast": dict(alt_ft=28000.0, vcas_kt=300.0, mass_t=180.0, cg_pct=30.0),
    "low_slow": dict(alt_ft=8000.0, vcas_kt=160.0, mass_t=120.0, cg_pct=17.0),
    "high_heavy": dict(alt_ft=38000.0, vcas_kt=220.0, mass_t=233.0, cg_pct=41.0),
    "mid": dict(alt_ft=18000.0, vcas_kt=220.0, mass_t=180.0, cg_pct=30.0),
}
DURATION_S = 30.0
ONSET_S = 10.0


def _runs(specs):
    rows = [single_run(MONITORED, m, f, seed=5, onset_s=ONSET_S, duration_s=DURATION_S,
                       **POINTS[p]).assign(stream=j, run_id=f"{p}-{m}-{f}")
            for j, (p, m, f) in enumerate(specs)]
    return pd.concat(rows, ignore_index=True)


@pytest.fixture(scope="module")
def learning():
    """Fault-free aircraft runs: the six manoeuvres at two points."""
    manoeuvres = ["cruise", "nose_up", "aoa_protection", "pitch_protection", "yaw_angle_mode",
                  "turn_coordination"]
    learn = _runs([(p, m, "none") for p in ("high_fast", "low_slow") for m in manoeuvres])
    sig, _ = simulate(learn, plant="aircraft")
    return sig


@pytest.fixture(scope="module")
def fitted(learning):
    """chen-global fitted on the fault-free runs of :func:`learning`."""
    return ChenGlobalEstimator().fit(learning)


def test_the_activity_bound_lowers_the_learned_threshold(fitted, learning):
    """τ0 is learned on |f̂| − b(t): below the constant threshold learned on |f̂| alone, which
    the turns set; without ``adaptive`` the bound is zero."""
    constant = ChenGlobalEstimator(adaptive=False).fit(learning)
    assert not constant.activity_bound(learning).any()
    b = fitted.activity_bound(learning)
    assert b.min() >= 0.0 and b.max() > 1.0
    assert fitted.threshold_ < 0.8 * constant.threshold_


def _vertices(det):
    return det._vertices(det._model(), *det.schedule_box_, det.design_["column"])[0]


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_the_time_window_of_the_recursion_changes_no_bit(fitted, learning, monkeypatch,
                                                         engine):
    """The estimator's inputs are formed TIME_WINDOW steps at a time (memory); a window that
    does not divide the run, or one step, gives the bits of the whole run at once, in both
    engines (the ramps' increments cross the windows' edges)."""
    import detectors.builtin.chen_global as cg
    from scenarios import compiled as kernels

    few = learning.take([0, 11]).truncate(1500)
    with kernels.use_engine(engine):
        monkeypatch.setattr(cg, "TIME_WINDOW", 10 ** 6)
        whole = fitted._components(few)
        for window in (997, 7, 1):
            monkeypatch.setattr(cg, "TIME_WINDOW", window)
            for a, b in zip(fitted._components(few), whole):
                assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("gust_channel", [True, False])
def test_compiled_recursion_is_bit_identical_to_numpy(fitted, learning, gust_channel):
    """The compiled step loop (detectors/builtin/chen_global_kernel.py) performs the NumPy loop's
    operations in its order: f̂ and the uncertainty filters' responses w have the same bytes,
    with the activity bound's filters and without, with the gust channel (two unknown
    inputs) and without (one)."""
    from scenarios import compiled as kernels

    det = fitted if gust_channel else ChenGlobalEstimator(gust_channel=False).fit(learning)
    few = learning.take([0, 5, 11])
    for bounds in (True, False):
        with kernels.use_engine("numpy"):
            ref = det._recursion(few, bounds)
        with kernels.use_engine("compiled"):
            fast = det._recursion(few, bounds)
        assert fast[0].tobytes() == ref[0].tobytes()
        if bounds:
            assert fast[1].tobytes() == ref[1].tobytes()
            assert np.abs(ref[1]).max() > 0.0       # the filters were driven
        assert np.abs(ref[0]).max() > 0.0


def test_lateral_model_is_affine_in_the_scheduling_vector(fitted):
    # the fit is exact to round-off (1e-9 of the largest entry) over the whole envelope grid
    assert fitted.model_["affine_residual"] < 1e-9
    sched = {"mach": np.array([0.5, 0.78]), "qbar_pa": np.array([9000.0, 14000.0]),
             "alt_ft": np.array([12000.0, 33000.0]), "mass_t": np.array([150.0, 210.0]),
             "cg_pct": np.array([25.0, 35.0])}
    A, B = lateral_models(sched)
    A2, B2 = fitted._model().matrices(scheduling_vector(sched))
    # points not on the fitting grid: still exact (relative 1e-9)
    assert np.abs(A2 - A).max() < 1e-9 * np.abs(A).max()
    assert np.abs(B2 - B).max() < 1e-9 * np.abs(B).max()


def test_gains_satisfy_eq_20_21_at_every_vertex(fitted):
    d = fitted.design_
    H = d["H"]
    verts = _vertices(fitted)
    assert len(verts) == 2 ** len(fitted.model_["keep"])
    L2 = d["L2"]
    # L2 H = I (eq. 21) to round-off
    np.testing.assert_allclose(L2 @ H, np.eye(H.shape[1]), atol=1e-9)
    for v in verts:
        L1 = -v.F @ d["H_dagger"] + d["Z1"] @ d["H_perp"]                  # eq. 20
        residual = v.F + L1 @ H
        # F + L1 H = 0, relative to the size of F (round-off of the pseudo-inverse)
        assert np.abs(residual).max() <= 1e-9 * np.abs(v.F).max()
    # stability at the vertices and on the grid inside (checked in fit, stored)
    assert fitted.stability_["vertex_max_real_pole"] < 0.0
    assert fitted.stability_["grid_max_real_pole"] < 0.0
    assert fitted.stability_["grid_max_discrete_modulus"] < 1.0


def test_gamma_is_confirmed_by_a_frequency_sweep_at_the_vertices(fitted):
    d = fitted.design_
    C = output_matrix()
    omega = np.logspace(-4, 4, 801)
    peaks = []
    for v in _vertices(fitted):
        L1 = -v.F @ d["H_dagger"] + d["Z1"] @ d["H_perp"]
        peaks.append(hinf_sweep(v.A + L1 @ C, v.M + L1 @ v.N, d["L2"] @ C, d["L2"] @ v.N,
                                omega).max())
    gamma = fitted.gamma_
    # γ bounds the error system at every vertex (solver tolerance 1e-6 relative) …
    assert max(peaks) <= gamma * (1.0 + 1e-6)
    # … and is not a loose bound: one common P for all vertices costs little here
    assert max(peaks) >= 0.9 * gamma


def _linear_signals(det, f_deg: float, perturbed: bool, n_steps: int = 9000):
    """Signals of the design's linear lateral model (rods and spoilers at zero deflection,
    a constant disconnection effect f_deg from t = 0) at one realistic flight point."""
    from scenarios import envelope
    from scenarios.aircraft.loop import surface_actuator

    ts = 0.01
    sched = envelope.measured_schedule(np.array([28000.0]), np.array([300.0]),
                                       np.array([180.0]), np.array([30.0]), 0.0, 0.0, 0.0, 0.0)
    A, B = fitted_model_matrices(det, sched)
    col = det.design_["column"]
    Phi, Gam = discretise(A, B[:, [col]], ts)
    C = output_matrix()
    H = det.design_["H"][:, :1] if perturbed else np.zeros((3, 1))
    x = np.zeros(4)
    y = np.empty((3, n_steps))
    for k in range(n_steps):
        y[:, k] = C @ x + H[:, 0] * f_deg
        x = Phi @ x + Gam[:, 0] * f_deg
    zeros = np.zeros((1, n_steps))
    aircraft = {name: y[OUTPUTS.index(name)][None] if name in OUTPUTS else zeros
                for name in ("p", "q", "r", "phi", "theta", "nz", "ny", "beta", "spoiler")}
    rods = {s: zeros for s in INPUT_SURFACES}
    rods.update({s: zeros for s in ("left_elevator", "right_elevator")})
    return Signals(ts=ts, command=zeros, current=zeros, rod_com=zeros, rod_mon=zeros,
                   surface=np.full((1, n_steps), np.nan), pressure=np.full((1, n_steps), np.nan),
                   schedule=sched, actuator=surface_actuator(MONITORED),
                   run_ids=np.array(["linear"]), aircraft=aircraft, rods=rods)


def fitted_model_matrices(det, sched):
    A, B = det._model().matrices(scheduling_vector(sched))
    return A[0], B[0]


def test_fault_estimate_converges_to_a_constant_fault_on_the_linear_model(fitted):
    f = 3.0                                                      # deg of aileron
    est = fitted.estimate(_linear_signals(fitted, f, perturbed=True))
    # design model (H = εE of Remark 4.1): G_f̂f = I, so f̂ → f once the transient of the
    # estimator's initial state (x̂ = y, β̂ = 0) has decayed; its slowest pole at this point
    # is a few 0.01 1/s, so after 90 s the error is a few 1e-5 of f and still shrinking
    err = np.abs(est[0] - f)
    assert err[-1] < 1e-4 * f
    assert err[-1] < err[-1000] < err[-3000] < 0.1 * err[1]
    # true model (H = 0): the static gain the fit reported (between its vertex extremes,
    # and above 0.9 for the default ε = 0.03)
    est0 = fitted.estimate(_linear_signals(fitted, f, perturbed=False))
    gain = est0[0, -1] / f
    lo, hi = fitted.static_gain_
    assert lo - 1e-3 <= gain <= hi + 1e-3
    assert gain > 0.9


def _true_lateral(point: dict, aero) -> tuple[np.ndarray, np.ndarray]:
    """(A (4, 4), B (4, 6)) of the aircraft's lateral block at the true flight *point* with
    the coefficient draws *aero* (states [β, p, r, φ], inputs of u_b)."""
    from scenarios import envelope
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT

    fc = envelope.flight_condition(**point)
    flight = {"mass_t": point["mass_t"], "cg_pct": point["cg_pct"], "mach": fc["mach"],
              "qbar_pa": fc["qbar_pa"], "tas_ms": fc["tas_ms"]}
    model = lpv.run_models(flight, aero)
    idx = [lpv.IB, lpv.IP, lpv.IR, lpv.IPHI]
    cols = [LAYOUT.names.index(s) for s in INPUT_SURFACES] + [lpv.I_SPOILER]
    return model.A[0][idx][:, idx], model.B[0][idx][:, cols]


def test_m_g_realises_the_coefficient_errors_of_table_2_exactly():
    """ΔA·x + ΔB·u of a coefficient draw d_c is M_g[:, c]·d_c·z_c, with z_c the model's
    aerodynamic acceleration of group c (static plus rate parts), at any x, u with φ = 0
    (z_cy also carries the gravity term g/V·φ of β̇, whose error is the measured speed's)."""
    point = dict(alt_ft=np.array([28000.0]), vcas_kt=np.array([300.0]),
                 mass_t=np.array([233.0]), cg_pct=np.array([41.0]))
    A0, B0 = _true_lateral(point, 0.0)
    Zx, Zu = signal_matrices(A0[None], B0[None])
    M = uncertainty_matrix()
    rng = np.random.default_rng(3)
    for c in CHANNELS:
        A1, B1 = _true_lateral(point, {c: 0.05})
        for _ in range(3):
            x, u = rng.normal(size=4), rng.normal(size=6)
            x[3] = 0.0
            z = Zx[0] @ x + Zu[0] @ u
            zc = sum(z[j] for j, (ch, _) in enumerate(SIGNALS) if ch == c)
            delta = (A1 - A0) @ x + (B1 - B0) @ u
            np.testing.assert_allclose(delta, M[:, CHANNELS.index(c)] * 0.05 * zc,
                                       atol=1e-12 * np.abs(delta).max())
    # the coefficient draws alone bound each term by 5 %; the flight-data errors add to it
    k = table2_error_bounds()
    assert k.shape == (len(SIGNALS),) and np.all(k > 0.05)
    same = scheduling_vector(dict(mach=np.array([0.6]), qbar_pa=np.array([1e4]),
                                  alt_ft=np.array([2e4]), mass_t=np.array([180.0]),
                                  cg_pct=np.array([30.0])))
    np.testing.assert_allclose(error_bounds(same, same, dict.fromkeys(CHANNELS, 0.05)), 0.05)


def _table2_signals(det, aero: dict, d_vcas: float, d_alt: float, d_mass: float,
                    n_steps: int = 3000, sub: int = 10):
    """Signals of the lateral rigid body with [CHEN] Table-2 errors and no fault: the true
    model carries the coefficient draws *aero* at the true flight point, the schedule the
    detector sees carries the flight-data errors. The rods fly a smooth roll doublet of the
    four ailerons (± 15°) with the rudder following; exact in each sub-step of ts/sub."""
    from scenarios import envelope
    from scenarios.aircraft.data import surface_actuator as actuator_of
    from scenarios.aircraft.loop import surface_actuator

    ts = 0.01
    point = dict(alt_ft=np.array([18000.0]), vcas_kt=np.array([220.0]),
                 mass_t=np.array([180.0]), cg_pct=np.array([30.0]))
    A, B = _true_lateral(point, aero)
    Phi, Gam = discretise(A, B, ts / sub)
    t = np.arange(n_steps * sub) * ts / sub
    bump = lambda t0: np.where((t > t0) & (t < t0 + 2.0),                    # noqa: E731
                               0.5 * (1.0 - np.cos(np.pi * (t - t0))), 0.0)
    roll = 15.0 * (bump(2.0) - bump(8.0))                                    # deg
    u = np.zeros((6, len(t)))
    u[0], u[2] = roll, roll                      # left ailerons
    u[1], u[3] = -roll, -roll                    # right ailerons
    u[4] = -0.2 * roll                           # rudder
    x = np.zeros(4)
    y = np.empty((3, n_steps))
    for k in range(len(t)):
        if k % sub == 0:
            y[:, k // sub] = output_matrix() @ x
        x = Phi @ x + Gam @ u[:, k]
    u = u[:, ::sub]
    sched = envelope.measured_schedule(point["alt_ft"], point["vcas_kt"], point["mass_t"],
                                       point["cg_pct"], d_alt, d_vcas, d_mass, 0.0)
    zeros = np.zeros((1, n_steps))
    aircraft = {name: y[OUTPUTS.index(name)][None] if name in OUTPUTS else zeros
                for name in ("p", "q", "r", "phi", "theta", "nz", "ny", "beta")}
    aircraft["spoiler"] = u[5][None]
    rods = {s: (actuator_of(s).r_mm * np.sin(np.radians(u[j])))[None]
            for j, s in enumerate(INPUT_SURFACES)}
    rods.update({s: zeros for s in ("left_elevator", "right_elevator")})
    return Signals(ts=ts, command=zeros, current=zeros, rod_com=zeros, rod_mon=zeros,
                   surface=np.full((1, n_steps), np.nan), pressure=np.full((1, n_steps), np.nan),
                   schedule=sched, actuator=surface_actuator(MONITORED),
                   run_ids=np.array(["table2"]), aircraft=aircraft, rods=rods)


@pytest.mark.parametrize("aero, d_vcas, d_alt, d_mass, corner", [
    ({"cy": 0.05, "cl": 0.05, "cn": -0.05}, -0.10, 0.10, 0.10, True),
    ({"cy": -0.05, "cl": -0.05, "cn": 0.05}, 0.10, -0.10, -0.10, True),
    ({"cy": 0.05, "cl": 0.05, "cn": 0.05}, 0.0, 0.0, 0.0, False),
])
def test_table2_errors_stay_within_the_activity_bound_on_the_design_model(
        fitted, aero, d_vcas, d_alt, d_mass, corner):
    """The uncertainty input is attenuated as designed: with only Table-2 errors (corners of
    the coefficient and flight-data errors) and no fault, |f̂| stays below the bound b(t)
    that M_g, the error dynamics and the Table-2 widths give, hence below the threshold."""
    sig = _table2_signals(fitted, aero, d_vcas, d_alt, d_mass)
    f_abs, b = fitted._components(sig)
    skip = 100                                   # the estimator's start (x̂ = y, β̂ = 0): 1 s
    # the manoeuvre moves f̂ by degrees (the bound is not vacuous) …
    assert f_abs[0, skip:].max() > 0.5
    # … and b covers it at every step (to 2 % of the activity bound: z is computed on the
    # estimated β and fault, not the true ones)
    assert np.all(f_abs[0, skip:] <= 1.02 * b[0, skip:] + 1e-3)
    det = fitted.detect(sig)
    assert not det.alarm[0, skip:].any()
    if corner:
        # at the Table-2 corners, without the bound the run would exceed τ0 alone
        assert f_abs[0, skip:].max() > fitted.threshold_


def test_detects_disconnection_and_stays_quiet_on_aircraft_runs(fitted):
    runs = _runs([("mid", "cruise", "none"), ("high_heavy", "turn_coordination", "none"),
                  ("low_slow", "yaw_angle_mode", "none"),
                  ("low_slow", "cruise", "disconnection"), ("mid", "cruise", "disconnection"),
                  ("high_heavy", "cruise", "disconnection")])
    sig, truth = simulate(runs, plant="aircraft")
    det = fitted.detect(sig)
    faulty = truth.fault != "none"
    assert not det.alarm[~faulty].any()
    onset = int(ONSET_S / sig.ts)
    assert not det.alarm[faulty, :onset].any()
    assert det.alarm[faulty, onset:].any(axis=1).all()


def test_needs_the_aircraft_plant():
    sig, _ = simulate(single_run("aileron", "cruise", "none", duration_s=20.0))
    with pytest.raises(ValueError, match=r'\[plant\] kind = "aircraft"'):
        ChenGlobalEstimator().fit(sig)


def test_an_actuator_level_campaign_is_refused_before_it_starts():
    """The campaign file is refused (so 'plan' and 'run' alike), and the runner asks the
    same rule for detectors built outside a campaign file."""
    from campaign.config import CampaignConfig, ConfigError
    from campaign.plant_setup import resolve
    from campaign.runner import CampaignSetupError, _check_compatibility, build_detectors
    from scenarios.plants import get_plant

    data = {
        "campaign": {"name": "x", "surface": "aileron", "duration_s": 20.0},
        "group": [{"fault": "none", "manoeuvres": ["cruise"], "count": 1}],
        "detector": [{"name": "chen-global"}],
    }
    with pytest.raises(ConfigError, match=r'chen-global.*\[plant\] kind = "aircraft"'):
        CampaignConfig.from_dict(data)
    config = CampaignConfig.from_dict({**data, "plant": {"kind": "aircraft"}})
    with pytest.raises(CampaignSetupError, match=r'chen-global.*\[plant\] kind = "aircraft"'):
        _check_compatibility(resolve(config, plant=get_plant("actuator")),
                             build_detectors(config))


@pytest.mark.parametrize("params, needle", [
    ({"h_perturbation": 0.0}, "h_perturbation"),
    ({"h_output": "beta"}, "h_output"),
    ({"safety": 1.0}, "safety"),
    ({"gust_channel": 1}, "gust_channel"),
    ({"adaptive": "yes"}, "adaptive"),
])
def test_bad_parameters_are_named(params, needle):
    with pytest.raises(ValueError, match=needle):
        ChenGlobalEstimator(**params).validate_params()

