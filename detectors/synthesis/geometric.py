"""Geometric fault detection and isolation filters ([VANEK] §2, after Massoumnia 1986):
general linear-algebra routines, not tied to one plant.

System ([VANEK] eq. 1)::

    ẋ = A x + B u + L1 f1 + L2 f2,    y = C x

Residual generator ([VANEK] eq. 2), sensitive to f1 and exactly blind to f2::

    ẇ = N w − G y + F u,    r = M w − H y

Construction ([VANEK] §2):

* W* — the smallest (C, A)-invariant (conditioned-invariant) subspace containing L2 = Im L2,
  limit of the non-decreasing recursion W₀ = L2, W_{k+1} = L2 + A(W_k ∩ Ker C);
* S* — the smallest (C, A)-unobservability subspace containing L2, limit of the
  non-increasing recursion Z₀ = X, Z_{k+1} = W* + (A⁻¹Z_k ∩ Ker C) (A⁻¹ the pre-image;
  Massoumnia 1986, the unobservability-subspace algorithm);
* solvability: S* ∩ L1 = 0 (Massoumnia, Verghese & Willsky 1989);
* P: X → X/S* with Ker P = S* (orthonormal rows spanning S*⊥, so P Pᵀ = I);
* H with Ker HC = Ker C + S* (rows spanning the left null space of C·S*); M P = HC, so
  M = HC Pᵀ;
* the friend Ĝ with (A + ĜC) S* ⊆ S*; Â = P (A + ĜC) Pᵀ;
* the output injection G̃ = X⁻¹K from the LMI of [VANEK] eq. 3–4 (solved with cvxpy and
  Clarabel, imported lazily); N = Â + G̃ M, G = P Ĝ + G̃ H, F = P B.

With e = w − P x the error obeys ė = N e − P L1 f1 and r = M e (P L2 = 0 because L2 ⊆ S*):
f2 never reaches r, and f1 does unless S* ∩ L1 ≠ 0.

The LMI of eq. 3–4 is imposed with a decay rate and a disk region so that the filter is not
only stable but has its poles where a sampled implementation can carry them (Chilali &
Gahinet 1996 D-stability regions, linear in X and K like eq. 3)::

    Âᵀ X + X Â + Mᵀ Kᵀ + K M + 2 α X ⪯ 0,            (eq. 3 with decay α ≥ 0)
    [[−ρ X, X Â + K M], [(X Â + K M)ᵀ, −ρ X]] ⪯ 0,      (poles in |λ| ≤ ρ)
    X ⪰ I                                             (eq. 4, normalised)

LPV ([VANEK] §5; Balas, Bokor & Szabó 2003): for a polytope of models A(θ) whose S* does
not depend on θ, :func:`design_lpv` keeps S*, P, H, M fixed, computes the friend at each θ
(linear in A, so affine when A is) and takes one G̃ from the LMI at every vertex with a
common X (:func:`injection_lmi_common`): the pole region then holds on the whole polytope.

Rank decisions use singular values: a singular value is counted as non-zero when it exceeds
``rtol × (largest singular value of the matrix tested, or 1 if that is zero)``; the default
``RTOL = 1e-9`` is far above double-precision round-off on well-scaled models of size ≤ 50
and far below any physical coupling of such models (scale the states first otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass

import threading
import warnings

import numpy as np

from scenarios.errors import InputError

#: Default relative rank tolerance of every subspace routine (module docstring).
RTOL = 1e-9


class GeometricDesignError(InputError, ValueError):
    """The geometric residual-generation problem has no solution (the message says why)."""


# ---- subspaces (columns of orthonormal basis matrices) ---------------------------------------
def _rank_cut(s: np.ndarray, rtol: float) -> int:
    if s.size == 0:
        return 0
    scale = s[0] if s[0] > 0 else 1.0
    return int(np.sum(s > rtol * scale))


def basis(M, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis (n, k) of the column space Im M of an (n, m) matrix; k is the number
    of singular values above rtol × the largest."""
    M = np.atleast_2d(np.asarray(M, float))
    n = M.shape[0]
    if M.size == 0 or M.shape[1] == 0:
        return np.zeros((n, 0))
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, :_rank_cut(s, rtol)]


def kernel(M, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis (m, k) of Ker M of an (p, m) matrix (same rank tolerance as
    :func:`basis`)."""
    M = np.atleast_2d(np.asarray(M, float))
    m = M.shape[1]
    if M.shape[0] == 0:
        return np.eye(m)
    _, s, Vt = np.linalg.svd(M, full_matrices=True)
    return Vt[_rank_cut(s, rtol):].T.conj()


def complement(V, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis of the orthogonal complement of Im V (V: (n, k))."""
    V = np.atleast_2d(np.asarray(V, float))
    return kernel(V.T, rtol) if V.shape[1] else np.eye(V.shape[0])


def subspace_sum(*Vs, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis of Im V1 + Im V2 + … (all with the same number of rows)."""
    return basis(np.hstack([np.atleast_2d(np.asarray(V, float)) for V in Vs]), rtol)


def intersection(V, W, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis of Im V ∩ Im W: the complement of (Im V)⊥ + (Im W)⊥."""
    V = np.atleast_2d(np.asarray(V, float))
    W = np.atleast_2d(np.asarray(W, float))
    n = V.shape[0]
    if V.shape[1] == 0 or W.shape[1] == 0:
        return np.zeros((n, 0))
    return complement(subspace_sum(complement(V, rtol), complement(W, rtol), rtol=rtol), rtol)


def preimage(A, V, rtol: float = RTOL) -> np.ndarray:
    """Orthonormal basis of A⁻¹ Im V = {x : A x ∈ Im V} (A need not be invertible)."""
    A = np.atleast_2d(np.asarray(A, float))
    Vp = complement(V, rtol)                     # A x ∈ Im V  ⇔  Vpᵀ A x = 0
    return kernel(Vp.T @ A, rtol) if Vp.shape[1] else np.eye(A.shape[1])


def contains(V, W, rtol: float = RTOL) -> bool:
    """True when Im W ⊆ Im V (rank of [V W] equals rank of V)."""
    return basis(np.hstack([V, W]), rtol).shape[1] == basis(V, rtol).shape[1]


def same_subspace(V, W, rtol: float = RTOL) -> bool:
    """True when Im V = Im W."""
    return contains(V, W, rtol) and contains(W, V, rtol)


# ---- Massoumnia's subspaces -------------------------------------------------------------------
def conditioned_invariant(A, C, L, rtol: float = RTOL) -> np.ndarray:
    """W*: the smallest (C, A)-invariant subspace containing Im L (module docstring); the
    recursion stops when the dimension stops growing (at most n steps)."""
    A = np.atleast_2d(np.asarray(A, float))
    W = basis(L, rtol)
    kerC = kernel(C, rtol)
    for _ in range(A.shape[0] + 1):
        nxt = subspace_sum(L, A @ intersection(W, kerC, rtol), rtol=rtol)
        if nxt.shape[1] == W.shape[1]:
            return nxt
        W = nxt
    return W


def unobservability_subspace(A, C, L, rtol: float = RTOL) -> np.ndarray:
    """S*: the smallest (C, A)-unobservability subspace containing Im L (module docstring),
    from W* and the non-increasing recursion Z_{k+1} = W* + (A⁻¹ Z_k ∩ Ker C)."""
    A = np.atleast_2d(np.asarray(A, float))
    n = A.shape[0]
    Wstar = conditioned_invariant(A, C, L, rtol)
    kerC = kernel(C, rtol)
    Z = np.eye(n)
    for _ in range(n + 1):
        nxt = subspace_sum(Wstar, intersection(preimage(A, Z, rtol), kerC, rtol), rtol=rtol)
        if nxt.shape[1] == Z.shape[1]:
            return nxt
        Z = nxt
    return Z


def friend(A, C, S, rtol: float = RTOL) -> np.ndarray:
    """A gain Ĝ (n, p) with (A + ĜC) Im S ⊆ Im S (S conditioned invariant), of the form
    Ĝ = Sc X with Sc spanning S⊥: solves X (C S) = −Scᵀ A S in the least-squares sense and
    checks the invariance (raises :class:`GeometricDesignError` when S is not
    (C, A)-invariant)."""
    A = np.atleast_2d(np.asarray(A, float))
    C = np.atleast_2d(np.asarray(C, float))
    Sc = complement(S, rtol)
    if S.shape[1] == 0 or Sc.shape[1] == 0:
        return np.zeros((A.shape[0], C.shape[0]))
    rhs = -(Sc.T @ A @ S)                        # (n−s, s)
    CS = C @ S                                   # (p, s)
    X = np.linalg.lstsq(CS.T, rhs.T, rcond=None)[0].T
    G = Sc @ X
    leak = np.linalg.norm(Sc.T @ (A + G @ C) @ S)
    if leak > 1e3 * rtol * max(np.linalg.norm(A), 1.0):
        raise GeometricDesignError(
            f"no friend Ĝ makes the subspace (A + ĜC)-invariant (leak {leak:.3g}): it is not "
            "(C, A)-invariant; pass a subspace from unobservability_subspace()")
    return G


# ---- the residual generator ----------------------------------------------------------------------
@dataclass(frozen=True)
class ResidualGenerator:
    """Matrices of [VANEK] eq. 2 and of its construction.

    S (n, s): basis of S*; P (n−s, n), H (q, p), M (q, n−s), G_hat (n, p), A_hat (n−s, n−s),
    G_tilde (n−s, q), N (n−s, n−s), G (n−s, p), F (n−s, m); L1 (n, k1), L2 (n, k2).
    Units: those of the model (w in the state unit, r in the output unit).
    """

    S: np.ndarray
    P: np.ndarray
    H: np.ndarray
    M: np.ndarray
    G_hat: np.ndarray
    A_hat: np.ndarray
    G_tilde: np.ndarray
    N: np.ndarray
    G: np.ndarray
    F: np.ndarray
    L1: np.ndarray
    L2: np.ndarray

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A_f, B_f, C_f, D_f) of the filter with input [u; y] and output r."""
        B_f = np.hstack([self.F, -self.G])
        D_f = np.hstack([np.zeros((self.M.shape[0], self.F.shape[1])), -self.H])
        return self.N, B_f, self.M, D_f

    def fault_to_residual(self, A, B, C, E, omega, D=None) -> np.ndarray:
        """Frequency response (len(omega), q, k) [output unit per fault unit] of the plant
        (A, B, C) with fault directions E (n, k) in series with this filter, omega [rad/s].
        ``D`` (p, k): the faults' direct feed-through to the outputs, y = Cx + D f."""
        n, nw = A.shape[0], self.N.shape[0]
        D = np.zeros((C.shape[0], E.shape[1])) if D is None else np.asarray(D, float)
        Acl = np.block([[A, np.zeros((n, nw))], [-self.G @ C, self.N]])
        Bcl = np.vstack([E, -self.G @ D])
        Ccl = np.hstack([-self.H @ C, self.M])
        eye = np.eye(n + nw)
        return np.array([Ccl @ np.linalg.solve(1j * w * eye - Acl, Bcl) - self.H @ D
                         for w in omega])


def _lmi_region(X, K, A_hat, M, decay: float, radius: float) -> list:
    """The constraints of [VANEK] eq. 3 with the decay rate and the disk (module docstring)
    for one Â (cvxpy expressions or arrays)."""
    import cvxpy as cp

    XA = X @ A_hat + K @ M
    lyap = XA + XA.T + 2.0 * decay * X
    disk = cp.bmat([[-radius * X, XA], [XA.T, -radius * X]])
    return [0.5 * (lyap + lyap.T) << 0, 0.5 * (disk + disk.T) << 0]


def _lmi_problem(k: int, q: int, decay: float, radius: float):
    """The LMI problem of :func:`injection_lmi` for Â (k, k), M (q, k), with Â and M as cvxpy
    parameters (DPP: compiled once per shape and region, re-solved with new values)."""
    import cvxpy as cp

    A_hat = cp.Parameter((k, k))
    M = cp.Parameter((q, k))
    X = cp.Variable((k, k), symmetric=True)
    K = cp.Variable((k, q))
    cons = [X >> np.eye(k)] + _lmi_region(X, K, A_hat, M, decay, radius)
    return cp.Problem(cp.Minimize(cp.norm(K, "fro")), cons), A_hat, M, X, K


_LMI_CACHE: dict = {}
_LMI_LOCK = threading.Lock()


def injection_lmi(A_hat, M, decay: float, radius: float, solver: str = "CLARABEL") -> np.ndarray:
    """G̃ = X⁻¹K from the LMI of [VANEK] eq. 3–4 with decay rate *decay* [1/s] and the disk
    |λ| ≤ *radius* [rad/s] (module docstring), minimising ‖K‖_F; N = Â + G̃ M then has its
    eigenvalues in {Re λ ≤ −decay, |λ| ≤ radius}. Raises :class:`GeometricDesignError` when
    infeasible ((M, Â) not detectable, or a region too tight)."""
    A_hat = np.atleast_2d(np.asarray(A_hat, float))
    M = np.atleast_2d(np.asarray(M, float))
    k, q = A_hat.shape[0], M.shape[0]
    if k == 0:
        return np.zeros((0, q))
    key = (k, q, float(decay), float(radius))
    with _LMI_LOCK:                       # one cached problem, shared by threads: serialise
        fresh = key not in _LMI_CACHE
        if fresh:
            _LMI_CACHE[key] = _lmi_problem(k, q, float(decay), float(radius))
        prob, pA, pM, X, K = _LMI_CACHE[key]
        pA.value, pM.value = A_hat, M
        # the first solve compiles the parametric problem and its data differ from the
        # cached path's in the last bits: solve every design through the cached path, so a
        # design does not depend on what the process solved before
        try:
            solution = _solve(prob, X, K, solver, "the LMI of [VANEK] eq. 3–4",
                              times=2 if fresh else 1)
        except GeometricDesignError:
            solution = _solve_afresh(A_hat, M, float(decay), float(radius), solver)
    return _injection(solution, [A_hat], M, decay, radius,
                      "no output injection places the filter poles in the region; lower the "
                      "decay rate or widen the radius, or check that (M, Â) is detectable")


def _solve_afresh(A_hat, M, decay: float, radius: float, solver: str):
    """The LMI of :func:`injection_lmi` compiled anew for this Â and M and solved once: the
    fallback when the solver fails on the cached parametric problem. At the boundary optimum
    of the minimum-‖K‖ injection (module docstring) the cached path's data, which differ
    from a fresh compilation's in the last bits, can make Clarabel stop without an answer
    (seen on ``vanek-isolation --seed 8080``: Â with two eigenvalues at 0, where a fresh
    compilation solves to ``optimal_inaccurate`` with every pole in the region). The answer
    is checked like any other (:func:`_injection`); a second failure is the design's error."""
    prob, pA, pM, X, K = _lmi_problem(A_hat.shape[0], M.shape[0], decay, radius)
    pA.value, pM.value = A_hat, M
    return _solve(prob, X, K, solver, "the LMI of [VANEK] eq. 3–4")


#: cvxpy's warning on an "optimal_inaccurate" status; :func:`_solve` takes it as that status
#: (checked by :func:`_injection`) instead of passing it on to the user.
_INACCURATE_WARNING = "Solution may be inaccurate"
_WARNINGS_LOCK = threading.Lock()


def _solve(prob, X, K, solver: str, what: str, times: int = 1):
    """Solve *prob* (*times* times); (status, X, K) as arrays (None when the solver gave
    none). A solver failure is a :class:`GeometricDesignError` naming *what*.

    cvxpy warns "Solution may be inaccurate" whenever the solver stops at its reduced
    tolerances (status ``optimal_inaccurate``). On the aircraft model of ``vanek-geometric``
    that happens at about one design in four (docs/vanek-geometric.md): the minimum-‖K‖ output
    injection puts the slowest filter pole exactly on the decay bound Re λ = −decay, a
    boundary optimum where Clarabel's last steps stall; other tolerances, iteration limits,
    equilibration or regularisation move the status between points without removing it. The
    design only uses G̃ = X⁻¹K, and :func:`_injection` checks its poles against the region
    (they are within 1e-5 of −decay when inaccurate): that check, not the warning, decides
    whether the design is used, so the warning is recorded as the status and not shown.
    Every solve starts cold, so the answer depends on the problem's data only, never on what
    the process solved before (a campaign's workers design in any order)."""
    import cvxpy as cp

    try:
        # the warning filters are process-wide: one solve at a time changes them
        with _WARNINGS_LOCK, warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_INACCURATE_WARNING,
                                    category=UserWarning)
            for _ in range(times):
                # never warm-started: cvxpy's default reuses the cached problem's Clarabel
                # solver, whose answer then depends on the design solved before it (other
                # bits, and once a pole at −0.4994 for Re λ ≤ −0.5)
                prob.solve(solver=solver, warm_start=False)
    except cp.error.SolverError as exc:
        raise GeometricDesignError(f"{what} failed in {solver}: {exc}") from exc
    return (prob.status, None if X.value is None else np.array(X.value),
            None if K.value is None else np.array(K.value))


def _injection(solution, A_hats, M, decay: float, radius: float, hint: str) -> np.ndarray:
    """G̃ = X⁻¹K from a solved LMI of eq. 3–4 (:func:`_solve`), checked at every Â of
    *A_hats*: an "optimal_inaccurate" answer is kept only when the poles of Â + G̃M are where
    eq. 3–4 put them (tolerance 1e-3 relative: far below any design meaning of decay and
    radius). *hint*: what to do when the LMI is infeasible."""
    import cvxpy as cp

    status, Xv, Kv = solution
    region = f"Re λ ≤ −{decay}, |λ| ≤ {radius}"
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or Xv is None:
        raise GeometricDesignError(f"the LMI of [VANEK] eq. 3–4 ({region}) is {status}: "
                                   f"{hint}")
    G = np.linalg.solve(Xv, Kv)
    for a in A_hats:
        eig = np.linalg.eigvals(a + G @ M)
        if eig.real.max() > -decay * (1.0 - 1e-3) or np.abs(eig).max() > radius * (1.0 + 1e-3):
            raise GeometricDesignError(
                f"the LMI solution of [VANEK] eq. 3–4 ({status}) leaves filter poles "
                f"{np.round(eig, 4).tolist()} outside {region}; lower the decay rate or "
                "widen the radius")
    return G


def injection_lmi_common(A_hats, M, decay: float, radius: float,
                         solver: str = "CLARABEL") -> np.ndarray:
    """One G̃ = X⁻¹K for every vertex Â_i of a polytope: the LMI of [VANEK] eq. 3–4 at every
    vertex with a common X and K, minimising ‖K‖_F. The constraints are affine in Â, so they
    then hold on the whole polytope: N(ρ) = Â(ρ) + G̃M has its poles in the region for every
    Â(ρ) in the convex hull of the vertices (quadratic D-stability, Chilali & Gahinet 1996).
    Raises :class:`GeometricDesignError` when infeasible."""
    import cvxpy as cp

    A_hats = [np.atleast_2d(np.asarray(a, float)) for a in A_hats]
    M = np.atleast_2d(np.asarray(M, float))
    k, q = A_hats[0].shape[0], M.shape[0]
    if k == 0:
        return np.zeros((0, q))
    X = cp.Variable((k, k), symmetric=True)
    K = cp.Variable((k, q))
    cons = [X >> np.eye(k)]
    for a in A_hats:
        cons += _lmi_region(X, K, a, M, float(decay), float(radius))
    prob = cp.Problem(cp.Minimize(cp.norm(K, "fro")), cons)
    solution = _solve(prob, X, K, solver, "the vertex LMI of [VANEK] eq. 3–4")
    return _injection(solution, A_hats, M, decay, radius,
                      "no one output injection places the filter poles in the region at "
                      "every vertex; lower the decay rate, widen the radius or shrink the "
                      "parameter box")


def design(A, B, C, L1, L2, *, decay: float = 1.0, radius: float = 20.0, rtol: float = RTOL,
           names1=None, solver: str = "CLARABEL") -> ResidualGenerator:
    """The residual generator of [VANEK] eq. 2 for fault directions L1 (detected) and L2
    (decoupled), with its poles in Re λ ≤ −decay [1/s], |λ| ≤ radius [rad/s].

    *names1*: names of the columns of L1 for the error message when S* ∩ L1 ≠ 0.
    Raises :class:`GeometricDesignError` when the problem has no solution.
    """
    A = np.atleast_2d(np.asarray(A, float))
    C = np.atleast_2d(np.asarray(C, float))
    n = A.shape[0]
    B = np.asarray(B, float).reshape(n, -1)
    L1 = np.asarray(L1, float).reshape(n, -1)
    L2 = np.asarray(L2, float).reshape(n, -1)
    S, P, H = _subspaces(A, C, L1, L2, rtol, names1)
    A_hat = P @ (A + friend(A, C, S, rtol) @ C) @ P.T
    G_tilde = injection_lmi(A_hat, H @ C @ P.T, decay, radius, solver)
    return _generator(A, B, C, L1, L2, S, P, H, G_tilde, rtol)


def _subspaces(A, C, L1, L2, rtol: float, names1=None):
    """S* (basis), P and H of the construction, after the solvability checks (S* not the
    whole space, S* ∩ L1 = 0; *names1* names the columns of L1 in the message)."""
    n = A.shape[0]
    S = unobservability_subspace(A, C, L2, rtol)
    P = complement(S, rtol).T
    if P.shape[0] == 0:
        raise GeometricDesignError(
            "the smallest unobservability subspace containing L2 is the whole state space: "
            "no residual can be blind to L2; measure more outputs or decouple fewer faults")
    lost = intersection(S, L1, rtol)
    bad = [j for j in range(L1.shape[1]) if contains(S, L1[:, [j]], rtol)]
    if lost.shape[1]:
        names = [(names1[j] if names1 is not None else f"L1[:, {j}]") for j in range(L1.shape[1])]
        hidden = [names[j] for j in bad] or names
        raise GeometricDesignError(
            f"S* ∩ L1 ≠ 0 (dimension {lost.shape[1]}): the fault direction(s) "
            f"{', '.join(hidden)} lie in the smallest unobservability subspace containing L2 "
            f"(dim S* = {S.shape[1]} of {n}), so no residual blind to L2 can see them "
            "([VANEK] §2); measure more outputs or decouple fewer faults")
    H = kernel((C @ S).T, rtol).T if S.shape[1] else np.eye(C.shape[0])
    return S, P, H


def _generator(A, B, C, L1, L2, S, P, H, G_tilde, rtol: float = RTOL) -> ResidualGenerator:
    """The residual generator for the model (A, B, C) on the subspaces S, P, H and the output
    injection G̃ (the friend is computed here)."""
    M = H @ C @ P.T
    G_hat = friend(A, C, S, rtol)
    A_hat = P @ (A + G_hat @ C) @ P.T
    return ResidualGenerator(S=S, P=P, H=H, M=M, G_hat=G_hat, A_hat=A_hat, G_tilde=G_tilde,
                             N=A_hat + G_tilde @ M, G=P @ G_hat + G_tilde @ H, F=P @ B,
                             L1=L1, L2=L2)


@dataclass(frozen=True)
class LPVResidualGenerator:
    """The residual generator of a parameter-varying model whose S* does not depend on the
    parameter (Balas, Bokor & Szabó 2003; [VANEK] §5): S, P, H, M fixed, one output
    injection G̃ for the whole polytope (:func:`injection_lmi_common`); the friend
    Ĝ(ρ) = :func:`friend` (A(ρ), C, S), linear in A, so that with A affine in ρ the filter
    matrices N(ρ), G(ρ), F(ρ) are affine in ρ too. :meth:`at` gives the filter at one
    parameter value."""

    S: np.ndarray
    P: np.ndarray
    H: np.ndarray
    G_tilde: np.ndarray
    C: np.ndarray
    rtol: float = RTOL

    def at(self, A, B, L1, L2) -> ResidualGenerator:
        """The filter for the model (A, B) of one parameter value (inside the design
        polytope: the pole region is guaranteed there only)."""
        return _generator(np.asarray(A, float), np.asarray(B, float), self.C,
                          np.asarray(L1, float), np.asarray(L2, float), self.S, self.P,
                          self.H, self.G_tilde, self.rtol)


def design_lpv(As, C, L1s, L2s, *, decay: float = 1.0, radius: float = 20.0,
               rtol: float = RTOL, names1=None, solver: str = "CLARABEL") -> LPVResidualGenerator:
    """The LPV residual generator for the vertex models (A_i, L1_i, L2_i) of a polytope:
    the construction of :func:`design` with the subspaces common to every vertex and the
    output injection from the vertex LMI (:func:`injection_lmi_common`). Raises
    :class:`GeometricDesignError` when S* differs between vertices (this construction needs
    a parameter-independent S*) or any vertex fails the checks of :func:`design`."""
    C = np.atleast_2d(np.asarray(C, float))
    As = [np.atleast_2d(np.asarray(A, float)) for A in As]
    subs = [_subspaces(A, C, np.asarray(L1, float).reshape(A.shape[0], -1),
                       np.asarray(L2, float).reshape(A.shape[0], -1), rtol, names1)
            for A, L1, L2 in zip(As, L1s, L2s)]
    S, P, H = subs[0]
    moved = [i for i, (Si, _, _) in enumerate(subs) if not same_subspace(Si, S, rtol)]
    if moved:
        raise GeometricDesignError(
            f"S* at vertices {moved} differs from S* at vertex 0: the LPV construction needs a "
            "parameter-independent smallest unobservability subspace; design per parameter "
            "value instead")
    A_hats = [P @ (A + friend(A, C, S, rtol) @ C) @ P.T for A in As]
    G_tilde = injection_lmi_common(A_hats, H @ C @ P.T, decay, radius, solver)
    return LPVResidualGenerator(S=S, P=P, H=H, G_tilde=G_tilde, C=C, rtol=rtol)


def bilinear(gen: ResidualGenerator, ts: float) -> tuple[np.ndarray, ...]:
    """The filter (input [u; y], output r) discretised at *ts* [s] by the bilinear (Tustin)
    transform, as in [VANEK] §5: (Ad, Bd, Cd, Dd) (:func:`bilinear_ss`)."""
    return bilinear_ss(*gen.state_space(), ts)


def bilinear_ss(A, B, C, D, ts: float) -> tuple[np.ndarray, ...]:
    """Tustin discretisation of (A, B, C, D) at *ts* [s] with a = ts/2:
    Ad = (I − aA)⁻¹(I + aA), Bd = (I − aA)⁻¹ B ts, Cd = C (I − aA)⁻¹, Dd = D + C Bd / 2
    (the realisation of scipy.signal.cont2discrete, method "bilinear")."""
    a = 0.5 * float(ts)
    ima = np.eye(A.shape[0]) - a * A
    Ad = np.linalg.solve(ima, np.eye(A.shape[0]) + a * A)
    Bd = np.linalg.solve(ima, ts * B)
    Cd = np.linalg.solve(ima.T, C.T).T
    return Ad, Bd, Cd, D + 0.5 * C @ Bd


def dc_gain(gen: ResidualGenerator) -> np.ndarray:
    """Steady-state gain (q, k1) from f1 to r: r = M (−N)⁻¹ (−P L1) f1 = M N⁻¹ P L1 f1."""
    return gen.M @ np.linalg.solve(gen.N, gen.P @ gen.L1)


__all__ = ["RTOL", "GeometricDesignError", "ResidualGenerator", "LPVResidualGenerator", "basis",
           "kernel", "complement", "subspace_sum", "intersection", "preimage", "contains",
           "same_subspace", "conditioned_invariant", "unobservability_subspace", "friend",
           "injection_lmi", "injection_lmi_common", "design", "design_lpv", "bilinear",
           "bilinear_ss", "dc_gain"]
