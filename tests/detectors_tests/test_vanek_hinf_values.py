"""detectors.synthesis.vanek_hinf pinned by value ([VANEK] §3, docs/vanek-geometric.md): the
weighted interconnections handed to the H∞ synthesis, written again from the module's documented
equations (the post-filter's model matching; the one-step filter's weights, Dryden shaping,
known inputs and noise σ·√Ts), the singular-perturbation reduction and the cascade against
hand-built systems whose answers are known in closed form, the sensor σ and the weights'
values, and the errors raised on bad input or a missing optional library."""

from __future__ import annotations

import builtins
import dataclasses
import functools

import numpy as np
import pytest

from detectors.builtin import vanek_geometric as vg
from detectors.synthesis import vanek_hinf as vh
from scenarios.aircraft import lpv
from scenarios.aircraft.data import AIRCRAFT_SENSORS

control = pytest.importorskip("control")       # the [hinf] extra, part of the [test] extra

TS = 0.01


def _tf(A, B, C, D, s):
    """Transfer matrix C (sI − A)⁻¹ B + D at the complex frequency s."""
    return C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D


@functools.lru_cache(maxsize=None)
def _generator():
    point = vg._point(*dataclasses.astuple(vg.NOMINAL))
    return vg.design_filter(point, TS)[0]        # the default design (outputs without α)


def _capture_hinfsyn(monkeypatch):
    """Record the plant and the measurement/control counts given to control.hinfsyn and
    the controller it returns."""
    seen = {}
    real = control.hinfsyn

    def hinfsyn(plant, nmeas, ncon):
        # a non-finite interconnection is wrong whatever it is, and SLICOT may take minutes
        # on one: refuse it before the synthesis
        assert all(np.isfinite(m).all() for m in (plant.A, plant.B, plant.C, plant.D))
        out = real(plant, nmeas, ncon)
        seen.update(plant=plant, nmeas=nmeas, ncon=ncon, K=out[0], gamma=out[2])
        return out

    monkeypatch.setattr(control, "hinfsyn", hinfsyn)
    return seen


def _same(actual, expected):
    np.testing.assert_allclose(np.asarray(actual), expected, rtol=1e-13,
                               atol=1e-15 * max(np.abs(expected).max(), 1.0))


def test_sensor_sigmas_and_one_step_weights():
    s = AIRCRAFT_SENSORS
    rate, att = np.radians(s.rate_noise_deg_s), np.radians(s.attitude_noise_deg)
    # in the design outputs' order α, q, θ, β, p, r, φ
    np.testing.assert_array_equal(vh.sensor_sigmas(vg.OUTPUTS), [np.radians(
        s.aoa_noise_deg), rate, att, np.radians(s.sideslip_noise_deg), rate, rate, att])
    np.testing.assert_array_equal(vh.sensor_sigmas(("phi", "beta")),
                                  [att, np.radians(s.sideslip_noise_deg)])
    w = vh.ONE_STEP
    assert (w.fault_rad, w.isolated_rad, w.known_rad, w.gust_rad) == pytest.approx(
        np.radians([3.0, 5.0, 5.0, 1.0]), rel=1e-15)
    assert (w.gust_bandwidth, w.omega_id, w.eps, w.exact_sigma_rad, w.max_pole) == (
        0.2, 1.0, 0.1, 1e-6, 100.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.eps = 1.0


def _model_matching(gen, sigma, fs, om, eps):
    """(A, B, C, D) of the post-filter's interconnection, from the module docstring: states
    [e; x_id]; inputs [w_f = f1/f_s; n (p); f̂]; outputs [x_id − f̂; ε f̂; r]."""
    N, M, H, G = gen.N, gen.M, gen.H, gen.G
    Sig = np.diag(sigma)
    nw, nq, p = N.shape[0], M.shape[0], len(sigma)
    pl1 = gen.P @ gen.L1[:, 0]
    A = np.zeros((nw + 1, nw + 1))
    A[:nw, :nw] = N
    A[nw, nw] = -om
    B = np.zeros((nw + 1, 1 + p + 1))
    B[:nw, 0] = -pl1 * fs                               # ė = N e − P L1 f1 − G Σ n
    B[:nw, 1:1 + p] = -G @ Sig
    B[nw, 0] = om * fs                                  # ẋ_id = −ω x_id + ω f1
    C = np.zeros((2 + nq, nw + 1))
    C[0, nw] = 1.0
    C[2:, :nw] = M
    D = np.zeros((2 + nq, 1 + p + 1))
    D[0, -1], D[1, -1] = -1.0, eps
    D[2:, 1:1 + p] = -H @ Sig                           # r = M e − H Σ n
    return A, B, C, D


def test_post_filter_interconnection_is_the_documented_model_matching(monkeypatch):
    seen = _capture_hinfsyn(monkeypatch)
    real_residualise = vh.residualise

    def residualise(*args):
        seen["max_pole"] = args[-1]
        return real_residualise(*args)

    monkeypatch.setattr(vh, "residualise", residualise)
    gen = _generator()
    sigma = vh.sensor_sigmas(vg.design_outputs()) * np.sqrt(TS)   # as lti-hinf uses it
    q = vh.post_filter(gen, sigma)          # defaults: f_s 0.1, ω_id 1, ε 0.1, 100 rad/s
    plant = seen["plant"]
    for got, want in zip((plant.A, plant.B, plant.C, plant.D),
                         _model_matching(gen, sigma, 0.1, 1.0, 0.1)):
        _same(got, want)
    assert (seen["nmeas"], seen["ncon"]) == (gen.M.shape[0], 1)
    assert seen["max_pole"] == 100.0                  # the documented default
    K = seen["K"]
    reduced = vh.residualise(np.asarray(K.A), np.asarray(K.B), np.asarray(K.C),
                             np.asarray(K.D), 100.0)
    for got, want in zip((q.A, q.B, q.C, q.D), reduced):
        np.testing.assert_array_equal(got, want)
    assert q.gamma == float(seen["gamma"])
    # the reduction is exercised: one mode of the central filter (measured 269 rad/s) goes
    assert np.abs(np.linalg.eigvals(K.A)).max() > 100.0 and q.A.shape[0] < K.A.shape[0]
    with pytest.raises(dataclasses.FrozenInstanceError):
        q.gamma = 0.0


def test_post_filter_of_a_hand_built_filter_with_fewer_residuals_than_states(monkeypatch):
    # two filter states, one residual, two sensors (the aircraft's filter has q = n − s),
    # two fault columns of which the post-filter tracks the first
    import types

    seen = _capture_hinfsyn(monkeypatch)
    gen = types.SimpleNamespace(N=np.array([[-1.0, 0.3], [0.0, -2.0]]),
                                M=np.array([[1.0, 0.5]]), H=np.array([[0.2, -0.1]]),
                                G=np.array([[0.4, 0.0], [0.1, 0.3]]), P=np.eye(2),
                                L1=np.array([[1.0, 0.0], [0.5, 1.0]]))   # f1 is the first
    sigma = np.array([0.01, 0.02])
    vh.post_filter(gen, sigma, fault_scale=0.2, omega_id=2.0, eps=0.3)
    plant = seen["plant"]
    for got, want in zip((plant.A, plant.B, plant.C, plant.D),
                         _model_matching(gen, sigma, 0.2, 2.0, 0.3)):
        _same(got, want)
    assert (seen["nmeas"], seen["ncon"]) == (1, 1)


def test_post_filter_weights_are_keyword_only():
    with pytest.raises(TypeError):
        vh.post_filter(_generator(), vh.sensor_sigmas(vg.design_outputs()), 0.2)


@pytest.mark.parametrize("kwargs", [{"omega_id": 0.0}, {"eps": 0.0}, {"omega_id": -1.0},
                                    {"eps": -0.1}])
def test_post_filter_refuses_non_positive_bandwidth_or_penalty(kwargs):
    with pytest.raises(ValueError, match="omega_id and eps must be > 0"):
        vh.post_filter(_generator(), vh.sensor_sigmas(vg.design_outputs()), **kwargs)


def _no_control(monkeypatch, missing):
    real = builtins.__import__

    def block(name, *args, **kwargs):
        if name == missing:
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", block)


@pytest.mark.parametrize("missing", ["control", "slycot"])
def test_missing_optional_libraries_name_the_extra(monkeypatch, missing):
    _no_control(monkeypatch, missing)
    with pytest.raises(vh.HinfUnavailableError, match=r"fdd-campaign\[hinf\]"):
        vh.post_filter(_generator(), vh.sensor_sigmas(vg.design_outputs()))
    with pytest.raises(vh.HinfUnavailableError, match=r"fdd-campaign\[hinf\]"):
        vh.one_step_filter(-np.eye(1), np.ones((1, 3)), np.ones((1, 1)), ("q",), 0, [1], [2],
                           [], [1e-3], [1e-3], TS)
    assert issubclass(vh.HinfUnavailableError, ImportError)


def test_residualise_keeps_the_slow_mode_and_the_dc_gain():
    # modes −1 and −200 (and −100: exactly at the limit, so not slow), mixed by a rotation
    rng = np.random.default_rng(1)
    Z, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    lam = np.array([-1.0, -200.0, -100.0])
    A = Z @ np.diag(lam) @ Z.T
    B, C, D = rng.normal(size=(3, 2)), rng.normal(size=(2, 3)), rng.normal(size=(2, 2))
    Ar, Br, Cr, Dr = vh.residualise(A, B, C, D, 100.0)
    assert Ar.shape == (1, 1) and Ar[0, 0] == pytest.approx(-1.0, rel=1e-12)
    b, c = Z.T @ B, C @ Z                               # modal coordinates
    for s in (0.0, 0.5j, 3.0j):
        # singular perturbation: the fast modes at their steady state −bᵢ/λᵢ
        want = (np.outer(c[:, 0], b[0]) / (s + 1.0) + D
                + sum(np.outer(c[:, i], b[i]) / -lam[i] for i in (1, 2)))
        np.testing.assert_allclose(_tf(Ar, Br, Cr, Dr, s), want, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(_tf(Ar, Br, Cr, Dr, 0.0), _tf(A, B, C, D, 0.0), rtol=1e-10)
    # a mode exactly at the limit is not slow (|λ| < max_pole): diagonal A, no round-off
    Ad = np.diag([-1.0, -100.0])
    assert vh.residualise(Ad, B[:2], C[:, :2], D, 100.0)[0].shape == (1, 1)
    assert vh.residualise(Ad, B[:2], C[:, :2], D, 100.0 + 1e-9)[0].shape == (2, 2)
    # nothing faster than the limit: the system is returned as it is
    out = vh.residualise(A, B, C, D, 1000.0)
    for got, want in zip(out, (A, B, C, D)):
        assert got is want


def test_cascade_is_the_filter_followed_by_q():
    rng = np.random.default_rng(2)
    Af, Bf = np.array([[-1.0, 0.5], [0.0, -2.0]]), rng.normal(size=(2, 4))
    Cf, Df = rng.normal(size=(3, 2)), rng.normal(size=(3, 4))

    class Gen:
        def state_space(self):
            return Af, Bf, Cf, Df

    q = vh.PostFilter(A=np.array([[-3.0]]), B=rng.normal(size=(1, 3)),
                      C=np.array([[0.7]]), D=rng.normal(size=(1, 3)), gamma=0.5)
    A, B, C, D = vh.cascade(Gen(), q)
    for s in (0.0, 1.0j, 4.0j):
        want = _tf(q.A, q.B, q.C, q.D, s) @ _tf(Af, Bf, Cf, Df, s)
        np.testing.assert_allclose(_tf(A, B, C, D, s), want, rtol=1e-12, atol=1e-14)


def _one_step_model():
    """The aircraft design model at the LTI point without the pitch attitude (stable)."""
    A, B = vg._model(vg._point(*dataclasses.astuple(vg.NOMINAL)))
    keep = [j for j, s in enumerate(lpv.STATES) if s != "theta"]
    names = [lpv.STATES[j] for j in keep]
    outs = ("q", "beta", "p", "r", "phi")
    C = np.eye(len(keep))[[names.index(o) for o in outs]]
    return A[np.ix_(keep, keep)], B[keep], C, outs


@pytest.mark.parametrize("feedthrough", [True, False])
def test_one_step_interconnection_is_the_documented_one(monkeypatch, feedthrough):
    seen = _capture_hinfsyn(monkeypatch)
    A, B, C, outs = _one_step_model()
    i1, i2, known, gusts = 2, [0, 6], [1, 3, 4, 5, 7], [lpv.I_GUST_BETA, lpv.I_GUST_ALPHA]
    sig_y = np.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-4
    sig_u = np.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-5
    d_g = np.zeros((5, 2))
    d_g[1, 0] = 1.0
    w = dataclasses.replace(vh.ONE_STEP, fault_rad=0.06, isolated_rad=0.08, known_rad=0.09,
                            gust_rad=0.02, gust_bandwidth=0.3, omega_id=1.5, eps=0.2)
    f = vh.one_step_filter(A, B, C, outs, i1, i2, known, gusts, sig_y, sig_u, 0.02, w,
                           gust_feedthrough=d_g if feedthrough else None)
    n, p, m, ng = A.shape[0], 5, len(known), 2
    N = n + 1 + ng
    # exogenous inputs in order: w_f, w_d (2), w_g (2), n_y (p), w_u (m), n_u (m); then f̂
    cw = {"f": 0, "d": slice(1, 3), "g": slice(3, 5), "ny": slice(5, 5 + p),
          "u": slice(5 + p, 5 + p + m), "nu": slice(5 + p + m, 5 + p + 2 * m)}
    nw = 5 + p + 2 * m
    Aa = np.zeros((N, N))
    Aa[:n, :n] = A
    Aa[:n, n + 1:] = B[:, gusts]                       # the gust states drive the aircraft
    Aa[n, n] = -1.5                                    # T_id
    Aa[n + 1:, n + 1:] = -0.3 * np.eye(ng)             # first-order Dryden shaping
    B1 = np.zeros((N, nw + 1))
    B1[:n, cw["f"]] = B[:, i1] * 0.06
    B1[n, cw["f"]] = 1.5 * 0.06
    B1[:n, cw["d"]] = B[:, i2] * 0.08
    B1[n + 1:, cw["g"]] = 0.02 * np.sqrt(2.0 * 0.3) * np.eye(ng)
    B1[:n, cw["u"]] = B[:, known] * 0.09
    C1 = np.zeros((2 + m + p, N))
    C1[0, n] = 1.0 / 0.06                              # (x_id − f̂)/f_s
    C1[2 + m:, :n] = C
    if feedthrough:
        C1[2 + m:, n + 1:] = d_g
    D1 = np.zeros((2 + m + p, nw + 1))
    D1[0, -1], D1[1, -1] = -1.0 / 0.06, 0.2 / 0.06     # −f̂/f_s, ε f̂/f_s
    D1[2:2 + m, cw["u"]] = 0.09 * np.eye(m)            # the known inputs, measured
    D1[2:2 + m, cw["nu"]] = np.diag(sig_u * np.sqrt(0.02))
    D1[2 + m:, cw["ny"]] = np.diag(sig_y * np.sqrt(0.02))
    plant = seen["plant"]
    for got, want in ((plant.A, Aa), (plant.B, B1), (plant.C, C1), (plant.D, D1)):
        _same(got, want)
    assert f.plant is plant and f.full is seen["K"]
    assert (seen["nmeas"], seen["ncon"]) == (m + p, 1)
    K = seen["K"]
    reduced = vh.residualise(np.asarray(K.A), np.asarray(K.B), np.asarray(K.C),
                             np.asarray(K.D), w.max_pole)
    for got, want in zip((f.A, f.B, f.C, f.D), reduced):
        np.testing.assert_array_equal(got, want)
    assert f.gamma == float(seen["gamma"]) and f.outputs == outs
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.gamma = 0.0


def test_one_step_refuses_a_model_that_is_not_stable():
    A = np.array([[0.0, 1.0], [0.0, -1.0]])            # an integrator: eigenvalue exactly 0
    with pytest.raises(ValueError, match="needs a stable design model"):
        vh.one_step_filter(A, np.eye(2)[:, [0, 1, 0, 1]], np.eye(2), ("a", "b"), 0, [1],
                           [2], [3], [1e-3, 1e-3], [1e-3], TS)
