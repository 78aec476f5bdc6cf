"""The model-error allowance of ``vanek-geometric``'s adaptive threshold: a bound, computed
online from the measured state and inputs, on the part of the residual r̂ that the
difference between the aircraft and the filter's design model produces.

Why it can be computed. The design model of :mod:`detectors.builtin.vanek_geometric` with the
angle-of-attack vane (``aoa_sensor``) measures every state (C = I on x̃ = (α + α_g, q, θ,
β + β_g, p, r, φ), the air-relative angles: :func:`detectors.builtin.vanek_geometric.
gust_sideslip_direction`). The aircraft of a run obeys the same linear equations
(:mod:`scenarios.aircraft.lpv`) with other matrices: its true flight point and aerodynamic
coefficients, where the filter has the measured point and the nominal coefficients
([CHEN] Table 2, docs/physics.md §6). So ::

    dx̃/dt = A x̃ + B u + d + (faults, gusts' rates),    d = ΔA x̃ + ΔB u,

with (A, B) the design model and ΔA, ΔB the aircraft's matrices minus them. d is an
unknown input of the filter like a fault; with the filter's error e = P x̃ − w,
ė = N e − P d and r = M e ([VANEK] eq. 2 with MP = HC), so its part of the reconstructed
residual is r̂_d = c M (sI − N)⁻¹ (−P) d, low-passed as r̂ (``smoothing_s``).

The bound. Each Table-2 error is constant over a run: the relative errors of the six
aerodynamic coefficients (every derivative of one coefficient scaled by 1 + d_c, ±5 %) and
of the measured VCAS, altitude, mass and CG (±10 %; the true value is the measured one
divided by 1 + d). For each error j and each end of its range (sign ±), the design model is
recomputed with that error alone (ΔA_j±, ΔB_j±: the model at the end minus the design
model) and the measured x̃, u are driven through the path above, giving r̂_j±(t). To first
order in the errors d ≈ Σ_j (ΔA_j x̃ + ΔB_j u)·κ_j with |κ_j| ≤ 1, so ::

    |r̂_d(t)| ≤ b(t) = |r̂_0(t)| + Σ_j max(|r̂_j+(t)|, |r̂_j−(t)|),

where r̂_0 is the part of a design made at a point other than the measured one (the LTI
filter's design point: ΔA_0 = A(measured point) − A(design point), known, 0 for the LPV
filter). Taking each error's worse end covers the curvature of the model in that error (a
10 % VCAS error is 21 % of q̄) but not products of two errors (second order, a few % of b).

What it does not bound (left to the learned constant τ0 of the threshold τ0 + b(t)): the
sensors' noise (in the measured x̃ and in r̂), the turbulence beyond the decoupled gust
directions, the COM rods' scale errors, the spoilers' coupling, and the products of errors.
With ``aoa_sensor`` false the angle of attack is not measured and d cannot be formed: the
threshold is then the constant τ0 (:mod:`detectors.builtin.vanek_geometric`).

Cost: 21 extra filters of the filter's order (3 states with α) per run and variant, driven
by 15 signals (the 7 states and the 8 surface inputs), vectorised over runs.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from scenarios.aircraft import lpv
from scenarios.envelope import AERO_COEFFICIENTS, half_widths

#: The Table-2 errors bounded, in order: the six aerodynamic coefficients, then the four
#: measured flight data (names of :func:`scenarios.envelope.half_widths` without ``d_``).
ERRORS: tuple[str, ...] = (*AERO_COEFFICIENTS, "vcas", "alt", "mass", "cg")
#: Measured flight data among :data:`ERRORS`, with the keyword of
#: :func:`detectors.builtin.vanek_geometric._point` they scale.
SCHEDULE_ERRORS = {"vcas": "vcas_kt", "alt": "alt_ft", "mass": "mass_t", "cg": "cg_pct"}
#: Steps whose inputs are formed at once in :func:`bound` (memory: n_runs × 21 × 4 floats each).
_BLOCK = 500
#: Number of inputs u of the model-error signal: the seven surfaces and the spoilers
#: (the gust columns act through the air-relative angles of x̃, module docstring).
N_INPUTS = lpv.N_SURFACES + 1


def table2_widths() -> dict[str, float]:
    """Relative half-width of each error of :data:`ERRORS` ([CHEN] Table 2,
    docs/physics.md §6: 0.05 for the aerodynamic coefficients, 0.10 for VCAS, altitude,
    mass and CG; :func:`scenarios.envelope.half_widths`)."""
    widths = half_widths()
    return {e: float(widths[f"d_{e}"]) for e in ERRORS}


def error_matrices(model, point: dict, design: tuple | None = None) -> np.ndarray:
    """The model-error matrices K_k = [ΔA_k, ΔB_k] (shape (1 + 2·len(ERRORS), n, n + N_INPUTS))
    at a measured flight *point* (keywords ``vcas_kt``, ``alt_ft``, ``mass_t``, ``cg_pct``).

    *model*: a function (point keywords, aero draws) → (A, B) of the design model's surface
    layout. *design*: the (A, B) the filter was designed on; None: the model at *point* (the
    LPV filter). Row 0 is the model at *point* minus *design* (zero for the LPV filter);
    rows 1 + 2j and 2 + 2j are the model with error j of :data:`ERRORS` at the lower and the
    upper end of its range (:func:`table2_widths`) minus the model at *point* (module
    docstring)."""
    widths = table2_widths()
    A0, B0 = model(point, {})
    Ad, Bd = (A0, B0) if design is None else design
    rows = [np.hstack([A0 - Ad, (B0 - Bd)[:, :N_INPUTS]])]
    for e in ERRORS:
        for sign in (-1.0, 1.0):
            w = sign * widths[e]
            if e in SCHEDULE_ERRORS:
                key = SCHEDULE_ERRORS[e]
                A, B = model({**point, key: point[key] / (1.0 + w)}, {})
            else:
                A, B = model(point, {e: w})
            rows.append(np.hstack([A - A0, (B - B0)[:, :N_INPUTS]]))
    return np.stack(rows)


def bound(K: np.ndarray, Ad: np.ndarray, Bdist: np.ndarray, cC: np.ndarray, cDdist: np.ndarray,
          s: np.ndarray, lowpass: tuple | None) -> np.ndarray:
    """b(t) (module docstring) of every run, shape (n_runs, n_steps), in the unit of r̂ times
    that of s (rad here).

    K (n_runs, n_k, n, n + N_INPUTS): :func:`error_matrices` of each run; Ad (n_runs, nw, nw),
    Bdist (n_runs, nw, n): the filter's error dynamics ė = N e − P d discretised (its input
    matrix for d); cC (n_runs, nw), cDdist (n_runs, n): its output r̂ = c M e discretised;
    s (n_runs, n_steps, n + N_INPUTS): the measured x̃ and u; *lowpass*: (b, a) of the
    low-pass on r̂, or None."""
    G = np.einsum("nij,nkjl->nkil", Bdist, K)                  # state input of each d_k
    H = np.einsum("nj,nkjl->nkl", cDdist, K)                   # direct feed-through
    n, T = s.shape[:2]
    n_k, nw = G.shape[1:3]
    G_flat = G.reshape(n, n_k * nw, -1).transpose(0, 2, 1)       # (n, 15, n_k·nw)
    AdT = Ad.transpose(0, 2, 1)
    z = np.zeros((n, n_k, nw))
    r = s @ H.transpose(0, 2, 1)                                 # (n, T, n_k)
    for t0 in range(0, T, _BLOCK):                               # inputs a block at a time
        sl = slice(t0, min(t0 + _BLOCK, T))
        drive = (s[:, sl] @ G_flat).reshape(n, -1, n_k, nw)
        zs = np.empty(drive.shape)
        for k in range(drive.shape[1]):                          # vectorised over runs
            zs[:, k] = z
            z = z @ AdT + drive[:, k]
        r[:, sl] += (zs.reshape(n, -1, nw) @ cC[:, :, None]).reshape(n, -1, n_k)
    if lowpass is not None:
        r = scipy.signal.lfilter(*lowpass, r, axis=1)
    r = np.abs(r)
    return r[:, :, 0] + np.maximum(r[:, :, 1::2], r[:, :, 2::2]).sum(axis=2)


__all__ = ["ERRORS", "SCHEDULE_ERRORS", "N_INPUTS", "table2_widths", "error_matrices", "bound"]
