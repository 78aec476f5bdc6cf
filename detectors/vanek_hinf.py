"""H∞ post-filter of the geometric residual by model matching ([VANEK] §3, Fig. 1).

The geometric filter's residual r (:mod:`detectors.geometric`) is decoupled from L2 exactly
but carries the sensor noise through its direct feed-through and its dynamics. A post-filter
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
here), so this is the nominal post-filter; the one-step H∞ design of [VANEK] §3 is not
implemented.

Synthesis with python-control's ``hinfsyn`` (SLICOT through slycot): the optional extra
``hinf`` (``pip install fdd-campaign[hinf]``), imported only here, at design time; the
online filtering needs numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometric import ResidualGenerator


def sensor_sigmas() -> np.ndarray:
    """σ of the design-model outputs (q, θ, β, p, r, φ) from the nominal aircraft sensor
    table :data:`scenarios.aircraft.data.AIRCRAFT_SENSORS` [rad, rad/s]."""
    from scenarios.aircraft.data import AIRCRAFT_SENSORS as s

    rate, att = np.radians(s.rate_noise_deg_s), np.radians(s.attitude_noise_deg)
    return np.array([rate, att, np.radians(s.sideslip_noise_deg), rate, rate, att])


class HinfUnavailableError(ImportError):
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
    s = slice(0, n_slow); f = slice(n_slow, None)
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
