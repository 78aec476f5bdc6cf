"""detectors.tail by value, on the path the shipped presets take: the generalised-Pareto
calibration of 50 or more learning runs (target 10⁻⁴ per run, 95 %, ``threshold_tail =
"exponential"``, the built-in detectors' defaults), the likelihood-ratio test of ξ ≤ 0 at its
decision boundary, and the exceedance probability of the certificate's curve.

Every expected value is recomputed here from the formulas of the module docstring (Coles
2001, §4.3 and §2.6.6) by a separate route: the generalised Pareto log-likelihood written out
(Coles eq. 4.10), maximised over the documented ξ grid (step 0.005, ξ = 0 included) with
SciPy's bounded scalar search over σ or over the quantity of interest, and the one-sided
profile-likelihood bound found where the profile falls z²/2 below its maximum (z the standard
normal quantile of the confidence: the one-sided bound of Wilks' χ²₁, χ²₁(2c − 1) = z_c²).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import optimize, stats

from detectors.calibrate import calibrate_threshold
from detectors.tail import CURVE_SHAPES, TailFitError, exceedance_curve, fit_tail

#: The documented ξ grid: [−0.5, 1] in steps of 0.005 (301 values, ξ = 0 included).
GRID = np.round(np.arange(-100, 201) * 0.005, 12)


def loglik(y, sigma, xi) -> np.ndarray:
    """Σ_i log GPD(y_i; ξ, σ) for each (σ, ξ) pair (Coles 2001 eq. 4.10), −inf outside the
    support."""
    y = np.asarray(y, float)[:, None]
    sigma = np.atleast_1d(np.asarray(sigma, float))[None, :]
    xi = np.atleast_1d(np.asarray(xi, float))[None, :]
    with np.errstate(all="ignore"):
        z = 1.0 + xi * y / sigma
        general = -np.log(sigma) - (1.0 + 1.0 / np.where(xi == 0, 1.0, xi)) * np.log(z)
        exponential = -np.log(sigma) - y / sigma
        ll = np.where(xi == 0, exponential, np.where(z > 0, general, -np.inf))
    return np.where(sigma > 0, ll, -np.inf).sum(axis=0)


def h(a: float, xi: np.ndarray) -> np.ndarray:
    """(a^ξ − 1)/ξ, log a at ξ = 0: the quantile's excess over u in units of σ."""
    safe = np.where(xi == 0, 1.0, xi)
    return np.where(xi == 0, math.log(a), (a ** safe - 1.0) / safe)


def tail_of(values):
    """(n, k, u, excesses): k = max(20, ⌈n/5⌉), u the (k + 1)-th largest value."""
    d = np.sort(np.asarray(values, float))[::-1]
    k = max(20, math.ceil(0.2 * d.size))
    return d.size, k, float(d[k]), d[:k] - d[k]


def quantile_reference(values, p: float, c: float, grid: np.ndarray):
    """(estimate, upper bound, ξ̂) of the (1 − p)-quantile: the profile over t = τ − u with
    σ = t/h(a, ξ), a = (k/n)/p, maximised over ξ in *grid*; the bound is the largest t whose
    profile is within z_c²/2 of the maximum."""
    n, k, u, y = tail_of(values)
    a = (k / n) / p

    def profile(s):                               # s = log t
        t = math.exp(s)
        return float(loglik(y, t / h(a, grid), grid).max())

    s = math.log(y.mean() * math.log(a)) + np.linspace(-6.0, 10.0, 801)
    prof = np.array([profile(v) for v in s])
    i = int(np.argmax(prof))
    best = optimize.minimize_scalar(lambda v: -profile(v), bounds=(s[i - 1], s[i + 1]),
                                    method="bounded", options={"xatol": 1e-12})
    s_hat, top = (best.x, -best.fun) if -best.fun >= prof[i] else (s[i], prof[i])
    level = top - 0.5 * stats.norm.ppf(c) ** 2
    j = i + int(np.flatnonzero(prof[i:] < level)[0])
    s_up = optimize.brentq(lambda v: profile(v) - level, s_hat, s[j], xtol=1e-13)
    t_hat = math.exp(s_hat)
    xi_hat = float(grid[np.argmax(loglik(y, t_hat / h(a, grid), grid))])
    return u + t_hat, u + math.exp(s_up), xi_hat


def sf_reference(values, x: float, c: float, grid: np.ndarray):
    """(estimate, upper bound, ξ̂, σ̂) of P(X ≥ x), x above u: (k/n)·q with the profile over
    s = −log q (σ = t/h(e^s, ξ), t = x − u) maximised over ξ in *grid*; the bound is the
    largest q (smallest s) whose profile is within z_c²/2 of the maximum; (ξ̂, σ̂) maximise
    the likelihood at the estimate."""
    n, k, u, y = tail_of(values)
    t = x - u
    safe = np.where(grid == 0, 1.0, grid)

    def profile(v):                               # v = log s
        s = math.exp(v)
        with np.errstate(all="ignore"):
            hh = np.where(grid == 0, s, np.expm1(safe * s) / safe)
        return float(loglik(y, t / hh, grid).max())

    v = np.linspace(math.log(1e-6), math.log(1e4), 2001)
    prof = np.array([profile(w) for w in v])
    i = int(np.argmax(prof))
    best = optimize.minimize_scalar(lambda w: -profile(w), bounds=(v[i - 1], v[i + 1]),
                                    method="bounded", options={"xatol": 1e-12})
    v_hat, top = (best.x, -best.fun) if -best.fun >= prof[i] else (v[i], prof[i])
    level = top - 0.5 * stats.norm.ppf(c) ** 2
    j = int(np.flatnonzero((v < v_hat) & (prof < level))[-1])
    v_up = optimize.brentq(lambda w: profile(w) - level, v[j], v_hat, xtol=1e-13)
    s_hat = math.exp(v_hat)
    hh = np.where(grid == 0, s_hat, np.expm1(safe * s_hat) / safe)
    j_hat = int(np.argmax(loglik(y, t / hh, grid)))
    return (k / n * math.exp(-s_hat), k / n * math.exp(-math.exp(v_up)), float(grid[j_hat]),
            float(t / hh[j_hat]))


def restricted_maximum(y, grid: np.ndarray) -> float:
    """max over ξ in *grid* and σ > 0 of the log-likelihood (σ by bounded search per ξ)."""
    best = -math.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for xi in grid:
            r = optimize.minimize_scalar(lambda ls: -loglik(y, math.exp(ls), xi)[0],
                                         bounds=(math.log(y.mean()) - 5, math.log(y.max()) + 5),
                                         method="bounded", options={"xatol": 1e-12})
            best = max(best, -r.fun)
    return best


def gaussian_maxima(seed: int, n: int, samples: int = 200) -> np.ndarray:
    """Per-run maxima of *samples* standard normal values: a residual's sensor-noise maximum."""
    return np.random.default_rng(seed).standard_normal((n, samples)).max(axis=1)


# ---- the calibration every preset takes: ≥ 50 runs, the generalised Pareto route ----------
@pytest.mark.parametrize("n, seed, tail, p, grid", [
    (50, 11, "exponential", 1e-4, GRID[GRID == 0.0]),
    (60, 12, "exponential", 1e-4, GRID[GRID == 0.0]),
    (120, 13, "exponential", 1e-4, GRID[GRID == 0.0]),
    (300, 14, "exponential", 1e-4, GRID[GRID == 0.0]),
    (100, 15, "light", 1e-4, GRID[GRID <= 0.0]),            # ξ̂ = 0, the light range's edge
    (100, 100, "light", 1e-4, GRID[GRID <= 0.0]),           # ξ̂ = −0.12, inside it
    (200, 1, "free", 1e-3, GRID),                           # ξ̂ = −0.105
    (200, 2, "free", 1e-3, GRID),                           # ξ̂ = −0.415
])
def test_the_default_calibration_is_the_profile_likelihood_bound_value_by_value(n, seed, tail,
                                                                                 p, grid):
    """target 10⁻⁴, 95 %, exponential tail (the built-in detectors' defaults) on 50 to 300
    learning runs (fewer than the 29 956 the order statistic needs), and the light and free
    shapes: threshold, estimate, k, u, ξ and σ as recomputed from the formulas. The bound is
    a root of the profile (1e-8 relative); the estimate is the maximum's position, found to
    about √ε ≈ 1e-8 in log t by both searches, so t̂ = τ̂ − u agrees to 1e-6 relative
    (σ̂ = t̂/h) and τ̂ to 1e-7.

    With ξ free to move over its grid the profile of τ is a maximum over 301 curves, with
    small local maxima where the maximising ξ changes; the module's search (a 61-point grid
    of t, then a bounded refinement) can stop on a neighbouring one: on other learning sets
    its estimate differed from this exhaustive search by up to 1.2e-3 relative and its bound
    by up to 2e-4 (n = 60, p = 10⁻⁴). The light and free cases here are ones where both
    find the same maximum; the exponential default has one ξ and a smooth profile."""
    x = gaussian_maxima(seed, n)
    cal = calibrate_threshold(x, p, 0.95, tail=tail)
    n_, k, u, _ = tail_of(x)
    est, up, xi = quantile_reference(x, p, 0.95, grid)
    assert cal.method == "gpd" and cal.supported
    assert (cal.n, cal.k, cal.u) == (n, k, u)
    assert cal.threshold == pytest.approx(up, rel=1e-8)
    assert cal.estimate == pytest.approx(est, rel=1e-7)
    assert cal.shape == pytest.approx(xi, abs=1e-12)     # the same grid node
    a = (k / n) / p                                  # σ̂ = t̂/h(a, ξ̂)
    assert cal.scale == pytest.approx((est - u) / float(h(a, np.array(xi))), rel=1e-6)
    assert cal.threshold > cal.estimate > u


def test_the_bound_is_one_sided_not_two_sided():
    """The 95 % bound sits where the profile has fallen z_0.95²/2 = 1.353, not
    z_0.975²/2 = 1.921 (the end of a two-sided 95 % interval): the two bounds differ by
    more than 1 % here, and the calibration gives the first."""
    x = gaussian_maxima(21, 80)
    cal = calibrate_threshold(x, 1e-4, 0.95, tail="exponential")
    grid = GRID[GRID == 0.0]
    _, one_sided, _ = quantile_reference(x, 1e-4, 0.95, grid)
    _, two_sided, _ = quantile_reference(x, 1e-4, 0.975, grid)
    assert two_sided > 1.01 * one_sided
    assert cal.threshold == pytest.approx(one_sided, rel=1e-8)


# ---- the likelihood-ratio test of ξ ≤ 0, at its decision boundary ---------------------------
def plotting_position_sample(xi0: float, n: int = 100) -> np.ndarray:
    """The n quantiles GPD(ξ₀, 1).ppf((i − ½)/n): a deterministic sample of a heavy tail."""
    return stats.genpareto.ppf((np.arange(1, n + 1) - 0.5) / n, xi0)


def lr_statistic(values) -> float:
    """2·(max log-likelihood, free ξ − max log-likelihood, ξ ≤ 0) of the top k excesses."""
    _, _, _, y = tail_of(values)
    return 2.0 * (restricted_maximum(y, GRID) - restricted_maximum(y, GRID[GRID <= 0.0]))


@pytest.mark.parametrize("tail", ["auto", "light"])
def test_the_light_tail_test_flips_between_the_one_sided_and_the_two_sided_critical_value(tail):
    """ξ ≤ 0 is a boundary hypothesis: 2Δℓ is ½χ²₀ + ½χ²₁ under it (Self & Liang 1987), so
    the 5 % critical value is z_0.95² = 2.706, not χ²₁(0.95) = z_0.975² = 3.841 (two-sided)
    nor z_0.95·2 = 3.290. A sample with 2Δℓ = 2.95 is rejected; one with 2.24 is not (it
    would be under z_0.95 = 1.645, a critical value left unsquared)."""
    crit = stats.norm.ppf(0.95) ** 2
    between = plotting_position_sample(0.52)
    below = plotting_position_sample(0.47)
    s_between, s_below = lr_statistic(between), lr_statistic(below)
    assert crit < s_between < 2 * stats.norm.ppf(0.95) < stats.chi2.ppf(0.95, 1)
    assert stats.norm.ppf(0.95) < s_below < crit
    rejected = fit_tail(between, tail=tail)
    kept = fit_tail(below, tail=tail)
    assert rejected.light_rejected is True and kept.light_rejected is False
    if tail == "auto":                                 # acted on: the free fit is used
        assert rejected.tail == "free" and rejected.shape > 0.0
        assert kept.tail == "light" and kept.shape <= 0.0
    else:                                              # reported, the light fit kept
        assert rejected.tail == kept.tail == "light"
    # at 90 % the critical value is z_0.90² = 1.642: the lower sample is rejected too
    assert fit_tail(below, tail=tail, confidence=0.90).light_rejected is True


def test_the_calibration_passes_its_confidence_to_the_light_tail_test():
    """calibrate_threshold's confidence is the test's: at 0.95 the 2Δℓ = 2.24 sample keeps
    ξ ≤ 0, at 0.9 (critical value 1.642) the free shape is used."""
    x = plotting_position_sample(0.47)
    assert "ξ ≤ 0 not rejected" in calibrate_threshold(x, 1e-3, 0.95, tail="light").note
    assert "rejected by the likelihood-ratio test, free shape" in calibrate_threshold(
        x, 1e-3, 0.90, tail="auto").note


@pytest.mark.parametrize("tail, grid", [("free", GRID), ("light", GRID[GRID <= 0.0]),
                                        ("exponential", GRID[GRID == 0.0])])
def test_the_fitted_shape_and_scale_are_the_maximum_likelihood_ones(tail, grid):
    """fit_tail's (ξ, σ) maximise the log-likelihood of the k excesses over the tail's ξ
    range (checked on the restricted maximum, 1e-9 absolute in log-likelihood)."""
    x = gaussian_maxima(31, 150)
    fit = fit_tail(x, tail=tail)
    _, k, u, y = tail_of(x)
    assert (fit.k, fit.u, fit.n, fit.largest) == (k, u, 150, x.max())
    assert np.isclose(grid, fit.shape, rtol=0, atol=1e-12).any()
    assert loglik(y, fit.scale, fit.shape)[0] == pytest.approx(restricted_maximum(y, grid),
                                                                abs=1e-9)
    np.testing.assert_allclose(fit.tail_values(), y, rtol=1e-12)


# ---- the certificate's exceedance probability: P(margin ≥ x) above u, ξ ∈ [0, 1] ----------
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("level", [1.0, 1.1])
def test_the_exceedance_probability_and_its_bound_value_by_value(seed, level):
    """fit_tail(…, CURVE_SHAPES).sf: the estimate (k/n)·q̂ and the bound (k/n)·q_up of the
    profile over s = −log q, as recomputed (1e-7 relative for the estimate, the maximum's
    search tolerance; 1e-10 for the bound, a root of the profile)."""
    x = gaussian_maxima(seed, 150, 100) / 3.5             # margins: max |r| / τ
    fit = fit_tail(x, shapes=CURVE_SHAPES)
    e = fit.sf(level)
    est, up, xi, sigma = sf_reference(x, level, 0.95, GRID[GRID >= 0.0])
    assert e.estimate == pytest.approx(est, rel=1e-7)
    assert e.upper == pytest.approx(up, rel=1e-10)
    assert e.upper > e.estimate and e.confidence == 0.95
    assert e.shape == pytest.approx(xi, abs=1e-12) and e.scale == pytest.approx(sigma, rel=1e-6)


def test_the_exceedance_probability_of_a_heavy_tail_value_by_value():
    """As above on 150 GPD(ξ = 0.3) values at their third largest: ξ̂ = 0.38, inside
    [0, 1], so the (ξ, σ) reported is the likelihood's maximiser, not the grid's edge."""
    x = stats.genpareto.rvs(0.3, size=150, random_state=np.random.default_rng(1))
    level = float(np.sort(x)[-3])
    e = fit_tail(x, shapes=CURVE_SHAPES).sf(level)
    est, up, xi, sigma = sf_reference(x, level, 0.95, GRID[GRID >= 0.0])
    assert 0.0 < xi < 1.0
    assert e.estimate == pytest.approx(est, rel=1e-7)
    assert e.upper == pytest.approx(up, rel=1e-10)
    assert e.shape == pytest.approx(xi, abs=1e-12) and e.scale == pytest.approx(sigma, rel=1e-6)


def test_k_must_leave_a_value_below_the_tail():
    """2 ≤ k < n: k = n would leave no (k + 1)-th value for u."""
    x = gaussian_maxima(41, 60)
    assert fit_tail(x, k=59).k == 59
    with pytest.raises(TailFitError, match="k = 60: the exceedances must be 2 ≤ k < n = 60"):
        fit_tail(x, k=60)
    with pytest.raises(TailFitError, match="k = 1: the exceedances must be 2 ≤ k < n = 60"):
        fit_tail(x, k=1)


def test_a_fit_is_hashable_by_identity_and_its_repr_leaves_out_the_arrays():
    """A TailFit holds arrays: it compares and hashes as the object it is (a set or a cache
    key can hold it), and its repr gives the fitted numbers, not the excesses."""
    x = gaussian_maxima(42, 60)
    a, b = fit_tail(x), fit_tail(x)
    assert a != b and a == a and len({a, b}) == 2
    with pytest.raises(AttributeError):                       # frozen
        a.k = 3
    text = repr(a)
    assert text.startswith(f"TailFit(n=60, k=20, u={a.u!r}, shape={a.shape!r}")
    assert "excesses" not in text and "unit=" not in text and "shapes=" not in text


# ---- the edges of the fit: ties at the cut, a tail too heavy to bound, q near 1 ------------
def test_a_tie_across_the_cut_moves_it_to_the_nearer_gap_the_larger_on_a_draw():
    """n = 150, rule k = 30: a group of four equal values at ranks 29-32 leaves the gaps at
    28 and 32, both 2 from 30: the larger k (32) is taken, u the next value below; with a
    fifth equal value the gap at 28 is the nearer."""
    x = np.linspace(1.0, 2.0, 150)[::-1].copy()             # distinct, largest first
    x[28:32] = x[28]
    fit = fit_tail(x)
    assert (fit.k, fit.u) == (32, x[32])
    x[28:33] = x[28]                                         # gaps at 28 and 33
    assert (fit_tail(x).k, fit_tail(x).u) == (28, x[28])
    y = np.linspace(1.0, 2.0, 150)[::-1].copy()
    y[29:31] = y[29]                                         # a pair tied across the cut
    assert (fit_tail(y).k, fit_tail(y).u) == (31, y[31])


def test_a_tie_cut_may_leave_exactly_the_fewest_exceedances():
    """n = 150, rule k = 30, 21 equal values at ranks 21-41: the gaps at 20 (10 away) and 41
    (11 away); k = 20 = MIN_EXCEEDANCES is still a tail."""
    x = np.linspace(1.0, 2.0, 150)[::-1].copy()
    x[20:41] = x[20]
    fit = fit_tail(x)
    assert (fit.k, fit.u) == (20, x[20])
    x[19:45] = x[19]                          # gaps at 19 (11 away) and 45: degenerate
    with pytest.raises(TailFitError, match=r"19 value\(s\) above the atom .*; 26 of 150 values "
                                           "equal u"):
        fit_tail(x)


def test_a_tie_holding_the_smallest_value_is_cut_above_never_below():
    """30 distinct values above an atom of 30 zeros, k = 59 asked: the cut cannot go below
    the atom (no value is left there for u), so it goes above it: k = 30, u = 0."""
    x = np.r_[np.linspace(1.0, 2.0, 30), np.zeros(30)]
    fit = fit_tail(x, k=59)
    assert (fit.k, fit.u) == (30, 0.0)


def test_a_tail_too_heavy_to_bound_is_an_error_that_says_so():
    """GPD(ξ = 1) values, p = 10⁻⁸: the profile of the quantile is still within its level
    10⁴ × the exponential estimate out; calibrate falls back and says why."""
    x = stats.genpareto.rvs(1.0, size=50, random_state=np.random.default_rng(0))
    fit = fit_tail(x)
    with pytest.raises(TailFitError, match="does not fall below its 0.95 level within 10⁴ × "
                                           "the estimate"):
        fit.quantile(1e-8)
    # the search reaches 10⁴ × the exponential estimate log((k/n)/p) mean excesses, no
    # further: here the bound at p = 10⁻⁶ (1.9e6) is inside, at 10⁻⁷ (1.9e7) beyond it
    assert fit.quantile(1e-6).upper == pytest.approx(1.907e6, rel=1e-3)
    with pytest.raises(TailFitError, match="too heavy to bound"):
        fit.quantile(1e-7)
    cal = calibrate_threshold(x, 1e-8, 0.95)
    assert cal.method == "max-factor" and "too heavy to bound" in cal.note
    assert fit.quantile(1e-3).upper > fit.quantile(1e-3).estimate      # a bounded one
    with pytest.raises(ValueError, match=r"p = 0.4: outside the fitted tail \(0, k/n = 0.4\)"):
        fit.quantile(0.4)
    with pytest.raises(ValueError, match=r"p = 0.0: outside the fitted tail"):
        fit.quantile(0.0)


def test_an_exceedance_probability_just_above_u_is_bounded_by_k_over_n():
    """At x = u + 10⁻⁹ the profile of s = −log q does not fall below its level before the
    grid's first s = 10⁻⁶: the bound is (k/n)·exp(−10⁻⁶); at or below u the tail does not
    apply."""
    x = gaussian_maxima(1, 100)
    fit = fit_tail(x)
    e = fit.sf(fit.u + 1e-9)
    assert e.upper == pytest.approx(0.2 * math.exp(-1e-6), rel=1e-15)
    with pytest.raises(ValueError, match="is not above the tail threshold u"):
        fit.sf(fit.u)


def test_the_curve_counts_at_or_below_u_and_fits_above_with_the_curve_shapes():
    """One sample: the share of values ≥ x (a value equal to x counts) with its exact bound at
    or below u, the ξ ∈ [0, 1] tail's sf above."""
    from reports.scoring.metrics import upper_bound

    x = gaussian_maxima(3, 120)
    fit = fit_tail(x, shapes=CURVE_SHAPES)
    d = np.sort(x)[::-1]
    levels = (d[30], fit.u, fit.u + 0.1)                      # a value, u, above u
    curve = exceedance_curve(x, levels)
    assert [c.method for c in curve] == ["counted", "counted", "tail"]
    assert (curve[0].count, curve[0].estimate) == (31, 31 / 120)
    assert curve[0].upper == float(upper_bound(31, 120, 0.95))
    assert curve[1].count == fit.k + 1
    e = fit.sf(fit.u + 0.1)
    assert (curve[2].estimate, curve[2].upper) == (e.estimate, e.upper)
    assert curve[2].parts == () and curve[2].n == 120


def test_the_curve_of_a_mixture_is_its_classes_curves_by_their_shares():
    """Σ_c w_c·(the class's own curve), or the pooled count (its share, its exact bound) at
    the levels where that bound is the smaller (here 2.5 and 4.0)."""
    from reports.scoring.metrics import upper_bound

    x = np.r_[gaussian_maxima(4, 150, 100), 1.2 * gaussian_maxima(5, 60, 100)]
    cls = np.array(["b"] * 150 + ["a"] * 60)
    levels = (2.5, 3.0, 3.6, 4.0)
    curve = exceedance_curve(x, levels, classes=cls)
    alone = {c: exceedance_curve(x[cls == c], levels) for c in ("a", "b")}
    for i, e in enumerate(curve):
        assert [p[0] for p in e.parts] == ["a", "b"]
        for name, how, est, up, w in e.parts:
            assert (how, est, up) == (alone[name][i].method, alone[name][i].estimate,
                                      alone[name][i].upper)
            assert w == (cls == name).mean()
        assert e.count == int((x >= levels[i]).sum()) and e.n == 210
        if e.method == "mixture":
            assert e.estimate == pytest.approx(sum(p[2] * p[4] for p in e.parts), rel=1e-12)
            assert e.upper == pytest.approx(sum(p[3] * p[4] for p in e.parts), rel=1e-12)
        else:
            assert (e.estimate, e.upper) == (e.count / 210,
                                             float(upper_bound(e.count, 210, 0.95)))
    assert [e.method for e in curve] == ["counted", "mixture", "mixture", "counted"]


def test_a_bounded_tail_at_a_tiny_target_is_found_below_a_tenth_of_the_exponential_estimate():
    """Evenly spread values (a finite end point: ξ = −1, held at −0.5) and p = 10⁻¹⁶: the
    quantile excess t̂ (2.5 mean excesses) is under a tenth of the exponential one
    (log a = 35), so the search over t must start lower than that; the light fit's bound and
    estimate as recomputed (tolerances of the default-route test)."""
    x = np.linspace(0.0, 1.0, 200)
    cal = calibrate_threshold(x, 1e-16, 0.95, tail="light")
    est, up, xi = quantile_reference(x, 1e-16, 0.95, GRID[GRID <= 0.0])
    n, k, u, y = tail_of(x)
    assert (est - u) / y.mean() < 0.1 * math.log((k / n) / 1e-16)
    assert cal.method == "gpd" and cal.shape == -0.5
    assert cal.threshold == pytest.approx(up, rel=1e-8)
    assert cal.estimate == pytest.approx(est, rel=1e-7)


def test_the_log_likelihood_a_few_pairs_at_a_time_is_the_written_out_one(monkeypatch):
    """With LOGLIK_TERMS = 50 and 20 excesses, 2 pairs are taken at a time: 301 × 3 pairs
    (every ξ of the grid, three σ; some outside the support) give Coles' eq. 4.10."""
    import detectors.tail as tail

    y = np.sort(gaussian_maxima(6, 20))[::-1] - 2.0
    y = y[y > 0]
    sigma = np.repeat([0.05, 0.5, 2.0], GRID.size).reshape(3, GRID.size)
    xi = np.broadcast_to(GRID, sigma.shape)
    monkeypatch.setattr(tail, "LOGLIK_TERMS", 50)
    got = tail._loglik(y, sigma, xi)
    want = loglik(y, sigma.ravel(), xi.ravel()).reshape(sigma.shape)
    assert got.shape == (3, GRID.size)
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-12)
    assert np.isinf(want).any() and np.isfinite(want).any()


def test_ten_distinct_excesses_are_enough_and_k_two_is_degenerate():
    """MIN_DISTINCT_EXCESSES = 10: the top 10 of distinct values are fitted; k = 2 passes the
    bounds 2 ≤ k < n but holds 2 distinct excesses, a degenerate tail."""
    x = gaussian_maxima(7, 60)
    assert fit_tail(x, k=10).k == 10
    with pytest.raises(TailFitError, match="degenerate: 9 distinct value"):
        fit_tail(x, k=9)
    with pytest.raises(TailFitError, match="degenerate: 2 distinct value"):
        fit_tail(x, k=2)


def test_the_models_exceedance_probability_is_nan_at_or_below_u():
    """model_sf: (k/n)·GPD(ξ̂, σ̂).sf(x − u) above u, NaN at and below u."""
    x = gaussian_maxima(8, 100)
    fit = fit_tail(x)
    got = fit.model_sf([fit.u - 0.1, fit.u, fit.u + 0.3])
    assert np.isnan(got[:2]).all()
    assert got[2] == pytest.approx(0.2 * stats.genpareto.sf(0.3, fit.shape, scale=fit.scale),
                                   rel=1e-14)


def test_a_sample_too_small_for_a_tail_is_counted_at_every_level():
    """30 values (fewer than the 50 a tail fit needs): every level is counted, none fails;
    the points are frozen, and the options after the levels are keyword-only."""
    from reports.scoring.metrics import upper_bound

    x = gaussian_maxima(9, 30)
    top = float(x.max())
    curve = exceedance_curve(x, (top, top + 1.0))
    assert [(c.method, c.count, c.estimate) for c in curve] == [("counted", 1, 1 / 30),
                                                                 ("counted", 0, 0.0)]
    assert curve[1].upper == float(upper_bound(0, 30, 0.95))
    with pytest.raises(AttributeError):
        curve[0].upper = 0.0
    with pytest.raises(TypeError):
        exceedance_curve(x, (top,), np.zeros(30))


def test_a_missing_class_label_is_a_class_of_its_own():
    """Labels None are not dropped nor merged: they form one class (named "nan", as pandas
    reads a missing label) with its share."""
    x = np.r_[gaussian_maxima(10, 60, 100), gaussian_maxima(11, 40, 100)]
    labels = np.array(["cruise"] * 60 + [None] * 40, dtype=object)
    e = exceedance_curve(x, (2.0,), classes=labels)[0]
    assert [(p[0], p[4]) for p in e.parts] == [("cruise", 0.6), ("nan", 0.4)]
    with pytest.raises(AttributeError):                       # estimates are frozen
        fit_tail(x).sf(3.0).upper = 0.0
