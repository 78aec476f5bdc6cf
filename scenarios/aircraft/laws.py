"""Normal-law-like flight control laws at Ts, vectorised over runs (docs/physics.md §7 phase 2).

The gains are scheduled on the *measured* flight point: the FCC builds the nominal linear
model (every aerodynamic draw 0) of :mod:`scenarios.aircraft.lpv` from the measured/estimated
Mach, q̄, TAS, mass and CG, and places the closed-loop poles on it. The real aircraft (true
flight point, Table-2 aero errors) therefore differs from the model the gains were placed on.

Pitch — load-factor command with integral action. On the short-period model
α̇ = a11·α + a12·q, q̇ = a21·α + a22·q + b·δe, Δn_z ≈ n_α·α, the law

    δe = δe_trim − k_n·(Δn_z − n_δ·δ̂e) − k_q·q − k_i·z,     ż = Δn_z − n_zc

gives the characteristic polynomial s³ − (a11 + a22')s² + (a11·a22' − a12·a21')s + b·k_i·a12·n_α
(a22' = a22 − b·k_q, a21' = a21 − b·k_n·n_α); matching it to (s² + 2ζωs + ω²)(s + a) fixes
k_q, k_n, k_i (:func:`gains`). The proportional path removes the elevator's direct lift
n_δ·δ̂e (nominal model, δ̂e from the elevators' COM rod acquisitions): fed back raw, that
feedthrough closes a fast algebraic loop whose gain k_n·n_δ exceeds 1 at low q̄, heavy
mass and aft CG. The integrator stops while the elevator order is clipped
(conditional integration, no wind-up).

Roll — roll-rate command with bank hold, by inversion of the nominal roll subsidence
ṗ = L_p·p + L_δa·δa:  φ_ref integrates the pilot's p_c, p_dem = p_c + k_φ·(φ_ref − φ),
δa = (ω_p·(p_dem − p) − L_p·p)/L_δa. The roll order δa moves the four ailerons
antisymmetrically (right +δa, left −δa) and the spoilers by the fixed coupling.

Yaw — damper and turn coordination: δr = (−k_r·(r − g·sin φ/V) + k_β·(β − β_c)
+ k_βi·∫(β − β_c))/N_δr, β_c the pedal sideslip order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..atmosphere import G0_MS2
from . import lpv
from .data import LAWS, LAYOUT, LawParams


@dataclass(frozen=True)
class Gains:
    """Per-run law gains (arrays (n,)) and control distributions."""

    k_n: np.ndarray          # rad per g
    k_q: np.ndarray          # rad per rad/s
    k_i: np.ndarray          # rad per g·s
    L_p: np.ndarray          # 1/s
    L_da: np.ndarray         # 1/s² per rad of roll order
    N_dr: np.ndarray         # 1/s² per rad of rudder
    nz_de: np.ndarray        # direct Δn_z per rad of elevator [g/rad] (nominal D term)
    tas_ms: np.ndarray       # measured TAS [m/s]


#: Roll-order distribution on the surfaces (right ailerons +1, left −1) and the spoilers.
ROLL_DISTRIBUTION = np.array(
    [0.0 if k != "aileron" else (1.0 if n.startswith("right") else -1.0)
     for n, k in zip(LAYOUT.names, LAYOUT.actuator)] + [1.0, 0.0, 0.0])
PITCH_DISTRIBUTION = np.array([1.0 if k == "elevator" else 0.0 for k in LAYOUT.actuator]
                              + [0.0, 0.0, 0.0])
YAW_DISTRIBUTION = np.array([1.0 if k == "rudder" else 0.0 for k in LAYOUT.actuator]
                            + [0.0, 0.0, 0.0])


def distributed(columns: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Σ_j weights[j]·columns[:, j] per run (row), summed in the order of j for every run
    alike. A matrix product ``columns @ weights`` sums in an order that depends on the number
    of rows (BLAS blocking), so a run's gains, and every sample after them, would depend on
    the runs simulated in the same block; a run must be a function of its plan row alone
    (docs/design.md §9, Determinism)."""
    out = np.zeros(columns.shape[0])
    for j in np.flatnonzero(weights):
        out = out + weights[j] * columns[:, j]
    return out


def gains(nominal: lpv.ContinuousModel, laws: LawParams = LAWS) -> Gains:
    """Pole placement of the module docstring on each run's nominal model."""
    A, B = nominal.A, nominal.B
    a11, a12 = A[:, lpv.IA, lpv.IA], A[:, lpv.IA, lpv.IQ]
    a21, a22 = A[:, lpv.IQ, lpv.IA], A[:, lpv.IQ, lpv.IQ]
    b = distributed(B[:, lpv.IQ, :], PITCH_DISTRIBUTION)
    n_alpha = nominal.C[:, 0, lpv.IA]
    w, z, a = laws.pitch_omega, laws.pitch_zeta, laws.pitch_integral
    c2, c1, c0 = 2 * z * w + a, w * w + 2 * z * w * a, w * w * a
    a22p = -c2 - a11
    a21p = (a11 * a22p - c1) / a12
    return Gains(
        k_n=(a21 - a21p) / b / n_alpha,
        k_q=(a22 - a22p) / b,
        k_i=c0 / (b * a12 * n_alpha),
        L_p=A[:, lpv.IP, lpv.IP],
        L_da=distributed(B[:, lpv.IP, :], ROLL_DISTRIBUTION),
        N_dr=distributed(B[:, lpv.IR, :], YAW_DISTRIBUTION),
        nz_de=distributed(nominal.D[:, 0, :], PITCH_DISTRIBUTION),
        tas_ms=nominal.tas_ms,
    )


@dataclass
class LawState:
    """Integrator states of the laws (arrays (n,))."""

    z_pitch: np.ndarray      # ∫(Δn_z − n_zc) dt [g·s]
    phi_ref: np.ndarray      # bank reference [rad]
    z_beta: np.ndarray       # ∫(β − β_c) dt [rad·s]

    @classmethod
    def zeros(cls, n: int) -> "LawState":
        return cls(np.zeros(n), np.zeros(n), np.zeros(n))


def step(state: LawState, meas: dict, nz_c, p_c, beta_c, g: Gains, ts: float,
         pitch_clipped, laws: LawParams = LAWS, g0: float = G0_MS2):
    """One FCC period: the pitch, roll and yaw orders [rad, perturbations from trim].

    ``meas`` holds the measured q, p, r [rad/s], φ, β [rad], Δn_z [g] and the elevators'
    mean deflection from trim, from their COM rod acquisitions, ``de`` [rad]; ``nz_c`` [g],
    ``p_c`` [rad/s], ``beta_c`` [rad] the pilot orders; ``pitch_clipped`` (bool (n,)) whether
    the previous elevator order was clipped. Updates ``state`` in place and returns
    (δe, δa, δr).
    """
    dnz_p = meas["dnz"] - g.nz_de * meas["de"]
    de = -g.k_n * dnz_p - g.k_q * meas["q"] - g.k_i * state.z_pitch
    state.z_pitch = state.z_pitch + np.where(pitch_clipped, 0.0, ts * (meas["dnz"] - nz_c))
    bank_max = np.radians(laws.bank_max_deg)
    phi_ref = state.phi_ref + ts * p_c
    state.phi_ref = phi_ref
    p_dem = p_c + laws.bank_gain * (phi_ref - meas["phi"])
    da = (laws.roll_bandwidth * (p_dem - meas["p"]) - g.L_p * meas["p"]) / g.L_da
    r_turn = g0 * np.sin(np.clip(meas["phi"], -bank_max, bank_max)) / g.tas_ms
    e_beta = meas["beta"] - beta_c
    dr = (-laws.yaw_damping * (meas["r"] - r_turn) + laws.sideslip_gain * e_beta
          + laws.sideslip_integral * state.z_beta) / g.N_dr
    state.z_beta = state.z_beta + ts * e_beta
    return de, da, dr


def turn_load_factor(phi, laws: LawParams = LAWS):
    """Load factor the pitch law adds in a level turn, 1/cos φ − 1 [g] (φ clipped at the
    bank limit of ``laws``)."""
    bank_max = np.radians(laws.bank_max_deg)
    return 1.0 / np.cos(np.clip(phi, -bank_max, bank_max)) - 1.0
