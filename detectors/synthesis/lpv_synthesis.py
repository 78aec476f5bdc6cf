"""LPV H−/H∞ fault-estimator synthesis of [CHEN] §4 (eq. 15–23), for any list of vertex
systems.

System ([CHEN] eq. 15), at each vertex ν_i of the scheduling polytope (eq. 8–9)::

    ẋ = A x + B u + F f + M δ
    y = C x + D u + H f + N δ

Estimator ([CHEN] eq. 16)::

    x̂' = A x̂ + B u − L1 (y − ŷ),   ŷ = C x̂ + D u,   f̂ = L2 (y − ŷ)

Gains ([CHEN] eq. 20–21), with H† the pseudo-inverse of H and H⊥ a matrix whose rows span
the left null space of H (H⊥ H = 0; it has n_y − n_f rows, none when n_y = n_f)::

    L1(ρ) = −F(ρ) H† + Z1 H⊥,    L2 = H† + Z2 H⊥

so that F(ρ) + L1(ρ) H = 0 and L2 H = I at every ρ: the fault reaches f̂ with the identity
(G_f̂f = I, eq. 19) and the error system e = x − x̂ is, from δ to f̂ − f ([CHEN] eq. 17)::

    ė = (A + L1 C) e + (M + L1 N) δ,    f̂ − f = L2 C e + L2 N δ.

The smallest γ bounding ‖δ → f̂ − f‖∞ at every vertex comes from the bounded-real-lemma
LMIs of [CHEN] eq. 23 with S = P Z1 (linear in P, S, Z2, γ), solved with cvxpy and the
Clarabel interior-point solver; then Z1 = P⁻¹ S. Reading implemented of eq. 23: its (2, 1)
block is P(M − F H† N) + S H⊥ N (the extracted text shows "S H⊥ C", which does not match
eq. 22 nor the dimensions when N ≠ C); the (2,1) and (3,·) blocks are the transposes of the
bounded-real-lemma layout of eq. 22. The pairs (i, j) of eq. 23 (A, C, N at ν_i, F at ν_j)
are all imposed when C or N vary over the vertices; when they are constant (as in [CHEN]
eq. 24–25, §6: "only r LMIs are required") the closed-loop matrices are affine in ρ and
the r diagonal pairs (i, i) are equivalent, so only those are imposed.

Remark 4.1: H must have full column rank; for a fault without direct feed-through (the
disconnection of eq. 25) it is perturbed to H + ε·E with a small ε (``h_perturbation``).

This module imports cvxpy only inside :func:`synthesise`: the online estimator never needs it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from scenarios.errors import InputError

from scenarios.params import param


class LMIInfeasibleError(InputError, ValueError):
    """The vertex LMIs of [CHEN] eq. 23 have no solution (the message says what to check)."""


@dataclass(frozen=True)
class SynthesisNumerics:
    """Numerical constants of the LMI synthesis (not physical parameters)."""

    strict_margin: float = param("-", "numerical",
                                 "LMIs '< 0' are imposed as '≤ −margin·I', and P ≥ margin·I")
    solver: str = param("-", "project rule (STYLE: LMIs with cvxpy + Clarabel)",
                        "cvxpy solver name")


NUMERICS = SynthesisNumerics(strict_margin=1e-7, solver="CLARABEL")


def _mat(a, rows: int | None = None, cols: int | None = None, name: str = "") -> np.ndarray:
    m = np.atleast_2d(np.asarray(a, dtype=float))
    if rows is not None and m.shape[0] != rows or cols is not None and m.shape[1] != cols:
        raise ValueError(f"vertex matrix {name} has shape {m.shape}, expected "
                         f"({rows if rows is not None else '·'}, "
                         f"{cols if cols is not None else '·'})")
    if not np.isfinite(m).all():
        raise ValueError(f"vertex matrix {name} has non-finite entries")
    return m


@dataclass(frozen=True)
class VertexSystem:
    """The system of [CHEN] eq. 15 frozen at one vertex of the scheduling polytope.

    Shapes: A (n, n), B (n, m), C (p, n), D (p, m), F (n, q), H (p, q), M (n, d), N (p, d)
    with n states, m inputs, p outputs, q faults, d uncertainty channels. Units are those of
    the model (the estimator inherits them: f̂ is in the unit of f).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    F: np.ndarray
    H: np.ndarray
    M: np.ndarray
    N: np.ndarray

    @classmethod
    def make(cls, A, B, C, D=None, F=None, H=None, M=None, N=None) -> "VertexSystem":
        """Build and check a vertex (D, N default to zeros; M to the identity; F to zeros)."""
        A = _mat(A, name="A")
        n = A.shape[0]
        if A.shape != (n, n):
            raise ValueError(f"vertex matrix A must be square, got {A.shape}")
        B = _mat(B, n, None, "B")
        C = _mat(C, None, n, "C")
        p, m = C.shape[0], B.shape[1]
        if H is None:
            raise ValueError("vertex matrix H (fault to output) is required; use zeros of "
                             "shape (n_outputs, n_faults) for a pure actuator fault and set "
                             "h_perturbation (Remark 4.1)")
        H = _mat(H, p, None, "H")
        q = H.shape[1]
        D = np.zeros((p, m)) if D is None else _mat(D, p, m, "D")
        F = np.zeros((n, q)) if F is None else _mat(F, n, q, "F")
        M = np.eye(n) if M is None else _mat(M, n, None, "M")
        N = np.zeros((p, M.shape[1])) if N is None else _mat(N, p, M.shape[1], "N")
        return cls(A=A, B=B, C=C, D=D, F=F, H=H, M=M, N=N)

    @property
    def dims(self) -> tuple[int, int, int, int, int]:
        """(n states, m inputs, p outputs, q faults, d uncertainty channels)."""
        return (self.A.shape[0], self.B.shape[1], self.C.shape[0], self.H.shape[1],
                self.M.shape[1])


def perturbed_h(H: np.ndarray, h_perturbation: float, direction=None) -> np.ndarray:
    """H + ε·E of [CHEN] Remark 4.1 (E: *direction*, default the first q columns of the
    identity). Returns H unchanged when ε = 0."""
    H = np.asarray(H, float)
    if h_perturbation == 0.0:
        return H
    E = np.eye(H.shape[0], H.shape[1]) if direction is None else np.asarray(direction, float)
    if E.shape != H.shape:
        raise ValueError(f"perturbation direction has shape {E.shape}, H has {H.shape}")
    return H + float(h_perturbation) * E


def pinv_and_perp(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H†, H⊥): pseudo-inverse and a left annihilator with orthonormal rows (H⊥ H = 0)."""
    H = np.asarray(H, float)
    perp = scipy.linalg.null_space(H.T).T          # (p − rank, p)
    return np.linalg.pinv(H), perp


@dataclass
class EstimatorDesign:
    """Result of :func:`synthesise`: free matrices, γ, and the gains of [CHEN] eq. 20–21.

    P (n, n), S (n, p−q), Z1 = P⁻¹S (n, p−q), Z2 (q, p−q), H_dagger (q, p), H_perp
    (p−q, p), L2 = H† + Z2 H⊥ (q, p); gamma is the smallest feasible bound of
    ‖δ → f̂ − f‖∞ over the vertices; vertices are the systems with the (possibly perturbed) H.
    """

    P: np.ndarray
    S: np.ndarray
    Z1: np.ndarray
    Z2: np.ndarray
    gamma: float
    H: np.ndarray
    H_dagger: np.ndarray
    H_perp: np.ndarray
    L2: np.ndarray
    vertices: list = field(default_factory=list)
    solver_status: str = ""

    def L1(self, F) -> np.ndarray:
        """L1 = −F H† + Z1 H⊥ ([CHEN] eq. 20) for the fault matrix F of a scheduling point."""
        F = np.asarray(F, float)
        return -F @ self.H_dagger + self.Z1 @ self.H_perp

    def error_system(self, v: VertexSystem) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
        """(Ā, B̄, C̄, D̄) of e' = Ā e + B̄ δ, f̂ − f = C̄ e + D̄ δ at vertex *v* ([CHEN] eq. 17)."""
        L1 = self.L1(v.F)
        return v.A + L1 @ v.C, v.M + L1 @ v.N, self.L2 @ v.C, self.L2 @ v.N

    def fault_channel(self, v: VertexSystem) -> tuple[np.ndarray, np.ndarray]:
        """(F + L1 H, L2 H): zero and the identity when eq. 20–21 hold."""
        return v.F + self.L1(v.F) @ self.H, self.L2 @ self.H

    def stability_margin(self, v: VertexSystem) -> float:
        """Largest real part of the eigenvalues of A + L1 C at *v* [1/s] (< 0: stable)."""
        return float(np.max(np.linalg.eigvals(self.error_system(v)[0]).real))


def hinf_sweep(A, B, C, D, omega) -> np.ndarray:
    """Largest singular value of C (jωI − A)⁻¹ B + D at each frequency of *omega* [rad/s]."""
    n = A.shape[0]
    out = np.empty(len(omega))
    for k, w in enumerate(omega):
        G = C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D
        out[k] = np.linalg.svd(G, compute_uv=False)[0]
    return out


def synthesise(vertices: list[VertexSystem], *, h_perturbation: float = 0.0,
               h_direction=None, numerics: SynthesisNumerics = NUMERICS) -> EstimatorDesign:
    """Solve the vertex LMIs of [CHEN] eq. 23 for P, S, Z2 and the smallest γ.

    Parameters
    ----------
    vertices : list of :class:`VertexSystem`
        The system at the vertices of the scheduling polytope ([CHEN] eq. 8); H must be the
        same at every vertex (an additive sensor fault, [CHEN] §4).
    h_perturbation : float
        ε of Remark 4.1: H is replaced by H + ε·E (E = *h_direction*, default the first
        columns of the identity) so that it has full column rank; 0 leaves H unchanged.

    Raises
    ------
    ValueError
        Inconsistent vertex shapes, or H without full column rank (set h_perturbation).
    LMIInfeasibleError
        When the solver finds no solution (e.g. (C, A) not detectable at some vertex, or a
        fault channel with zeros on the imaginary axis: [CHEN] Assumption 4.1).
    """
    import cvxpy as cp

    if not vertices:
        raise ValueError("synthesise needs at least one vertex system")
    dims = vertices[0].dims
    for i, v in enumerate(vertices):
        if v.dims != dims:
            raise ValueError(f"vertex {i} has dimensions {v.dims}, vertex 0 has {dims}")
        if not np.allclose(v.H, vertices[0].H):
            raise ValueError(f"vertex {i} has a different H: [CHEN] §4 needs a constant H "
                             "(additive sensor fault)")
    n, _, p, q, d = dims
    H = perturbed_h(vertices[0].H, h_perturbation, h_direction)
    if np.linalg.matrix_rank(H) < q:
        raise ValueError(f"H (shape {H.shape}) has rank {np.linalg.matrix_rank(H)} < {q} "
                         "faults: [CHEN] Assumption 4.1(ii) needs full column rank; set "
                         "h_perturbation to a small ε > 0 (Remark 4.1)")
    verts = [VertexSystem(A=v.A, B=v.B, C=v.C, D=v.D, F=v.F, H=H, M=v.M, N=v.N)
             for v in vertices]
    Hd, Hp = pinv_and_perp(H)
    k = Hp.shape[0]                                    # p − q

    eps = numerics.strict_margin
    P = cp.Variable((n, n), symmetric=True)
    S = cp.Variable((n, k)) if k else None
    Z2 = cp.Variable((q, k)) if k else None
    gamma = cp.Variable(nonneg=True)
    constant_output = all(np.allclose(v.C, verts[0].C) and np.allclose(v.N, verts[0].N)
                          for v in verts)
    pairs = ([(i, i) for i in range(len(verts))] if constant_output
             else [(i, j) for i in range(len(verts)) for j in range(len(verts))])
    cons = [P >> eps * np.eye(n)]
    for i, j in pairs:
        vi, vj = verts[i], verts[j]
        pa = P @ vi.A - P @ vj.F @ Hd @ vi.C          # P(A − F H† C)
        pm = P @ vi.M - P @ vj.F @ Hd @ vi.N          # P(M − F H† N)
        l2 = Hd                                        # H† + Z2 H⊥
        if k:
            pa = pa + S @ Hp @ vi.C
            pm = pm + S @ Hp @ vi.N
            l2 = Hd + Z2 @ Hp
        c_bar = l2 @ vi.C
        d_bar = l2 @ vi.N
        block = cp.bmat([
            [pa + pa.T, pm, c_bar.T],
            [pm.T, -gamma * np.eye(d), d_bar.T],
            [c_bar, d_bar, -gamma * np.eye(q)],
        ])
        size = n + d + q
        # symmetrise explicitly (cvxpy checks symmetry of the expression it constrains)
        cons.append(0.5 * (block + block.T) << -eps * np.eye(size))
    prob = cp.Problem(cp.Minimize(gamma), cons)
    try:
        prob.solve(solver=numerics.solver)
    except cp.error.SolverError as exc:
        raise LMIInfeasibleError(f"the LMI solver {numerics.solver} failed on [CHEN] eq. 23 "
                                 f"({len(pairs)} vertex LMIs): {exc}") from exc
    if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or gamma.value is None:
        raise LMIInfeasibleError(
            f"the vertex LMIs of [CHEN] eq. 23 are {prob.status} ({len(verts)} vertices, "
            f"{len(pairs)} LMIs): no stable estimator with G_f̂f = I exists for this polytope. "
            "Check [CHEN] Assumption 4.1 at every vertex: (C, A) detectable, H of full column "
            "rank (Remark 4.1: h_perturbation), no zeros of f → y on the imaginary axis; or "
            "shrink the scheduling polytope")
    Pv = np.asarray(P.value)
    Sv = np.asarray(S.value) if k else np.zeros((n, 0))
    Z2v = np.asarray(Z2.value) if k else np.zeros((q, 0))
    Z1v = np.linalg.solve(Pv, Sv) if k else np.zeros((n, 0))
    return EstimatorDesign(P=Pv, S=Sv, Z1=Z1v, Z2=Z2v, gamma=float(gamma.value), H=H,
                           H_dagger=Hd, H_perp=Hp, L2=Hd + Z2v @ Hp, vertices=verts,
                           solver_status=str(prob.status))


def discretise(A, B, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation at period *ts* [s]: (Φ, Γ) = (e^{A·ts}, ∫ e^{A·s} ds·B)."""
    A = np.atleast_2d(np.asarray(A, float))
    B = np.atleast_2d(np.asarray(B, float))
    n, m = A.shape[0], B.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A * ts
    aug[:n, n:] = B * ts
    e = scipy.linalg.expm(aug)
    return e[:n, :n], e[:n, n:]


def discrete_estimator(design: EstimatorDesign, v: VertexSystem, ts: float) -> dict:
    """The estimator of [CHEN] eq. 16 frozen at vertex *v*, discretised at *ts* [s] by
    zero-order hold on its inputs (u, y)::

        x̂_{k+1} = Φ x̂_k + Γu u_k + Γy y_k,    f̂_k = L2 (y_k − C x̂_k − D u_k)

    Returns {"Phi", "Gu", "Gy", "L2", "C", "D"}. (A global-level detector evaluates these
    affine in ρ online; this frozen form is what the tests and the stability checks use.)
    """
    L1 = design.L1(v.F)
    A_e = v.A + L1 @ v.C                       # x̂' = (A + L1 C) x̂ + (B + L1 D) u − L1 y
    B_e = np.hstack([v.B + L1 @ v.D, -L1])
    Phi, G = discretise(A_e, B_e, ts)
    m = v.B.shape[1]
    return {"Phi": Phi, "Gu": G[:, :m], "Gy": G[:, m:], "L2": design.L2, "C": v.C, "D": v.D}
