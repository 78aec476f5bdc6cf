"""The generic LPV H−/H∞ estimator synthesis of [CHEN] eq. 20–23 (detectors.synthesis.lpv_synthesis)
on small systems with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from detectors.synthesis.lpv_synthesis import (LMIInfeasibleError, VertexSystem, discrete_estimator,
                                     hinf_sweep, synthesise)

OMEGA = np.logspace(-4, 4, 1500)   # rad/s: covers every pole of the systems below by decades


def _scalar(a: float) -> VertexSystem:
    """ẋ = −a·x + a·u + δ, y = x + f: the local actuator model's structure ([CHEN] eq. 24)."""
    return VertexSystem.make(A=[[-a]], B=[[a]], C=[[1.0]], H=[[1.0]], M=[[1.0]])


def _two_output() -> list[VertexSystem]:
    """Two states, two outputs, one fault entering both the state and the output."""
    A1 = np.array([[-1.0, 2.0], [0.0, -3.0]])
    A2 = np.array([[-2.0, 1.0], [0.5, -4.0]])
    F1 = np.array([[0.0], [1.0]])
    F2 = np.array([[0.5], [1.0]])
    H = np.array([[1.0], [0.5]])
    return [VertexSystem.make(A=A, B=[[1.0], [0.5]], C=np.eye(2), H=H, F=F, M=np.eye(2))
            for A, F in ((A1, F1), (A2, F2))]


def test_scalar_vertices_give_the_known_gamma():
    # one output, one fault: H⊥ is empty, L1 = −F·H† = 0, L2 = 1; the error system is
    # 1/(s + a), whose H∞ norm is 1/a: the worst vertex gives γ = 1/a_min.
    design = synthesise([_scalar(2.0), _scalar(10.0)])
    # Clarabel's default tolerances reach ~1e-8 relative; 1e-5 leaves room for the
    # strict-inequality margin (1e-7) of the LMIs
    assert design.gamma == pytest.approx(0.5, rel=1e-5)
    assert design.L2 == pytest.approx(np.ones((1, 1)))
    assert design.L1(np.zeros((1, 1))) == pytest.approx(np.zeros((1, 1)))
    assert np.all(np.linalg.eigvalsh(design.P) > 0)


def test_two_output_gains_satisfy_eq_20_21_and_the_sweep_confirms_gamma():
    design = synthesise(_two_output())
    assert design.H_perp.shape == (1, 2)         # p − q = 1 degree of design freedom
    for v in design.vertices:
        decoupled, identity = design.fault_channel(v)
        # F + L1·H = 0 and L2·H = I hold by construction (eq. 20–21): rounding only
        np.testing.assert_allclose(decoupled, 0.0, atol=1e-9)
        np.testing.assert_allclose(identity, np.eye(1), atol=1e-12)
        assert design.stability_margin(v) < 0.0
        peak = hinf_sweep(*design.error_system(v), OMEGA).max()
        # the bounded-real LMI is a certificate: the frequency response may not exceed γ
        # (tolerance: solver accuracy plus the grid, which can only under-estimate the peak)
        assert peak <= design.gamma * (1.0 + 1e-4)
    # the design freedom of the one row of H⊥ is used (Z1 = P⁻¹S of shape n × (p − q))
    assert design.Z1.shape == (2, 1) and np.abs(design.Z1).max() > 1e-3


def test_fault_estimate_converges_to_a_constant_fault_with_unit_static_gain():
    # Linear two-output system at a vertex, constant order u = 0.4 and fault f = 0.7 from
    # step 50; estimator eq. 16 discretised by zero-order hold; plant discretised the same
    # way. (With a varying order, holding y over a period adds an O(Ts·|L1|·ẋ) error; at a
    # steady state both the plant and the estimator keep their continuous equilibria, so
    # the static gain f → f̂ is exactly 1 there.)
    design = synthesise(_two_output())
    v = design.vertices[0]
    ts, T, f0 = 0.01, 3000, 0.7
    est = discrete_estimator(design, v, ts)
    from detectors.synthesis.lpv_synthesis import discretise

    Phi_p, G_p = discretise(v.A, np.hstack([v.B, v.F]), ts)
    x = np.zeros(2)
    xh = np.array([0.3, -0.2])            # wrong initial estimate: must be forgotten
    f_hat = np.empty(T)
    for k in range(T):
        u = np.array([0.4])
        f = np.array([f0 if k >= 50 else 0.0])
        y = v.C @ x + v.H @ f
        f_hat[k] = (est["L2"] @ (y - est["C"] @ xh - est["D"] @ u))[0]
        x = Phi_p @ x + G_p @ np.concatenate([u, f])
        xh = est["Phi"] @ xh + est["Gu"] @ u + est["Gy"] @ y
    # static gain f → f̂ is 1: after 25 s the initial-error transient (slowest error pole
    # ≥ 1 1/s, see stability_margin) has decayed below 1e-6 of the fault
    assert f_hat[-1] == pytest.approx(f0, rel=1e-6)
    assert np.abs(f_hat[-500:] - f0).max() < 1e-6


def test_rank_deficient_h_needs_the_remark_4_1_perturbation():
    # an actuator fault with no direct feed-through (disconnection, eq. 25): H = 0
    verts = [VertexSystem.make(A=[[-1.0, 0.0], [1.0, -2.0]], B=[[1.0], [0.0]], C=np.eye(2),
                               F=[[1.0], [0.0]], H=np.zeros((2, 1)), M=np.eye(2))]
    with pytest.raises(ValueError, match="h_perturbation"):
        synthesise(verts)
    design = synthesise(verts, h_perturbation=1e-2)
    _, identity = design.fault_channel(design.vertices[0])
    np.testing.assert_allclose(identity, np.eye(1), atol=1e-12)
    np.testing.assert_allclose(design.H, [[1e-2], [0.0]])


def test_infeasible_lmis_raise_a_clear_error():
    # unstable A with a single output: H⊥ is empty, L1 = 0, nothing can stabilise e
    with pytest.raises(LMIInfeasibleError, match="Assumption 4.1"):
        synthesise([VertexSystem.make(A=[[1.0]], B=[[1.0]], C=[[1.0]], H=[[1.0]])])


def test_bad_vertex_shapes_are_named():
    with pytest.raises(ValueError, match="vertex 1 has dimensions"):
        synthesise([_scalar(1.0), _two_output()[0]])
    with pytest.raises(ValueError, match="matrix C"):
        VertexSystem.make(A=np.eye(2), B=np.ones((2, 1)), C=np.ones((1, 3)), H=[[1.0]])
