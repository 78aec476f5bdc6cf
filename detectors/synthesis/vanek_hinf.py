"""H∞ post-filter of the geometric residual by model matching ([VANEK] §3, Fig. 1).

The geometric filter's residual r (:mod:`detectors.synthesis.geometric`) is decoupled from L2
exactly but carries the sensor noise through its direct feed-through and its dynamics. A post-filter
Q (one output, the fault estimate f̂ = Q r) is synthesised so that f̂ tracks the fault
through an ideal band-limited response T_id = ω_id/(s + ω_id) ([VANEK] §5: "fault tracking
is achieved only in a limited frequency range described by T_id") while the noise is
attenuated, by minimising ‖z‖ over ‖w‖ (H∞) in the interconnection

    ė = N e − P L1 f1 − G Σ n,     r = M e − H Σ n        (error of the geometric filter)
    ẋ_id = −ω_id x_id + ω_id f1                            (ideal fault tracking T_id)
    z = [x_id − f̂;  ε f̂],   w = [f1/f_s; n],   measurement r,   control f̂

with Σ = diag(σ) the sensors' noise amplitude (unit-intensity n: for white noise of standard
deviation σ sampled at Ts, Σ = σ·√Ts) and ε the small
penalty on f̂ that [VANEK] §5 adds for well-posedness (W_p). Reading implemented: the
uncertainty weight W_u, the Dryden weight W_dr and the fault-error weight W_e of [VANEK]
Fig. 3 are left out (W_e = 1; the lateral gust is decoupled exactly by the geometric filter
here), so this is the nominal post-filter.

The one-step H∞ FDI filter of [VANEK] §3 (:func:`one_step_filter`), for comparison: no
geometric pre-filter; one H∞ synthesis on the aircraft model weighs fault tracking against
the elevator and rudder faults, the Dryden gusts and the sensor noise together, so the
isolation is approximate (attenuation, not decoupling).

Synthesis with python-control's ``hinfsyn`` (SLICOT through slycot): the optional extra
``hinf`` (``pip install fdd-campaign[hinf]``), imported only here, at design time; the
online filtering needs numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios.errors import InputError

from scenarios.params import param

from .geometric import ResidualGenerator


def sensor_sigmas(outputs) -> np.ndarray:
    """σ of the design-model *outputs* (names of states: ``alpha``, ``q``, ``theta``, ``beta``,
    ``p``, ``r``, ``phi``; :data:`detectors.builtin.vanek_geometric.OUTPUTS`) from the nominal
    aircraft sensor table :data:`scenarios.aircraft.data.AIRCRAFT_SENSORS` [rad, rad/s]."""
    from scenarios.aircraft.data import AIRCRAFT_SENSORS as s

    rate, att = np.radians(s.rate_noise_deg_s), np.radians(s.attitude_noise_deg)
    sigma = {"alpha": np.radians(s.aoa_noise_deg), "q": rate, "theta": att,
             "beta": np.radians(s.sideslip_noise_deg), "p": rate, "r": rate, "phi": att}
    return np.array([sigma[o] for o in outputs])


class HinfUnavailableError(InputError, ImportError):
    """python-control or slycot is missing (the message says how to install them)."""


@dataclass(frozen=True)
class PostFilter:
    """Q = (A, B, C, D): input r, output f̂ (model units); gamma: the achieved H∞ bound."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    gamma: float


def post_filter(gen: ResidualGenerator, sigma_y, *, fault_scale: float = 0.1,
                omega_id: float = 1.0, eps: float = 0.1, max_pole: float = 100.0) -> PostFilter:
    """The H∞ post-filter of the module docstring for the geometric filter *gen*.

    sigma_y : sequence (p,)
        Noise standard deviation of each output of the design model [output units].
    fault_scale : float
        Size of the fault to track [fault units] (the exogenous fault input is f1 /
        fault_scale, so that tracking and noise are weighed at the sizes that matter).
    omega_id : float
        Bandwidth of the ideal fault tracking T_id [rad/s] (> 0).
    eps : float
        Penalty on the filter output (> 0).
    max_pole : float
        The central H∞ filter can have poles far beyond what a sampled implementation
        carries ([VANEK] §5 drops its μ filters for that reason); modes faster than this
        [rad/s] are removed by balanced truncation matching the DC gain
        (``control.balred(..., method="matchdc")``).
    """
    try:
        import control
        import slycot  # noqa: F401  (hinfsyn needs it)
    except ImportError as exc:
        raise HinfUnavailableError(
            f"the H∞ post-filter needs python-control and slycot ({exc}); install the "
            "optional extra: pip install 'fdd-campaign[hinf]'") from exc
    if not omega_id > 0.0 or not eps > 0.0:
        raise ValueError(f"omega_id and eps must be > 0, got {omega_id!r}, {eps!r}")
    N, M, H, G = gen.N, gen.M, gen.H, gen.G
    Sig = np.diag(np.asarray(sigma_y, float))
    nw, q, p = N.shape[0], M.shape[0], Sig.shape[0]
    pl1 = (gen.P @ gen.L1)[:, :1] * fault_scale
    # states [e; x_id], inputs [f1; n; u], outputs [z1; z2; r]
    A = np.block([[N, np.zeros((nw, 1))], [np.zeros((1, nw)), -omega_id * np.ones((1, 1))]])
    B1 = np.block([[-pl1, -G @ Sig], [omega_id * fault_scale * np.ones((1, 1)),
                                      np.zeros((1, p))]])
    B2 = np.zeros((nw + 1, 1))
    C1 = np.block([[np.zeros((1, nw)), np.ones((1, 1))], [np.zeros((1, nw + 1))]])
    D11 = np.zeros((2, 1 + p))
    D12 = np.array([[-1.0], [eps]])
    C2 = np.hstack([M, np.zeros((q, 1))])
    D21 = np.hstack([np.zeros((q, 1)), -H @ Sig])
    D22 = np.zeros((q, 1))
    plant = control.ss(A, np.hstack([B1, B2]), np.vstack([C1, C2]),
                       np.block([[D11, D12], [D21, D22]]))
    K, _, gamma, _ = control.hinfsyn(plant, q, 1)
    return PostFilter(*residualise(np.asarray(K.A), np.asarray(K.B), np.asarray(K.C),
                                   np.asarray(K.D), max_pole), gamma=float(gamma))


def residualise(A, B, C, D, max_pole: float):
    """Singular-perturbation reduction: the modes of A faster than *max_pole* [rad/s] are
    set to their steady state (ordered real Schur form A = Z [[T11, T12], [0, T22]] Zᵀ, slow
    block first; x_f = −T22⁻¹ B_f u). The DC gain is kept exactly."""
    import scipy.linalg

    T, Z, n_slow = scipy.linalg.schur(A, output="real",
                                      sort=lambda re, im: abs(complex(re, im)) < max_pole)
    if n_slow == A.shape[0]:
        return A, B, C, D
    Bt, Ct = Z.T @ B, C @ Z
    s = slice(0, n_slow)
    f = slice(n_slow, None)
    T22_Bf = np.linalg.solve(T[f, f], Bt[f])
    return (T[s, s], Bt[s] - T[s, f] @ T22_Bf, Ct[:, s],
            D - Ct[:, f] @ T22_Bf)


def cascade(gen: ResidualGenerator, q: PostFilter):
    """(A, B, C, D) of the geometric filter (input [u; y]) followed by *q*: output f̂."""
    Af, Bf, Cf, Df = gen.state_space()
    nf, nq = Af.shape[0], q.A.shape[0]
    A = np.block([[Af, np.zeros((nf, nq))], [q.B @ Cf, q.A]])
    B = np.vstack([Bf, q.B @ Df])
    C = np.hstack([q.D @ Cf, q.C])
    D = q.D @ Df
    return A, B, C, D


@dataclass(frozen=True)
class OneStepWeights:
    """Scales of the one-step H∞ design ([VANEK] §3, Fig. 3 weights)."""

    fault_rad: float = param("rad", "est. (3°: the size of [VANEK]'s liquid jam)",
                             "aileron fault to track (scale of w_f)")
    isolated_rad: float = param("rad", "est. (5°)", "elevator and rudder faults to reject")
    known_rad: float = param("rad", "est. (5°)", "known surface deflections (exogenous)")
    gust_rad: float = param("rad", "est. (σ 1°: moderate turbulence, docs/physics.md §7)",
                            "Dryden gust angles W_dr")
    gust_bandwidth: float = param("rad/s", "est. (V/L at cruise)",
                                  "pole of the first-order gust shaping filter")
    omega_id: float = param("rad/s", "[VANEK] §5 (T_id; est. value)",
                            "bandwidth of the ideal fault tracking T_id")
    eps: float = param("-", "[VANEK] §5 (W_p; est. value)", "penalty on the filter output")
    exact_sigma_rad: float = param("rad", "numerical", "noise σ given to inputs known exactly "
                                   "(the spoiler order), so that D21 has full row rank")
    max_pole: float = param("rad/s", "[VANEK] §5 (sampled at 0.01 s)",
                            "faster filter modes are residualised")


ONE_STEP = OneStepWeights(fault_rad=np.radians(3.0), isolated_rad=np.radians(5.0),
                          known_rad=np.radians(5.0), gust_rad=np.radians(1.0),
                          gust_bandwidth=0.2, omega_id=1.0, eps=0.1, exact_sigma_rad=1e-6,
                          max_pole=100.0)


@dataclass(frozen=True)
class OneStepFilter:
    """The one-step filter (A, B, C, D): input [u_known; y] (y in the order of the design
    outputs, pitch attitude excluded), output f̂ [rad]; ``gamma`` the achieved H∞ bound;
    ``plant`` the weighted interconnection and ``full`` the unreduced filter (for checks)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    gamma: float
    plant: object
    full: object
    outputs: tuple


def one_step_filter(A, B, C, outputs, i1: int, i2: list, known: list, i_gust: list,
                    sigma_y, sigma_u, ts: float, w: OneStepWeights = ONE_STEP,
                    gust_feedthrough=None) -> OneStepFilter:
    """The one-step H∞ FDI filter of [VANEK] §3 for the model (A, B, C) [rad, rad/s].

    Weighted interconnection (states: aircraft x, ideal tracking x_id, gust filters x_g)::

        ẋ = A x + B[:, i1] f_s w_f + B[:, i2] d_s w_d + B[:, i_gust] x_g + B[:, known] u_s w_u
        ẋ_id = −ω_id x_id + ω_id f_s w_f           (T_id)
        ẋ_g = −ω_g x_g + g_s √(2ω_g) w_g           (first-order Dryden shaping, W_dr)
        z = [(x_id − f̂)/f_s;  ε f̂/f_s]
        m = [u_s w_u + Σ_u n_u;  C x + D_g x_g + Σ_y n_y]   (known inputs, then outputs)

    w = [w_f, w_d, w_g, n_y, w_u, n_u], all unit-size; Σ the sensor σ·√Ts (white noise
    sampled at Ts). The known inputs are exogenous and measured, so the filter learns to
    cancel their effect; the elevator and rudder faults and the gusts are attenuated, not
    decoupled. ``gust_feedthrough`` D_g (p, len(i_gust)): the gusts' direct effect on the
    outputs (an air-relative sideslip sensor reads β + β_g); zero when None. *A* must be
    stable for the filtering problem: the caller leaves out pure integrator states (the
    pitch attitude with speed held).
    python-control's ``hinfsyn`` (SLICOT) at design time only.
    """
    try:
        import control
        import slycot  # noqa: F401
    except ImportError as exc:
        raise HinfUnavailableError(
            f"the one-step H∞ filter needs python-control and slycot ({exc}); install the "
            "optional extra: pip install 'fdd-campaign[hinf]'") from exc
    if np.linalg.eigvals(A).real.max() >= 0.0:
        raise ValueError("the one-step H∞ filter needs a stable design model; leave out "
                         "integrator states (e.g. the pitch attitude with speed held)")
    n, p, m, ng = A.shape[0], C.shape[0], len(known), len(i_gust)
    N = n + 1 + ng
    Sy = np.diag(np.asarray(sigma_y, float) * np.sqrt(ts))
    Su = np.diag(np.asarray(sigma_u, float) * np.sqrt(ts))
    nw = 1 + len(i2) + ng + p + m + m
    Aa = np.zeros((N, N))
    Aa[:n, :n] = A
    Aa[:n, n + 1:] = B[:, i_gust]
    Aa[n, n] = -w.omega_id
    Aa[n + 1:, n + 1:] = -w.gust_bandwidth * np.eye(ng)
    B1 = np.zeros((N, nw))
    c = 0
    B1[:n, c] = B[:, i1] * w.fault_rad
    B1[n, c] = w.omega_id * w.fault_rad
    c += 1
    B1[:n, c:c + len(i2)] = B[:, i2] * w.isolated_rad
    c += len(i2)
    B1[n + 1:, c:c + ng] = w.gust_rad * np.sqrt(2.0 * w.gust_bandwidth) * np.eye(ng)
    c += ng
    iy = c
    c += p
    B1[:n, c:c + m] = B[:, known] * w.known_rad
    iu = c
    c += m
    C1 = np.zeros((2, N))
    C1[0, n] = 1.0 / w.fault_rad
    D12 = np.array([[-1.0 / w.fault_rad], [w.eps / w.fault_rad]])
    C2 = np.zeros((m + p, N))
    C2[m:, :n] = C
    if gust_feedthrough is not None:
        C2[m:, n + 1:] = np.asarray(gust_feedthrough, float).reshape(p, ng)
    D21 = np.zeros((m + p, nw))
    D21[m:, iy:iy + p] = Sy
    D21[:m, iu:iu + m] = np.eye(m) * w.known_rad
    D21[:m, iu + m:] = Su
    plant = control.ss(Aa, np.hstack([B1, np.zeros((N, 1))]), np.vstack([C1, C2]),
                       np.block([[np.zeros((2, nw)), D12], [D21, np.zeros((m + p, 1))]]))
    K, _, gamma, _ = control.hinfsyn(plant, m + p, 1)
    Ar, Br, Cr, Dr = residualise(np.asarray(K.A), np.asarray(K.B), np.asarray(K.C),
                                 np.asarray(K.D), w.max_pole)
    return OneStepFilter(A=Ar, B=Br, C=Cr, D=Dr, gamma=float(gamma), plant=plant, full=K,
                         outputs=tuple(outputs))
