"""A generalised Pareto tail fitted once to a sample of per-run maxima (docs/thresholds.md,
docs/evidence.md).

Peaks over threshold: of *n* values, the k = :func:`tail_size` (n) largest are modelled as
u + Y, u the (k + 1)-th largest value and Y generalised Pareto (``scipy.stats.genpareto``,
shape ξ, scale σ), so that above u

    P(X > x) = (k/n)·(1 + ξ(x − u)/σ)^(−1/ξ)        (exp(−(x − u)/σ) at ξ = 0)

(Pickands–Balkema–de Haan; Coles, *An Introduction to Statistical Modeling of Extreme
Values*, 2001, eqs. 4.2 and 4.13). The share k/n is taken as known (k is fixed by the rule,
not estimated). The model is continuous above u, so a value equal to u is no exceedance:
when values tie across the cut (rounding, or an atom such as per-run maxima that are exactly
0 in most runs) the cut moves to the nearest gap between distinct values
(:func:`_cut_between_ties`), and fewer than :data:`MIN_EXCEEDANCES` above it is a
degenerate tail. Both uses of the fit go through one object, :class:`TailFit`:

* :meth:`TailFit.quantile` — the (1 − p)-quantile and the upper end of its one-sided
  profile-likelihood confidence interval (threshold calibration, :mod:`detectors.calibrate`);
* :meth:`TailFit.sf` — the exceedance probability P(X ≥ x) and the upper end of its
  one-sided profile-likelihood confidence interval;
* :func:`exceedance_curve` — P(X ≥ x) at several levels of a sample or of a mixture of
  classes (each class counted where its values reach x, else its own tail with ξ in
  :data:`CURVE_SHAPES`; the mixture of the class tails), for the false-alarm certificates
  of ``fdd-campaign certify`` (docs/evidence.md).

Profile likelihood (Coles 2001 §2.6.6 and §4.3.4): the quantity of interest replaces one
parameter (σ = t/h(a, ξ), h(a, ξ) = (a^ξ − 1)/ξ, with t the excess of the quantile over u
and a = 1/(conditional exceedance probability)); the log-likelihood is maximised over ξ in
:data:`SHAPE_RANGE` (a grid of step 0.005, ξ = 0 included) and the one-sided bound at
confidence c is where it falls z_c²/2 below its maximum (Wilks' theorem, χ²₁, z_c the
standard normal c-quantile). Deterministic: no random draw.

Why this k and this range of ξ: with the tens to hundreds of runs of a campaign a
mean-excess plot is too noisy to choose u automatically, so a fixed share (the top fifth)
with a floor of :data:`MIN_EXCEEDANCES` is used, a common compromise between the bias of a
low u and the variance of few exceedances; ξ ∈ [−0.5, 1] because the maximum-likelihood
estimator is regular above −0.5 and ξ ≥ 1 (an infinite mean) is not a residual's tail.

Assumptions: the values are independent draws from one distribution (exchangeable runs),
and its tail above u is generalised Pareto. The goodness-of-fit figure
(:attr:`TailFit.gof_pvalue`, Kolmogorov–Smirnov of the excesses against the fitted model)
is optimistic, the parameters coming from the same data: a small value rejects the model,
a large one does not prove it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from reports.scoring.metrics import upper_bound

__all__ = ["CURVE_SHAPES", "EXPONENTIAL_SHAPES", "Exceedance", "LIGHT_SHAPES",
           "MIN_DISTINCT_EXCESSES", "MIN_EXCEEDANCES", "MIN_TAIL_FIT_RUNS",
           "SHAPE_RANGE", "TAIL_KINDS",
           "TAIL_FRACTION", "TailEstimate", "TailFit", "TailFitError",
           "exceedance_curve", "fit_tail", "tail_size"]

#: Fewest values for the generalised Pareto tail fit.
MIN_TAIL_FIT_RUNS = 50
#: Fewest exceedances k of the tail fit.
MIN_EXCEEDANCES = 20
#: Share of the values in the fitted tail (k = max(MIN_EXCEEDANCES, ⌈0.2 n⌉)).
TAIL_FRACTION = 0.2
#: Fewest distinct positive excesses over u for the tail to be fitted at all.
MIN_DISTINCT_EXCESSES = 10
#: Range of the shape ξ of the fitted generalised Pareto distribution.
SHAPE_RANGE = (-0.5, 1.0)
#: ξ values over which the profile likelihood is maximised (step 0.005, ξ = 0 included).
SHAPES = np.linspace(SHAPE_RANGE[0], SHAPE_RANGE[1], 301)
#: ``tail = "light"``: ξ ≤ 0 (exponential or lighter: the Gumbel and Weibull domains).
LIGHT_SHAPES = SHAPES[SHAPES <= 0.0]
#: ξ grid of the tail fits of :func:`exceedance_curve` (the certificate's exceedance curve):
#: ξ ∈ [0, 1], no finite end point. A margin driven by Gaussian sensor noise has none (its
#: maximum is in the Gumbel domain, ξ = 0), and the ξ < 0 that a fit to its top fifth
#: prefers is pre-asymptotic: it puts an end point where brute force finds runs beyond
#: (docs/evidence.md, "Choosing the method"). ξ = 0 is the lightest tail the bound allows.
CURVE_SHAPES = SHAPES[SHAPES >= 0.0]
#: ``tail = "exponential"``: ξ = 0, the Gumbel domain's tail, the lightest with no end point.
EXPONENTIAL_SHAPES = SHAPES[SHAPES == 0.0]
#: What :func:`fit_tail` may assume of the tail: ``"free"`` (ξ in :data:`SHAPE_RANGE`),
#: ``"light"`` (ξ ≤ 0), ``"auto"`` (light unless a likelihood-ratio test rejects ξ ≤ 0),
#: ``"exponential"`` (ξ = 0).
TAIL_KINDS = ("free", "light", "auto", "exponential")


class TailFitError(ValueError):
    """The values cannot support a tail fit (too few, or a degenerate tail); the message
    says why."""


def tail_size(n: int) -> int:
    """k = max(:data:`MIN_EXCEEDANCES`, ⌈:data:`TAIL_FRACTION`·n⌉): the values in the
    fitted tail."""
    return max(MIN_EXCEEDANCES, math.ceil(TAIL_FRACTION * int(n) - 1e-9))


@dataclass(frozen=True)
class TailEstimate:
    """One quantity of a tail fit with its one-sided profile-likelihood bound.

    estimate : the maximum-likelihood value (a quantile in the values' unit, or a
        probability)
    upper : the upper end of the one-sided interval at *confidence*
    confidence : the confidence of *upper*
    shape, scale : ξ and σ (values' unit) at the maximum of this profile
    gof_pvalue : Kolmogorov–Smirnov p-value of the excesses against the model at
        (shape, scale) (indicative only, see the module docstring)
    """

    estimate: float
    upper: float
    confidence: float
    shape: float
    scale: float
    gof_pvalue: float = math.nan


def _h(a: float, xi: np.ndarray) -> np.ndarray:
    """(a^ξ − 1)/ξ (log a at ξ = 0): the (1 − p)-quantile's excess over u in units of σ,
    a = (k/n)/p."""
    xi = np.asarray(xi, float)
    safe = np.where(xi == 0.0, 1.0, xi)
    return np.where(xi == 0.0, math.log(a), np.expm1(safe * math.log(a)) / safe)


#: Largest number of (parameter pair × excess) terms one evaluation of the log-likelihood
#: holds at once (16 MB of float64): more parameter pairs are taken a block at a time.
LOGLIK_TERMS = 2_000_000


def _loglik(y: np.ndarray, sigma: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Generalised Pareto log-likelihood of the excesses *y* (k,) for parameters broadcast
    together (−inf outside the support; Coles 2001 eq. 4.10), at most
    :data:`LOGLIK_TERMS` terms at a time (each pair's value does not depend on the block it
    is computed in)."""
    sigma, xi = np.broadcast_arrays(np.asarray(sigma, float), np.asarray(xi, float))
    per = max(1, LOGLIK_TERMS // max(y.size, 1))
    if sigma.size <= per:
        return _loglik_block(y, sigma, xi)
    s, x = sigma.ravel(), xi.ravel()
    return np.concatenate([_loglik_block(y, s[i:i + per], x[i:i + per])
                           for i in range(0, s.size, per)]).reshape(sigma.shape)


def _loglik_block(y: np.ndarray, sigma: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """:func:`_loglik` of one block of parameter pairs (*sigma*, *xi* of one shape).

    One (…, k) array is made and transformed in place (y/σ, then ξ·y/σ, then its log1p)
    instead of a new array at each step: the profiles evaluate it on millions of
    (σ, ξ, y) triples. Whether a parameter pair holds every excess in the support
    (ξ·y/σ > −1 for all y) is decided at the smallest and the largest excess, where
    ξ·(y/σ), monotone in y, takes its extremes, with the same operations; outside the
    support the sum is not used (−inf is returned), so its log1p may be NaN there. The
    values are those of the elementwise form, to the bit."""
    zero = xi == 0.0
    safe = np.where(zero, 1.0, xi)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = y / sigma[..., None]                         # excesses in units of σ
        z *= safe[..., None]                             # ξ·y/σ (y/σ itself where ξ = 0)
        inside = sigma > 0.0
        if y.size:
            inside &= (safe * (y.min() / sigma) > -1.0) & (safe * (y.max() / sigma) > -1.0)
        q_sum = z[zero].sum(axis=-1)                     # ξ = 0: Σ y/σ
        np.log1p(z, out=z)
        tail = np.asarray((1.0 + 1.0 / safe) * z.sum(axis=-1))
        tail[zero] = q_sum
        ll = -y.size * np.log(sigma) - tail
    return np.where(inside, ll, -np.inf)


def _profile(y: np.ndarray, a: float, t, shapes: np.ndarray = SHAPES,
             ) -> tuple[np.ndarray, np.ndarray]:
    """Profile log-likelihood of the quantile excess *t* (maximised over ξ in *shapes*,
    σ = t/h(ξ)) and the maximising ξ, for each value of *t*."""
    t = np.atleast_1d(np.asarray(t, float))
    h = _h(a, shapes)
    out, arg = np.empty(t.size), np.empty(t.size)
    step = max(1, LOGLIK_TERMS // (shapes.size * y.size))
    for s in range(0, t.size, step):
        ll = _loglik(y, t[s:s + step, None] / h[None, :], shapes[None, :])
        j = np.argmax(ll, axis=1)
        out[s:s + step] = ll[np.arange(ll.shape[0]), j]
        arg[s:s + step] = shapes[j]
    return out, arg


def _profile_rate(y: np.ndarray, t: float, s, shapes: np.ndarray = SHAPES) -> np.ndarray:
    """Profile log-likelihood of s = −log q, q = P(Y > t | Y > 0) the conditional
    exceedance probability of the excess *t* (> 0), for each value of *s* (> 0):
    σ = t/h(e^s, ξ), maximised over ξ."""
    s = np.atleast_1d(np.asarray(s, float))
    out = np.empty(s.size)
    step = max(1, LOGLIK_TERMS // (shapes.size * y.size))
    xi = shapes[None, :]
    safe = np.where(xi == 0.0, 1.0, xi)
    for i in range(0, s.size, step):
        si = s[i:i + step, None]
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            h = np.where(xi == 0.0, si, np.expm1(safe * si) / safe)
            ll = _loglik(y, t / h, np.broadcast_to(xi, h.shape))
        out[i:i + step] = ll.max(axis=1)
    return out


def _profile_maximum(y: np.ndarray, a: float, shapes: np.ndarray = SHAPES):
    """(maximum, its t, the log grid of t, the profile on it) of the quantile profile for
    a = (k/n)/p: the profile on a wide log grid of t, its maximum refined."""
    from scipy.optimize import minimize_scalar

    t0 = math.log(a)                              # the exponential tail's quantile (ξ = 0)
    grid = t0 * np.logspace(-2.0, 4.0, 61)
    prof, _ = _profile(y, a, grid, shapes)
    i = int(np.argmax(prof))
    lo, hi = math.log(grid[max(i - 1, 0)]), math.log(grid[min(i + 1, grid.size - 1)])
    best = minimize_scalar(lambda s: -_profile(y, a, math.exp(s), shapes)[0][0], bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-10})
    ll_max, t_hat = max((float(prof[i]), float(grid[i])), (-float(best.fun), math.exp(best.x)))
    return ll_max, t_hat, grid, prof


def _ks(y: np.ndarray, xi: float, sigma: float) -> float:
    """Kolmogorov–Smirnov p-value of the excesses *y* against GPD(ξ, σ) (same unit)."""
    from scipy.stats import genpareto, kstest

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # the distribution's own cdf with the parameters, not a frozen distribution: the
        # same values without building one (0.3 ms, 18 tail fits in a monitor's fit)
        return float(kstest(y, lambda x: genpareto.cdf(x, xi, scale=sigma)).pvalue)


def fit_tail(values, k: int | None = None, tail: str = "free",
             confidence: float = 0.95, shapes: np.ndarray | None = None) -> TailFit:
    """Fit the generalised Pareto tail of *values* (module docstring).

    Parameters
    ----------
    values : array_like (n,)
        Finite values (e.g. per-run maxima), n ≥ :data:`MIN_TAIL_FIT_RUNS`.
    k : int, optional
        Exceedances to fit (default :func:`tail_size` (n)); 2 ≤ k < n.
    tail : str
        What the shape may be (:data:`TAIL_KINDS`): ``"free"``, ξ in :data:`SHAPE_RANGE`;
        ``"light"``, ξ ≤ 0 — an exponential or lighter tail, the domain of attraction of a
        maximum of Gaussian noise (Gumbel) or of a bounded quantity (Weibull), which is what a
        residual driven by sensor noise and bounded parameter draws is; ``"auto"``, light
        unless the likelihood-ratio test of ξ ≤ 0 against the free fit rejects it at level
        1 − *confidence* (2·Δ log-likelihood > z²_confidence, the one-sided boundary test of
        Self & Liang 1987), in which case the free fit is used (:attr:`TailFit.tail` says
        which). With ``"light"`` and ``"auto"``, :attr:`TailFit.light_rejected` says whether
        the test rejected ξ ≤ 0 (``"light"`` keeps it and reports it). ``"exponential"``,
        ξ = 0: the tail of the Gumbel domain itself, with no end point. The ξ < 0 that a
        light fit of a few tens of exceedances prefers is pre-asymptotic for a maximum of
        Gaussian noise (its tail approaches the exponential from below) and puts an end point
        where brute force finds runs beyond (docs/thresholds.md, "Which tail"); ξ = 0 is
        conservative for every tail in the light domain and, like "light", wrong for a heavy
        one (ξ > 0): the likelihood-ratio test of ξ ≤ 0 is run and reported
        (:attr:`TailFit.light_rejected`).
    confidence : float
        ``"auto"``: the test's confidence (default 0.95).
    shapes : array_like, optional
        ``"free"``: the ξ grid (default :data:`SHAPES`), e.g. :data:`CURVE_SHAPES`.

    Raises
    ------
    TailFitError
        Fewer than :data:`MIN_TAIL_FIT_RUNS` values, non-finite values, or a degenerate
        tail (fewer than :data:`MIN_DISTINCT_EXCESSES` distinct values above u).
    """
    x = np.asarray(values, dtype=float).ravel()
    if not np.isfinite(x).all():
        raise TailFitError(f"{int((~np.isfinite(x)).sum())} non-finite value(s); drop them "
                           "before fitting the tail")
    n = int(x.size)
    if n < MIN_TAIL_FIT_RUNS:
        raise TailFitError(f"{n} values: fewer than the {MIN_TAIL_FIT_RUNS} the tail fit "
                           "needs")
    k = tail_size(n) if k is None else int(k)
    if not 2 <= k < n:
        raise TailFitError(f"k = {k}: the exceedances must be 2 ≤ k < n = {n}")
    desc = np.sort(x)[::-1]
    u = float(desc[k])
    if desc[k - 1] == u:
        k, u = _cut_between_ties(desc, k)
    y_raw = desc[:k] - u
    positive = y_raw[y_raw > 0.0]
    if np.unique(positive).size < MIN_DISTINCT_EXCESSES:
        raise TailFitError(f"the tail is degenerate: {np.unique(positive).size} distinct "
                           f"value(s) above u = {u:g} among the top {k} (fewer than "
                           f"{MIN_DISTINCT_EXCESSES})")
    if tail not in TAIL_KINDS:
        raise ValueError(f"tail = {tail!r}: not one of {', '.join(TAIL_KINDS)}")
    unit = float(y_raw.mean())                    # work in units of the mean excess
    y = y_raw / unit
    a = math.e                                    # any quantile: the maximum is the MLE
    fits = {}
    free = SHAPES if shapes is None else np.asarray(shapes, float)
    # the fit asked for, and the free and light fits the test of ξ ≤ 0 compares
    needed = {"free"} if tail == "free" else {"free", "light", tail}
    for kind, shapes in (("free", free), ("light", LIGHT_SHAPES),
                         ("exponential", EXPONENTIAL_SHAPES)):
        if kind not in needed:
            continue
        ll, t_hat, _, _ = _profile_maximum(y, a, shapes)
        fits[kind] = (ll, t_hat, float(_profile(y, a, t_hat, shapes)[1][0]), shapes)
    rejected = None
    if tail != "free":               # the test is reported with "light", acted on with "auto"
        from scipy.stats import norm

        rejected = bool(2.0 * (fits["free"][0] - fits["light"][0])
                        > float(norm.ppf(confidence)) ** 2)
        if tail == "auto":
            tail = "free" if rejected else "light"
    _, t_hat, xi_hat, shapes = fits[tail]
    sigma_hat = float(t_hat / _h(a, xi_hat))
    return TailFit(n=n, k=k, u=u, shape=xi_hat, scale=sigma_hat * unit,
                   gof_pvalue=_ks(y, xi_hat, sigma_hat), largest=float(desc[0]), unit=unit,
                   excesses=y, tail=tail, light_rejected=rejected, shapes=shapes)


def _cut_between_ties(desc: np.ndarray, k: int) -> tuple[int, float]:
    """(k, u) when values tie across the cut (``desc[k - 1] == desc[k]``, *desc* sorted
    largest first): the model is continuous above u, so a value equal to u is not an
    exceedance. The cut moves to the gap nearest the rule's *k*, just above the tied group
    or just below it (then u is the next smaller value; not when the group holds the
    smallest value), the larger k on a draw: rounding ties (a residual quantised by its
    sensor) move it by a value or two; an atom (runs whose statistic never left 0) leaves
    the values above it. Fewer than :data:`MIN_EXCEEDANCES` is a degenerate tail."""
    n, tie = desc.size, desc[k]
    above, through = int(np.count_nonzero(desc > tie)), int(np.count_nonzero(desc >= tie))
    cuts = [above] + ([through] if through < n else [])
    k = min(cuts, key=lambda c: (abs(c - k), -c))
    if k < MIN_EXCEEDANCES:
        raise TailFitError(f"the tail is degenerate: {k} value(s) above the atom at "
                           f"u = {tie:g} (fewer than {MIN_EXCEEDANCES}); {through - above} "
                           f"of {n} values equal u")
    return k, float(desc[k])


@dataclass(frozen=True, eq=False)
class TailFit:
    """A generalised Pareto tail fitted to *n* values (module docstring: model, rule for k,
    profile likelihood, assumptions). Made by :func:`fit_tail`.

    n : values fitted
    k : exceedances (the values above u)
    u : tail threshold, the (k + 1)-th largest value (values' unit)
    shape, scale : maximum-likelihood ξ (in :data:`SHAPE_RANGE`) and σ (values' unit)
    gof_pvalue : Kolmogorov–Smirnov p-value of the excesses against the fitted model
        (indicative only: optimistic, the parameters come from the same data)
    largest : the largest value
    """

    n: int
    k: int
    u: float
    shape: float
    scale: float
    gof_pvalue: float
    largest: float
    unit: float = field(repr=False)                 # mean excess: the working unit
    excesses: np.ndarray = field(repr=False)        # the k excesses over u, in units of unit
    tail: str = "free"                              # the shape range fitted (TAIL_KINDS)
    light_rejected: bool | None = None              # not free: whether ξ ≤ 0 was rejected
    shapes: np.ndarray = field(repr=False, default_factory=lambda: SHAPES)  # its ξ grid

    # ---- quantiles ---------------------------------------------------------------------
    def quantile(self, p: float, confidence: float = 0.95) -> TailEstimate:
        """The (1 − p)-quantile of the values (P(X > x) = p) and the upper end of its
        one-sided profile-likelihood interval at *confidence*; p must be in (0, k/n).

        Raises :class:`TailFitError` when the profile does not fall below its level within
        10⁴ × the estimate (a tail too heavy to bound)."""
        from scipy.optimize import brentq
        from scipy.stats import genpareto, norm

        n, k, u, unit, y = self.n, self.k, self.u, self.unit, self.excesses
        if not 0.0 < p < k / n:
            raise ValueError(f"p = {p!r}: outside the fitted tail (0, k/n = {k / n:g}); "
                             "a quantile below u is an empirical one")
        a = (k / n) / p
        shapes = self.shapes
        ll_max, t_hat, grid, prof = _profile_maximum(y, a, shapes)
        _, xi_hat = _profile(y, a, t_hat, shapes)
        xi_hat = float(xi_hat[0])
        sigma_hat = float(t_hat / _h(a, xi_hat))
        level = ll_max - 0.5 * float(norm.ppf(confidence)) ** 2   # one-sided: χ²₁(2c − 1)/2
        above = np.flatnonzero((grid > t_hat) & (prof < level))
        if above.size == 0:
            raise TailFitError(f"the profile likelihood of the quantile does not fall below "
                               f"its {confidence:g} level within 10⁴ × the estimate (the "
                               "tail is too heavy to bound)")
        j = int(above[0])
        left = max(math.log(t_hat), math.log(grid[j - 1])) if j > 0 else math.log(t_hat)
        s_up = brentq(lambda s: _profile(y, a, math.exp(s), shapes)[0][0] - level, left,
                      math.log(grid[j]), xtol=1e-12, rtol=1e-12)
        tau_up = u + unit * math.exp(s_up)
        tau_hat = u + unit * float(genpareto.isf(p * n / k, xi_hat, scale=sigma_hat))
        return TailEstimate(estimate=float(tau_hat), upper=float(tau_up),
                            confidence=float(confidence), shape=xi_hat,
                            scale=sigma_hat * unit, gof_pvalue=_ks(y, xi_hat, sigma_hat))

    # ---- exceedance probabilities ------------------------------------------------------
    def sf(self, x: float, confidence: float = 0.95) -> TailEstimate:
        """P(X ≥ x) and the upper end of its one-sided profile-likelihood interval at
        *confidence*.

        *x* must be above u: (k/n)·q with q = P(Y > x − u) of the fitted tail, its bound
        (k/n)·q_up with q_up the largest q whose profile log-likelihood is within z²/2 of
        the maximum (k/n taken as known; q_up ≤ 1). At or below u the tail model does not
        apply (ValueError): count the values instead.
        """
        from scipy.optimize import brentq, minimize_scalar
        from scipy.stats import norm

        n, k, u, unit, y = self.n, self.k, self.u, self.unit, self.excesses
        x = float(x)
        if not x > u:
            raise ValueError(f"x = {x:g} is not above the tail threshold u = {u:g}: the "
                             "tail model does not apply there; use the empirical share")
        t = (x - u) / unit
        grid = np.logspace(-6.0, 4.0, 201)            # s = −log q
        shapes = self.shapes
        prof = _profile_rate(y, t, grid, shapes)
        i = int(np.argmax(prof))
        lo, hi = math.log(grid[max(i - 1, 0)]), math.log(grid[min(i + 1, grid.size - 1)])
        best = minimize_scalar(lambda v: -_profile_rate(y, t, math.exp(v), shapes)[0],
                               bounds=(lo, hi),
                               method="bounded", options={"xatol": 1e-10})
        ll_max, s_hat = max((float(prof[i]), float(grid[i])),
                            (-float(best.fun), math.exp(best.x)))
        level = ll_max - 0.5 * float(norm.ppf(confidence)) ** 2
        below = np.flatnonzero((grid < s_hat) & (prof < level))
        if below.size == 0:                           # not bounded away from q = 1
            s_up = float(grid[0])
        else:
            j = int(below[-1])
            right = min(math.log(s_hat), math.log(grid[j + 1]))
            s_up = math.exp(brentq(lambda v: _profile_rate(y, t, math.exp(v), shapes)[0] - level,
                                   math.log(grid[j]), right, xtol=1e-12, rtol=1e-12))
        xi_hat, sigma_hat = self._at_rate(t, s_hat)
        return TailEstimate(estimate=float(k / n * math.exp(-s_hat)),
                            upper=float(k / n * math.exp(-s_up)),
                            confidence=float(confidence), shape=xi_hat, scale=sigma_hat * unit,
                            gof_pvalue=_ks(y, xi_hat, sigma_hat))

    def _at_rate(self, t: float, s: float) -> tuple[float, float]:
        """(ξ, σ in working units) maximising the likelihood with σ tied to s = −log q."""
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            shapes = self.shapes
            h = _h(math.exp(s), shapes) if s < 700 else np.full(shapes.size, np.inf)
            ll = _loglik(self.excesses, t / h, shapes)
        j = int(np.argmax(ll))
        return float(shapes[j]), float(t / h[j])

    # ---- diagnostics -------------------------------------------------------------------
    def diagnostics(self) -> dict:
        """k, u, ξ, σ, the goodness-of-fit p-value, n and the largest value (for tables)."""
        return {"k": self.k, "u": self.u, "shape": self.shape, "scale": self.scale,
                "gof_pvalue": self.gof_pvalue, "n": self.n, "largest": self.largest,
                "tail": self.tail}

    def model_sf(self, x) -> np.ndarray:
        """P(X > x) of the fitted model at the maximum-likelihood (ξ, σ): (k/n)·(1 +
        ξ(x − u)/σ)^(−1/ξ) above u (NaN at or below u)."""
        from scipy.stats import genpareto

        x = np.asarray(x, float)
        out = (self.k / self.n) * genpareto.sf(x - self.u, self.shape, scale=self.scale)
        return np.where(x > self.u, out, np.nan)

    def tail_values(self) -> np.ndarray:
        """The k exceedances over u (values' unit), largest first."""
        return self.excesses * self.unit


# ---- exceedance curves: counted where the data reach, a mixture of class tails beyond --------
@dataclass(frozen=True)
class Exceedance:
    """P(X ≥ level) of a sample, possibly a mixture of classes, with its one-sided upper
    bound (made by :func:`exceedance_curve`).

    level : the level x (values' unit)
    estimate, upper : the estimate and the upper end of its one-sided interval at
        *confidence*
    confidence : the confidence of *upper*
    method : ``"counted"`` (the share of values ≥ x, exact Clopper–Pearson bound),
        ``"tail"`` (one generalised Pareto tail) or ``"mixture"`` (Σ_c w_c · the class's
        own counted or tail estimate)
    count, n : values ≥ x, values
    parts : per class (class, method, estimate, upper, weight); empty for one sample
    """

    level: float
    estimate: float
    upper: float
    confidence: float
    method: str
    count: int
    n: int
    parts: tuple = ()


def _one_curve(x: np.ndarray, levels: np.ndarray, confidence: float, shapes: np.ndarray,
               ) -> list[tuple[str, float, float]]:
    """(method, estimate, upper) of P(X ≥ level) of one sample at each level: counted at
    or below the tail threshold u (or when no tail can be fitted), the tail fit's
    :meth:`TailFit.sf` above it."""
    n = x.size
    try:
        fit = fit_tail(x, shapes=shapes)
    except TailFitError:
        fit = None
    out = []
    for level in levels:
        if fit is None or level <= fit.u:
            c = int((x >= level).sum())
            out.append(("counted", c / n, float(upper_bound(c, n, confidence))))
        else:
            est = fit.sf(level, confidence)
            out.append(("tail", est.estimate, est.upper))
    return out


def exceedance_curve(values, levels, *, classes=None, confidence: float = 0.95,
                     shapes: np.ndarray | None = None, jobs: int = 1) -> list[Exceedance]:
    """P(X ≥ x) at each of *levels* with its one-sided upper bound at *confidence*.

    Without *classes*: the values are one sample; at or below the tail threshold u of
    :func:`fit_tail` (or when the tail cannot be fitted) the probability is counted (the
    share of values ≥ x, exact Clopper–Pearson bound), above u it is the fitted tail's
    :meth:`TailFit.sf`.

    With *classes* (one label per value, e.g. the manoeuvre of each run): the values are a
    mixture, and the tail of a mixture is the mixture of its classes' tails,
    P(X ≥ x) = Σ_c w_c P(X ≥ x | c), w_c the share of class c among the values (the run
    distribution's weights when the runs are drawn with them). Each class is treated as one
    sample (above), the estimate is Σ w_c p̂_c and the bound Σ w_c p_c,up. The sum holds
    whenever every class's bound holds, so its confidence is at least 1 − m(1 − c) for m
    classes (union bound), and in practice that of the class whose term dominates the sum
    (the others' bounds are themselves conservative). The pooled counted bound is valid
    for the mixture too, so the returned bound is the smaller of the two (``method =
    "counted"`` when the pooled count is the smaller), which costs at most another 1 − c.
    Measured on brute force: about 99.5 % coverage at c = 0.95 (docs/evidence.md).

    *shapes*: the ξ grid of the tail fits (default :data:`CURVE_SHAPES`). *jobs* > 1 fits
    the classes on that many threads (the profiles' array arithmetic runs outside the GIL);
    each class's curve is the same whichever thread computes it.
    """
    x = np.asarray(values, dtype=float).ravel()
    lv = np.asarray(levels, dtype=float).ravel()
    shapes = CURVE_SHAPES if shapes is None else np.asarray(shapes, float)
    n = x.size
    counts = [int((x >= v).sum()) for v in lv]
    if classes is None:
        return [Exceedance(float(v), p, up, float(confidence), m, c, n)
                for v, c, (m, p, up) in zip(lv, counts, _one_curve(x, lv, confidence, shapes))]
    labels = np.asarray(classes).ravel()
    if labels.shape != x.shape:
        raise ValueError(f"classes has {labels.size} entries for {x.size} values; give one "
                         "class per value")
    # the classes named as str and sorted (those of np.unique of the labels as str), each
    # value's class found by hashing the labels: no str copy of every label is made
    codes, uniques = pd.factorize(labels, use_na_sentinel=False)
    names, which = np.unique(np.asarray(uniques).astype(str), return_inverse=True)
    cls = which.ravel()[codes]
    weights = np.bincount(cls, minlength=names.size) / n

    def curve(j):
        return _one_curve(x[cls == j], lv, confidence, shapes)

    if jobs > 1 and names.size > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(min(int(jobs), names.size)) as pool:
            per_class = list(pool.map(curve, range(names.size)))
    else:
        per_class = [curve(j) for j in range(names.size)]
    pooled = [float(upper_bound(c, n, confidence)) for c in counts]
    out = []
    for i, v in enumerate(lv):
        parts = tuple((str(c), pc[i][0], pc[i][1], pc[i][2], float(w))
                      for c, w, pc in zip(names, weights, per_class))
        est = float(sum(w * p for _, _, p, _, w in parts))
        up = float(sum(w * u for _, _, _, u, w in parts))
        method = "mixture"
        if pooled[i] < up:
            up, method = pooled[i], "counted"
            est = counts[i] / n
        out.append(Exceedance(float(v), est, up, float(confidence), method, counts[i], n,
                              parts))
    return out
