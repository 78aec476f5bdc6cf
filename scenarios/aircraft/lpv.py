"""Rigid-body linear models of each run's flight point and their discretisation (LPV).

State x = [α, q, θ, β, p, r, φ] (rad, rad/s), perturbations from the trimmed level flight
of the run, stability axes (θ0 = γ0 = 0). Inputs u = [δ_1 … δ_7, δ_sp, α_g, β_g]: the
seven surface deflections from their trim positions (order of
:data:`scenarios.aircraft.data.LAYOUT`), the spoilers' equivalent aileron angle (fixed
coupling) and the gust angles of attack and sideslip, all in rad. Speed is held (no
phugoid): the short period with pitch attitude and the four lateral states.

Equations (Etkin & Reid eqs. 4.9,18–19 with u = 0, w = V·α, v = V·β; dimensional
derivatives of Tables 4.4–4.5 built from the non-dimensional set at the run's q̄, V)::

    (m·V − Zα̇)·α̇ = Zα·α_a + (m·V + Zq)·q + Σ Zδ·δ
    Iy·q̇ − Mα̇·α̇ = Mα·α_a + Mq·q + Σ Mδ·δ
    θ̇ = q
    m·V·β̇ = Yβ·β_a + Yp·p + (Yr − m·V)·r + m·g·φ + Σ Yδ·δ
    Ix·ṗ − Izx·ṙ = Lβ·β_a + Lp·p + Lr·r + Σ Lδ·δ
    Iz·ṙ − Izx·ṗ = Nβ·β_a + Np·p + Nr·r + Σ Nδ·δ
    φ̇ = p

with the air-relative angles α_a = α + α_g, β_a = β + β_g, where α_g = −w_g/V and
β_g = −v_g/V for Dryden gust velocities w_g, v_g along the body z and y axes (a wind
blowing down lowers the angle of attack). Load factors at the CG (positive up and right)::

    Δn_z = V·(q − α̇)/g,     n_y = V·(β̇ + r)/g − φ

Discretisation: exact zero-order hold at Ts, Φ = e^{A·Ts}, Γ = ∫₀^Ts e^{A·s} ds·B, from the
exponential of the augmented matrix [[A, B], [0, 0]]·Ts, batched over runs
(``scipy.linalg.expm`` on an (n, 17, 17) stack); the closed loop adds the exact ramp term of
the surfaces, which move during the period (:func:`discretise_ramp`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..atmosphere import G0_MS2
from ..envelope import A330, AERO_COEFFICIENTS, KG_PER_T, PERCENT, AircraftParams
from ..servo import compressibility_factor
from .data import (A330_SCALING, B747, B747_CONDITION, B747_DERIVATIVES, LAYOUT, AirframeData,
                   ReferenceCondition, ScalingParams, StabilityDerivatives, SurfaceLayout)

#: State names, in array order.
STATES: tuple[str, ...] = ("alpha", "q", "theta", "beta", "p", "r", "phi")
N_STATES = len(STATES)
N_SURFACES = len(LAYOUT.names)
#: Input columns after the surfaces: spoiler equivalent angle, gust α, gust β.
I_SPOILER, I_GUST_ALPHA, I_GUST_BETA = N_SURFACES, N_SURFACES + 1, N_SURFACES + 2
N_INPUTS = N_SURFACES + 3
IA, IQ, ITH, IB, IP, IR, IPHI = range(N_STATES)


@dataclass(frozen=True)
class Airframes:
    """Per-run mass and inertias [kg, kg·m²] and geometry [m², m] (arrays (n,))."""

    mass_kg: np.ndarray
    Ix: np.ndarray
    Iy: np.ndarray
    Iz: np.ndarray
    Izx: np.ndarray
    S: float
    c: float
    b: float


def a330_airframes(mass_t, aircraft: AircraftParams = A330, scaling: ScalingParams = A330_SCALING,
                   reference: AirframeData = B747) -> Airframes:
    """A330-class mass and inertias of each run, scaled from the reference airframe
    (:class:`scenarios.aircraft.data.ScalingParams`). Wing area and MAC: ``aircraft``."""
    m = np.asarray(mass_t, dtype=float) * KG_PER_T
    k = m / reference.mass_kg
    span2 = (scaling.span_m / reference.span_m) ** 2
    len2 = (scaling.length_m / reference.length_m) ** 2
    diag2 = ((scaling.span_m ** 2 + scaling.length_m ** 2)
             / (reference.span_m ** 2 + reference.length_m ** 2))
    return Airframes(mass_kg=m, Ix=reference.Ix_kgm2 * k * span2, Iy=reference.Iy_kgm2 * k * len2,
                     Iz=reference.Iz_kgm2 * k * diag2, Izx=reference.Izx_kgm2 * k * span2,
                     S=aircraft.wing_area_m2, c=aircraft.mac_m, b=scaling.span_m)


def reference_airframe(reference: AirframeData = B747) -> Airframes:
    """The reference airframe itself (one run), for the mode checks."""
    one = np.ones(1)
    return Airframes(mass_kg=reference.mass_kg * one, Ix=reference.Ix_kgm2 * one,
                     Iy=reference.Iy_kgm2 * one, Iz=reference.Iz_kgm2 * one,
                     Izx=reference.Izx_kgm2 * one, S=reference.wing_area_m2,
                     c=reference.mac_m, b=reference.span_m)


#: [CHEN] Table 2 coefficient (``scenarios.envelope.AERO_COEFFICIENTS``) each derivative of
#: the model belongs to, by the first letters of its name (docs/physics.md §6): the
#: speed-held model carries no drag (Cx) derivative.
AXIS_OF_PREFIX: dict[str, str] = {"Cz": "cz", "Cm": "cm", "Cy": "cy", "Cl": "cl", "Cn": "cn"}


def derivative_axis(name: str) -> str:
    """The [CHEN] Table 2 coefficient (``cz``, ``cm``, ``cy``, ``cl``, ``cn``) of derivative
    *name* (``Cm_alpha`` → ``cm``)."""
    return AXIS_OF_PREFIX[name[:2]]


def _axis_factors(aero, shape) -> dict[str, np.ndarray]:
    """(1 + d) of each coefficient: *aero* a number or array (every coefficient) or a mapping
    coefficient → draw (a coefficient left out: 0)."""
    from collections.abc import Mapping

    if isinstance(aero, Mapping):
        unknown = sorted(set(aero) - set(AERO_COEFFICIENTS))
        if unknown:
            raise ValueError(f"unknown aerodynamic coefficient(s) {unknown}; allowed: "
                             f"{', '.join(AERO_COEFFICIENTS)}")
        draws = {c: aero.get(c, 0.0) for c in AERO_COEFFICIENTS}
    else:
        draws = {c: aero for c in AERO_COEFFICIENTS}
    return {c: np.broadcast_to(1.0 + np.asarray(d, float), shape) for c, d in draws.items()}


def _nominal_derivatives(mach, cg, deriv, ref_condition, ref_cg_pct, scaling):
    """The derivatives of each run before the uncertainty: Prandtl–Glauert scaling relative to
    the reference Mach, Cmα and Cmδe moved with the CG (:class:`ScalingParams`)."""
    pg = (compressibility_factor(mach, scaling.mach_cap)
          / compressibility_factor(ref_condition.mach, scaling.mach_cap))
    out = {name: getattr(deriv, name) * pg for name in deriv.__dataclass_fields__}
    dh = (cg - ref_cg_pct) / PERCENT
    out["Cm_alpha"] = out["Cm_alpha"] - out["Cz_alpha"] * dh
    out["Cm_de"] = out["Cm_de"] - out["Cz_de"] * dh
    return out, dh


def scheduled_derivatives(mach, cg_pct, aero=0.0, deriv: StabilityDerivatives = B747_DERIVATIVES,
                          ref_condition: ReferenceCondition = B747_CONDITION,
                          ref_cg_pct: float = B747.cg_ref_pct,
                          scaling: ScalingParams = A330_SCALING) -> dict[str, np.ndarray]:
    """Non-dimensional derivatives of each run (arrays (n,)): Prandtl–Glauert Mach scaling
    relative to the reference Mach, CG shift of Cmα and Cmδe, and each derivative times
    (1 + d) with d the draw of its own coefficient (:func:`derivative_axis`; [CHEN] Table 2).

    *aero*: a number or array applied to every coefficient, or a mapping ``{"cz": d, …}``
    over :data:`scenarios.envelope.AERO_COEFFICIENTS` (a coefficient left out: 0)."""
    mach, cg = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (mach, cg_pct)))
    out, _ = _nominal_derivatives(mach, cg, deriv, ref_condition, ref_cg_pct, scaling)
    shape = np.broadcast_shapes(mach.shape, *(np.shape(v) for v in (
        aero.values() if isinstance(aero, dict) else [aero])))
    factor = _axis_factors(aero, shape)
    return {k: v * factor[derivative_axis(k)] for k, v in out.items()}


def _surface_rows(nom: dict, dh, layout: SurfaceLayout, span_m: float,
                  mac_m: float) -> dict[str, np.ndarray]:
    """Nominal non-dimensional control derivatives [1/rad] of every input column, per
    coefficient (``Cz``, ``Cm``, ``Cy``, ``Cl``, ``Cn``; arrays (n, N_INPUTS)); the gust
    columns are 0 here (see :func:`continuous_model`). See :class:`SurfaceLayout`."""
    n = np.shape(nom["Cz_de"])
    rows = {k: np.zeros(n + (N_INPUTS,)) for k in AXIS_OF_PREFIX}
    for j, (name, kind) in enumerate(zip(layout.names, layout.actuator)):
        side = 1.0 if name.startswith("right") else -1.0
        if kind == "elevator":
            rows["Cz"][..., j] = layout.elevator_share * nom["Cz_de"]
            rows["Cm"][..., j] = layout.elevator_share * nom["Cm_de"]
            rows["Cl"][..., j] = side * layout.elevator_arm_m / span_m * rows["Cz"][..., j]
            rows["Cn"][..., j] = layout.elevator_yaw * rows["Cl"][..., j]
        elif kind == "aileron":
            inboard = "inboard" in name
            share = layout.inboard_share if inboard else layout.outboard_share
            arm = layout.inboard_arm_m if inboard else layout.outboard_arm_m
            aft = layout.inboard_aft_m if inboard else layout.outboard_aft_m
            k = 0.5 * side * share * layout.aileron_factor
            rows["Cl"][..., j] = k * nom["Cl_da"]
            rows["Cn"][..., j] = k * nom["Cn_da"]
            lift = -side * rows["Cl"][..., j] * span_m / arm          # CLδ of this aileron
            rows["Cz"][..., j] = -lift
            rows["Cm"][..., j] = -lift * aft / mac_m - rows["Cz"][..., j] * dh
        elif kind == "rudder":
            for key in ("Cy", "Cl", "Cn"):
                rows[key][..., j] = nom[key + "_dr"]
    rows["Cl"][..., I_SPOILER] = layout.aileron_factor * layout.spoiler_factor * nom["Cl_da"]
    rows["Cn"][..., I_SPOILER] = layout.spoiler_yaw_ratio * rows["Cl"][..., I_SPOILER]
    return rows


def control_derivatives(mach, cg_pct, aero=0.0, layout: SurfaceLayout = LAYOUT,
                        deriv: StabilityDerivatives = B747_DERIVATIVES,
                        ref_condition: ReferenceCondition = B747_CONDITION,
                        ref_cg_pct: float = B747.cg_ref_pct,
                        scaling: ScalingParams = A330_SCALING,
                        aircraft: AircraftParams = A330) -> dict[str, np.ndarray]:
    """Non-dimensional control derivatives [1/rad] of every input column and every
    coefficient (``Cz``, ``Cm``, ``Cy``, ``Cl``, ``Cn`` → arrays (n, N_INPUTS)): each surface
    acts on every axis it physically should (:class:`SurfaceLayout`, docs/physics.md §7), each
    row times (1 + d) of its own coefficient ([CHEN] Table 2; *aero* as in
    :func:`scheduled_derivatives`)."""
    mach, cg = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (mach, cg_pct)))
    nom, dh = _nominal_derivatives(mach, cg, deriv, ref_condition, ref_cg_pct, scaling)
    rows = _surface_rows(nom, dh, layout, scaling.span_m, aircraft.mac_m)
    shape = np.broadcast_shapes(mach.shape, *(np.shape(v) for v in (
        aero.values() if isinstance(aero, dict) else [aero])))
    factor = _axis_factors(aero, shape)
    return {k: v * factor[AXIS_OF_PREFIX[k]][..., None] for k, v in rows.items()}


@dataclass(frozen=True)
class ContinuousModel:
    """ẋ = A·x + B·u, Δn_z, n_y = C·x + D·u, batched (A (n,7,7), B (n,7,10), C
    (n,2,7), D (n,2,10))."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    tas_ms: np.ndarray


def continuous_model(qbar_pa, tas_ms, derivs: dict, frames: Airframes, controls: dict,
                     g: float = G0_MS2) -> ContinuousModel:
    """The linear model of the module docstring for each run: stability derivatives *derivs*
    (:func:`scheduled_derivatives`), control derivatives *controls* of every input column
    (:func:`control_derivatives`; the gust columns are set here)."""
    qbar, V = np.broadcast_arrays(np.asarray(qbar_pa, float), np.asarray(tas_ms, float))
    n = qbar.shape[0]
    d = {k: np.broadcast_to(v, (n,)) for k, v in derivs.items()}
    S, c, b, m = frames.S, frames.c, frames.b, frames.mass_kg
    qS, qSc, qSb = qbar * S, qbar * S * c, qbar * S * b
    hc, hb = c / (2.0 * V), b / (2.0 * V)
    ctl = {k: np.broadcast_to(v, (n, N_INPUTS)) for k, v in controls.items()}

    E = np.zeros((n, N_STATES, N_STATES))
    F = np.zeros_like(E)
    G = np.zeros((n, N_STATES, N_INPUTS))
    # longitudinal
    E[:, IA, IA] = m * V - qS * hc * d["Cz_alphadot"]
    F[:, IA, IA] = qS * d["Cz_alpha"]
    F[:, IA, IQ] = m * V + qS * hc * d["Cz_q"]
    G[:, IA, :] = qS[:, None] * ctl["Cz"]
    G[:, IA, I_GUST_ALPHA] = qS * d["Cz_alpha"]
    E[:, IQ, IQ] = frames.Iy
    E[:, IQ, IA] = -qSc * hc * d["Cm_alphadot"]
    F[:, IQ, IA] = qSc * d["Cm_alpha"]
    F[:, IQ, IQ] = qSc * hc * d["Cm_q"]
    G[:, IQ, :] = qSc[:, None] * ctl["Cm"]
    G[:, IQ, I_GUST_ALPHA] = qSc * d["Cm_alpha"]
    E[:, ITH, ITH] = 1.0
    F[:, ITH, IQ] = 1.0
    # lateral-directional
    E[:, IB, IB] = m * V
    F[:, IB, IB] = qS * d["Cy_beta"]
    F[:, IB, IP] = qS * hb * d["Cy_p"]
    F[:, IB, IR] = qS * hb * d["Cy_r"] - m * V
    F[:, IB, IPHI] = m * g
    G[:, IB, :] = qS[:, None] * ctl["Cy"]
    G[:, IB, I_GUST_BETA] = qS * d["Cy_beta"]
    for row, inertia, cross, key in ((IP, frames.Ix, IR, "Cl"), (IR, frames.Iz, IP, "Cn")):
        E[:, row, row] = inertia
        E[:, row, cross] = -frames.Izx
        F[:, row, IB] = qSb * d[key + "_beta"]
        F[:, row, IP] = qSb * hb * d[key + "_p"]
        F[:, row, IR] = qSb * hb * d[key + "_r"]
        G[:, row, :] = qSb[:, None] * ctl[key]
        G[:, row, I_GUST_BETA] = qSb * d[key + "_beta"]
    E[:, IPHI, IPHI] = 1.0
    F[:, IPHI, IP] = 1.0

    A = np.linalg.solve(E, F)
    B = np.linalg.solve(E, G)
    C = np.zeros((n, 2, N_STATES))
    D = np.zeros((n, 2, N_INPUTS))
    k = (V / g)[:, None]
    C[:, 0, :] = -k * A[:, IA, :]
    C[:, 0, IQ] += k[:, 0]
    D[:, 0, :] = -k * B[:, IA, :]
    C[:, 1, :] = k * A[:, IB, :]
    C[:, 1, IR] += k[:, 0]
    C[:, 1, IPHI] -= 1.0
    D[:, 1, :] = k * B[:, IB, :]
    return ContinuousModel(A=A, B=B, C=C, D=D, tas_ms=V)


def discretise(model: ContinuousModel, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH (Φ, Γ) of every run at period *ts* [s] (module docstring)."""
    n = model.A.shape[0]
    aug = np.zeros((n, N_STATES + N_INPUTS, N_STATES + N_INPUTS))
    aug[:, :N_STATES, :N_STATES] = model.A * ts
    aug[:, :N_STATES, N_STATES:] = model.B * ts
    ex = expm(aug)
    return ex[:, :N_STATES, :N_STATES], ex[:, :N_STATES, N_STATES:]


def discretise_ramp(model: ContinuousModel, ts: float, n_ramp: int = N_SURFACES):
    """(Φ, Γ, Γ₁) of every run: inputs held at u_k over the period plus, for the first
    *n_ramp* inputs (the surfaces), a ramp to u_{k+1} (first-order hold):
    x_{k+1} = Φ·x_k + Γ·u_k + Γ₁·(u_{k+1} − u_k)[:n_ramp]. Exact, from the exponential of
    [[A, B, 0], [0, 0, I/Ts], [0, 0, 0]]·Ts = [[Φ, Γ, Γ₁], [0, I, I], [0, 0, I]]."""
    n = model.A.shape[0]
    ns, ni = N_STATES, N_INPUTS
    aug = np.zeros((n, ns + ni + n_ramp, ns + ni + n_ramp))
    aug[:, :ns, :ns] = model.A * ts
    aug[:, :ns, ns:ns + ni] = model.B * ts
    aug[:, ns:ns + n_ramp, ns + ni:] = np.eye(n_ramp)
    ex = expm(aug)
    return ex[:, :ns, :ns], ex[:, :ns, ns:ns + ni], ex[:, :ns, ns + ni:]


def run_models(flight: dict, aero, *, aircraft: AircraftParams = A330,
               layout: SurfaceLayout = LAYOUT) -> ContinuousModel:
    """Continuous models of a batch from its true flight condition (``flight`` holds
    ``mass_t``, ``cg_pct``, ``mach``, ``qbar_pa``, ``tas_ms`` arrays) and its aerodynamic
    draws *aero* (a mapping ``{"cx": d, …, "cn": d}`` of arrays, or one number or array
    for every coefficient; 0: the nominal model)."""
    frames = a330_airframes(flight["mass_t"], aircraft)
    derivs = scheduled_derivatives(flight["mach"], flight["cg_pct"], aero)
    controls = control_derivatives(flight["mach"], flight["cg_pct"], aero, layout,
                                   aircraft=aircraft)
    return continuous_model(flight["qbar_pa"], flight["tas_ms"], derivs, frames, controls)


def reference_model(condition: ReferenceCondition = B747_CONDITION,
                    reference: AirframeData = B747) -> ContinuousModel:
    """The reference airframe at its own flight condition (for the mode checks)."""
    qbar = 0.5 * condition.rho_kgm3 * condition.tas_ms ** 2
    derivs = scheduled_derivatives(condition.mach, reference.cg_ref_pct, 0.0)
    controls = control_derivatives(condition.mach, reference.cg_ref_pct, 0.0)
    return continuous_model(np.array([qbar]), np.array([condition.tas_ms]), derivs,
                            reference_airframe(reference), controls)


def modes(model: ContinuousModel) -> dict[str, np.ndarray]:
    """Eigenvalues [1/s] of the longitudinal (α, q) block and of the lateral block of each
    run: ``short_period`` (upper-half-plane root), ``dutch_roll`` (same), ``roll`` (the
    fastest real root), ``spiral`` (the slowest real root)."""
    lon = np.linalg.eigvals(model.A[:, :2, :2])
    lat = np.linalg.eigvals(model.A[:, IB:, IB:])
    sp = lon[np.arange(len(lon)), np.argmax(lon.imag, axis=1)]
    dr = lat[np.arange(len(lat)), np.argmax(lat.imag, axis=1)]
    real = np.where(np.abs(lat.imag) < 1e-9, lat.real, np.nan)
    return {"short_period": sp, "dutch_roll": dr, "roll": np.nanmin(real, axis=1),
            "spiral": np.nanmax(real, axis=1)}
