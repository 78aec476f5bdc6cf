"""The parametric uncertainty δ_g of [CHEN] eq. 25 realised from [CHEN] Table 2 on the lateral
model of ``chen-global``, and the activity-driven bound it gives on the fault estimate.

Realisation (an LFT-like factorisation, [CHEN] §6 "M_g is obtained using a linear fractional
transformation-based realization"). The lateral rigid body of :mod:`scenarios.aircraft.lpv`
is, in stability axes, ::

    m·V·β̇        = Y(β, p, r, u) − m·V·r + m·g·φ
    Ix·ṗ − Izx·ṙ  = L(β, p, r, u)
    Iz·ṙ − Izx·ṗ  = N(β, p, r, u)

with Y, L, N the side force, rolling and yawing moments, sums of derivative × state or input
× q̄·S (× b/2V for the rates). [CHEN] Table 2 errs each coefficient group by ±5 %
(docs/physics.md §6: every ``Cy_*`` by 1 + d_cy, every ``Cl_*`` by 1 + d_cl, every ``Cn_*``
by 1 + d_cn) and the measured flight data by ±10 % (VCAS, altitude, mass, CG), which reach
the model through the scheduling vector ρ = (q̄·PG/m, q̄·PG/(m·V), q̄·PG/(m·V²), g/V) of
:func:`detectors.builtin.chen_global.scheduling_vector`. Every one of these errors scales a whole
aerodynamic term of one row, so the difference between the aircraft and the estimator's
model is ::

    ΔA·x + ΔB·u = M_g·δ_g,    M_g = | 1     0        0     |
                                    | 0     1     Izx/Ix  |
                                    | 0  Izx/Iz     1     |
                                    | 0     0        0     |

(rows β, p, r, φ; columns e_β, E⁻¹e_p and E⁻¹e_r scaled to a unit diagonal entry, E the
inertia matrix [[Ix, −Izx], [−Izx, Iz]] of the p, r rows). The three columns are the
directions in which a side force, a rolling moment and a yawing moment accelerate the
aircraft; with inertias proportional to the mass they do not
depend on the flight point, so M_g is constant as [CHEN] eq. 25 has it (N_g = 0: the
sensors φ, p, r are not affected by the aerodynamic data). δ_g has one entry per column,
δ_g,c = κ_c·z_c, where z_c is the aerodynamic acceleration of group c the model computes
(M_g⁻¹ on the rows β, p, r of the aerodynamic part of A·x + B·u) and κ_c the run's relative
error, constant over a run. Schedule errors scale the static terms (β, controls: q̄·PG/m) and
the rate terms (p, r: q̄·PG/(m·V)) differently, so z_cl and z_cn are split into a static and
a rate part, each with its own bound; z_cy keeps one (the side force is small): five driving
signals (:data:`SIGNALS`).

Bound on the estimate ([CHEN] eq. 17, N_g = 0). The estimation error obeys
ė = Ā e + M_g δ_g, f̂ − f = L2 C e with Ā = A + L1 C, so with κ constant over the run ::

    f̂ − f = Σ_j κ_j · w_j,    w_j = L2 C (s I − Ā)⁻¹ M_g[:, c(j)] · z_j

and |f̂ − f| ≤ Σ_j k_j |w_j| where k_j ≥ |κ_j| is the Table-2 bound of signal j
(:func:`error_bounds`). The w_j are computed online from the measured activity (the model's
aerodynamic accelerations on the measured p, r, φ, the estimated β and the rods, with the
estimated fault and gust included), through the estimator's own error dynamics: an adaptive
threshold in the sense of [COMB]'s interval bounds that scale with the input, here with the
gain of the designed estimator rather than a learned envelope.
"""

from __future__ import annotations

import numpy as np

#: Columns of M_g: the side-force, rolling-moment and yawing-moment channels ([CHEN] Table 2).
CHANNELS = ("cy", "cl", "cn")
#: Driving signals of the bound: (channel, part); part "all", "static" (β and controls, scaled
#: by q̄·PG/m) or "rate" (p and r, scaled by q̄·PG/(m·V)).
SIGNALS = (("cy", "all"), ("cl", "static"), ("cl", "rate"), ("cn", "static"), ("cn", "rate"))
#: Components of the scheduling vector (:func:`detectors.builtin.chen_global.scheduling_vector`)
#: that scale each part: static terms q̄·PG/m; rate terms q̄·PG/(m·V); the side-force row carries
#: Yβ, Yδ (q̄·PG/(m·V)), Yp, Yr (q̄·PG/(m·V²)) and the gravity term g/V.
SCHEDULE_COMPONENTS = {"static": (0,), "rate": (1,), "all": (1, 2, 3)}


def inertia_ratios(masses_t=(120.0, 180.0, 233.0)) -> tuple[float, float]:
    """(Izx/Ix, Izx/Iz) of :func:`scenarios.aircraft.lpv.a330_airframes`; raises ValueError
    when they vary with the mass (M_g would then not be constant)."""
    from scenarios.aircraft import lpv

    f = lpv.a330_airframes(np.asarray(masses_t, float))
    rx, rz = f.Izx / f.Ix, f.Izx / f.Iz
    if np.ptp(rx) > 1e-12 * abs(rx[0]) or np.ptp(rz) > 1e-12 * abs(rz[0]):
        raise ValueError("the inertia ratios Izx/Ix, Izx/Iz of scenarios.aircraft.lpv vary with "
                         "the mass: M_g of chen-global is no longer constant")
    return float(rx[0]), float(rz[0])


def uncertainty_matrix() -> np.ndarray:
    """M_g (4, 3) of [CHEN] eq. 25 on x_b = [β, p, r, φ], columns :data:`CHANNELS`
    (module docstring)."""
    rx, rz = inertia_ratios()
    return np.array([[1.0, 0.0, 0.0],
                     [0.0, 1.0, rx],
                     [0.0, rz, 1.0],
                     [0.0, 0.0, 0.0]])


def error_bounds(rho_true: np.ndarray, rho_measured: np.ndarray, coefficient_widths: dict
                 ) -> np.ndarray:
    """k_j ≥ |κ_j| of each signal of :data:`SIGNALS` ([CHEN] Table 2).

    The aircraft's term is (1 + d_c)·ρ_k·(derivative) where the model has ρ̂_k·(derivative):
    κ = (1 + d_c)·ρ_k/ρ̂_k − 1. *rho_true*, *rho_measured*: scheduling vectors (…, 4) of
    the
    same flight points seen without and with the Table-2 measurement errors (every corner);
    *coefficient_widths*: half-width of d_c per channel (``{"cy": 0.05, …}``).
    """
    ratio = np.asarray(rho_true, float) / np.asarray(rho_measured, float)
    out = []
    for channel, part in SIGNALS:
        r = ratio[..., list(SCHEDULE_COMPONENTS[part])]
        d = float(coefficient_widths[channel])
        out.append(max(float((1.0 + d) * r.max()) - 1.0, 1.0 - float((1.0 - d) * r.min())))
    return np.array(out)


def signal_matrices(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Zx (n, 5, 4), Zu (n, 5, 6)): the driving signals z = Zx·x̃ + Zu·ũ of :data:`SIGNALS`
    from the nominal lateral model A (n, 4, 4), B (n, 4, 6) of each run.

    x̃ = [β_a, p, r, φ] with β_a the aerodynamic sideslip (estimated β plus the estimated gust
    sideslip), ũ the surface deflections with the estimated fault added. The kinematic term
    −r of β̇ and the φ̇ = p row are not aerodynamic and left out; the gravity term g/V·φ is
    kept in the side-force signal (its error is the measured speed's).
    """
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    n = A.shape[0]
    minv = np.linalg.inv(uncertainty_matrix()[:3])           # rows β, p, r
    static_x = np.zeros((n, 4, 4))
    static_x[:, :, 0] = A[:, :, 0]                            # β column
    static_x[:, 0, 3] = A[:, 0, 3]                            # g/V·φ in the β̇ row
    rate_x = np.zeros((n, 4, 4))
    rate_x[:, :, 1:3] = A[:, :, 1:3]
    rate_x[:, 0, 2] += 1.0                                    # drop the kinematic −r of β̇
    rate_x[:, 3] = 0.0                                        # φ̇ = p is kinematics
    zs_x = minv @ static_x[:, :3]                             # (n, 3, 4) per channel
    zr_x = minv @ rate_x[:, :3]
    zs_u = minv @ B[:, :3]
    Zx = np.stack([zs_x[:, 0] + zr_x[:, 0], zs_x[:, 1], zr_x[:, 1], zs_x[:, 2], zr_x[:, 2]],
                  axis=1)
    zero = np.zeros_like(zs_u[:, 0])
    Zu = np.stack([zs_u[:, 0], zs_u[:, 1], zero, zs_u[:, 2], zero], axis=1)
    return Zx, Zu


def signal_columns() -> np.ndarray:
    """Index into :data:`CHANNELS` (the column of M_g) of each signal of :data:`SIGNALS`."""
    return np.array([CHANNELS.index(c) for c, _ in SIGNALS])


#: Largest spread of the fault column's direction over the vertices for which
#: ``"fault-removed"`` still gives a constant M (numerical, not a physical parameter).
DIRECTION_TOLERANCE = 1e-9


def design_uncertainty_matrix(design: str, fault_columns: np.ndarray) -> np.ndarray:
    """M of the H∞ objective of [CHEN] eq. 23 for the global estimator (4, 3).

    ``"table2"``: :func:`uncertainty_matrix`. The fault column F = B_b·W lies in its span
    (the monitored aileron's rolling and yawing moments are sums of the L and N terms that
    d_cl, d_cn scale), so minimising the gain from δ_g to f̂ also lowers the gain of every
    input that enters along F, the fault's own path included, where H = 0 leaves the fault
    only the small ε of Remark 4.1.

    ``"fault-removed"``: (I − f fᵀ)·M_g, f the unit direction of F. The part of the Table-2
    uncertainty along F cannot be told apart from the fault in the state equation (a 5 % error
    on L_δa is a fault of 5 % of δa); it is left out of the objective, so γ no longer
    penalises the fault's path, and the rest of δ_g (side force, the moments off F) is kept.
    F = ρ₁·(Y_δ, L_δ, N_δ)-column with inertias proportional to the mass, so its direction
    is the same at every vertex and M stays constant, as [CHEN] eq. 25 has it.

    *fault_columns*: F at every vertex (n_vertices, 4); ValueError when its direction varies
    (the projection would then depend on ρ and the vertex property would not hold).
    """
    M = uncertainty_matrix()
    if design == "table2":
        return M
    if design != "fault-removed":
        raise ValueError(f"unknown uncertainty design {design!r}; allowed: table2, "
                         "fault-removed")
    F = np.asarray(fault_columns, float)
    f = F / np.linalg.norm(F, axis=-1, keepdims=True)
    f = f * np.sign(f @ f[0])[:, None]
    if float(np.abs(f - f[0]).max()) > DIRECTION_TOLERANCE:
        raise ValueError("the fault column's direction varies over the scheduling polytope: "
                         "uncertainty = \"fault-removed\" needs a constant direction; use "
                         "uncertainty = \"table2\"")
    return M - np.outer(f[0], f[0] @ M)
