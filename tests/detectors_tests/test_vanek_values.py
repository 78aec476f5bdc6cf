"""vanek-geometric pinned by value (docs/vanek-geometric.md, [VANEK] §2, §5): the design
model, the fault directions and the filter's construction against the documented choices,
the filter's inputs and its residual r̂ = g⁺ r (then the first-order low-pass) against a
plain-Python recursion of the filter of [VANEK] eq. 2 discretised by scipy's own Tustin map,
on hand-built aircraft signals of a few runs at different flight points; the learned
threshold's formula and the decision boundary (n − 1 against n confirmation steps, latching,
an alarm at the last step, |r̂| = τ exactly). Small inputs only: no simulation."""

from __future__ import annotations

import builtins
import dataclasses
import functools
from collections import OrderedDict
import pickle

import numpy as np
import pytest
import scipy.signal

from detectors import calibrate
from detectors.synthesis import geometric as geo
from detectors.synthesis import vanek_model_error as me
from detectors.builtin import vanek_geometric as vg
from detectors.base import Capabilities, Detection, at_threshold_scale, set_threshold_scale
from detectors.builtin.position_monitor import PositionMonitor
from scenarios import envelope
from scenarios.aircraft import lpv
from scenarios.aircraft.data import AIRCRAFT_ACTUATORS, LAYOUT, surface_actuator
from scenarios.atmosphere import tas_ms
from scenarios.signals import Signals

TS = 0.01                                   # s: the aircraft plant's sampling period
N_STEPS = 60
OUTPUTS = ("alpha", "q", "theta", "beta", "p", "r", "phi")      # with the α vane
#: the outputs of the design without the α vane (aoa_sensor = false)
NO_AOA_OUTPUTS = ("q", "theta", "beta", "p", "r", "phi")
#: (VCAS kt, altitude ft, mass t, CG % MAC) of the hand-built runs: off the LTI design point
POINTS = ((200.0, 26000.0, 180.0, 25.0), (280.0, 33000.0, 220.0, 35.0))
#: known inputs in the documented order: every surface but the left elevator and the rudder
KNOWN = ("right_elevator", "left_inboard_aileron", "right_inboard_aileron",
         "left_outboard_aileron", "right_outboard_aileron")


def _lever(name):
    return AIRCRAFT_ACTUATORS[LAYOUT.actuator[LAYOUT.names.index(name)]].r_mm


def _signals(points=POINTS, monitored="left_elevator", seed=0, n_steps=N_STEPS):
    """Hand-built aircraft signals: every rod and sensor a random walk from a non-zero first
    sample (so that what is referenced to its first sample is seen), one rod reading past
    its lever arm on each side."""
    rng = np.random.default_rng(seed)
    n = len(points)
    v, h, m, cg = (np.array(c, float) for c in zip(*points))
    fc = envelope.flight_condition(h, v, m, cg)
    schedule = {"vcas_kt": v, "alt_ft": h, "mass_t": m, "cg_pct": cg, "mach": fc["mach"],
                "qbar_pa": fc["qbar_pa"], "alpha_deg": fc["alpha_deg"]}

    def walk(start, step):
        return start + np.cumsum(rng.normal(0.0, step, (n, n_steps)), axis=1)

    rods = {s: walk(rng.uniform(-8.0, 8.0, (n, 1)), 0.3) for s in LAYOUT.names}
    if n_steps > 30:
        rods["right_outboard_aileron"][0, 20] = 1.2 * _lever("right_outboard_aileron")
        rods["left_outboard_aileron"][n - 1, 30] = -1.3 * _lever("left_outboard_aileron")
    aircraft = {s: walk(rng.uniform(-2.0, 2.0, (n, 1)), 0.05)
                for s in ("p", "q", "r", "phi", "theta", "nz", "ny", "beta", "alpha", "spoiler")}
    order = walk(rng.uniform(-3.0, 3.0, (n, 1)), 0.5)
    rod_com = rods[monitored] if monitored in rods else order
    nan = np.full((n, n_steps), np.nan)
    return Signals(ts=TS, command=order, current=np.zeros((n, n_steps)), rod_com=rod_com,
                   rod_mon=rod_com, surface=nan, pressure=nan, schedule=schedule,
                   actuator=surface_actuator(monitored),
                   run_ids=np.array([f"r{i}" for i in range(n)]), aircraft=aircraft, rods=rods)


# ---- plain references --------------------------------------------------------------------
def _outputs(aoa):
    return OUTPUTS if aoa else NO_AOA_OUTPUTS


def _plain_inputs(sig, monitored, aoa=False):
    """v = [u; y] [rad, rad/s] (docs/vanek-geometric.md): the known rods as deflections
    asin(x/r) (clipped to the lever arm) relative to their first sample, the left inboard
    aileron's expected rod from the nominal servo model when it is monitored, the spoiler
    angle as measured, the outputs as measured except θ (relative to its first sample) and α
    (relative to θ's first sample: α0 = θ0 in trimmed level flight)."""
    cols = []
    for name in KNOWN:
        x = (PositionMonitor.model_output(sig) if name == monitored == vg.FAULT_SURFACE
             else sig.rods[name])
        d = np.array([[np.arcsin(min(max(xi / _lever(name), -1.0), 1.0)) for xi in row]
                      for row in x])
        cols.append(d - d[:, :1])
    cols.append(np.radians(sig.aircraft["spoiler"]))
    theta0 = np.radians(sig.aircraft["theta"])[:, :1]
    for o in _outputs(aoa):
        y = np.radians(sig.aircraft[o])
        cols.append(y - theta0 if o in ("theta", "alpha") else y)
    return np.stack(cols, axis=2)


def _design_model(point, design_model="aircraft", aoa=False):
    """(A, B, C) of the design model: the simulated aircraft's layout, or the elevators in
    unison (no elevator roll arm), outputs q, θ, β, p, r, φ, or with the α vane (*aoa*)
    α, q, θ, β, p, r, φ (every state)."""
    layout = LAYOUT if design_model == "aircraft" else dataclasses.replace(LAYOUT,
                                                                          elevator_arm_m=0.0)
    m = lpv.run_models(point, np.zeros(1), layout=layout)
    C = np.zeros((len(_outputs(aoa)), lpv.N_STATES))
    for i, o in enumerate(_outputs(aoa)):
        C[i, lpv.STATES.index(o)] = 1.0
    return m.A[0], m.B[0], C


def _point(v, h, mass, cg):
    fc = envelope.flight_condition(np.atleast_1d(h), np.atleast_1d(v), np.atleast_1d(mass),
                                   np.atleast_1d(cg))
    return {"mass_t": np.atleast_1d(float(mass)), "cg_pct": np.atleast_1d(float(cg)),
            "mach": fc["mach"], "qbar_pa": fc["qbar_pa"], "tas_ms": fc["tas_ms"]}


def _directions(A, B, gusts=True, aoa=False):
    """L1: the left inboard aileron's column; L2: the left elevator's, the rudder's, e_β and,
    with the α vane (*aoa*), e_α (the gusts, with the air-relative β and α measured)."""
    col = LAYOUT.names.index
    L2 = [B[:, col("left_elevator")], B[:, col("rudder")]]
    if gusts:
        L2.append(np.eye(lpv.N_STATES)[:, lpv.STATES.index("beta")])
    if gusts and aoa:
        L2.append(np.eye(lpv.N_STATES)[:, lpv.STATES.index("alpha")])
    return B[:, [col(vg.FAULT_SURFACE)]], np.column_stack(L2)


def _known_columns():
    return [LAYOUT.names.index(s) for s in KNOWN] + [lpv.I_SPOILER]


@functools.lru_cache(maxsize=None)
def _reference_generator(v, h, mass, cg, gusts=True, aoa=False):
    A, B, C = _design_model(_point(v, h, mass, cg), aoa=aoa)
    L1, L2 = _directions(A, B, gusts, aoa)
    return geo.design(A, B[:, _known_columns()], C, L1, L2, decay=0.5, radius=20.0)


def _run_filter(A, B, C, D, v, c):
    """Plain recursion of the continuous filter (A, B, C, D) discretised by
    scipy.signal.cont2discrete (bilinear) at TS, from w = 0, output c·y [model units]."""
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), TS, method="bilinear")
    out = np.empty(v.shape[:2])
    for i in range(v.shape[0]):
        w = np.zeros(A.shape[0])
        for k in range(v.shape[1]):
            out[i, k] = c @ (Cd @ w + Dd @ v[i, k])
            w = Ad @ w + Bd @ v[i, k]
    return out


def _geometric_estimate(gen, v, smoothing_s=2.0):
    """r̂ [deg]: [VANEK] eq. 2 (ẇ = N w − G y + F u, r = M w − H y), r̂ = g⁺ r with g = M N⁻¹
    P L1, then 1/(τ s + 1) by Tustin: y_k = (x_k + x_{k−1} − (1 − 2τ/Ts) y_{k−1})/(1 + 2τ/Ts)."""
    g = gen.M @ np.linalg.solve(gen.N, gen.P @ gen.L1[:, 0])
    m = gen.F.shape[1]
    B = np.hstack([gen.F, -gen.G])
    D = np.hstack([np.zeros((gen.M.shape[0], m)), -gen.H])
    r = _run_filter(gen.N, B, gen.M, D, v, g / (g @ g))
    return np.degrees(_lowpassed(r, smoothing_s) if smoothing_s > 0.0 else r)


def _lowpassed(r, smoothing_s):
    """1/(τ s + 1) by Tustin along axis 1, from rest."""
    k = 2.0 * smoothing_s / TS
    y = np.zeros_like(r)
    for i in range(r.shape[0]):
        prev_x = prev_y = 0.0
        for t in range(r.shape[1]):
            y[i, t] = (r[i, t] + prev_x - (1.0 - k) * prev_y) / (1.0 + k)
            prev_x, prev_y = r[i, t], y[i, t]
    return y


def _close(actual, expected):
    # the two Tustin realisations differ by round-off, amplified by the filter's DC gain
    # (about 10³ from inputs in rad to r̂): 1e-9 of the largest value is far below any
    # change of a coefficient or an index
    np.testing.assert_allclose(actual, expected, rtol=0.0,
                               atol=1e-9 * max(np.abs(expected).max(), 1e-12))
    assert np.abs(expected).max() > 1e-3          # a residual that is not trivially zero


# ---- design model, directions and construction -------------------------------------------
def test_documented_constants_and_defaults():
    assert dataclasses.astuple(vg.NOMINAL) == (240.0, 30000.0, 200.0, 30.0)
    assert vg.AFFINE_BOX.vcas_kt == (160.0, 300.0) and vg.AFFINE_BOX.alt_ft == (8000.0, 38000.0)
    assert vg.OUTPUTS == OUTPUTS and vg.FAULT_SURFACE == "left_inboard_aileron"
    assert vg.ISOLATED_SURFACES == ("left_elevator", "rudder")
    assert set(vg.ZERO_TRIM) == {"q", "beta", "p", "r", "phi"}
    assert vg.VanekGeometric().get_params() == {
        "safety": 1.5, "confirm_s": 0.05, "decay": 0.5, "radius": 20.0,
        "decouple_gusts": True, "smoothing_s": 2.0, "variants": ("lti", "lpv"),
        "threshold_method": "evt", "target_fa_per_run": 1e-4, "threshold_confidence": 0.95,
        "threshold_tail": "exponential", "design_model": "aircraft", "aoa_sensor": True,
        "adaptive": True}
    assert vg.design_outputs() == NO_AOA_OUTPUTS and vg.design_outputs(True) == OUTPUTS
    assert vg.DESIGN_MODELS == ("aircraft", "unison")
    with pytest.raises(dataclasses.FrozenInstanceError):
        vg.NOMINAL.vcas_kt = 250.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        vg.AFFINE_BOX.vcas_kt = (100.0, 400.0)
    f = vg._Filter(Ad=np.eye(1), Bd=np.eye(1), Cd=np.eye(1), Dd=np.eye(1), c=np.ones(1))
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.c = np.zeros(1)               # a cached design cannot be altered
    # an aileron filter (isolation scored on the other surfaces' faults) whose decision is
    # |r̂|/τ, so that a campaign's threshold_scale applies (test_a_threshold_scale_...)
    assert vg.VanekGeometric.capabilities == Capabilities(
        needs_fit=True, causal=True, needs_aircraft=True, fault_surfaces=(vg.FAULT_SURFACE,),
        threshold_scale=True)


def test_columns_output_matrix_and_flight_point():
    i1, i2, known = vg._columns()
    assert i1 == LAYOUT.names.index("left_inboard_aileron")
    assert i2 == [LAYOUT.names.index("left_elevator"), LAYOUT.names.index("rudder")]
    assert known == _known_columns()
    x = np.arange(1.0, lpv.N_STATES + 1.0)
    assert list(vg._output_matrix() @ x) == [x[lpv.STATES.index(o)] for o in NO_AOA_OUTPUTS]
    assert list(vg._output_matrix(True) @ x) == [x[lpv.STATES.index(o)] for o in OUTPUTS]
    p = vg._point(250.0, 20000.0, 190.0, 28.0)
    fc = envelope.flight_condition(20000.0, 250.0, 190.0, 28.0)
    assert p["mass_t"].tolist() == [190.0] and p["cg_pct"].tolist() == [28.0]
    assert p["mach"] == pytest.approx(fc["mach"], rel=1e-12)
    assert p["qbar_pa"] == pytest.approx(fc["qbar_pa"], rel=1e-12)
    assert p["tas_ms"] == pytest.approx(fc["tas_ms"], rel=1e-12)
    # measured Mach and q̄, when given, are used as they are
    p = vg._point(250.0, 20000.0, 190.0, 28.0, mach=0.5, qbar_pa=9000.0)
    assert p["mach"].tolist() == [0.5] and p["qbar_pa"].tolist() == [9000.0]
    assert p["tas_ms"] == pytest.approx(tas_ms(np.array([0.5]), np.array([20000.0])), rel=1e-12)


def test_design_model_is_the_aircrafts_and_the_ablation_moves_the_elevators_in_unison():
    point = _point(*POINTS[0])
    left, right = LAYOUT.names.index("left_elevator"), LAYOUT.names.index("right_elevator")
    plant = lpv.run_models(point, np.zeros(1))
    A, B = vg._model(point)                      # default: the simulated aircraft's layout
    np.testing.assert_array_equal(A, plant.A[0])
    np.testing.assert_array_equal(B, plant.B[0])
    p = lpv.STATES.index("p")
    assert B[p, left] == -B[p, right] != 0.0      # an asymmetric elevator pair rolls it
    A, B = vg._model(point, "unison")
    A_ref, B_ref, _ = _design_model(point, "unison")
    np.testing.assert_array_equal(A, A_ref)
    np.testing.assert_array_equal(B, B_ref)
    np.testing.assert_allclose(B[:, left], B[:, right], rtol=1e-12, atol=0.0)
    assert B[p, left] == 0.0                      # no roll from an elevator in the ablation
    with pytest.raises(ValueError, match="design_model 'both'"):
        vg._model(point, "both")


def test_fault_directions_and_the_gust_sideslip_check():
    A, B, _ = _design_model(_point(*POINTS[0]))
    e_beta = vg.gust_sideslip_direction(A, B)
    np.testing.assert_array_equal(e_beta, np.eye(lpv.N_STATES)[:, lpv.STATES.index("beta")])
    for gusts in (True, False):
        for aoa in (False, True):
            L1, L2 = vg._fault_columns(A, B, gusts, aoa)
            L1_ref, L2_ref = _directions(A, B, gusts, aoa)
            np.testing.assert_array_equal(L1, L1_ref)
            np.testing.assert_array_equal(L2, L2_ref)
        # default (no α): e_β only among the gusts
        assert vg._fault_columns(A, B, gusts)[1].shape[1] == (3 if gusts else 2)
    # a gust column that departs from A e_β by 1e-6 of it is refused
    bad = B.copy()
    bad[:, lpv.I_GUST_BETA] *= 1.0 + 1e-6
    with pytest.raises(ValueError, match="not the β column of A"):
        vg.gust_sideslip_direction(A, bad)
    bad = B.copy()
    bad[np.argmin(np.abs(A[:, lpv.IB])), lpv.I_GUST_BETA] += 1e-6 * np.abs(A[:, lpv.IB]).max()
    with pytest.raises(ValueError, match="not the β column of A"):
        vg.gust_sideslip_direction(A, bad)
    # round-off is accepted: a zero entry off by half of 1e-12 × the column's largest entry
    # (that entry is 1.9 /s here, so an absolute tolerance of 1e-12 / 1.9 would refuse it)
    assert np.abs(A[:, lpv.IB]).max() > 1.5
    ok = B.copy()
    ok[np.argmin(np.abs(A[:, lpv.IB])), lpv.I_GUST_BETA] += 0.5e-12 * np.abs(A[:, lpv.IB]).max()
    np.testing.assert_array_equal(vg.gust_sideslip_direction(A, ok), e_beta)
    # the same check for the gust angle of attack (the α vane reads α + α_g)
    np.testing.assert_array_equal(vg.gust_aoa_direction(A, B),
                                  np.eye(lpv.N_STATES)[:, lpv.STATES.index("alpha")])
    bad = B.copy()
    bad[:, lpv.I_GUST_ALPHA] *= 1.0 + 1e-6
    with pytest.raises(ValueError, match="not the α column of A"):
        vg.gust_aoa_direction(A, bad)


@pytest.mark.parametrize("aoa", [False, True], ids=["no_aoa", "aoa_sensor"])
@pytest.mark.parametrize("gusts", [True, False])
def test_design_filter_is_the_documented_construction(gusts, aoa):
    point = _point(*POINTS[0])
    kwargs = ({} if gusts else {"decouple_gusts": False}) | ({"aoa_sensor": True} if aoa else {})
    gen, f = vg.design_filter(point, TS, **kwargs)      # defaults: decay 0.5, radius 20
    ref = _reference_generator(*POINTS[0], gusts=gusts, aoa=aoa)
    for name in ("N", "G", "F", "H", "M", "P", "L1", "L2"):
        np.testing.assert_allclose(getattr(gen, name), getattr(ref, name), rtol=0.0,
                                   atol=1e-12 * np.abs(getattr(ref, name)).max(), err_msg=name)
    g = ref.M @ np.linalg.solve(ref.N, ref.P @ ref.L1[:, 0])
    np.testing.assert_allclose(f.c, g / (g @ g), rtol=1e-12)
    assert f.c @ g == pytest.approx(1.0, rel=1e-12)     # r̂ = f1 at steady state
    Ad, Bd, Cd, Dd = geo.bilinear(ref, TS)
    for a, b in ((f.Ad, Ad), (f.Bd, Bd), (f.Cd, Cd), (f.Dd, Dd)):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * np.abs(b).max())


def test_design_filter_passes_decay_and_radius():
    point = _point(*POINTS[0])
    gen, _ = vg.design_filter(point, TS, decay=1.0, radius=10.0)
    eig = np.linalg.eigvals(gen.N)
    assert np.all(eig.real <= -1.0 + 1e-6) and np.all(np.abs(eig) <= 10.0 + 1e-6)
    gen_default, _ = vg.design_filter(point, TS)
    assert np.linalg.eigvals(gen_default.N).real.max() > -1.0 + 1e-3   # a different design


# ---- inputs and residual -------------------------------------------------------------------
@pytest.mark.parametrize("aoa", [False, True], ids=["no_aoa", "aoa_sensor"])
@pytest.mark.parametrize("monitored", ["left_elevator", "left_inboard_aileron"])
def test_filter_inputs(monitored, aoa):
    sig = _signals(monitored=monitored)
    v = (vg.VanekGeometric.filter_inputs(sig, True) if aoa
         else vg.VanekGeometric.filter_inputs(sig))
    assert v.shape == (2, N_STEPS, len(KNOWN) + 1 + len(_outputs(aoa)))
    np.testing.assert_allclose(v, _plain_inputs(sig, monitored, aoa), rtol=1e-13, atol=1e-15)
    # the rods past their lever arm read as full deflection, the expected rod is not the rod
    j = KNOWN.index("right_outboard_aileron")
    assert v[0, 20, j] + np.arcsin(sig.rods["right_outboard_aileron"][0, 0]
                                   / _lever("right_outboard_aileron")) == pytest.approx(np.pi / 2)
    expected = PositionMonitor.model_output(sig)
    j = KNOWN.index("left_inboard_aileron")
    rod = sig.rods["left_inboard_aileron"]
    differs = np.abs(expected - rod).max() > 1.0
    assert differs                  # the hand-built order is far from the aileron's rod
    uses_model = np.allclose(v[:, :, j], _plain_inputs(
        dataclasses.replace(sig, actuator=surface_actuator(vg.FAULT_SURFACE)),
        vg.FAULT_SURFACE)[:, :, j])
    assert uses_model == (monitored == vg.FAULT_SURFACE)


def _fitted_max(variants=("lti", "lpv"), **kwargs):
    """The detector with ``"max"`` thresholds, without the α vane unless *kwargs* say so (the
    hand-built filters below are those of that design; the α design has its own cases)."""
    kwargs.setdefault("aoa_sensor", False)
    return vg.VanekGeometric(variants=variants, threshold_method="max", **kwargs)


@pytest.mark.parametrize("aoa", [False, True], ids=["no_aoa", "aoa_sensor"])
def test_lti_and_lpv_residuals_against_the_plain_recursion(aoa):
    sig = _signals()
    est = _fitted_max(aoa_sensor=aoa).estimates(sig)
    assert set(est) == {"lti", "lpv"}
    v = _plain_inputs(sig, "left_elevator", aoa)
    nominal = dataclasses.astuple(vg.NOMINAL)
    _close(est["lti"], _geometric_estimate(_reference_generator(*nominal, aoa=aoa), v))
    for i, p in enumerate(POINTS):
        _close(est["lpv"][i], _geometric_estimate(_reference_generator(*p, aoa=aoa),
                                                  v[i:i + 1])[0])


def test_lpv_variant_uses_the_measured_mach_and_qbar():
    sig = _signals()
    sig.schedule["mach"] = sig.schedule["mach"] * 1.05
    est = _fitted_max(variants="lpv").estimates(sig)
    assert set(est) == {"lpv"}
    v = _plain_inputs(sig, "left_elevator")
    for i, (vc, h, m, cg) in enumerate(POINTS):
        A, B, C = _design_model({"mass_t": np.array([m]), "cg_pct": np.array([cg]),
                                 "mach": sig.schedule["mach"][i:i + 1],
                                 "qbar_pa": sig.schedule["qbar_pa"][i:i + 1],
                                 "tas_ms": tas_ms(sig.schedule["mach"][i:i + 1],
                                                  np.array([h]))})
        L1, L2 = _directions(A, B)
        gen = geo.design(A, B[:, _known_columns()], C, L1, L2, decay=0.5, radius=20.0)
        _close(est["lpv"][i], _geometric_estimate(gen, v[i:i + 1])[0])


def test_no_low_pass_at_zero_smoothing_and_the_designs_parameters_reach_the_filter():
    sig = _signals(points=POINTS[:1])
    v = _plain_inputs(sig, "left_elevator")
    est = _fitted_max(variants=("lti",), smoothing_s=0.0).estimates(sig)
    _close(est["lti"], _geometric_estimate(
        _reference_generator(*dataclasses.astuple(vg.NOMINAL)), v, smoothing_s=0.0))
    det = _fitted_max(variants=("lti",), smoothing_s=0.5, decay=1.0, radius=10.0,
                      decouple_gusts=False)
    A, B, C = _design_model(_point(*dataclasses.astuple(vg.NOMINAL)))
    L1, L2 = _directions(A, B, gusts=False)
    gen = geo.design(A, B[:, _known_columns()], C, L1, L2, decay=1.0, radius=10.0)
    _close(det.estimates(sig)["lti"], _geometric_estimate(gen, v, smoothing_s=0.5))


def test_the_design_cache_is_keyed_on_the_point_and_not_pickled():
    det = _fitted_max()
    sig = _signals()
    first = det.estimates(sig)
    assert len(det._cache) == 3                 # the nominal point and the two run points
    again = det.estimates(sig)
    for k in first:
        np.testing.assert_array_equal(first[k], again[k])
    assert len(det._cache) == 3
    det.thresholds_deg_ = {"lti": 1.0}
    copy = pickle.loads(pickle.dumps(det))
    assert "_cache" not in vars(copy) and copy.thresholds_deg_ == {"lti": 1.0}
    assert "_cache" in vars(det)


def test_the_design_cache_keys_exact_points_and_is_bounded(monkeypatch):
    """Two runs whose measured points agree to 1e-6 (the rounding of the former key) still
    get their own designs: which one a worker designed first must not matter. And the cache
    keeps at most DESIGN_CACHE_SIZE designs, the oldest dropped first (the lpv variant
    designs one per run)."""
    det = _fitted_max(variants=("lpv",))
    near = ((210.0, 26000.0, 180.0, 25.0), (210.0 + 1e-7, 26000.0, 180.0, 25.0))
    det.estimates(_signals(points=near))
    first, second = list(det._cache)
    monkeypatch.setattr(vg, "DESIGN_CACHE_SIZE", 3)
    det.estimates(_signals(points=POINTS))
    assert len(det._cache) == 3 and first not in det._cache and second in det._cache


def test_a_design_made_while_another_thread_empties_the_cache_is_returned(monkeypatch):
    """The cache is shared by the threads of a detector: when another thread empties it
    between the size check and the eviction (popitem on an empty cache raises KeyError), the
    design just made is still returned and the cache left as it is."""

    class EmptiedMeanwhile(OrderedDict):
        def popitem(self, last=True):
            self.clear()                        # what the other thread did
            return super().popitem(last)

    det = _fitted_max()
    det._cache = EmptiedMeanwhile(old="a design")
    monkeypatch.setattr(vg, "DESIGN_CACHE_SIZE", 1)
    assert det._memo("new", lambda: "its design") == "its design"
    assert len(det._cache) == 0


def test_the_design_cache_holds_4096_designs():
    """The default bound: 4096 designs of 5.5 KB, about 22 MB per detector (the lpv variants
    design one per run); the 4097th drops the oldest."""
    det = _fitted_max()
    for k in range(4096):
        det._memo(k, lambda: k)
    assert len(det._cache) == 4096 and 0 in det._cache
    assert det._memo(4096, lambda: "new") == "new"
    assert len(det._cache) == 4096 and 0 not in det._cache and 1 in det._cache


def test_affine_model_is_the_least_squares_fit_over_the_realistic_points():
    model, err = vg.affine_model()
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]][["vcas_kt", "alt_ft"]].drop_duplicates().to_numpy(float)
    AB = np.array([np.hstack(_design_model(_point(v, h, 200.0, 30.0))[:2]) for v, h in pts])
    X = np.column_stack([np.ones(len(pts)), pts])
    coef = np.linalg.lstsq(X, AB.reshape(len(pts), -1), rcond=None)[0]
    n = lpv.N_STATES
    for v, h in ((200.0, 20000.0), (290.0, 9000.0)):
        fit = (coef[0] + v * coef[1] + h * coef[2]).reshape(AB.shape[1:])
        A, B = model(v, h)
        np.testing.assert_allclose(A, fit[:, :n], rtol=1e-9, atol=1e-12 * np.abs(fit).max())
        np.testing.assert_allclose(B, fit[:, n:], rtol=1e-9, atol=1e-12 * np.abs(fit).max())
    fits = (X @ coef).reshape(AB.shape)
    err_ref = max(np.abs(fits[:, :, s] - AB[:, :, s]).max() / np.abs(AB[:, :, s]).max()
                  for s in (slice(0, n), slice(n, None)))
    assert err == pytest.approx(err_ref, rel=1e-9)
    # another mass: the fit moves with it
    A_heavy, _ = vg.affine_model(mass_t=230.0)[0](200.0, 20000.0)
    assert not np.allclose(A_heavy, model(200.0, 20000.0)[0])


@functools.lru_cache(maxsize=None)
def _affine_family():
    return vg.design_affine(TS)


def test_design_affine_on_the_aircraft_is_designed_at_each_point_clipped_to_the_box():
    model, _ = vg.affine_model()
    C = _design_model(_point(*POINTS[0]))[2]
    at = _affine_family()
    for theta, inside in (((230.0, 20000.0), (230.0, 20000.0)),
                          ((400.0, 50000.0), (300.0, 38000.0))):
        A, B = model(*inside)
        L1, L2 = _directions(A, B)
        ref = geo.design(A, B[:, _known_columns()], C, L1, L2, decay=0.5, radius=20.0)
        gen, f = at(*theta)
        for name in ("N", "G", "F", "H", "M"):
            np.testing.assert_allclose(getattr(gen, name), getattr(ref, name), rtol=0.0,
                                       atol=1e-7 * np.abs(getattr(ref, name)).max())


def test_design_affine_unison_is_the_corner_lmi_family_clipped_to_the_box():
    model, _ = vg.affine_model(design_model="unison")
    corners = [(160.0, 8000.0), (160.0, 38000.0), (300.0, 8000.0), (300.0, 38000.0)]
    As, L1s, L2s = [], [], []
    for c in corners:
        A, B = model(*c)
        L1, L2 = _directions(A, B)
        As.append(A)
        L1s.append(L1)
        L2s.append(L2)
    C = _design_model(_point(*POINTS[0]))[2]
    fam = geo.design_lpv(As, C, L1s, L2s, decay=0.5, radius=20.0)
    at = vg.design_affine(TS, design_model="unison")
    for theta, inside in (((230.0, 20000.0), (230.0, 20000.0)),
                          ((400.0, 50000.0), (300.0, 38000.0)),
                          ((100.0, 1000.0), (160.0, 8000.0))):
        A, B = model(*inside)
        L1, L2 = _directions(A, B)
        ref = fam.at(A, B[:, _known_columns()], L1, L2)
        gen, f = at(*theta)
        for name in ("N", "G", "F", "H", "M"):
            np.testing.assert_allclose(getattr(gen, name), getattr(ref, name), rtol=0.0,
                                       atol=1e-7 * np.abs(getattr(ref, name)).max())
        g = ref.M @ np.linalg.solve(ref.N, ref.P @ ref.L1[:, 0])
        np.testing.assert_allclose(f.c, g / (g @ g), rtol=1e-6)


def test_affine_variant_residual_at_each_runs_schedule():
    sig = _signals()
    est = _fitted_max(variants=("lpv-affine",)).estimates(sig)
    v = _plain_inputs(sig, "left_elevator")
    at = _affine_family()
    for i, (vc, h, _, _) in enumerate(POINTS):
        _close(est["lpv-affine"][i], _geometric_estimate(at(vc, h)[0], v[i:i + 1])[0])


# ---- fit and decision ------------------------------------------------------------------------
def _stubbed(det, residuals):
    """*det* whose estimates are the given r̂ [deg] (the decision and the fit on their own)."""
    det.estimates = lambda signals, v=None: {k: np.asarray(r, float) for k, r in residuals.items()}
    return det


def test_max_threshold_is_safety_times_the_largest_learning_residual():
    sig = _signals()
    r = {"lti": np.array([[0.1, -0.7, 0.2], [0.3, 0.2, -0.1]]),
         "lpv": np.array([[0.05, 0.1, 0.0], [-0.4, 0.2, 0.3]])}
    det = _stubbed(_fitted_max(safety=1.7), r).fit(sig)
    assert det.thresholds_deg_ == {"lti": 1.7 * 0.7, "lpv": 1.7 * 0.4}
    assert det.learning_runs_ == 2 and det.adaptive_ is False
    assert not hasattr(det, "calibration_")


def test_adaptive_threshold_is_tau0_plus_the_allowance():
    """With the α vane and ``adaptive``, τ0 is learned on each run's largest |r̂| − b(t)
    (clipped at 0) and the decision residual is |r̂|/(τ0 + b(t)); the variants without an
    allowance (here lpv-affine) keep |r̂|/τ."""
    sig = _signals()
    r = {"lti": np.array([[0.1, -0.7, 0.2], [0.3, 0.2, -0.1]]),
         "lpv-affine": np.array([[0.05, 0.1, 0.0], [-0.4, 0.2, 0.3]])}
    b = {"lti": np.array([[0.0, 0.6, 0.1], [0.0, 0.1, 0.0]])}
    det = _stubbed(_fitted_max(variants=("lti", "lpv-affine"), safety=1.7, aoa_sensor=True),
                   r)
    det.allowances = lambda signals, v=None: b
    det.fit(sig)
    # lti: largest |r̂| − b per run 0.1 (run 0: 0.1, 0.1, 0.1) and 0.3 → τ0 = 1.7 × 0.3
    assert det.adaptive_ is True
    assert det.thresholds_deg_ == {"lti": pytest.approx(1.7 * 0.3, rel=1e-12),
                                   "lpv-affine": 1.7 * 0.4}
    out = det.detect(sig)
    np.testing.assert_allclose(out["lti"].residual,
                               np.abs(r["lti"]) / (det.thresholds_deg_["lti"] + b["lti"]),
                               rtol=1e-15)
    np.testing.assert_array_equal(out["lpv-affine"].residual,
                                  np.abs(r["lpv-affine"]) / (1.7 * 0.4))


def test_a_learned_threshold_of_zero_is_refused():
    """τ0 is learned on each run's largest (|r̂| − b)⁺: learning runs whose |r̂| never
    exceeds b(t) (no sensor noise) give τ0 = 0, a threshold that would alarm on any
    residual above the allowance; the fit refuses it, naming the variant."""
    sig = _signals()
    r = {"lti": np.array([[0.1, -0.5, 0.2], [0.3, 0.2, -0.1]])}
    det = _stubbed(_fitted_max(variants=("lti",), aoa_sensor=True), r)
    det.allowances = lambda signals, v=None: {"lti": np.abs(r["lti"])}
    with pytest.raises(ValueError, match=r"\[lti\]: the learned threshold is 0.0"):
        det.fit(sig)
    det.allowances = lambda signals, v=None: {"lti": np.abs(r["lti"]) - 1e-3}
    assert det.fit(sig).thresholds_deg_ == {"lti": pytest.approx(1.5e-3, rel=1e-9)}


def test_the_allowance_needs_alpha_and_is_off_for_a_detector_fitted_before_it():
    """τ0 + b(t) is used with the α vane and ``adaptive`` (both defaults); without α (the
    bound needs every state) or without ``adaptive`` the thresholds are constant and no
    allowance is computed; a fitted state without ``adaptive_`` (fitted before the allowance
    existed) keeps its constant thresholds; ``adaptive_`` once fitted is what counts."""
    sig = _signals(points=POINTS[:1], n_steps=3)
    assert vg.VanekGeometric()._bounded()
    for kwargs in ({"aoa_sensor": False}, {"adaptive": False},
                   {"aoa_sensor": False, "adaptive": False}):
        det = vg.VanekGeometric(**kwargs)
        assert not det._bounded() and det.allowances(sig) == {}, kwargs
    legacy = vg.VanekGeometric()
    legacy.thresholds_deg_ = {"lti": 1.0, "lpv": 1.0}
    assert not legacy._bounded() and legacy.allowances(sig) == {}
    legacy.adaptive_ = True
    assert legacy._bounded()
    fitted = vg.VanekGeometric(adaptive=True)
    fitted.adaptive_ = False
    assert not fitted._bounded()


@pytest.mark.parametrize("variant", ["lti", "lpv"])
def test_allowance_terms_are_each_errors_worse_end_through_the_error_path(variant):
    """``allowance_terms`` by a plain recursion (detectors/synthesis/vanek_model_error.py):
    row k of the run's error matrices K gives the model error d_k = K_k s (s = [x̃; u],
    :meth:`model_error_signals`), and r̂_k its response through the filter's error path
    (e' = Ad e + Bdist d, r̂ = c (Cd e + Ddist d)), low-passed as r̂; the design point's term
    is |r̂_0| (non-zero for lti, whose design point is not the runs'), error j's
    max(|r̂_(1+2j)|, |r̂_(2+2j)|), in degrees; and the terms sum to ``allowances``' b(t)."""
    sig = _signals()
    det = vg.VanekGeometric(variants=(variant,))
    terms = det.allowance_terms(sig, variant)
    assert list(terms) == ["design point", *me.ERRORS]
    s = det.model_error_signals(sig)
    sched = sig.schedule
    for i, f in enumerate(det._filters(variant, sig)):
        K = det._error_matrices(variant, {k: float(sched[k][i]) for k in
                                          ("vcas_kt", "alt_ft", "mass_t", "cg_pct")},
                                sched["mach"][i], sched["qbar_pa"][i])
        assert K.shape[0] == 1 + 2 * len(me.ERRORS)
        r = np.empty((K.shape[0], s.shape[1]))
        for k, Kk in enumerate(K):
            e = np.zeros(f.Ad.shape[0])
            for t, d in enumerate(s[i] @ Kk.T):
                r[k, t] = f.c @ (f.Cd @ e + f.Ddist @ d)
                e = f.Ad @ e + f.Bdist @ d
        r = np.degrees(np.abs(_lowpassed(r, det.smoothing_s)))
        expected = {"design point": r[0]} | {e: np.maximum(r[1 + 2 * j], r[2 + 2 * j])
                                             for j, e in enumerate(me.ERRORS)}
        for name, term in expected.items():
            np.testing.assert_allclose(terms[name][i], term, rtol=0.0,
                                       atol=1e-9 * r.max(), err_msg=name)
        assert (r[0].max() > 1e-3 * r.max()) == (variant == "lti")
        # a 10 % VCAS error's two ends differ (q̄ scales by 1/1.1² and 1/0.9²): which rows
        # pair into a term matters
        j = me.ERRORS.index("vcas")
        assert np.abs(r[1 + 2 * j] - r[2 + 2 * j]).max() > 1e-3 * r.max()
    np.testing.assert_allclose(sum(terms.values()), det.allowances(sig)[variant], rtol=1e-12,
                               atol=1e-12 * np.abs(det.allowances(sig)[variant]).max())
    with pytest.raises(ValueError, match="lpv-affine.*allowed: lti, lpv"):
        det.allowance_terms(sig, "lpv-affine")


@pytest.mark.parametrize("monitored", ["left_elevator", "left_inboard_aileron"])
def test_model_error_signals_are_the_measured_states_and_every_surface(monitored):
    """s = [x̃; u] of the allowance (docs/vanek-geometric.md): the seven states α, q, θ, β,
    p, r, φ as the filter reads them with the α vane (θ relative to its first sample, α to
    θ's), then every surface's deflection asin(x/r) from its COM rod (the monitored one as it
    moves, not its expected rod) relative to its first sample, then the spoiler angle."""
    sig = _signals(monitored=monitored)
    s = vg.VanekGeometric.model_error_signals(sig)
    assert s.shape == (2, N_STEPS, lpv.N_STATES + me.N_INPUTS)
    assert lpv.STATES == OUTPUTS
    plain = _plain_inputs(sig, monitored, aoa=True)
    cols = [plain[:, :, len(KNOWN) + 1 + OUTPUTS.index(x)] for x in lpv.STATES]
    for name in LAYOUT.names:
        d = np.arcsin(np.clip(sig.rods[name] / _lever(name), -1.0, 1.0))
        cols.append(d - d[:, :1])
    cols.append(np.radians(sig.aircraft["spoiler"]))
    np.testing.assert_allclose(s, np.stack(cols, axis=2), rtol=1e-13, atol=1e-15)
    # given the filter's inputs with α, the same
    v = vg.VanekGeometric.filter_inputs(sig, aoa_sensor=True)
    np.testing.assert_array_equal(vg.VanekGeometric.model_error_signals(sig, v), s)


def test_evt_threshold_is_the_calibrated_one_per_class():
    rng = np.random.default_rng(5)
    n = 80
    classes = np.array(["cruise", "turn"] * (n // 2))
    sig = _signals(points=POINTS * (n // 2), n_steps=4)
    r = {"lti": rng.gamma(4.0, 0.1, (n, 4)) * np.where(classes == "turn", 3.0, 1.0)[:, None]}
    maxima = np.abs(r["lti"]).max(axis=1)
    taus = set()
    for given in (classes, None):
        det = _stubbed(vg.VanekGeometric(variants=("lti",), safety=1.3, target_fa_per_run=0.05,
                                         threshold_confidence=0.9, threshold_tail="free",
                                         adaptive=False),
                       r).fit(dataclasses.replace(sig, classes=given))
        tau, cal = calibrate.learned_threshold(maxima, "evt", 1.3, 0.05, 0.9, tail="free",
                                               classes=given)
        assert det.thresholds_deg_ == {"lti": tau}
        assert det.calibration_ == {"lti": cal}
        assert det.learning_runs_ == n
        taus.add(tau)
    assert len(taus) == 2                       # the classes matter for this learning set


@pytest.mark.parametrize("confirm_s, n_confirm", [(0.05, 6), (0.0, 1), (0.024, 3)])
def test_confirmation_boundary_and_latching(confirm_s, n_confirm):
    sig = _signals(points=POINTS * 2, n_steps=12)
    tau = 0.8
    base = np.full((4, 12), 0.5 * tau)
    r = base.copy()
    r[0, 2:2 + n_confirm - 1] = tau             # n − 1 steps at the threshold: no alarm
    r[1, 2:2 + n_confirm] = -tau                # n steps (negative side): alarm, latched
    r[2, 12 - n_confirm:] = tau * (1.0 + 1e-12) # alarm at the last step only
    r[3, 12 - n_confirm:] = np.nextafter(tau, 0.0)  # just below the threshold
    det = vg.VanekGeometric(variants=("lti",), confirm_s=confirm_s)
    det.thresholds_deg_ = {"lti": tau}
    out = _stubbed(det, {"lti": r}).detect(sig)
    assert set(out) == {"lti"} and isinstance(out["lti"], Detection)
    np.testing.assert_array_equal(out["lti"].residual, np.abs(r) / tau)
    alarm = out["lti"].alarm
    assert not alarm[0].any() and not alarm[3].any()
    first = 2 + n_confirm - 1
    assert not alarm[1, :first].any() and alarm[1, first:].all()
    assert not alarm[2, :-1].any() and alarm[2, -1]


def test_a_threshold_scale_is_every_threshold_times_s():
    """The capability ``threshold_scale``: the detection with thresholds τ × s is the
    unscaled one with its decision divided by s (:func:`detectors.base.at_threshold_scale`),
    so a campaign's ``threshold_scale`` can be applied to vanek-geometric."""
    sig = _signals(points=POINTS * 2, n_steps=10)
    tau, s = 0.8, 1.25
    # |r̂|/τ from step 4 on: 1.1 (alarms unscaled only), 1.3 and −1.3 (both), 0.9 (neither)
    r = {"lti": np.outer([1.1, 1.3, -1.3, 0.9], np.r_[np.full(4, 0.5), np.ones(6)]) * tau}

    def detector(scale):
        det = vg.VanekGeometric(variants=("lti",), confirm_s=0.02)
        det.thresholds_deg_ = {"lti": tau * scale}
        return _stubbed(det, r)

    base = set_threshold_scale(detector(1.0), s).detect(sig)["lti"]
    scaled, direct = at_threshold_scale(base, s), detector(s).detect(sig)["lti"]
    np.testing.assert_allclose(scaled.decision, direct.decision, rtol=1e-15)
    np.testing.assert_array_equal(scaled.alarm, direct.alarm)
    assert (base.alarm != direct.alarm).any()      # the scale moves some alarms


def test_bad_signals_and_parameters_are_refused_before_work():
    sig = _signals(points=POINTS[:1], n_steps=3)
    for missing in ("spoiler", "q", "alpha"):
        aircraft = {k: v for k, v in sig.aircraft.items() if k != missing}
        with pytest.raises(ValueError, match=rf"lacks \['{missing}'\]") as err:
            vg.VanekGeometric().check_signals(dataclasses.replace(sig, aircraft=aircraft))
        # the way out of a missing α vane is named only when α is what is missing
        assert ("or set aoa_sensor = false" in str(err.value)) == (missing == "alpha")
    no_alpha = {k: v for k, v in sig.aircraft.items() if k != "alpha"}
    vg.VanekGeometric(aoa_sensor=False).check_signals(dataclasses.replace(sig,
                                                                          aircraft=no_alpha))
    vg.VanekGeometric().check_signals(sig)
    with pytest.raises(ValueError, match="confirm_s"):
        vg.VanekGeometric(confirm_s=-0.01).validate_params()
    with pytest.raises(ValueError, match="smoothing_s"):
        vg.VanekGeometric(smoothing_s=-1.0).validate_params()
    with pytest.raises(ValueError, match="decay"):
        vg.VanekGeometric(decay=0.0).validate_params()
    # the declared bounds' edges are accepted
    vg.VanekGeometric(safety=1.01, confirm_s=0.0, smoothing_s=0.0, decay=0.01,
                      radius=0.02).validate_params()


def test_only_the_hinf_variants_need_python_control(monkeypatch):
    real = builtins.__import__

    def no_control(name, *args, **kwargs):
        if name in ("control", "slycot"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_control)
    vg.VanekGeometric(variants=("lti", "lpv", "lpv-affine")).validate_params()
    for variant in ("lti-hinf", "one-step", ("lti", "lti-hinf")):
        with pytest.raises(ValueError, match=r"fdd-campaign\[hinf\]"):
            vg.VanekGeometric(variants=variant).validate_params()


# ---- the H∞ variants' wiring (their synthesis: tests/detectors_tests/test_vanek_hinf_values.py) --
def test_lti_hinf_residual_is_the_cascade_with_the_sampled_noise_and_no_low_pass():
    from detectors.synthesis import vanek_hinf as vh

    sig = _signals()
    est = _fitted_max(variants=("lti-hinf",)).estimates(sig)
    gen = _reference_generator(*dataclasses.astuple(vg.NOMINAL))
    q = vh.post_filter(gen, vh.sensor_sigmas(NO_AOA_OUTPUTS) * np.sqrt(TS))
    # the geometric filter (input [u; y], output r) in series with Q (input r, output f̂)
    m = gen.F.shape[1]
    Bf = np.hstack([gen.F, -gen.G])
    Df = np.hstack([np.zeros((gen.M.shape[0], m)), -gen.H])
    nf, nq = gen.N.shape[0], q.A.shape[0]
    A = np.block([[gen.N, np.zeros((nf, nq))], [q.B @ gen.M, q.A]])
    B = np.vstack([Bf, q.B @ Df])
    C = np.hstack([q.D @ gen.M, q.C])
    D = q.D @ Df
    _close(est["lti-hinf"], np.degrees(_run_filter(A, B, C, D, _plain_inputs(sig, "left_elevator"),
                                                   np.ones(1))))


def test_one_step_residual_ignores_the_pitch_attitude_and_is_not_low_passed(monkeypatch):
    # the detector's one design (one H∞ synthesis, about 4 CPU-s): recorded as it is made,
    # its point checked against the nominal one, rather than made a second time here
    sig = _signals()
    designs = []
    real = vg.one_step_design

    def recorded(*args):
        designs.append((args, real(*args)))
        return designs[-1][1]

    monkeypatch.setattr(vg, "one_step_design", recorded)
    est = _fitted_max(variants=("one-step",)).estimates(sig)
    [((point, ts, design_model, aoa), (f, _))] = designs
    assert (ts, design_model, aoa) == (TS, "unison", False)
    for name, value in _point(*dataclasses.astuple(vg.NOMINAL)).items():
        np.testing.assert_allclose(point[name], value, rtol=1e-12, err_msg=name)
    v = _plain_inputs(sig, "left_elevator")
    theta = len(KNOWN) + 1 + NO_AOA_OUTPUTS.index("theta")
    v = np.delete(v, theta, axis=2)
    _close(est["one-step"], np.degrees(_run_filter(f.A, f.B, f.C, f.D, v, np.ones(1))))


@pytest.mark.parametrize("aoa", [False, True], ids=["no_aoa", "aoa_sensor"])
def test_one_step_design_model_noise_and_gust_feedthrough(monkeypatch, aoa):
    from detectors.synthesis import vanek_hinf as vh
    from scenarios.params import SENSORS

    seen = {}

    class Captured(Exception):
        """The synthesis's inputs are recorded; the synthesis itself (4 CPU-s) is not run."""

    def capture(*args, **kwargs):
        seen["args"], seen["kwargs"] = args, kwargs
        raise Captured

    monkeypatch.setattr(vh, "one_step_filter", capture)
    point = _point(*POINTS[0])
    with pytest.raises(Captured):
        if aoa:
            vg.one_step_design(point, TS, aoa_sensor=True)
        else:
            vg.one_step_design(point, TS)
    A, B, C, outs, i1, i2, known, gusts, sig_y, sig_u, ts = seen["args"]
    A_full, B_full, _ = _design_model(point, "unison")     # the one-step filter's model
    keep = [j for j, s in enumerate(lpv.STATES) if s != "theta"]
    np.testing.assert_array_equal(A, A_full[np.ix_(keep, keep)])
    np.testing.assert_array_equal(B, B_full[keep])
    assert list(outs) == ["alpha"] * aoa + ["q", "beta", "p", "r", "phi"]
    states = [lpv.STATES[j] for j in keep]
    C_ref = np.zeros((len(outs), len(keep)))
    for i, o in enumerate(outs):
        C_ref[i, states.index(o)] = 1.0
    np.testing.assert_array_equal(C, C_ref)
    assert (i1, list(i2), list(known)) == (2, [0, 6], _known_columns())
    assert list(gusts) == [lpv.I_GUST_BETA, lpv.I_GUST_ALPHA] and ts == TS
    np.testing.assert_array_equal(sig_y, np.delete(vh.sensor_sigmas(_outputs(aoa)),
                                                   _outputs(aoa).index("theta")))
    rods = [SENSORS.rod_noise_mm / _lever(s) for s in KNOWN]
    np.testing.assert_allclose(sig_u, rods + [vh.ONE_STEP.exact_sigma_rad], rtol=1e-15)
    d_g = np.zeros((len(outs), 2))
    d_g[outs.index("beta"), 0] = 1.0               # the vanes read β + β_g and α + α_g
    if aoa:
        d_g[outs.index("alpha"), 1] = 1.0
    np.testing.assert_array_equal(seen["kwargs"]["gust_feedthrough"], d_g)


def test_design_options_are_keyword_only():
    point = _point(*POINTS[0])
    with pytest.raises(TypeError):
        vg.design_filter(point, TS, False)
    with pytest.raises(TypeError):
        vg.design_affine(TS, False)


def test_a_runs_estimate_does_not_depend_on_the_runs_designed_before_it():
    # designs are cached by the exact flight point (θ of lpv-affine, the point of lpv): a run
    # 2e-7 kt and 2e-7 t from another gets its own filter, so its r̂ is the same whether or
    # not the other run shared its chunk (the mass enters the lpv point, the speed the
    # lpv-affine one)
    v, h, mass, cg = POINTS[0]
    sig = _signals(points=(POINTS[0], (v + 2e-7, h, mass + 2e-7, cg)))
    same = {k: v[:1].repeat(2, axis=0) for k, v in sig.aircraft.items()}
    rods = {k: v[:1].repeat(2, axis=0) for k, v in sig.rods.items()}
    sig = dataclasses.replace(sig, aircraft=same, rods=rods)
    sig.schedule["mach"] = sig.schedule["mach"][:1].repeat(2)
    sig.schedule["qbar_pa"] = sig.schedule["qbar_pa"][:1].repeat(2)
    det = _fitted_max(variants=("lpv", "lpv-affine"))
    est = det.estimates(sig)
    alone = _fitted_max(variants=("lpv", "lpv-affine")).estimates(sig.take([1]))
    for k in est:
        np.testing.assert_array_equal(est[k][1], alone[k][0], err_msg=k)
    assert sum(key[0] == "affine" for key in det._cache) == 2
    assert sum(key[0] == "geometric" for key in det._cache) == 2
    det._cache.clear()
    det.estimates(sig.take([0]))
    # sampling periods are told apart to 1e-9 s: 2e-10 s more reuses the designs, 2e-9 s not
    det.estimates(dataclasses.replace(sig.take([0]), ts=TS + 2e-10))
    assert len(det._cache) == 2                 # the affine filter and the lpv one
    det.estimates(dataclasses.replace(sig.take([0]), ts=TS + 2e-9))
    assert len(det._cache) == 4 and len(det._families) == 2


def test_the_design_model_the_thresholds_were_learned_with_is_kept():
    """A fitted detector records its design model (``design_model_``) and detects with it;
    one fitted before the parameter existed (learned thresholds, no ``design_model_``, as a
    campaign directory of that version stores it) was fitted on the unison model and keeps
    it, so its thresholds and filters stay together on a resume."""
    sig = _signals()
    aircraft = _fitted_max().fit(sig)
    unison = _fitted_max(design_model="unison").fit(sig)
    assert aircraft.design_model_ == "aircraft" and unison.design_model_ == "unison"
    # the two designs differ on these signals (the elevator's roll)
    a, u = aircraft.estimates(sig), unison.estimates(sig)
    assert np.abs(a["lpv"] - u["lpv"]).max() > 1e-3 * np.abs(u["lpv"]).max()
    legacy = _fitted_max()                          # the default parameters of this version
    vars(legacy).update({k: v for k, v in vars(unison).items()
                         if k.endswith("_") and k != "design_model_"})
    assert legacy._layout() == "unison"
    for variant, r in legacy.estimates(sig).items():
        np.testing.assert_array_equal(r, u[variant])
    assert _fitted_max()._layout() == "aircraft"     # not fitted: the parameter


def test_the_outputs_the_thresholds_were_learned_with_are_kept(tmp_path):
    """A fitted detector records whether it read the α vane (``aoa_sensor_``) and detects
    with those outputs whatever its parameter says later: a campaign directory fitted when
    α was the default (its ``fitted/`` file holds the learned state) resumes with α, its
    thresholds and filters together; one fitted before the parameter existed did not read
    α."""
    from campaign.store.directory import CampaignDir

    sig = _signals()
    alpha = _fitted_max(aoa_sensor=True).fit(sig)
    default = _fitted_max().fit(sig)
    assert alpha.aoa_sensor_ is True and default.aoa_sensor_ is False
    a, d = alpha.estimates(sig), default.estimates(sig)
    # the two designs differ on these signals (α read, the vertical gust decoupled)
    assert np.abs(a["lpv"] - d["lpv"]).max() > 1e-3 * np.abs(d["lpv"]).max()
    moved = _fitted_max()                           # the default parameters of this version
    vars(moved).update({k: v for k, v in vars(alpha).items() if k.endswith("_")})
    assert moved._reads_alpha()
    for variant, r in moved.estimates(sig).items():
        np.testing.assert_array_equal(r, a[variant])
    # as a resume reads it: the fitted file written and rebuilt as data
    cdir = CampaignDir(tmp_path / "campaign")
    cdir.open('{"campaign": {"name": "x"}}')
    cdir.write_fitted("vanek-geometric", "vanek-geometric", alpha)
    back = cdir.read_fitted("vanek-geometric", "vanek-geometric")
    assert back._reads_alpha() and back.thresholds_deg_ == alpha.thresholds_deg_
    for variant, r in back.estimates(sig).items():
        np.testing.assert_array_equal(r, a[variant])
    legacy = _fitted_max(aoa_sensor=True)
    vars(legacy).update({k: v for k, v in vars(default).items()
                         if k.endswith("_") and k != "aoa_sensor_"})
    assert not legacy._reads_alpha()                # fitted before the parameter existed
    assert _fitted_max(aoa_sensor=True)._reads_alpha()   # not fitted: the parameter
    assert not _fitted_max()._reads_alpha()
