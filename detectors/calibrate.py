"""Thresholds calibrated to a target per-run false-alarm probability (docs/thresholds.md).

A detector that learns a threshold from fault-free learning runs reduces each run to one
value per check: the run's largest |r| (its *per-run maximum*). A fault-free run raises a
false alarm on that check only if its per-run maximum exceeds the threshold τ (a
confirmation time or an integrator only removes alarms), so the per-run false-alarm
probability of the check is at most P(X > τ), X the per-run maximum of a fault-free run.
:func:`calibrate_threshold` chooses τ from the learning runs' maxima x_1 … x_n so that
P(X > τ) ≤ p = ``target_fa_per_run`` at a stated confidence, by one of three routes, in
this order:

``"order-statistic"`` (distribution-free; used whenever n is large enough)
    τ = the r-th largest learning value, r the largest rank with
    P(Binomial(n, p) ≥ r) ≥ confidence. If the true (1 − p)-quantile is q, the r-th largest
    of n values is ≥ q exactly when at least r of them exceed q, an event of probability
    P(Binomial(n, p) ≥ r) for continuous X; so P(X > τ) ≤ p holds with at least that
    probability, whatever the distribution of X. It needs
    n ≥ ln(1 − confidence)/ln(1 − p) (r = 1, the maximum; :func:`min_learning_runs`):
    about 30 000 runs for p = 10⁻⁴ at 95 %.
``"gpd"`` (peaks over threshold; n ≥ :data:`MIN_TAIL_FIT_RUNS` but too few runs for the
    order statistics)
    The k = max(:data:`MIN_EXCEEDANCES`, ⌈:data:`TAIL_FRACTION`·n⌉) largest values are
    modelled as u + Y with u the (k + 1)-th largest value and Y generalised Pareto
    (``scipy.stats.genpareto``, shape ξ, scale σ), so that P(X > x) = (k/n)·(1 +
    ξ(x − u)/σ)^(−1/ξ) above u. Why this k: the tail model holds only far enough into the
    tail, and two parameters need enough points; with the tens to hundreds of learning
    runs of a campaign a mean-excess plot is too noisy to choose u automatically, so a
    fixed fraction (the top fifth) with a floor of 20 exceedances is used, a common
    compromise between the bias of a low u and the variance of few exceedances.
    The shape is restricted to ξ ∈ [−0.5, 1] (:data:`SHAPE_RANGE`: the maximum-likelihood
    estimator is regular above −0.5; ξ ≥ 1, an infinite mean, is not a residual's tail).
    τ̂ = the (1 − p)-quantile of the fitted model, u + σ·((k/(np))^ξ − 1)/ξ, and the
    threshold returned is the upper end of its one-sided profile-likelihood confidence
    interval: the largest τ whose profile log-likelihood (maximised over ξ with σ tied to
    τ) is within z²/2 of the maximum, z the standard normal ``confidence`` quantile
    (Wilks' theorem, χ²₁). Deterministic: no random draw.
``"max-factor"`` (the learning set cannot support the target)
    Fewer than :data:`MIN_TAIL_FIT_RUNS` runs, a tail too degenerate to fit (fewer than
    :data:`MIN_DISTINCT_EXCESSES` distinct values above u, e.g. many runs with the same
    maximum) and too few runs for even the maximum to guarantee the target: τ = max ×
    ``fallback_factor``, the same rule as a detector's ``safety`` × max, and the result says
    ``supported = False`` with the reason in ``note``. No probability is claimed then.

Assumptions. The learning runs are independent draws from the same fault-free population
as the evaluation runs (the same manoeuvres, envelope, uncertainties and duration: p is
per run *of the campaign's duration*); only the per-run maximum matters. The confidence is
a frequentist statement about the learning set: over repeated learning sets, at least (or,
for the profile likelihood, approximately) a fraction ``confidence`` of the thresholds
computed have P(X > τ) ≤ p. With *classes* (e.g. the manoeuvre of each run) every class is
calibrated on its own runs and τ is the largest of the class thresholds, so the guarantee
holds for each class whatever the mix of classes in the evaluation (each class at the
stated confidence; all at once with at least 1 − m·(1 − confidence) for m classes, by the
union bound).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import Param
from .state import register_state_type
from .tail import (MIN_DISTINCT_EXCESSES, MIN_EXCEEDANCES, MIN_TAIL_FIT_RUNS, SHAPE_RANGE,
                   TAIL_FRACTION, TAIL_KINDS, TailFitError, fit_tail, tail_size)

__all__ = ["Calibration", "MIN_DISTINCT_EXCESSES", "MIN_EXCEEDANCES", "MIN_TAIL_FIT_RUNS",
           "SHAPE_RANGE", "TAIL_FRACTION", "THRESHOLD_METHODS", "THRESHOLD_PARAMS",
           "calibrate_threshold", "leave_one_out_ratios", "learned_threshold", "usable_classes",
           "min_learning_runs", "tail_size"]

#: ``threshold_method`` of the built-in detectors: ``"max"`` (safety × the largest learning
#: value) or ``"evt"`` (:func:`calibrate_threshold`; the default).
THRESHOLD_METHODS = ("max", "evt")

#: The four parameters every built-in detector that learns thresholds declares.
THRESHOLD_PARAMS: tuple[Param, ...] = (
    Param("threshold_method", "choice", choices=THRESHOLD_METHODS,
          doc="how thresholds are learned: max = safety × the largest fault-free value of the "
          "learning set; evt = calibrated to target_fa_per_run (docs/thresholds.md)"),
    Param("target_fa_per_run", "float", gt=0.0, lt=0.1,
          doc="evt: target probability that a fault-free run of the campaign's duration "
          "raises a false alarm"),
    Param("threshold_confidence", "float", gt=0.5, lt=1.0,
          doc="evt: confidence that the calibrated threshold meets target_fa_per_run"),
    Param("threshold_tail", "choice", choices=TAIL_KINDS,
          doc="evt: the tail fit's shape: free (ξ in [-0.5, 1]), light (ξ ≤ 0: exponential or "
          "lighter, as a maximum of sensor noise and bounded draws is), auto (light unless a "
          "likelihood-ratio test rejects it), exponential (ξ = 0: the Gumbel domain's tail, "
          "no end point; docs/thresholds.md)"),
)


@register_state_type
@dataclass(frozen=True)
class Calibration:
    """A calibrated threshold and how it was obtained (stored with a fitted detector).

    threshold : the threshold to use (same unit as the values)
    method : ``"order-statistic"``, ``"gpd"``, ``"max-factor"`` or ``"per-class"``
    supported : whether the learning set supports P(X > threshold) ≤ target at the confidence
    target_fa_per_run, confidence : what was asked
    n : learning values used
    k : ``"gpd"``: exceedances fitted; ``"order-statistic"``: rank of the value taken
        (1 = the largest); 0 otherwise
    u : ``"gpd"``: the tail threshold (the (k + 1)-th largest value); NaN otherwise
    shape, scale : ``"gpd"``: ξ and σ of the fitted tail (maximum likelihood, ξ in
        :data:`SHAPE_RANGE`); NaN otherwise
    estimate : ``"gpd"``: the point estimate τ̂ of the (1 − p)-quantile (the threshold is
        its upper confidence bound); ``"order-statistic"``: the threshold; ``"per-class"``:
        the largest class estimate (NaN when no class has one); NaN otherwise
    gof_pvalue : ``"gpd"``: Kolmogorov–Smirnov p-value of the excesses against the fitted
        model (indicative only: the parameters come from the same data, so it is
        optimistic); NaN otherwise
    largest : the largest learning value
    note : what happened, in words
    per_class : ``"per-class"``: (class, :class:`Calibration`) pairs; empty otherwise
    """

    threshold: float
    method: str
    supported: bool
    target_fa_per_run: float
    confidence: float
    n: int
    k: int = 0
    u: float = math.nan
    shape: float = math.nan
    scale: float = math.nan
    estimate: float = math.nan
    gof_pvalue: float = math.nan
    largest: float = math.nan
    note: str = ""
    per_class: tuple = ()


# ---- rules ---------------------------------------------------------------------------------
def _check_probability(name: str, value, lo: float = 0.0) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: not a number; give a probability in "
                         f"({lo:g}, 1)") from None
    if not (lo < v < 1.0):
        raise ValueError(f"{name} = {value!r}: outside ({lo:g}, 1); give a probability in "
                         f"({lo:g}, 1), e.g. {name} = {0.95 if lo else 1e-4:g}")
    return v


def min_learning_runs(target_fa_per_run: float, confidence: float = 0.95,
                      method: str = "order-statistic") -> int:
    """The smallest number of fault-free learning runs for which *method* can support
    P(X > τ) ≤ *target_fa_per_run* at *confidence*.

    ``"order-statistic"``: the smallest n with 1 − (1 − p)^n ≥ confidence, i.e.
    n ≥ ln(1 − confidence)/ln(1 − p) — the largest of n values then exceeds the true
    (1 − p)-quantile with probability ≥ confidence, with no assumption on the distribution
    (p = 10⁻⁴ at 95 %: 29 956 runs; p = 10⁻³: 2 995; p = 10⁻²: 299).
    ``"gpd"``: :data:`MIN_TAIL_FIT_RUNS`, the fewest runs the tail is fitted on; beyond that
    the support rests on the generalised Pareto model of the tail (the bound widens as
    p falls below k/n).
    """
    p = _check_probability("target_fa_per_run", target_fa_per_run)
    c = _check_probability("confidence", confidence, 0.5)
    if method == "gpd":
        return MIN_TAIL_FIT_RUNS
    if method != "order-statistic":
        raise ValueError(f"method = {method!r}: not 'order-statistic' or 'gpd'")
    n = max(1, math.ceil(math.log1p(-c) / math.log1p(-p)))
    while n > 1 and -math.expm1((n - 1) * math.log1p(-p)) >= c:   # guard the rounding
        n -= 1
    while -math.expm1(n * math.log1p(-p)) < c:
        n += 1
    return n


# ---- the calibration -----------------------------------------------------------------------
def calibrate_threshold(values, target_fa_per_run: float, confidence: float = 0.95, *,
                        classes=None, fallback_factor: float = 1.5,
                        tail: str = "free") -> Calibration:
    """The threshold τ with P(X > τ) ≤ *target_fa_per_run* at *confidence*, X the per-run
    maximum of a fault-free run, from the learning runs' maxima *values* (module docstring:
    routes, assumptions and what the confidence means).

    Parameters
    ----------
    values : array_like (n,)
        One value per fault-free learning run: its largest |r| of the check (≥ 0, finite;
        n ≥ 2, per class too).
    target_fa_per_run : float
        p in (0, 1): the highest accepted probability that one fault-free run (of the
        campaign's duration) exceeds τ.
    confidence : float
        In (0.5, 1): the confidence of the guarantee (default 0.95).
    classes : array_like (n,), optional
        A class per value (e.g. the manoeuvre of each run): each class is calibrated on its
        own values and τ is the largest class threshold (``method = "per-class"``).
    fallback_factor : float
        ≥ 1: τ = the largest value × this factor when the learning set cannot support the
        target (``method = "max-factor"``, ``supported = False``).
    tail : str
        Shape range of the tail fit, one of :data:`detectors.tail.TAIL_KINDS` (``"free"``,
        ``"light"``, ``"auto"``, ``"exponential"``; :func:`detectors.tail.fit_tail`).

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        Non-finite or negative values, fewer than 2 values (in the set or in a class),
        *target_fa_per_run* outside (0, 1), *confidence* outside (0.5, 1), a
        *fallback_factor* below 1, or *classes* of another length.
    """
    p = _check_probability("target_fa_per_run", target_fa_per_run)
    c = _check_probability("confidence", confidence, 0.5)
    try:
        factor = float(fallback_factor)
    except (TypeError, ValueError):
        factor = math.nan
    if not (math.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"fallback_factor = {fallback_factor!r}: must be a finite number ≥ 1 "
                         "(the largest learning value is multiplied by it when the learning "
                         "set cannot support the target), e.g. 1.5")
    x = _check_values(values, "values")
    if classes is None:
        return _calibrate_one(x, p, c, factor, tail)
    labels = np.asarray(classes)
    if labels.shape != x.shape:
        raise ValueError(f"classes has {labels.size} entries for {x.size} values; give one "
                         "class per value (e.g. the manoeuvre of each learning run)")
    parts = []
    for label in sorted({str(v) for v in labels.tolist()}):
        sel = np.array([str(v) == label for v in labels.tolist()])
        parts.append((label, _calibrate_one(_check_values(x[sel], f"class {label!r}"), p, c,
                                            factor, tail)))
    best = max(parts, key=lambda item: item[1].threshold)
    unsupported = [label for label, cal in parts if not cal.supported]
    note = (f"largest of {len(parts)} class thresholds ({best[0]!r}, {best[1].method})"
            + (f"; not supported for class(es) {', '.join(map(repr, unsupported))}"
               if unsupported else ""))
    # the largest class estimate; a class without one (NaN, "max-factor") is left out, so
    # the result does not depend on where that class sorts
    estimate = max((cal.estimate for _, cal in parts if not math.isnan(cal.estimate)),
                   default=math.nan)
    return Calibration(threshold=best[1].threshold, method="per-class",
                       supported=not unsupported, target_fa_per_run=p, confidence=c,
                       n=int(x.size), estimate=estimate,
                       largest=float(x.max()), note=note, per_class=tuple(parts))


def _check_values(values, what: str) -> np.ndarray:
    try:
        x = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: not an array of numbers; give one per-run maximum per "
                         "learning run") from None
    if x.ndim != 1:
        raise ValueError(f"{what}: expected a 1-D array (one value per learning run), got "
                         f"shape {x.shape}")
    if x.size < 2:
        raise ValueError(f"{what}: {x.size} value(s); at least 2 learning runs are needed to "
                         "calibrate a threshold (see min_learning_runs for how many support a "
                         "target)")
    bad = ~np.isfinite(x)
    if bad.any():
        raise ValueError(f"{what}: {int(bad.sum())} non-finite value(s) (first at index "
                         f"{int(np.flatnonzero(bad)[0])}: {x[bad][0]}); per-run maxima must be "
                         "finite: drop NaN warm-up samples before taking each run's maximum")
    if (x < 0).any():
        raise ValueError(f"{what}: negative value {x[x < 0][0]}; per-run maxima of |r| are ≥ 0")
    return x


def _calibrate_one(x: np.ndarray, p: float, c: float, factor: float,
                   tail: str = "free") -> Calibration:
    n = int(x.size)
    desc = np.sort(x)[::-1]
    common = dict(target_fa_per_run=p, confidence=c, n=n, largest=float(desc[0]))
    need = min_learning_runs(p, c)
    if n >= need:
        return _order_statistic(desc, p, c, common)
    why = None
    if n < MIN_TAIL_FIT_RUNS:
        why = (f"{n} runs: fewer than the {MIN_TAIL_FIT_RUNS} the tail fit needs and the "
               f"{need} the largest value needs to guarantee p = {p:g} at {c:g}")
    else:
        fit = _gpd(desc, n, tail_size(n), p, c, common, tail)
        if isinstance(fit, Calibration):
            return fit
        why = fit + f", and {n} runs are fewer than the {need} the largest value needs"
    return Calibration(threshold=float(desc[0] * factor), method="max-factor",
                       supported=False, note=f"not supported: {why}; threshold = largest "
                       f"value × {factor:g} (no probability claimed)", **common)


def _order_statistic(desc: np.ndarray, p: float, c: float, common: dict) -> Calibration:
    from scipy.stats import binom

    n = desc.size
    ranks = np.arange(1, n + 1)
    ok = binom.sf(ranks - 1, n, p) >= c          # P(Binomial(n, p) ≥ r) ≥ confidence
    r = int(ranks[ok].max())
    tau = float(desc[r - 1])
    return Calibration(threshold=tau, method="order-statistic", supported=True, k=r,
                       estimate=tau, note=f"the {_ordinal(r)} largest of {n} values "
                       f"(P(Binomial({n}, {p:g}) ≥ {r}) ≥ {c:g}; distribution-free)", **common)


def _ordinal(r: int) -> str:
    if r == 1:
        return "1st"
    suffix = "th" if 10 <= r % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(r % 10, "th")
    return f"{r}{suffix}"


# ---- the generalised Pareto tail (detectors.tail) -----------------------------------------
def _gpd(desc: np.ndarray, n: int, k: int, p: float, c: float, common: dict,
         tail: str = "free"):
    """The "gpd" :class:`Calibration`, or the reason (str) the tail cannot be fitted: the
    upper profile-likelihood bound of the (1 − p)-quantile of :func:`detectors.tail.fit_tail`
    (shape range *tail*, :data:`detectors.tail.TAIL_KINDS`)."""
    try:
        fit = fit_tail(desc, k, tail=tail, confidence=c)
        k = fit.k                     # moved when values tie across the cut (fit_tail)
        if p >= k / n:                # p is in the data, not in the tail
            return f"p = {p:g} is not in the fitted tail (k/n = {k / n:g})"
        q = fit.quantile(p, c)
    except TailFitError as exc:
        return str(exc)
    edges = {"free": SHAPE_RANGE, "exponential": ()}.get(fit.tail, (SHAPE_RANGE[0],))
    at_bound = " (ξ at the edge of its range)" if q.shape in edges else ""
    assumed = {"light": "light tail (ξ ≤ 0)", "exponential": "exponential tail (ξ = 0)"}
    if fit.tail == "free" and fit.light_rejected:
        at_bound += "; light tail (ξ ≤ 0) rejected by the likelihood-ratio test, free shape"
    elif fit.tail in assumed and fit.light_rejected:
        at_bound += (f"; {assumed[fit.tail]} assumed although the likelihood-ratio test "
                     "rejects ξ ≤ 0 for this sample: check it with fdd-campaign certify")
    elif fit.tail in assumed:
        at_bound += f"; {assumed[fit.tail]}, ξ ≤ 0 not rejected by the likelihood-ratio test"
    return Calibration(
        threshold=q.upper, method="gpd", supported=True, k=k, u=fit.u, shape=q.shape,
        scale=q.scale, estimate=q.estimate, gof_pvalue=q.gof_pvalue,
        note=(f"generalised Pareto tail of the top {k} of {n} values above u = {fit.u:g}: "
              f"ξ = {q.shape:.3g}{at_bound}, σ = {q.scale:.3g}; (1 − p)-quantile "
              f"{q.estimate:.6g}, upper {c:g} profile-likelihood bound {q.upper:.6g}"),
        **common)


# ---- helpers for the detectors ---------------------------------------------------------------
def usable_classes(classes):
    """*classes* (the learning runs' manoeuvres, ``Signals.classes``), or None when it is
    None or some class has a single run, which cannot be calibrated alone: the runs are
    then pooled."""
    if classes is None:
        return None
    _, counts = np.unique(np.asarray(classes, dtype=str), return_counts=True)
    return None if counts.min() < 2 else classes


def learned_threshold(maxima: np.ndarray, method: str, safety: float,
                      target_fa_per_run: float, confidence: float, tail: str = "free",
                      classes=None) -> tuple[float, Calibration | None]:
    """(threshold, calibration) of one check from the learning runs' per-run maxima.

    ``method = "max"``: ``safety × max(maxima)`` and no calibration; ``"evt"`` (the
    built-in detectors' default): :func:`calibrate_threshold` with
    ``fallback_factor = safety`` (so a learning set that cannot support the target falls
    back to the ``"max"`` threshold); the safety factor is not applied on top of a
    calibrated threshold. *tail*: the tail fit's shape range (:func:`detectors.tail.fit_tail`);
    *classes*: the learning runs' manoeuvres (``Signals.classes``) to calibrate each class on
    its own, τ the largest class threshold, or None to pool the runs.
    """
    if method == "max":
        return float(safety * np.max(maxima)), None
    if method != "evt":
        raise ValueError(f"threshold_method = {method!r}: not one of "
                         f"{', '.join(THRESHOLD_METHODS)}")
    x = np.asarray(maxima, dtype=float)
    if x.size == 1 and np.isfinite(x).all() and x[0] >= 0.0:
        # one learning run: no calibration is possible, the fallback's note says why
        cal = _calibrate_one(x, float(target_fa_per_run), float(confidence), float(safety),
                             tail)
        return cal.threshold, cal
    cal = calibrate_threshold(maxima, target_fa_per_run, confidence, fallback_factor=safety,
                              tail=tail, classes=usable_classes(classes))
    return cal.threshold, cal


def leave_one_out_ratios(maxima: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """Per run i, max over checks q of maxima[i, q] / max(max_{j≠i} maxima[j, q], floor).

    For a detector whose thresholds share one profile over many checks (e.g. the
    moving-average bounds λ_q of comb-interval): the profile learned without run i scales
    run i like an unseen run, so these ratios are (exchangeable) per-run maxima of the
    one check "some q exceeds s × profile", whose calibrated s scales the whole profile.
    *maxima* (n, Q) with n ≥ 2.
    """
    m = np.asarray(maxima, float)
    if m.ndim != 2 or m.shape[0] < 2:
        raise ValueError(f"maxima must be (n_runs ≥ 2, n_checks), got shape {m.shape}")
    order = np.argsort(-m, axis=0, kind="stable")
    top1 = m[order[0], np.arange(m.shape[1])]
    top2 = m[order[1], np.arange(m.shape[1])]
    others = np.where(np.arange(m.shape[0])[:, None] == order[0][None, :], top2[None, :],
                      top1[None, :])
    denom = np.maximum(others, float(floor))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(denom > 0.0, m / np.where(denom > 0.0, denom, 1.0),
                         np.where(m > 0.0, np.inf, 0.0))
    return ratio.max(axis=1)
