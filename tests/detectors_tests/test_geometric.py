"""The geometric residual-generator routines of detectors.synthesis.geometric ([VANEK] §2) on small
systems whose subspaces are known by hand."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from detectors.synthesis import geometric as geo

E = np.eye(3)


def _span(*cols):
    return np.column_stack(cols)


# Example 1: x1' = −x1 + x2, x2' = −2x2 + f2, x3' = −3x3 + x1 + f1, y = (x1, x3).
# By hand: W0 = ⟨e2⟩ ⊆ Ker C, A e2 = e1 − 2e2 → W* = ⟨e1, e2⟩; Z1 = W* + Ker C = ⟨e1, e2⟩ and
# A⁻¹Z1 ∩ Ker C = ⟨e2⟩ → S* = ⟨e1, e2⟩; H annihilates C S* = ⟨(1, 0)⟩ → H = ±(0, 1).
A1 = np.array([[-1.0, 1.0, 0.0], [0.0, -2.0, 0.0], [1.0, 0.0, -3.0]])
C1 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])

# Example 2 (S* larger than W*): x1' = −x1 + f2, x2' = −2x2 + f1, x3' = −3x3 + x1, y = (x1, x2).
# W0 = ⟨e1⟩, W0 ∩ Ker C = 0 → W* = ⟨e1⟩; Z1 = ⟨e1, e3⟩, A⁻¹Z1 ∩ Ker C = ⟨e3⟩ → S* = ⟨e1, e3⟩
# (the mode x3, unobservable once x1 is discarded, joins the unobservability subspace).
A2 = np.array([[-1.0, 0.0, 0.0], [0.0, -2.0, 0.0], [1.0, 0.0, -3.0]])
C2 = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

# Example 3 (no solution): the integrator chain x1' = x2, x2' = x3, x3' = f2, y = x1:
# W* = S* = the whole space.
A3 = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
C3 = np.array([[1.0, 0.0, 0.0]])


def test_subspace_primitives():
    V = _span(E[0], E[1])
    W = _span(E[1], E[2])
    assert geo.same_subspace(geo.intersection(V, W), E[:, [1]])
    assert geo.same_subspace(geo.subspace_sum(V, W), E)
    assert geo.same_subspace(geo.kernel(C1), E[:, [1]])
    # A3 maps e3 → e2, e2 → e1, e1 → 0: A3⁻¹⟨e1⟩ = ⟨e1, e2⟩
    assert geo.same_subspace(geo.preimage(A3, E[:, [0]]), V)
    # a direction at 1e-12 of the others is rank-deficient at RTOL = 1e-9, kept at 1e-14
    near = _span(E[0], E[0] + 1e-12 * E[1])
    assert geo.basis(near).shape[1] == 1 and geo.basis(near, rtol=1e-14).shape[1] == 2


def test_example_1_subspaces_and_matrices():
    assert geo.same_subspace(geo.conditioned_invariant(A1, C1, E[:, [1]]), _span(E[0], E[1]))
    S = geo.unobservability_subspace(A1, C1, E[:, [1]])
    assert geo.same_subspace(S, _span(E[0], E[1]))
    gen = geo.design(A1, np.zeros((3, 1)), C1, E[:, [2]], E[:, [1]], decay=1.0, radius=20.0)
    assert gen.P.shape == (1, 3) and abs(abs(gen.P[0, 2]) - 1.0) < 1e-12   # X/S* ≅ x3
    assert np.allclose(np.abs(gen.H), [[0.0, 1.0]], atol=1e-12)
    assert np.allclose(gen.M @ gen.P, gen.H @ C1, atol=1e-12)           # M P = H C
    # (A + Ĝ C) S* ⊆ S*
    assert np.linalg.norm(gen.P @ (A1 + gen.G_hat @ C1) @ S) < 1e-12
    eig = np.linalg.eigvals(gen.N)
    assert np.all(eig.real <= -1.0 + 1e-6) and np.all(np.abs(eig) <= 20.0 + 1e-6)


def test_example_2_unobservability_subspace_exceeds_conditioned_invariant():
    L2 = E[:, [0]]
    assert geo.same_subspace(geo.conditioned_invariant(A2, C2, L2), L2)
    S = geo.unobservability_subspace(A2, C2, L2)
    assert geo.same_subspace(S, _span(E[0], E[2]))
    gen = geo.design(A2, np.zeros((3, 1)), C2, E[:, [1]], L2)
    assert gen.N.shape == (1, 1)
    assert np.allclose(np.abs(gen.H), [[0.0, 1.0]], atol=1e-12)


def test_unsolvable_problems_name_the_fault_direction():
    assert geo.same_subspace(geo.unobservability_subspace(A3, C3, E[:, [2]]), E)
    with pytest.raises(geo.GeometricDesignError, match="whole state space"):
        geo.design(A3, np.zeros((3, 1)), C3, E[:, [0]], E[:, [2]])
    with pytest.raises(geo.GeometricDesignError, match=r"S\* ∩ L1 ≠ 0.*left_inboard_aileron"):
        geo.design(A1, np.zeros((3, 1)), C1, (E[0] + E[1])[:, None], E[:, [1]],
                   names1=["left_inboard_aileron"])


def _random_plant(seed):
    """A stable 6-state plant, 3 outputs, 2 inputs, one fault of each kind."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((6, 6))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(6)
    return (A, rng.standard_normal((6, 2)), rng.standard_normal((3, 6)),
            rng.standard_normal((6, 1)), rng.standard_normal((6, 1)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_decoupling_and_sensitivity_frequency_sweep(seed):
    A, B, C, L1, L2 = _random_plant(seed)
    gen = geo.design(A, B, C, L1, L2, decay=0.5, radius=30.0)
    omega = np.logspace(-3, 3, 61)
    g2 = np.abs(gen.fault_to_residual(A, B, C, L2, omega)).max()
    g1 = np.abs(gen.fault_to_residual(A, B, C, L1, omega)).max(axis=(1, 2))
    # exact decoupling: only round-off (unit-norm data, κ ≲ 1e4) may leak from f2
    assert g2 < 1e-9 * g1.max()
    # sensitivity: a non-zero steady-state gain from f1 ([VANEK] §2: r ≠ 0 when f1 ≠ 0)
    dc = geo.dc_gain(gen)
    assert np.linalg.norm(dc) > 1e-3
    assert np.allclose(gen.fault_to_residual(A, B, C, L1, [0.0])[0].real, dc, rtol=1e-8,
                       atol=1e-12)


def test_decoupling_in_simulation_with_the_bilinear_filter():
    A, B, C, L1, L2 = _random_plant(3)
    ts = 0.01
    gen = geo.design(A, B, C, L1, L2, decay=0.5, radius=30.0)
    Ad, Bd, Cd, Dd = geo.bilinear(gen, ts)
    # plant discretised exactly with inputs [u, f1, f2] held (zero-order hold)
    E_all = np.hstack([B, L1, L2])
    Ap, Bp, *_ = scipy.signal.cont2discrete((A, E_all, C, np.zeros((3, 4))), ts, method="zoh")
    T = 3000
    t = np.arange(T) * ts
    u = np.column_stack([np.sin(0.7 * t), np.sign(np.sin(0.3 * t))])
    f2 = np.where(t > 5.0, 1.0 + 0.5 * np.sin(2.0 * t), 0.0)[:, None]
    f1 = np.where(t > 20.0, 1.0, 0.0)[:, None]

    def residual(f1_on: bool):
        x = np.zeros(6)
        w = np.zeros(Ad.shape[0])
        out = np.empty((T, Cd.shape[0]))
        for k in range(T):
            y = C @ x
            inp = np.concatenate([u[k], y])
            out[k] = Cd @ w + Dd @ inp
            w = Ad @ w + Bd @ inp
            x = Ap @ x + Bp @ np.concatenate([u[k], f1[k] if f1_on else [0.0], f2[k]])
        return out

    r = residual(False)
    # f2 and u alone: the residual stays at the Tustin/ZOH mismatch of the known input u,
    # O(ts²) relative, far below the f1 signature (a unit step gives |r| ~ |dc gain|)
    r1 = residual(True)
    dc = np.linalg.norm(geo.dc_gain(gen))
    assert np.abs(r).max() < 1e-2 * dc
    assert np.linalg.norm(r1[-1]) > 0.5 * dc


def test_friend_refuses_a_subspace_that_is_not_conditioned_invariant():
    # ⟨e2⟩ of example 1: A e2 = e1 − 2e2 leaves it, and C e2 = 0 gives no injection to fix it
    with pytest.raises(geo.GeometricDesignError, match="not"):
        geo.friend(A1, C1, E[:, [1]])


def test_bilinear_matches_scipy():
    A, B, C, L1, L2 = _random_plant(4)
    gen = geo.design(A, B, C, L1, L2, decay=0.5, radius=30.0)
    ref = scipy.signal.cont2discrete(gen.state_space(), 0.01, method="bilinear")[:4]
    for mine, theirs in zip(geo.bilinear(gen, 0.01), ref):
        assert np.allclose(mine, theirs, rtol=1e-12, atol=1e-14)


def test_lmi_design_does_not_depend_on_what_was_solved_before():
    # campaign workers solve designs in any order: the same data must give the same bits
    A, B, C, L1, L2 = _random_plant(5)
    gen = geo.design(A, B, C, L1, L2, decay=0.5, radius=30.0)
    geo._LMI_CACHE.clear()
    first = geo.injection_lmi(gen.A_hat, gen.M, 0.5, 30.0)
    other = geo.design(*_random_plant(6), decay=0.5, radius=30.0)
    geo.injection_lmi(other.A_hat, other.M, 0.5, 30.0)
    assert np.array_equal(first, geo.injection_lmi(gen.A_hat, gen.M, 0.5, 30.0))


# An LPV family of example 1: x3' = a(ρ) x3 + b(ρ) x1 + f1 with a = −3 + 3.5ρ, b = 1 + ρ,
# ρ ∈ [0, 1] (unstable x3 at ρ = 1). By hand, for every ρ: S* = ⟨e1, e2⟩, X/S* ≅ x3, M = ±1,
# the friend removes b·x1 through y1, Â(ρ) = a(ρ); with decay 1 one injection for the whole
# interval needs a(ρ) + G̃ ≤ −1, i.e. G̃ ≤ −1.5, and the least ‖K‖ (X = 1) gives G̃ = −1.5.
def _A1(rho):
    A = A1.copy()
    A[2, 2] = -3.0 + 3.5 * rho
    A[2, 0] = 1.0 + rho
    return A


def test_lpv_design_one_injection_for_the_polytope():
    fam = geo.design_lpv([_A1(0.0), _A1(1.0)], C1, [E[:, [2]]] * 2, [E[:, [1]]] * 2,
                         decay=1.0, radius=20.0)
    assert geo.same_subspace(fam.S, _span(E[0], E[1]))
    for rho in np.linspace(0.0, 1.0, 11):
        gen = fam.at(_A1(rho), np.zeros((3, 1)), E[:, [2]], E[:, [1]])
        # the injection (in the sign of M): N = a(ρ) − 1.5 (solver tolerance 1e-5)
        assert gen.N[0, 0] == pytest.approx(-3.0 + 3.5 * rho - 1.5, abs=1e-5)
        assert np.linalg.eigvals(gen.N).real.max() <= -1.0 + 1e-5
        w = np.logspace(-2, 2, 9)
        aileron = np.abs(gen.fault_to_residual(_A1(rho), np.zeros((3, 1)), C1, E[:, [2]], w))
        leak = np.abs(gen.fault_to_residual(_A1(rho), np.zeros((3, 1)), C1, E[:, [1]], w))
        assert aileron.min() > 1e-3 and leak.max() < 1e-12 * aileron.max()


def test_lpv_design_refuses_a_parameter_dependent_unobservability_subspace():
    # with x1' = −x1 (no x2 in it) at the second vertex, by hand W* = S* = ⟨e2⟩ there,
    # against ⟨e1, e2⟩ at the first
    B = _A1(0.0)
    B[0, 1] = 0.0
    assert geo.same_subspace(geo.unobservability_subspace(B, C1, E[:, [1]]), E[:, [1]])
    with pytest.raises(geo.GeometricDesignError, match="S\\* at vertices \\[1\\] differs"):
        geo.design_lpv([_A1(0.0), B], C1, [E[:, [2]]] * 2, [E[:, [1]]] * 2)


def test_an_inaccurate_lmi_answer_is_a_checked_status_not_a_warning():
    """cvxpy warns "Solution may be inaccurate" on an optimal_inaccurate status; the design
    takes it as that status, shows no warning, and keeps the answer only because the poles
    of Â + G̃M are checked against the region (detectors.synthesis.geometric._solve, _injection)."""
    import warnings

    import cvxpy as cp

    class Inaccurate:                       # a problem whose solver stops at reduced accuracy
        status = cp.OPTIMAL_INACCURATE

        def solve(self, solver, warm_start=True):
            warnings.warn("Solution may be inaccurate. Try another solver, adjusting the "
                          "solver settings, or solve with verbose=True for more information.")

    class Value:
        def __init__(self, v):
            self.value = v

    with warnings.catch_warnings():
        warnings.simplefilter("error")      # any warning that escapes fails the test
        status, X, K = geo._solve(Inaccurate(), Value(np.eye(1)), Value(np.array([[-2.0]])),
                                  "CLARABEL", "test")
    assert status == cp.OPTIMAL_INACCURATE
    # the check decides: Â = 0, M = 1, G̃ = −2 puts the pole at −2, inside Re λ ≤ −0.5
    G = geo._injection((status, X, K), [np.zeros((1, 1))], np.eye(1), 0.5, 20.0, "hint")
    assert G[0, 0] == pytest.approx(-2.0)
    # an inaccurate answer outside the region is refused
    with pytest.raises(geo.GeometricDesignError, match="outside"):
        geo._injection((status, X, -0.1 * K), [np.zeros((1, 1))], np.eye(1), 0.5, 20.0, "h")


#: Â and M of the injection LMI at which Clarabel stopped without an answer on the cached
#: parametric problem (vanek-geometric, `fdd-campaign run vanek-isolation --seed 8080`): a
#: 4-state filter with two eigenvalues of Â at 0, decay 0.5 1/s, radius 20 rad/s.
STALLED_A_HAT = np.array([
    [-0.000200700000196656, -0.1939566608399679, -0.07748858738897829, 1.5418979806012572e-17],
    [0.0006535726572825147, -0.4477951725105224, 0.014529477637227096, 1.7674347106139984e-18],
    [-0.003002285138028007, -0.19100273806189208, -0.562014542507303, -4.671077449479853e-18],
    [0.000842148442700302, 0.8923969036364673, 0.34245082044154374, 0.0]])
STALLED_M = np.array([[0.1799498948239988, 0.9187523319982269, 0.3514430078983666, 0.0],
                      [-0.983658401660919, 0.16594652287246983, 0.06984196724336235, 0.0],
                      [0.0, 0.0, 0.0, 1.0]])


def test_a_solver_failure_on_the_cached_lmi_is_solved_afresh(monkeypatch):
    """When the solver fails on the cached parametric LMI
    (detectors.synthesis.geometric.injection_lmi), the LMI is compiled anew and solved once; its
    answer passes the same pole check. Forced here by a first _solve that raises, on the Â, M where
    it happened in a campaign."""
    calls = []
    real = geo._solve

    def failing_once(prob, X, K, solver, what, times=1):
        calls.append(what)
        if len(calls) == 1:
            raise geo.GeometricDesignError(f"{what} failed in {solver}: forced")
        return real(prob, X, K, solver, what, times)

    monkeypatch.setattr(geo, "_solve", failing_once)
    G = geo.injection_lmi(STALLED_A_HAT, STALLED_M, 0.5, 20.0)
    assert len(calls) == 2
    eig = np.linalg.eigvals(STALLED_A_HAT + G @ STALLED_M)
    # the region of eq. 3–4 with _injection's 1e-3 relative tolerance
    assert eig.real.max() <= -0.5 * (1 - 1e-3) and np.abs(eig).max() <= 20.0


@pytest.mark.parametrize("aoa", [False, True], ids=["default", "aoa_sensor"])
def test_aircraft_designs_over_the_envelope_raise_no_solver_warning_and_are_valid(aoa):
    """At the realistic flight points where Clarabel answers optimal_inaccurate (about one
    in four, a boundary optimum: the slowest pole on Re λ = −decay), no warning reaches the
    user and every design is valid: poles in the region, the decoupled directions blind;
    for the default outputs (no α) and with the α vane."""
    import warnings

    from scenarios import envelope

    from detectors.builtin.vanek_geometric import _columns, _fault_columns, _model, _output_matrix
    from detectors.builtin.vanek_geometric import _point, design_filter

    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]].iloc[::4]
    C = _output_matrix(aoa)
    i1, _, _ = _columns()
    w = np.logspace(-3, 2, 21)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for r in pts.itertuples():
            point = _point(r.vcas_kt, r.alt_ft, r.mass_t, r.cg_pct)
            gen, _ = design_filter(point, 0.01, aoa_sensor=aoa)
            eig = np.linalg.eigvals(gen.N)
            # the region Re λ ≤ −0.5, |λ| ≤ 20 within the 1e-3 of _injection's check
            assert eig.real.max() <= -0.5 * (1 - 1e-3) and np.abs(eig).max() <= 20.0 * 1.001
            A, B = _model(point)
            _, L2 = _fault_columns(A, B, True, aoa)
            seen = np.abs(gen.fault_to_residual(A, B, C, B[:, [i1]], w)).max()
            leak = np.abs(gen.fault_to_residual(A, B, C, L2, w)).max()
            assert leak < 1e-9 * seen            # round-off only


def test_an_aircraft_design_does_not_depend_on_the_point_designed_before():
    """Two measured flight points of a 5 000-run cruise learning set (vanek-scenarios'
    envelope, seed 5151: runs 0 and 3317), (vcas kt, alt ft, mass t, CG %, Mach, q̄ Pa).
    With Clarabel warm-started from the solver of the previous design (cvxpy's default for
    a cached problem), the second point's design came out with other bits after the first,
    its slowest pole at −0.4994 (outside Re λ ≤ −0.5): a campaign's run failed, or its
    residual depended on which runs its worker had designed before."""
    from detectors.builtin.vanek_geometric import _point, design_filter

    before = (231.68423259096056, 22788.786668195728, 169.2224516612348, 26.416140033232676,
              0.5370020300486386, 8351.693136749542)
    point = (287.0463427683012, 25225.37535437143, 166.9732794601374, 18.48710815711765,
             0.6908949836822355, 12440.704361900067)
    geo._LMI_CACHE.clear()
    alone = design_filter(_point(*point), 0.01, aoa_sensor=True)[1]
    geo._LMI_CACHE.clear()
    design_filter(_point(*before), 0.01, aoa_sensor=True)
    after = design_filter(_point(*point), 0.01, aoa_sensor=True)[1]
    assert np.array_equal(alone.Ad, after.Ad) and np.array_equal(alone.Bd, after.Bd)
