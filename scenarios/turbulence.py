"""Dryden atmospheric turbulence (docs/physics.md §7; MIL-F-8785C §3.7, MIL-HDBK-1797).

Gust velocities u_g, v_g, w_g [m/s] along the body axes are white noise shaped by the
Dryden forming filters of MIL-HDBK-1797 (medium/high altitude, above 2000 ft, where the
turbulence is isotropic: σ_u = σ_v = σ_w = σ and L_u = 2·L_v = 2·L_w = L = 1750 ft).
With T = L/V (V the true airspeed) the filters are, for white noise of unit intensity:

    H_u(s)     = σ·sqrt(2·T) / (1 + T·s)                        R_u(τ) = σ²·exp(−τ/T)
    H_v,w(s)   = σ·sqrt(T)·(1 + √3·T·s) / (1 + T·s)²            R_w(τ) = σ²·(1 − τ/(2T))·exp(−τ/T)

(MIL-HDBK-1797 writes them with 2·L_v = L and a 1/π from its spectrum convention; the
autocorrelations R on the right follow from them and are what the tests check.)

Discretisation: exact zero-order hold of each filter at the sample period ts (closed form
below; it equals ``scipy.signal.cont2discrete(..., method="zoh")``), driven by discrete
unit white noise and scaled so that the *discrete* stationary variance is exactly σ².
The filter state at the first sample is drawn from its stationary distribution, so the
record is stationary from t = 0 (no quiet start, no warm-up to discard). The filtering
itself is ``scipy.signal.lfilter``: no Python loop over time steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .atmosphere import ISA_CONSTANTS
from .compiled import filtered_normals_1, resolve_engine
from .params import param

#: Metres per foot [m/ft] (the atmosphere's, :data:`scenarios.atmosphere.ISA_CONSTANTS`).
FT_TO_M: float = ISA_CONSTANTS.ft_m

#: Zero of the lateral/vertical Dryden filter, in units of 1/T (MIL-HDBK-1797: 1 + √3·T·s).
_DRYDEN_VW_ZERO: float = math.sqrt(3.0)


@dataclass(frozen=True)
class DrydenParams:
    """Dryden turbulence intensity and scale (docs/physics.md §7, MIL-F-8785C / MIL-HDBK-1797).

    σ is interpolated linearly in altitude between the table points and held constant
    outside them (clamped), like the standard's σ-vs-altitude chart read at a few points.
    """

    alt_table_ft: tuple[float, ...] = param(
        "ft", "docs/physics.md §7", "altitudes of the σ table (strictly increasing)")
    sigma_table_ms: tuple[float, ...] = param(
        "m/s", "docs/physics.md §7 (read from the MIL-F-8785C / MIL-HDBK-1797 high-altitude "
        "intensity chart, 'moderate' = 10⁻³ probability of exceedance)",
        "turbulence intensity σ_u = σ_v = σ_w at the table altitudes")
    scale_length_ft: float = param(
        "ft", "MIL-F-8785C / MIL-HDBK-1797 medium/high altitude (L_u = 2·L_v = 2·L_w = 1750 ft)",
        "scale length L of the forming filters")
    name: str = param("-", "-", "label of the intensity level")

    def __post_init__(self):
        alts = np.asarray(self.alt_table_ft, dtype=float)
        sigmas = np.asarray(self.sigma_table_ms, dtype=float)
        if alts.ndim != 1 or alts.shape != sigmas.shape or alts.size == 0:
            raise ValueError("alt_table_ft and sigma_table_ms must be non-empty and of equal "
                             "length")
        if not (np.all(np.isfinite(alts)) and np.all(np.diff(alts) > 0)):
            raise ValueError("alt_table_ft must be finite and strictly increasing, got "
                             f"{self.alt_table_ft}")
        if not (np.all(np.isfinite(sigmas)) and np.all(sigmas >= 0)):
            raise ValueError(f"sigma_table_ms must be finite and ≥ 0, got {self.sigma_table_ms}")
        if not (math.isfinite(self.scale_length_ft) and self.scale_length_ft > 0):
            raise ValueError(f"scale_length_ft must be finite and > 0, got {self.scale_length_ft}")

    def sigma_ms(self, alt_ft: float) -> float:
        """Turbulence intensity σ at an altitude [m/s] (linear interpolation, clamped)."""
        return float(np.interp(alt_ft, self.alt_table_ft, self.sigma_table_ms))

    @property
    def scale_length_m(self) -> float:
        """Scale length L [m]."""
        return self.scale_length_ft * FT_TO_M


#: Moderate turbulence (docs/physics.md §7): σ = 3.0 / 2.3 / 1.9 / 1.45 m/s at 8 / 18 / 28 / 38 kft.
MODERATE = DrydenParams(
    alt_table_ft=(8000.0, 18000.0, 28000.0, 38000.0),
    sigma_table_ms=(3.0, 2.3, 1.9, 1.45),
    scale_length_ft=1750.0,
    name="moderate",
)

#: Turbulence levels a campaign may choose (``[plant] turbulence``, aircraft plant): name →
#: Dryden table, ``None`` for calm air ([CHEN] footnote 1: the ADDSAFE runs had no wind).
LEVELS: dict[str, DrydenParams | None] = {"moderate": MODERATE, "none": None}


def level(name: str) -> DrydenParams | None:
    """The Dryden table of turbulence level *name* (:data:`LEVELS`; ``None``: calm air)."""
    if name not in LEVELS:
        raise ValueError(f"unknown turbulence level {name!r}; allowed: {', '.join(LEVELS)}")
    return LEVELS[name]


class DiscreteFilter(NamedTuple):
    """A discrete filter for ``scipy.signal.lfilter``: coefficients in z⁻¹, ``a[0] = 1``."""

    b: np.ndarray
    a: np.ndarray


class DrydenFilters(NamedTuple):
    """The unit-variance discrete Dryden filters of one airspeed (see :func:`dryden_filters`)."""

    u: DiscreteFilter
    vw: DiscreteFilter
    time_constant_s: float


def dryden_filters(tas_ms: float, ts: float, params: DrydenParams = MODERATE) -> DrydenFilters:
    """Unit-variance discrete Dryden filters for true airspeed ``tas_ms`` [m/s], period ``ts`` [s].

    Exact zero-order-hold discretisation, in closed form, with T = L/V and φ = exp(−ts/T):

    * u: 1/(1 + T·s)  →  (1 − φ)·z⁻¹ / (1 − φ·z⁻¹)
    * v, w: (1 + c·T·s)/(1 + T·s)², c = √3  →  (c₁·z⁻¹ + c₂·z⁻²) / (1 − φ·z⁻¹)², with
      c₁ = 1 − φ + h·φ, c₂ = φ·(φ − 1 − h), h = (c − 1)·ts/T (step-invariant transform of
      the partial fractions 1/s − 1/(s + 1/T) + (c − 1)/T/(s + 1/T)²)

    each scaled so that unit discrete white noise gives unit stationary output variance (the
    σ·sqrt(·) gains of the continuous filters only fix that variance). The variances, from
    the impulse responses (k + 1)·φᵏ of 1/(1 − φ·z⁻¹)², are (1 − φ)/(1 + φ) for u and
    [(c₁ + c₂)²·(1 + φ)² + (c₁ − c₂)²·(1 − φ)²] / (2·(1 − φ²)³) for v, w (a sum of
    positive terms: no cancellation when ts ≪ T).
    """
    if not (math.isfinite(tas_ms) and tas_ms > 0):
        raise ValueError(f"tas_ms must be finite and > 0, got {tas_ms!r}")
    if not (math.isfinite(ts) and ts > 0):
        raise ValueError(f"ts must be finite and > 0, got {ts!r}")
    T = params.scale_length_m / tas_ms
    phi = math.exp(-ts / T)
    u = DiscreteFilter(np.array([0.0, math.sqrt(1.0 - phi * phi)]), np.array([1.0, -phi]))
    h = (_DRYDEN_VW_ZERO - 1.0) * ts / T
    c1 = 1.0 - phi + h * phi
    c2 = phi * (phi - 1.0 - h)
    var_vw = (((c1 + c2) * (1.0 + phi)) ** 2 + ((c1 - c2) * (1.0 - phi)) ** 2) \
        / (2.0 * (1.0 - phi * phi) ** 3)
    g = 1.0 / math.sqrt(var_vw)
    vw = DiscreteFilter(np.array([0.0, g * c1, g * c2]), np.array([1.0, -2.0 * phi, phi * phi]))
    return DrydenFilters(u=u, vw=vw, time_constant_s=T)


def _stationary_state_factor(filt: DiscreteFilter) -> np.ndarray:
    """Square-root factor S (S·Sᵀ = P) of the stationary covariance P of ``lfilter``'s state.

    For a unit-variance filter of :func:`dryden_filters` (b[0] = 0, order 1 or 2) driven by
    unit white noise x. lfilter's state (transposed direct form II) is, with y[n] = z₀[n−1]:
    order 1: z₀[n] = y[n+1], P = [1]; order 2: z₀[n] = y[n+1], z₁[n] = b₂·x[n] − a₂·y[n], so
    P₀₀ = R₀ = 1, P₀₁ = b₁·b₂ − a₂·R₁, P₁₁ = b₂² + a₂², with the lag-1 autocorrelation
    R₁ = (b₁·b₂ − a₁)/(1 + a₂) (Yule–Walker equation of the ARMA recursion). Drawing
    ``zi = S @ N(0, I)`` starts the filter in its stationary distribution.
    """
    if filt.a.size == 2:
        return np.ones((1, 1))
    p01, l11 = _order2_state_factor(filt)
    return np.array([[1.0, 0.0], [p01, l11]])


def _order2_state_factor(filt: DiscreteFilter) -> tuple[float, float]:
    """(P₀₁, sqrt(P₁₁ − P₀₁²)) of an order-2 unit-variance filter (see above), as floats."""
    b, a = filt
    b1, b2, a1, a2 = float(b[1]), float(b[2]), float(a[1]), float(a[2])
    r1 = (b1 * b2 - a1) / (1.0 + a2)
    p01 = b1 * b2 - a2 * r1
    p11 = b2 * b2 + a2 * a2
    return p01, math.sqrt(max(p11 - p01 * p01, 0.0))


def _check_inputs(n_steps, alt_ft, rng) -> int:
    if isinstance(n_steps, bool) or int(n_steps) != n_steps or n_steps < 1:
        raise ValueError(f"n_steps must be a positive integer, got {n_steps!r}")
    if not math.isfinite(alt_ft):
        raise ValueError(f"alt_ft must be finite, got {alt_ft!r}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return int(n_steps)


def dryden_gusts(n_steps: int, ts: float, tas_ms: float, alt_ft: float,
                 rng: np.random.Generator, params: DrydenParams = MODERATE) -> np.ndarray:
    """Gust velocities along the body axes, shape (3, n_steps): u_g, v_g, w_g [m/s].

    Sample k is time k·ts; σ = ``params.sigma_ms(alt_ft)``; filters of
    :func:`dryden_filters` at ``tas_ms``, started in their stationary state. Random numbers
    come from ``rng`` in a fixed order (5 normals for the initial states of the u, v and w
    filters, then 3·n_steps driving normals), so the result is a deterministic function of
    the generator's state.
    """
    from scipy.signal import lfilter     # imported when first needed (0.7 s): not at start-up

    n_steps = _check_inputs(n_steps, alt_ft, rng)
    filters = dryden_filters(float(tas_ms), float(ts), params)
    z0 = rng.standard_normal(5)
    noise = rng.standard_normal((3, n_steps))
    gusts = np.empty((3, n_steps))
    gusts[0], _ = lfilter(filters.u.b, filters.u.a, noise[0],
                          zi=_stationary_state_factor(filters.u) @ z0[:1])
    zi_vw = z0[1:].reshape(2, 2) @ _stationary_state_factor(filters.vw).T  # a state per row
    gusts[1:], _ = lfilter(filters.vw.b, filters.vw.a, noise[1:], axis=-1, zi=zi_vw)
    gusts *= params.sigma_ms(alt_ft)
    return gusts


#: Gust components, in the row order of :func:`dryden_gusts`.
GUST_COMPONENTS: tuple[str, ...] = ("u", "v", "w")


def _lagged_initial_state(filt: DiscreteFilter, beta: float, gamma: float,
                          xi: np.ndarray) -> np.ndarray:
    """Stationary ``lfilter`` state of (forming filter) · β·z⁻¹/(1 − γ·z⁻¹), from normals ``xi``.

    Series states: the forming filter's (z₀, z₁) (z₁ absent for order 1) and the lag's w,
    with w⁺ = γ·w + β·z₀, z₀⁺ = −a₁·z₀ + z₁ + b₁·x, z₁⁺ = b₂·x − a₂·z₀. Their stationary
    covariance (P₀₀ = 1 and P₀₁ from :func:`_stationary_state_factor`) in closed form:

        q₀ = E[w·z₀] = β·(P₀₁ − a₁ − γ·a₂) / (1 + γ·a₁ + γ²·a₂)
        q₁ = E[w·z₁] = −a₂·(γ·q₀ + β)
        r  = E[w²]   = (2·γ·β·q₀ + β²) / (1 − γ²)

    A draw of (z₀, z₁, w) is mapped to the cascade's transposed-direct-form-II state by
    matching the next outputs of the free response: Y₀ = w, Y₁ = γ·Y₀ + β·z₀,
    Y₂ = γ·Y₁ + β·(z₁ − a₁·z₀); zc₀ = Y₀, zc₁ = Y₁ + A₁·Y₀, zc₂ = Y₂ + A₁·Y₁ + A₂·Y₀ with
    A the cascade's denominator (a)·(1 − γ·z⁻¹). Pure float arithmetic: this runs once per
    simulated run.
    """
    a = filt.a
    a1 = float(a[1])
    a2 = float(a[2]) if a.size > 2 else 0.0
    A1, A2 = a1 - gamma, a2 - gamma * a1
    if a.size > 2:
        p01, l11 = _order2_state_factor(filt)
    else:
        p01, l11 = 0.0, 0.0
    q0 = beta * (p01 - a1 - gamma * a2) / (1.0 + gamma * a1 + gamma * gamma * a2)
    r = (2.0 * gamma * beta * q0 + beta * beta) / (1.0 - gamma * gamma)
    z0 = xi[0]
    if a.size > 2:
        q1 = -a2 * (gamma * q0 + beta)
        l21 = (q1 - q0 * p01) / l11
        l22 = math.sqrt(max(r - q0 * q0 - l21 * l21, 0.0))
        z1 = p01 * xi[0] + l11 * xi[1]
        w = q0 * xi[0] + l21 * xi[1] + l22 * xi[2]
    else:
        z1 = 0.0
        w = q0 * xi[0] + math.sqrt(max(r - q0 * q0, 0.0)) * xi[1]
    y0 = w
    y1 = gamma * y0 + beta * z0
    y2 = gamma * y1 + beta * (z1 - a1 * z0)
    zc = [y0, y1 + A1 * y0, y2 + A1 * y1 + A2 * y0]
    return np.array(zc[:a.size])


def lagged_gust(n_steps: int, ts: float, tas_ms: float, alt_ft: float,
                rng: np.random.Generator, *, component: str = "w", lag_s: float = 0.0,
                params: DrydenParams = MODERATE, engine: str | None = None) -> np.ndarray:
    """One Dryden gust component [m/s] through a first-order lag 1/(1 + lag_s·s), (n_steps,).

    The response of a control law of bandwidth 1/lag_s to one gust component. The lag is
    discretised with a zero-order hold, β·z⁻¹/(1 − γ·z⁻¹) with γ = exp(−ts/lag_s),
    β = 1 − γ, and cascaded with the forming filter of :func:`dryden_filters` into one
    ``lfilter`` call, started in the cascade's stationary state
    (:func:`_lagged_initial_state`), so the response is stationary from the first sample.
    ``lag_s = 0`` gives the gust itself, with the statistics of the matching row of
    :func:`dryden_gusts` (not the same numbers: the draws differ). Random numbers: the
    initial-state normals (order of the cascade), then n_steps driving normals. *engine*:
    ``"compiled"`` draws and filters the driving normals in one call
    (:func:`scenarios.compiled.filtered_normals_1`), ``"numpy"`` with ``rng.standard_normal``
    and ``scipy.signal.lfilter``; the same values bit for bit. Default
    :func:`scenarios.compiled.current_engine`.
    """
    n_steps = _check_inputs(n_steps, alt_ft, rng)
    if component not in GUST_COMPONENTS:
        raise ValueError(
            f"unknown gust component {component!r}; allowed: {', '.join(GUST_COMPONENTS)}")
    if not (math.isfinite(lag_s) and lag_s >= 0):
        raise ValueError(f"lag_s must be finite and ≥ 0, got {lag_s!r}")
    filters = dryden_filters(float(tas_ms), float(ts), params)
    forming = filters.u if component == "u" else filters.vw
    sigma = params.sigma_ms(alt_ft)
    if lag_s == 0:
        factor = _stationary_state_factor(forming)
        zi = sigma * (factor @ rng.standard_normal(factor.shape[0]))
        b, a = sigma * forming.b, forming.a
    else:
        gamma = math.exp(-ts / lag_s)
        beta = 1.0 - gamma
        zi = sigma * _lagged_initial_state(forming, beta, gamma,
                                           rng.standard_normal(forming.a.size))
        m = forming.a.size
        b = np.zeros(m + 1)
        b[1:] = (sigma * beta) * forming.b                   # σ·b·β·z⁻¹
        a = np.zeros(m + 1)
        a[:m] = forming.a
        a[1:] -= gamma * forming.a                           # a·(1 − γ·z⁻¹)
    if resolve_engine(engine) == "compiled":
        gust = np.empty(n_steps)
        filtered_normals_1(rng, np.asarray(b, float), np.asarray(a, float),
                           np.array(zi, dtype=float), gust)
        return gust
    from scipy.signal import lfilter

    gust, _ = lfilter(b, a, rng.standard_normal(n_steps), zi=zi)
    return gust
