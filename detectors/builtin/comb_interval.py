"""The set-membership interval detector of [COMB] (Combastel, Thabet, Raïssi, Zolghadri,
Gucik): an interval predictor absorbs the imprecision of the servo-loop model, a dead-zone
residual keeps only what the interval cannot explain, and a threshold learned from the
variability of that residual (moving-average bounds λ_q) decides, after a first-order
residual filter.

Model ([COMB] eq. 3–4, 19)
--------------------------
The rod position follows the first-order LPV model

    x_{k+1} = g_k·x_k + (1 − g_k)·h_k·u_k,   g_k ∈ g_k^c ± g_k^r,   h_k ∈ h^c ± h^r,

with, at the *measured* flight point (``Signals.schedule``) and the *nominal* actuator
(``Signals.actuator``), the centre of eq. 19

    g_k^c = 1 − γ(u_k, y_k, θ)·T,   h^c = 1,

where γ = ẋ/(u − y) is the loop gain of the nominal servo-loop evaluated at the measured
position y ([COMB] eq. 1–2: "substituting y for x in γ"). γ is computed with the plant's own
rate law (:func:`scenarios.servo.rod_rate`, current sat(K·(u − y)), hinge load at y), so it
includes the current saturation the paper's eq. 2 leaves out. The radius of g is
g_k^r = min(κ1 + κ2·|u_k − x_k^c|, κ3) ([COMB] §4). Measurement y_k is the COM rod
acquisition by default (``sensor``); the FCC's one-period transport delay is not in the
model: the mismatch it creates during transients is covered by g^r (see ``kappa``).

Interval predictor ([COMB] Proposition 3)
-----------------------------------------
Centre (eq. 14) and radius (eq. 15)::

    x_{k+1}^c = g^c·x^c + (1 − g^c)·h^c·u
    x_{k+1}^r = (|g^c| + g^r)·x^r + g^r·|x^c − h^c·u| + (|1 − g^c| + g^r)·h^r·|u|

Reading implemented: the extracted text of eq. 15 shows "g_k^c |x_k^c − h_k^c u_k|" and
"h_k^r u_k"; the appendix proof gives x^r_{k+1} = |w_k|·1 with w_k = [g^c·x^r,
g^r·(x^c − h^c·u), g^r·x^r, (1 − g^c)·h^r·u, −g^r·h^r·u], i.e. the factor of |x^c − h^c·u|
is g^r (not g^c) and u enters through |u|. That is the form above (it reduces to a
guaranteed enclosure; with g^c in place of g^r the radius would not vanish in the LTI case).
Stability (eq. 17): |g^c| + g^r < 1, checked by :meth:`IntervalDetector.fit` over the flight
envelope (:func:`stability_margin`).

Residual, filter and threshold ([COMB] §3.1–3.3)
------------------------------------------------
* dead-zone residual (eq. 18): r_k = dz(y_k, x_k^c ± x_k^r);
* filter F_a (eq. 8–9 with b = 1 − a, c = 1): ε_k = a·ε_{k−1} + (1 − a)·r_k, ε_0 = r_0
  (the initial condition of Corollary 2's proof, μ_0 = λ_1);
* noise characterisation (eq. 6): λ_q = ς·max_k |r_{k/q}| over the learning set, q = 1…q̄,
  r_{k/q} the moving average of the q last residuals of one run; with
  ``threshold_method = "evt"`` the safety factor ς is instead calibrated
  (:mod:`detectors.calibrate`, docs/thresholds.md): λ_q = s·max(λ⁰_q, floor), λ⁰_q the
  learning maximum (ς = 1), and s the threshold, at ``target_fa_per_run``, of the per-run
  statistic max_q m_q/λ⁰_q (m_q the run's own max_k |r_{k/q}|), each learning run scaled by
  the profile learned without it (:func:`detectors.calibrate.leave_one_out_ratios`). Since
  |ε_k| ≤ τ_k whenever every |r_{k/q}| ≤ λ_q (eq. 10), a fault-free run then raises an alarm
  with probability ≤ ``target_fa_per_run`` in every variant;
* threshold: eq. 11 for k < q̄ (τ_k = τ_{k,k} with μ = λ_1), eq. 13 (constant) for k ≥ q̄,
  from eq. 10::

      τ_{k,r} = a^r·λ_1 + (1 − a)·( r·a^{r−1}·λ_r + Σ_{q=1}^{r−1} q·(a^{q−1} − a^q)·λ_q )

* decision: alarm from the first step with |ε_k| ≥ τ_k, latched ([COMB] §4 writes >; the
  two differ only at equality, and ≥ makes a run's margin, the largest |ε_k|/τ_k before
  onset, ≥ s exactly when it alarms at threshold × s). One detector variant per pole a
  (``"a=0.9"``); the normalised residual |ε_k|/τ_k is also the decision statistic.

Also learned and stored ([COMB] §3.1.1): the power-law bound λ_q ≤ α·q^γ + β (memory
compression; ``use_power_law`` makes the threshold use it) and the variability measure
v(u) = Σ_{q=2}^{q̄} (1 − λ_q/λ_1)/q² / (ζ(2) − 1), here truncated at q̄ (a lower bound of
the paper's infinite sum, in [0, 1)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios import compiled as kernels
from scenarios.params import ActuatorParams, param
from scenarios.servo import PlantArrays, authority_limits, plant_arrays, rod_rate
from scenarios.catalog import FAULT_TYPES
from scenarios.signals import Signals

from ..base import Capabilities, Coverage, Detection, Detector, decide
from ..calibrate import (THRESHOLD_PARAMS, calibrate_threshold, leave_one_out_ratios,
                        usable_classes)
from ..params import Param

#: Default residual-filter poles ([COMB] §4, Table 1).
DEFAULT_POLES: tuple[float, ...] = (0.6, 0.8, 0.9, 0.95, 0.99)

#: Measurements the detector can use as y_k [mm] (surface converted by x = r·sin δ).
SENSORS = ("rod_com", "rod_mon", "surface")


@dataclass(frozen=True)
class IntervalNumerics:
    """Numerical constants of the detector (not physical parameters)."""

    gain_eps_mm: float = param("mm", "numerical", "|u − y| below which γ is evaluated at "
                               "±this error (the limit ẋ/(u − y) as u − y → 0)")
    stability_grid_deflections: int = param("-", "numerical", "deflections per flight point "
                                            "of the eq. 17 check")
    stability_grid_errors: int = param("-", "numerical", "loop errors u − y per deflection "
                                       "of the eq. 17 check")


NUMERICS = IntervalNumerics(gain_eps_mm=1e-6, stability_grid_deflections=31,
                            stability_grid_errors=41)


# ----------------------------------------------------------------------------------------
# Equations (pure functions, vectorised; tested one by one)
# ----------------------------------------------------------------------------------------
def loop_gain(u_mm, y_mm, plant: PlantArrays, eps_mm: float = NUMERICS.gain_eps_mm):
    """γ(u, y, θ) = ẋ/(u − y) [1/s] of the nominal loop at the measured position y
    ([COMB] eq. 2 with y substituted for x; current sat(K·(u − y)) as in docs/physics.md §3)."""
    e = np.asarray(u_mm, float) - np.asarray(y_mm, float)
    e = np.where(np.abs(e) < eps_mm, np.where(e < 0.0, -eps_mm, eps_mm), e)
    i_mA = np.clip(plant.K * e, -plant.i_max, plant.i_max)
    return rod_rate(y_mm, i_mA, plant, True) / e


def g_center(u_mm, y_mm, plant: PlantArrays, ts: float):
    """g^c = 1 − γ(u, y, θ)·T ([COMB] eq. 19)."""
    return 1.0 - loop_gain(u_mm, y_mm, plant) * ts


def g_radius(u_mm, xc_mm, kappa):
    """g^r = min(κ1 + κ2·|u − x^c|, κ3) ([COMB] §4); κ2 in 1/mm."""
    k1, k2, k3 = kappa
    return np.minimum(k1 + k2 * np.abs(np.asarray(u_mm) - np.asarray(xc_mm)), k3)


def predictor_step(xc, xr, u, gc, gr, hc: float = 1.0, hr: float = 0.0):
    """One step of the interval predictor: ([COMB] eq. 14, eq. 15 as derived in the
    appendix proof, see the module docstring). Returns (x^c_{k+1}, x^r_{k+1})."""
    xc_next = gc * xc + (1.0 - gc) * hc * u
    xr_next = ((np.abs(gc) + gr) * xr + gr * np.abs(xc - hc * u)
               + (np.abs(1.0 - gc) + gr) * hr * np.abs(u))
    return xc_next, xr_next


def dead_zone(y, lower, upper):
    """Interval residual r = dz(y, [lower, upper]) ([COMB] eq. 18)."""
    return np.where(y > upper, y - upper, np.where(y < lower, y - lower, 0.0))


def moving_average_bounds(r: np.ndarray, q_max: int, safety: float) -> np.ndarray:
    """λ_q = ς·max_k |r_{k/q}|, q = 1…q_max ([COMB] eq. 6), over every run (row) of *r*.

    Moving averages are taken within a run only (windows never span two runs).
    Returns an array of length q_max (index q − 1).
    """
    # the largest of the per-run maxima: max over rows of (max_k |…|/q) = max_k,rows |…|/q
    return safety * moving_average_maxima(r, q_max).max(axis=0)


def moving_average_maxima(r: np.ndarray, q_max: int) -> np.ndarray:
    """max_k |r_{k/q}| of each run (row) of *r*, q = 1…q_max: shape (n_runs, q_max) [mm]
    (:func:`moving_average_bounds` before the maximum over runs and the safety factor)."""
    r = np.atleast_2d(np.asarray(r, float))
    T = r.shape[1]
    if q_max > T:
        raise ValueError(f"q_max = {q_max} exceeds the length of the learning runs "
                         f"({T} steps); lower q_max or use longer learning runs")
    c = np.concatenate([np.zeros((r.shape[0], 1)), np.cumsum(r, axis=1)], axis=1)
    out = np.empty((r.shape[0], q_max))
    finite = np.isfinite(c).all(axis=1)
    if kernels.current_engine() == "compiled" and finite.any():
        rows = np.flatnonzero(finite)
        part = np.empty((rows.size, q_max))
        _window_maxima(np.ascontiguousarray(c[rows]), part)
        out[rows] = part
        if finite.all():
            return out
        c = c[~finite]        # rows with ±inf or NaN: the reference below (NaN propagates)
    else:
        finite = np.zeros(r.shape[0], dtype=bool)
    for q in range(1, q_max + 1):
        out[~finite, q - 1] = np.max(np.abs(c[:, q:] - c[:, :-q]), axis=1) / q
    return out


def filter_threshold(lam: np.ndarray, a: float, r: int, mu: float | None = None) -> float:
    """τ_{k,r} of [COMB] eq. 10 with b = 1 − a, c = 1 (unit static gain), μ_{k−r} = *mu*
    (default λ_1, Corollary 2). ``lam[q − 1]`` = λ_q; 0 ≤ r ≤ len(lam)."""
    lam = np.asarray(lam, float)
    mu = lam[0] if mu is None else mu
    if r == 0:
        return float(mu)
    q = np.arange(1, r)
    tail = np.sum(q * (a ** (q - 1) - a ** q) * lam[:r - 1]) if r > 1 else 0.0
    return float(a ** r * mu + (1.0 - a) * (r * a ** (r - 1) * lam[r - 1] + tail))


def threshold_schedule(lam: np.ndarray, a: float) -> np.ndarray:
    """τ_k for k = 0…q̄: eq. 11 (k < q̄) then the constant of eq. 12/13 (index q̄)."""
    q_bar = len(lam)
    return np.array([filter_threshold(lam, a, k) for k in range(q_bar + 1)])


def power_law_bound(lam: np.ndarray) -> tuple[float, float, float]:
    """(α, γ, β) with α·q^γ + β ≥ λ_q for every q ([COMB] §3.1.1, memory compression).

    α, γ: least squares of log(λ_q − β0) on log q with β0 just below min λ_q; β then
    raised by the largest shortfall so the curve bounds every λ_q.
    """
    lam = np.asarray(lam, float)
    q = np.arange(1, len(lam) + 1, dtype=float)
    beta0 = 0.5 * float(lam.min())
    excess = np.maximum(lam - beta0, 1e-12 * max(float(lam.max()), 1e-300))
    gamma, log_alpha = np.polyfit(np.log(q), np.log(excess), 1)
    alpha = float(np.exp(log_alpha))
    fit = alpha * q ** gamma + beta0
    beta = beta0 + max(float(np.max(lam - fit)), 0.0)
    return alpha, float(gamma), beta


def variability(lam: np.ndarray) -> float:
    """v(u) = Σ_{q=2}^{q̄} (1 − λ_q/λ_1)/q² / (ζ(2) − 1) ([COMB] §3.1.1 remark, truncated
    at q̄); 0 for a signal without variability, < 1."""
    lam = np.asarray(lam, float)
    q = np.arange(1, len(lam) + 1, dtype=float)
    zeta2 = math.pi ** 2 / 6.0
    return float(np.sum((1.0 - lam / lam[0]) / q ** 2) / (zeta2 - 1.0))


def stability_margin(kappa, act: ActuatorParams, ts: float, max_error_mm: float,
                     points=None) -> tuple[float, dict]:
    """max(|g^c| + g^r) of [COMB] eq. 17 over the flight envelope, and where it occurs.

    Domain: every point of *points* (default: the [CHEN] Table-1 grid) × deflections
    within the authority of that point (:func:`scenarios.servo.authority_limits`) × loop
    errors |u − y| ≤ *max_error_mm*, with x^c = y. Eq. 17 holds when the value is < 1.
    """
    from scenarios import envelope

    pts = envelope.grid_points() if points is None else points
    fc = envelope.flight_condition(pts["alt_ft"].to_numpy(float), pts["vcas_kt"].to_numpy(float),
                                   pts["mass_t"].to_numpy(float), pts["cg_pct"].to_numpy(float))
    plant = plant_arrays(act, qbar_pa=fc["qbar_pa"], alpha_deg=fc["alpha_deg"], mach=fc["mach"])
    lo, hi = authority_limits(plant, act)
    nd, ne = NUMERICS.stability_grid_deflections, NUMERICS.stability_grid_errors
    frac = np.linspace(0.0, 1.0, nd)
    defl = lo[:, None] + (hi - lo)[:, None] * frac[None, :]                  # (P, D)
    y = act.deg_to_mm(defl)[:, :, None]                                         # (P, D, 1)
    err = np.linspace(-max_error_mm, max_error_mm, ne)[None, None, :]          # (1, 1, E)
    col = PlantArrays(**{k: np.asarray(v)[:, None, None] for k, v in vars(plant).items()})
    gc = g_center(y + err, y, col, ts)
    gr = g_radius(y + err, y, kappa)
    total = np.abs(gc) + gr
    p, d, e = np.unravel_index(int(np.argmax(total)), total.shape)
    where = {"alt_ft": float(pts["alt_ft"].iloc[p]), "vcas_kt": float(pts["vcas_kt"].iloc[p]),
             "deflection_deg": float(defl[p, d]), "error_mm": float(err[0, 0, e]),
             "g_c": float(gc[p, d, e]), "g_r": float(gr[p, d, e])}
    return float(total[p, d, e]), where


# ----------------------------------------------------------------------------------------
# Compiled recursions (numba; the NumPy code above and in IntervalDetector is the reference)
# ----------------------------------------------------------------------------------------
@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _predict_block(u, y, plant, ts, eps_mm, kappa, hr, x0_radius, xc_out, xr_out, r_out):
    """Interval predictor and residual of a batch of runs, compiled: per step g^c of
    [COMB] eq. 19 (:func:`g_center`, with the plant law of
    :func:`scenarios.compiled.loaded_rates`), g^r (:func:`g_radius`), eq. 14–15
    (:func:`predictor_step`, h^c = 1) and the dead-zone residual of eq. 18
    (:func:`dead_zone`), in the NumPy reference's order of operations.

    *u*, *y* (n, T) [mm]; *plant* the :func:`scenarios.compiled.plant_fields` of the runs;
    *kappa* (3,). Writes x^c, x^r [mm] into *xc_out*, *xr_out* when they are (n, T) (skipped
    when they are empty) and r [mm] into *r_out* when it is (n, T).

    SIMD-friendly form: blocks of :data:`scenarios.compiled.BLOCK` runs, steps outer; g^c
    reads the measurements only, so the rate law runs as one packed pass over the block
    (its asin calls apart), then the recursion as a branch-free loop over the block.
    """
    n, T = u.shape
    store_interval = xc_out.shape[0] == n and xc_out.shape[1] == T
    store_residual = r_out.shape[0] == n and r_out.shape[1] == T
    k1, k2, k3 = kappa[0], kappa[1], kappa[2]
    B = kernels.BLOCK
    xc_run = np.empty(B)
    xr_run = np.empty(B)
    yk = np.empty(B)
    ek = np.empty(B)
    ik = np.empty(B)
    rate = np.empty(B)
    s_buf = np.empty(B)
    a_buf = np.empty(B)
    for b0 in range(0, n, B):
        b = min(b0 + B, n) - b0
        for t in range(b):
            xc_run[t] = y[b0 + t, 0]
            xr_run[t] = x0_radius
        for k in range(T):
            # g^c = 1 − γ·T, γ = ẋ/(u − y) at the measured y (eq. 19, loop_gain)
            for t in range(b):
                r = b0 + t
                e = u[r, k] - y[r, k]
                e = (-eps_mm if e < 0.0 else eps_mm) if abs(e) < eps_mm else e
                yk[t] = y[r, k]
                ek[t] = e
                ik[t] = min(max(plant[kernels.P_K, r] * e, -plant[kernels.P_IMAX, r]),
                            plant[kernels.P_IMAX, r])
            kernels.loaded_rates(yk, ik, plant, b0, b, s_buf, a_buf, rate)
            for t in range(b):
                r = b0 + t
                uk = u[r, k]
                xc = xc_run[t]
                xr = xr_run[t]
                if store_interval:
                    xc_out[r, k] = xc
                    xr_out[r, k] = xr
                if store_residual:                   # eq. 18: dz(y, x^c ± x^r)
                    upper = xc + xr
                    lower = xc - xr
                    v = yk[t]
                    r_out[r, k] = (v - upper if v > upper else
                                   (v - lower if v < lower else 0.0))
                gc = 1.0 - rate[t] / ek[t] * ts
                # g^r = min(κ1 + κ2·|u − x^c|, κ3) (§4; NaN propagates as in np.minimum)
                gr = k1 + k2 * abs(uk - xc)
                gr = k3 if (not gr < k3 and gr == gr) else gr
                # eq. 14–15 (predictor_step with h^c = 1)
                xc_run[t] = gc * xc + (1.0 - gc) * 1.0 * uk
                xr_run[t] = ((abs(gc) + gr) * xr + gr * abs(xc - 1.0 * uk)
                             + (abs(1.0 - gc) + gr) * hr * abs(uk))


@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _decide_block(r, a, tau, norm_out, alarm_out):
    """Filter F_a, normalised residual and latched alarm of one pole, compiled
    ([COMB] eq. 8–9: ε_k = a·ε_{k−1} + (1 − a)·r_k, ε_0 = r_0; |ε_k|/τ_k with τ_k =
    ``tau[min(k, len(tau) − 1)]``; alarm from the first |ε_k| ≥ τ_k on: [COMB] §4 writes
    > τ, which differs only where |ε_k| = τ_k exactly, and ≥ makes the run's margin ≥ s
    exactly the alarm at threshold × s, :class:`detectors.base.Detection`).

    The filter update is written as ``scipy.signal.lfilter`` evaluates it for this
    first-order filter (state z = a·ε, output ε = z + (1 − a)·r), so both give the same
    bits. Writes *norm_out* (n, T) and *alarm_out* (n, T) bool.
    """
    n, T = r.shape
    b0 = 1.0 - a
    last = tau.shape[0] - 1
    for i in range(n):
        z = a * r[i, 0]                  # initial state so that ε_0 = r_0 (Corollary 2)
        latched = False
        for k in range(T):
            x = r[i, k]
            eps = z + b0 * x
            z = 0.0 * x - (-a) * eps
            v = abs(eps) / tau[min(k, last)]
            norm_out[i, k] = v
            if v >= 1.0:
                latched = True
            alarm_out[i, k] = latched


@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _window_maxima(c, out):
    """out[i, q − 1] = max_k |c[i, k + q] − c[i, k]| / q for q = 1 … out.shape[1]: the
    moving-average maxima of :func:`moving_average_maxima` from the running sums *c*
    (n, T + 1), compiled. Rows must be finite (the maximum of exact values is the same
    whatever the order they are compared in, so the bits are NumPy's). The window length
    is the inner loop, over contiguous memory and without branches (SIMD-friendly)."""
    n, T1 = c.shape
    q_max = out.shape[1]
    m = np.empty(q_max)
    for i in range(n):
        ci = c[i]
        for q in range(q_max):
            m[q] = -1.0
        for k in range(T1 - 1):
            top = min(q_max, T1 - 1 - k)
            base = ci[k]
            for q in range(top):
                d = abs(ci[k + 1 + q] - base)
                m[q] = d if d > m[q] else m[q]
        for q in range(q_max):
            out[i, q] = m[q] / (q + 1)


def _warm_kernels() -> None:
    """Compile (or load from the cache) the kernels of this module on tiny inputs."""
    z2 = np.zeros((1, 2))
    plant = np.ones((kernels.FIELD_ROWS, 1))
    plant[kernels.P_XMIN] = -1.0
    empty = np.zeros((0, 0))
    for z in (z2, kernels.read_only_view(z2)):    # signals as detect reads them: read-only
        _predict_block(z, z, plant, 0.01, 1e-6, np.ones(3), 0.0, 0.5, empty, empty,
                       np.zeros((1, 2)))
    _decide_block(z2, 0.5, np.ones(2), np.zeros((1, 2)), np.zeros((1, 2), dtype=np.bool_))
    _window_maxima(np.zeros((1, 3)), np.zeros((1, 2)))


kernels.register_warmup(_warm_kernels, kernels=(_predict_block, _decide_block,
                                                _window_maxima))


# ----------------------------------------------------------------------------------------
# The detector
# ----------------------------------------------------------------------------------------
class IntervalDetector(Detector):
    """Set-membership interval detector of [COMB] (see the module docstring).

    Parameters
    ----------
    poles : sequence of float
        Residual-filter poles a, 0 < a < 1; each is reported as its own variant
        ``"a=<pole>"`` ([COMB] Table 1: 0.6, 0.8, 0.9, 0.95, 0.99).
    safety : float
        Safety factor ς > 1 of the noise characterisation ([COMB] eq. 6; §4: 1.2).
    kappa : (κ1 [-], κ2 [1/mm], κ3 [-])
        g^r = min(κ1 + κ2·|u − x^c|, κ3) ([COMB] §4); positive, and eq. 17 must hold
        over the envelope (checked by ``fit``). Tuned (est.) to cover the nominal model's
        mismatch on this simulator: Kci/supply/hinge-moment/scheduling errors (≈ 10 % of
        γ·T ≈ 0.1–0.15) and the unmodelled FCC transport delay during transients.
    h_radius : float
        h^r ≥ 0, radius of the static gain h ∈ 1 ± h^r ([COMB] eq. 4; 0: the loop has no
        static error, §3.3).
    q_max : int
        q̄, longest moving-average window of λ_q [steps] (≥ 2).
    x0_radius_mm : float
        Radius x_0^r of the initial state around the first measurement [mm] (≥ 0).
    sensor : str
        Measurement y: ``"rod_com"`` (the loop's own acquisition, default), ``"rod_mon"``
        or ``"surface"`` (surface sensor converted by x = r·sin δ; [COMB] used it).
    use_power_law : bool
        Compute the threshold from the power-law bound α·q^γ + β instead of λ_q.
    floor_mm : float
        Smallest λ_q [mm] (guards against a learning set whose residual is all zero).
    threshold_method, target_fa_per_run, threshold_confidence, threshold_tail
        How thresholds are learned: calibrated to a per-run false-alarm target per
        manoeuvre (``"evt"``, the default) or ``safety`` × the largest learning value
        (``"max"``); :data:`detectors.calibrate.THRESHOLD_PARAMS`, docs/thresholds.md.
    """

    capabilities = Capabilities(needs_fit=True, needs_surface_sensor=False, causal=True,
                                fit_concurrently=True, threshold_scale=True)

    parameters = (
        Param("poles", "floats", gt=0.0, lt=1.0, unique=True, scalar=True,
              doc="residual-filter poles a, one variant \"a=<pole>\" each",
              source="[COMB] §4, Table 1"),
        Param("safety", "float", gt=1.0, doc="safety factor ς of the noise characterisation "
              "λ_q", source="[COMB] eq. 6, §4"),
        Param("kappa", "floats", length=3, gt=0.0, unit="-, 1/mm, -",
              doc="(κ1, κ2, κ3) of g^r = min(κ1 + κ2·|u − x^c|, κ3); fit checks eq. 17 over "
              "the envelope", source="[COMB] §4; values est."),
        Param("h_radius", "float", ge=0.0, doc="radius h^r of the static gain h ∈ 1 ± h^r "
              "(0: no static error)", source="[COMB] eq. 4, §3.3"),
        Param("q_max", "int", ge=2, unit="steps", doc="longest moving-average window q̄ of "
              "λ_q", source="[COMB] eq. 6; value est."),
        Param("x0_radius_mm", "float", ge=0.0, unit="mm", doc="radius x_0^r of the initial "
              "state around the first measurement"),
        Param("sensor", "choice", choices=SENSORS, doc="measurement y: COM or MON rod, or the "
              "surface sensor converted by x = r·sin δ", source="est.; [COMB] used the "
              "surface sensor"),
        Param("use_power_law", "bool", doc="threshold from the power-law bound α·q^γ + β "
              "instead of λ_q", source="[COMB] §3.1.1"),
        Param("floor_mm", "float", gt=0.0, unit="mm", doc="smallest λ_q (guards against an "
              "all-zero learning residual)"),
        *THRESHOLD_PARAMS,
    )

    def __init__(self, poles=DEFAULT_POLES, safety=1.2, kappa=(0.02, 0.02, 0.06),
                 h_radius=0.0, q_max=300, x0_radius_mm=0.5, sensor="rod_com",
                 use_power_law=False, floor_mm=1e-4, threshold_method="evt",
                 target_fa_per_run=1e-4, threshold_confidence=0.95,
                 threshold_tail="exponential"):
        self.poles = poles
        self.safety = safety
        self.kappa = kappa
        self.h_radius = h_radius
        self.q_max = q_max
        self.x0_radius_mm = x0_radius_mm
        self.sensor = sensor
        self.use_power_law = use_power_law
        self.floor_mm = floor_mm
        self.threshold_method = threshold_method
        self.target_fa_per_run = target_fa_per_run
        self.threshold_confidence = threshold_confidence
        self.threshold_tail = threshold_tail

    def _poles(self) -> tuple[float, ...]:
        if isinstance(self.poles, (int, float)):
            return (float(self.poles),)
        return tuple(float(a) for a in self.poles)

    def variant_names(self) -> tuple[str, ...]:
        """One variant per pole, ``"a=<pole>"``, in the order of ``poles``."""
        return tuple(self.variant_name(a) for a in self._poles())

    @staticmethod
    def variant_name(a: float) -> str:
        """Name of the variant of pole *a* (``"a=0.9"``)."""
        return f"a={a:g}"

    def coverage(self, variant: str | None = None) -> Coverage:
        """Every fault type on the surface sensor; on a rod sensor every one but the
        disconnection, which leaves the rod following its order (docs/physics.md §5:
        "rod signals look healthy"), so the residual of the rod never sees it
        (docs/interval-detector.md)."""
        if self.sensor == "surface":
            return Coverage(None, "")
        return Coverage(tuple(f for f in FAULT_TYPES if f != "disconnection"),
                        f"a disconnection leaves the {self.sensor} measurement following "
                        "its order (docs/physics.md §5), which the interval residual "
                        "reads ([COMB] §3, docs/interval-detector.md)")

    def check_signals(self, signals: Signals) -> None:
        super().check_signals(signals)
        if self.sensor == "surface" and not signals.has_surface_sensor:
            raise ValueError("IntervalDetector(sensor='surface') needs a surface position "
                             "sensor, but this surface has none (surface signal is NaN); use "
                             "sensor='rod_com' or 'rod_mon'")
        if signals.actuator is None:
            raise ValueError("IntervalDetector needs the nominal actuator parameters "
                             "(Signals.actuator is None)")

    # ---- the interval predictor and residual ------------------------------------------
    def measurement(self, signals: Signals) -> np.ndarray:
        """y_k [mm], shape (n_runs, n_steps)."""
        if self.sensor == "surface":
            return signals.actuator.deg_to_mm(signals.surface)
        return np.asarray(getattr(signals, self.sensor), float)

    def _plant(self, signals: Signals) -> PlantArrays:
        sch = signals.schedule
        return plant_arrays(signals.actuator, qbar_pa=sch["qbar_pa"],
                            alpha_deg=sch["alpha_deg"], mach=sch["mach"])

    def _compiled(self, signals: Signals, interval: bool, residual: bool):
        """(y, x^c, x^r, r) of :func:`_predict_block`; x^c, x^r (or r) are None when not
        asked for."""
        y = np.ascontiguousarray(self.measurement(signals), dtype=float)
        u = np.ascontiguousarray(signals.command, dtype=float)
        n, T = u.shape
        empty = np.zeros((0, 0))
        xc = np.empty((n, T)) if interval else empty
        xr = np.empty((n, T)) if interval else empty
        r = np.empty((n, T)) if residual else empty
        _predict_block(u, y, kernels.plant_fields(self._plant(signals)), float(signals.ts),
                       float(NUMERICS.gain_eps_mm),
                       np.array([float(k) for k in self.kappa]), float(self.h_radius),
                       float(self.x0_radius_mm), xc, xr, r)
        return (y, xc if interval else None, xr if interval else None,
                r if residual else None)

    def predict(self, signals: Signals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(y, x^c, x^r) [mm], each (n_runs, n_steps): the interval prediction x^c ± x^r of
        [COMB] eq. 14–15 at every step (time loop only; vectorised over runs). Compiled
        (:func:`_predict_block`) or the NumPy loop below, as
        :func:`scenarios.compiled.current_engine` says."""
        if kernels.current_engine() == "compiled":
            y, xc, xr, _ = self._compiled(signals, interval=True, residual=False)
            return y, xc, xr
        plant = self._plant(signals)
        y = self.measurement(signals)
        u = np.asarray(signals.command, float)
        n, T = u.shape
        # g^c depends on the measured (u_k, y_k) only, not on the recursion: all steps at once
        columns = PlantArrays(**{k: np.asarray(v)[:, None] for k, v in vars(plant).items()})
        gc_all = g_center(u, y, columns, signals.ts)
        xc_all = np.empty((n, T))
        xr_all = np.empty((n, T))
        xc = y[:, 0].copy()
        xr = np.full(n, float(self.x0_radius_mm))
        kappa = tuple(float(k) for k in self.kappa)
        hr = float(self.h_radius)
        for k in range(T):
            xc_all[:, k] = xc
            xr_all[:, k] = xr
            gr = g_radius(u[:, k], xc, kappa)
            xc, xr = predictor_step(xc, xr, u[:, k], gc_all[:, k], gr, 1.0, hr)
        return y, xc_all, xr_all

    def rate_evaluations_per_step(self) -> int:
        """Evaluations of the rate law (docs/physics.md §3) per run and step of ``detect``:
        the predictor's one, at the measured rod ([COMB] eq. 14; ``fdd-campaign bench``'s
        arithmetic floor)."""
        return 1

    def interval_residual(self, signals: Signals) -> np.ndarray:
        """r_k = dz(y_k, x_k^c ± x_k^r) [mm] ([COMB] eq. 18), shape (n_runs, n_steps)."""
        if kernels.current_engine() == "compiled":    # fused: no (n, T) x^c, x^r kept
            return self._compiled(signals, interval=False, residual=True)[3]
        y, xc, xr = self.predict(signals)
        return dead_zone(y, xc - xr, xc + xr)

    @staticmethod
    def filtered(r: np.ndarray, a: float) -> np.ndarray:
        """ε_k = a·ε_{k−1} + (1 − a)·r_k, ε_0 = r_0 ([COMB] eq. 8–9, unit static gain)."""
        from scipy.signal import lfilter

        r = np.asarray(r, float)
        # initial state chosen so that ε_0 = r_0 (Corollary 2: filter state starts in the
        # range of its input): ε_0 = a·ε_{−1} + (1 − a)·r_0 = r_0  ⇔  ε_{−1} = r_0
        zi = (a * r[:, :1])
        out, _ = lfilter([1.0 - a], [1.0, -a], r, axis=1, zi=zi)
        return out

    # ---- contract ----------------------------------------------------------------------
    def _fit(self, signals: Signals) -> None:
        r = self.interval_residual(signals)
        if signals.n_steps < self.q_max:
            raise ValueError(f"q_max = {self.q_max} steps is longer than the learning runs "
                             f"({signals.n_steps} steps); lower q_max or lengthen the "
                             "learning runs")
        max_error = float(np.max(np.abs(signals.command - self.measurement(signals))))
        margin, where = stability_margin(tuple(float(k) for k in self.kappa),
                                         signals.actuator, signals.ts, max_error)
        if not margin < 1.0:
            raise ValueError(
                f"kappa = {list(self.kappa)} violates the stability condition |g^c| + g^r < 1 "
                f"of [COMB] eq. 17 over the envelope: {margin:.4f} at altitude "
                f"{where['alt_ft']:g} ft, VCAS {where['vcas_kt']:g} kt, deflection "
                f"{where['deflection_deg']:.1f}°, loop error {where['error_mm']:.2f} mm "
                f"(g^c = {where['g_c']:.4f}, g^r = {where['g_r']:.4f}); fix: choose kappa so "
                f"that g^r = min(κ1 + κ2·|u − x^c|, κ3) stays below 1 − |g^c| = "
                f"{1.0 - abs(where['g_c']):.4f} there (κ3 below it is enough)")
        if self.threshold_method == "max":
            lam = np.maximum(moving_average_bounds(r, int(self.q_max), float(self.safety)),
                             float(self.floor_mm))
        else:
            lam = self._calibrated_bounds(r, signals.classes)
        alpha, gamma, beta = power_law_bound(lam)
        self.lambda_q_ = lam
        self.power_law_ = {"alpha": alpha, "gamma": gamma, "beta": beta}
        self.variability_ = variability(lam)
        self.stability_margin_ = margin
        self.max_loop_error_mm_ = max_error
        basis = self._threshold_basis()
        self.thresholds_ = {self.variant_name(a): threshold_schedule(basis, a)
                            for a in self._poles()}
        self.learning_runs_ = int(signals.n_runs)

    def _calibrated_bounds(self, r: np.ndarray, classes=None) -> np.ndarray:
        """λ_q = s·max(λ⁰_q, floor) with s calibrated (``threshold_method = "evt"``, module
        docstring); stores the calibration in ``calibration_``. When the learning set cannot
        support the target (``calibration_.supported`` False) λ_q is the ``"max"`` rule's."""
        floor = float(self.floor_mm)
        m = moving_average_maxima(r, int(self.q_max))
        profile = np.maximum(m.max(axis=0), floor)
        ratios = leave_one_out_ratios(m, floor)
        cal = calibrate_threshold(ratios, float(self.target_fa_per_run),
                                  float(self.threshold_confidence),
                                  fallback_factor=float(self.safety),
                                  tail=self.threshold_tail,
                                  classes=usable_classes(classes))
        self.calibration_ = cal
        if not cal.supported:       # the learning set cannot support the target: the max rule
            return np.maximum(moving_average_bounds(r, int(self.q_max), float(self.safety)),
                              floor)
        return np.maximum(cal.threshold * profile, floor)

    def _threshold_basis(self) -> np.ndarray:
        if self.use_power_law:
            q = np.arange(1, len(self.lambda_q_) + 1, dtype=float)
            p = self.power_law_
            return p["alpha"] * q ** p["gamma"] + p["beta"]
        return self.lambda_q_

    def _detect(self, signals: Signals) -> dict[str, Detection]:
        r = self.interval_residual(signals)
        T = signals.n_steps
        k = np.minimum(np.arange(T), int(self.q_max))
        compiled = kernels.current_engine() == "compiled"
        out = {}
        for a in self._poles():
            name = self.variant_name(a)
            if name not in self.thresholds_:
                raise ValueError(f"pole {a:g} has no learned threshold: the detector was "
                                 f"fitted with poles {sorted(self.thresholds_)}; fit again")
            if compiled:
                norm = np.empty(r.shape)
                alarm = np.empty(r.shape, dtype=bool)
                _decide_block(r, float(a), np.ascontiguousarray(self.thresholds_[name],
                                                                dtype=float), norm, alarm)
                out[name] = Detection(alarm=alarm, residual=norm, decision=norm)
                continue
            tau = self.thresholds_[name][k][None, :]
            norm = np.abs(self.filtered(r, a)) / tau
            # the decision is |ε_k|/τ_k itself (no confirmation): the alarm where it first
            # reaches 1 ([COMB] §4, ≥ for > as in _decide_block)
            out[name] = Detection(alarm=decide(norm), residual=norm, decision=norm)
        return out


kernels.invalidate_stale_cache(__name__)   # numba cache built from other kernel sources: flushed
