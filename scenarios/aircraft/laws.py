"""Normal-law-like flight control laws at Ts, vectorised over runs (docs/aircraft.md §4,
docs/physics.md §7.3).

The gains are scheduled on the *measured* flight point: the FCC builds the nominal linear
model (every aerodynamic draw 0) of :mod:`scenarios.aircraft.lpv` from the measured/estimated
Mach, q̄, TAS, mass and CG, and places the closed-loop poles on it. The real aircraft (true
flight point, Table-2 aero errors) therefore differs from the model the gains were placed on.

Pitch — load-factor command with pitch-rate feedback and integral action (docs/aircraft.md
§4.1). On the short-period model α̇ = a11·α + a12·q, q̇ = a21·α + a22·q + b·δe,
Δn_z ≈ n_α·α, the law

    δe = δe_trim − k_n·F(Δn_z − n_δ·δ̂e) − k_q·F(q) − k_i·z,     ż = Δn_z − n_zc

(F the first-order filter of §4.4) gives, without F, the characteristic polynomial
s³ − (a11 + a22')s² + (a11·a22' − a12·a21')s + b·k_i·a12·n_α (a22' = a22 − b·k_q,
a21' = a21 − b·k_n·n_α); matching it to (s² + 2ζω_sp·s + ω_sp²)(s + a) fixes k_q, k_n, k_i
(:func:`gains`). The closed-loop short-period frequency is scheduled on the control
anticipation parameter of MIL-F-8785C §3.2.2.1.1, ω_sp = sqrt(CAP·n_α) bounded to
[ω_min, ω_max] (:func:`short_period_omega`), so the gains stay bounded where the elevator's
pitching moment b and n_α are small (low q̄, heavy, aft CG). The proportional path removes the
elevator's direct lift n_δ·δ̂e (nominal model, δ̂e from the elevators' COM rod acquisitions):
fed back raw, that feedthrough closes a fast algebraic loop whose gain k_n·n_δ can exceed 1.
The integrator stops while an elevator order is limited (in position or in rate; conditional
integration, no wind-up).

Roll — roll-rate command with bank hold, by inversion of the nominal roll subsidence
ṗ = L_p·p + L_δa·δa (docs/aircraft.md §4.2): φ_ref integrates the pilot's p_c,
p_dem = p_c + k_φ·(φ_ref − φ), δa = (ω_p·(p_dem − F(p)) − L_p·F(p))/L_δa. The roll order δa
moves the four ailerons antisymmetrically (right +δa, left −δa) and the spoilers by the fixed
coupling.

Yaw — damper and turn coordination (docs/aircraft.md §4.3): δr = (−k_r·(F(r) − g·sin φ/V)
+ k_β·(F(β) − β_c) + k_βi·∫(F(β) − β_c))/N_δr, β_c the pedal sideslip order.

Orders (docs/aircraft.md §4.4): every fed-back measurement passes a first-order filter
y ← y + c·(x − y), c = 1 − exp(−Ts/τ) (:func:`filter_coefficient`); every surface order is
clipped to its authority and then rate-limited (:func:`rate_limit`), the spoilers' order too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..atmosphere import G0_MS2
from ..params import AILERON, ELEVATOR
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
    omega_sp: np.ndarray     # closed-loop short-period ω the pitch gains are placed for [rad/s]


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


def short_period_omega(n_alpha, laws: LawParams = LAWS) -> np.ndarray:
    """Closed-loop short-period frequency [rad/s] for a load factor per angle of attack
    *n_alpha* [g/rad]: ω_sp = sqrt(CAP·n_α) bounded to [ω_min, ω_max] (docs/aircraft.md §4.1,
    eq. 4.2; CAP of MIL-F-8785C §3.2.2.1.1)."""
    w = np.sqrt(laws.pitch_cap * np.asarray(n_alpha, dtype=float))
    return np.clip(w, laws.pitch_omega_min, laws.pitch_omega_max)


def gains(nominal: lpv.ContinuousModel, laws: LawParams = LAWS) -> Gains:
    """Pole placement of the module docstring on each run's nominal model
    (docs/aircraft.md §4.1, eq. 4.3)."""
    A, B = nominal.A, nominal.B
    a11, a12 = A[:, lpv.IA, lpv.IA], A[:, lpv.IA, lpv.IQ]
    a21, a22 = A[:, lpv.IQ, lpv.IA], A[:, lpv.IQ, lpv.IQ]
    b = distributed(B[:, lpv.IQ, :], PITCH_DISTRIBUTION)
    n_alpha = nominal.C[:, 0, lpv.IA]
    w = short_period_omega(n_alpha, laws)
    z, a = laws.pitch_zeta, laws.pitch_integral
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
        omega_sp=w,
    )


def filter_coefficient(tau_s: float, ts: float) -> float:
    """Gain c = 1 − exp(−Ts/τ) of the first-order filter y ← y + c·(x − y) at period *ts*
    [s] for time constant *tau_s* [s] (docs/aircraft.md §4.4, eq. 4.8: the exact
    discretisation of τ·ẏ = x − y with x held over the period)."""
    return 1.0 - math.exp(-ts / tau_s)


def filter_coefficients(ts: float, laws: LawParams = LAWS) -> tuple[float, float, float]:
    """(c_pitch, c_roll, c_yaw) of :func:`filter_coefficient` for the three laws."""
    return (filter_coefficient(laws.pitch_filter_s, ts),
            filter_coefficient(laws.roll_filter_s, ts),
            filter_coefficient(laws.yaw_filter_s, ts))


def rate_limit(previous, order, max_step):
    """*order* moved from *previous* by at most *max_step* (same unit, per period):
    previous + clip(order − previous, −max_step, max_step) (docs/aircraft.md §4.4, eq. 4.9)."""
    return previous + np.clip(order - previous, -max_step, max_step)


def order_rate_limits_deg_s(laws: LawParams = LAWS) -> np.ndarray:
    """Rate limit [deg/s] of each surface order, in :data:`LAYOUT` order."""
    per_kind = {"elevator": laws.elevator_rate_deg_s, "aileron": laws.aileron_rate_deg_s,
                "rudder": laws.rudder_rate_deg_s}
    return np.array([per_kind[k] for k in LAYOUT.actuator])


def order_steps(ts: float, laws: LawParams = LAWS) -> tuple[np.ndarray, float]:
    """Largest change per period *ts* of each surface order [deg] (:data:`LAYOUT` order)
    and of the spoilers' roll order [rad] (the ailerons' rate)."""
    return order_rate_limits_deg_s(laws) * ts, math.radians(laws.aileron_rate_deg_s) * ts


def pitch_loop_matrix(model: lpv.ContinuousModel, g: Gains, laws: LawParams = LAWS,
                      servo_bandwidth_per_s: float = ELEVATOR.bandwidth_per_s) -> np.ndarray:
    """State matrices (n, 6, 6) of the linear closed pitch loop of each run, on the states
    [α, q, F(Δn_z − n̂_δ·δe), F(q), z, δe] (docs/aircraft.md §4.5): the short period of
    *model* (the aircraft flown: nominal, or with its aerodynamic draws) with the elevators'
    lift and pitching moment, the law of gains *g* (placed on the nominal model, whose direct
    lift n̂_δ = ``g.nz_de`` it removes) with its filters F (``pitch_filter_s``) and
    integrator, and the elevator servo as a first-order lag of bandwidth
    *servo_bandwidth_per_s* [1/s] (Kci·K of scenarios.params.ELEVATOR: 15/s); the FCC's
    sampling (Ts = 0.01 s) is left out."""
    A, B = model.A, model.B
    n = A.shape[0]
    b_a = distributed(B[:, lpv.IA, :], PITCH_DISTRIBUTION)
    b_q = distributed(B[:, lpv.IQ, :], PITCH_DISTRIBUTION)
    n_alpha = model.C[:, 0, lpv.IA]
    n_de = distributed(model.D[:, 0, :], PITCH_DISTRIBUTION)
    tau, bw = laws.pitch_filter_s, servo_bandwidth_per_s
    M = np.zeros((n, 6, 6))
    M[:, 0, 0], M[:, 0, 1], M[:, 0, 5] = A[:, lpv.IA, lpv.IA], A[:, lpv.IA, lpv.IQ], b_a
    M[:, 1, 0], M[:, 1, 1], M[:, 1, 5] = A[:, lpv.IQ, lpv.IA], A[:, lpv.IQ, lpv.IQ], b_q
    M[:, 2, 0], M[:, 2, 2], M[:, 2, 5] = n_alpha / tau, -1.0 / tau, (n_de - g.nz_de) / tau
    M[:, 3, 1], M[:, 3, 3] = 1.0 / tau, -1.0 / tau
    M[:, 4, 0], M[:, 4, 5] = n_alpha, n_de                   # ż = Δn_z (n_zc = 0)
    M[:, 5, 2], M[:, 5, 3], M[:, 5, 4] = -bw * g.k_n, -bw * g.k_q, -bw * g.k_i
    M[:, 5, 5] = -bw
    return M


def roll_loop_matrix(model: lpv.ContinuousModel, g: Gains, laws: LawParams = LAWS,
                     servo_bandwidth_per_s: float = AILERON.bandwidth_per_s) -> np.ndarray:
    """State matrices (n, 3, 3) of the linear closed roll-rate loop of each run on
    [p, F(p), δa] (docs/aircraft.md §4.5): the roll subsidence ṗ = L_p·p + L_δa·δa of
    *model* (the ailerons and the spoilers), the law of gains *g* with its filter F
    (``roll_filter_s``) and the aileron servo as a first-order lag of bandwidth
    *servo_bandwidth_per_s* [1/s] (Kci·K of scenarios.params.AILERON: 17.5/s); the bank hold,
    the spoilers' one-period lag and the FCC's sampling are left out."""
    A, B = model.A, model.B
    n = A.shape[0]
    tau, bw, w = laws.roll_filter_s, servo_bandwidth_per_s, laws.roll_bandwidth
    M = np.zeros((n, 3, 3))
    M[:, 0, 0], M[:, 0, 2] = A[:, lpv.IP, lpv.IP], distributed(B[:, lpv.IP, :], ROLL_DISTRIBUTION)
    M[:, 1, 0], M[:, 1, 1] = 1.0 / tau, -1.0 / tau
    M[:, 2, 1], M[:, 2, 2] = -bw * (w + g.L_p) / g.L_da, -bw
    return M


def dominant_pair(eigenvalues: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ω [rad/s], ζ) of the complex pair of lowest frequency in each row of *eigenvalues*
    (n, m); NaN where a row has none."""
    ev = np.asarray(eigenvalues)
    pair = np.where(np.abs(ev.imag) > 1e-9, np.abs(ev), np.inf)
    j = np.argmin(pair, axis=1)
    e = ev[np.arange(len(ev)), j]
    has = np.isfinite(pair[np.arange(len(ev)), j])
    w = np.where(has, np.abs(e), np.nan)
    return w, np.where(has, -e.real / np.where(has, np.abs(e), 1.0), np.nan)


@dataclass
class LawState:
    """Integrator and filter states of the laws (arrays (n,))."""

    z_pitch: np.ndarray      # ∫(Δn_z − n_zc) dt [g·s]
    phi_ref: np.ndarray      # bank reference [rad]
    z_beta: np.ndarray       # ∫(F(β) − β_c) dt [rad·s]
    nz_f: np.ndarray         # filtered Δn_z − n_δ·δ̂e [g]
    q_f: np.ndarray          # filtered q [rad/s]
    p_f: np.ndarray          # filtered p [rad/s]
    r_f: np.ndarray          # filtered r [rad/s]
    beta_f: np.ndarray       # filtered β [rad]

    @classmethod
    def zeros(cls, n: int) -> "LawState":
        return cls(*(np.zeros(n) for _ in range(8)))


def step(state: LawState, meas: dict, nz_c, p_c, beta_c, g: Gains, ts: float,
         pitch_clipped, laws: LawParams = LAWS, g0: float = G0_MS2):
    """One FCC period: the pitch, roll and yaw orders [rad, perturbations from trim],
    before the authority and rate limits of the surfaces (docs/aircraft.md §4).

    ``meas`` holds the measured q, p, r [rad/s], φ, β [rad], Δn_z [g] and the elevators'
    mean deflection from trim, from their COM rod acquisitions, ``de`` [rad]; ``nz_c`` [g],
    ``p_c`` [rad/s], ``beta_c`` [rad] the pilot orders; ``pitch_clipped`` (bool (n,)) whether
    the previous elevator order was limited (position or rate). Updates ``state`` in place
    and returns (δe, δa, δr).
    """
    c_pitch, c_roll, c_yaw = filter_coefficients(ts, laws)
    dnz_p = meas["dnz"] - g.nz_de * meas["de"]
    state.nz_f = state.nz_f + c_pitch * (dnz_p - state.nz_f)
    state.q_f = state.q_f + c_pitch * (meas["q"] - state.q_f)
    de = -g.k_n * state.nz_f - g.k_q * state.q_f - g.k_i * state.z_pitch
    state.z_pitch = state.z_pitch + np.where(pitch_clipped, 0.0, ts * (meas["dnz"] - nz_c))
    bank_max = np.radians(laws.bank_max_deg)
    phi_ref = state.phi_ref + ts * p_c
    state.phi_ref = phi_ref
    p_dem = p_c + laws.bank_gain * (phi_ref - meas["phi"])
    state.p_f = state.p_f + c_roll * (meas["p"] - state.p_f)
    da = (laws.roll_bandwidth * (p_dem - state.p_f) - g.L_p * state.p_f) / g.L_da
    r_turn = g0 * np.sin(np.clip(meas["phi"], -bank_max, bank_max)) / g.tas_ms
    state.r_f = state.r_f + c_yaw * (meas["r"] - state.r_f)
    state.beta_f = state.beta_f + c_yaw * (meas["beta"] - state.beta_f)
    e_beta = state.beta_f - beta_c
    dr = (-laws.yaw_damping * (state.r_f - r_turn) + laws.sideslip_gain * e_beta
          + laws.sideslip_integral * state.z_beta) / g.N_dr
    state.z_beta = state.z_beta + ts * e_beta
    return de, da, dr


def turn_load_factor(phi, laws: LawParams = LAWS):
    """Load factor the pitch law adds in a level turn, 1/cos φ − 1 [g] (φ clipped at the
    bank limit of ``laws``)."""
    bank_max = np.radians(laws.bank_max_deg)
    return 1.0 / np.cos(np.clip(phi, -bank_max, bank_max)) - 1.0
