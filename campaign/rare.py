"""Subset simulation: the probability of a rare event of a simulation, P(g(X) ≥ 1), as a
product of conditional probabilities (docs/evidence.md).

Au, S.-K. and Beck, J. L. (2001), *Estimation of small failure probabilities in high
dimensions by subset simulation*, Probabilistic Engineering Mechanics 16(4), 263–277
(the estimator, eq. 5, and its coefficient of variation, eqs. 27–29); the Markov chains
move in standard normal space by the conditional sampling of Papaioannou, I., Betz, W.,
Zwirglmaier, K. and Straub, D. (2015), *MCMC algorithms for subset simulation*,
Probabilistic Engineering Mechanics 41, 89–103 (§4.2: z' = ρ z + √(1 − ρ²) ξ, which
leaves N(0, I) invariant, accepted when it stays in the current level's domain).

Level 0 draws *n* points from the prior. At each level the ⌈p₀ n⌉ points of largest g are
kept, their smallest g is the next intermediate threshold b, and each of them seeds a chain
of ⌊1/p₀⌋ states conditional on g ≥ b (the next *n* points; the level's conditional
probability is the share of points ≥ b, p₀ unless values tie at b); once the p₀-quantile reaches 1,
P̂ = p₀^L × (share of the last level's points with g ≥ 1). Besides the standard normal
coordinates a point carries *nuisance* variables drawn from their prior by the caller
(e.g. which manoeuvre, which noise stream): a move redraws each with probability 1/2 (an
independence proposal from the prior, reversible with respect to it), so the chains target
the prior restricted to the level's domain in every coordinate.

The interval: δ² = Σ_i δ_i², δ_i² = (1 − P_i)/(n P_i)·(1 + γ_i) with γ_i from the
correlation of the chains' indicators (Au and Beck 2001, eqs. 27–29; γ_0 = 0), the levels
taken as uncorrelated (which understates δ); log P̂ is taken as normal with standard
deviation √(ln(1 + δ²)), and each bound is one-sided at the confidence asked. The
estimator is biased by O(1/n) and the interval is asymptotic: they are a cross-check of
the tail fit, not an exact bound. Deterministic for a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["SubsetResult", "subset_simulation"]


@dataclass(frozen=True)
class SubsetResult:
    """The outcome of :func:`subset_simulation`.

    probability : P̂(g ≥ 1) (0 when no point reached 1 within ``max_levels``)
    lower, upper : one-sided bounds at *confidence* (``upper`` with P̂ = 0: p₀^L times the
        exact binomial bound of 0 hits in the last level's n points)
    cov : δ, the estimated coefficient of variation of P̂
    levels : intermediate thresholds b_1 … b_L (g units)
    evaluations : calls of g (points simulated)
    reached : whether the p₀-quantile of g reached 1 (the estimate is complete)
    stalled : whether a level's threshold did not rise above the previous one (the chains
        stopped climbing, e.g. g constant over a region): the result is then incomplete
    """

    probability: float
    lower: float
    upper: float
    confidence: float
    cov: float
    levels: tuple = ()
    evaluations: int = 0
    reached: bool = True
    stalled: bool = False
    samples: dict = field(default_factory=dict, repr=False)


def _gamma(indicator: np.ndarray) -> float:
    """γ of Au and Beck (2001), eq. 29, from the indicators of *chains* (n_c, n_s)."""
    n_c, n_s = indicator.shape
    p = float(indicator.mean())
    r0 = p * (1.0 - p)
    if n_s < 2 or r0 <= 0.0:
        return 0.0
    out = 0.0
    for k in range(1, n_s):
        r_k = float((indicator[:, :-k] * indicator[:, k:]).mean()) - p * p
        out += 2.0 * (1.0 - k / n_s) * r_k / r0
    return max(out, 0.0)


def subset_simulation(g, sample_prior, n_dims: int, *, n: int = 500, p0: float = 0.1,
                      rho: float = 0.8, max_levels: int = 8, confidence: float = 0.95,
                      seed: int = 0, log=None) -> SubsetResult:
    """P(g ≥ 1) by subset simulation (module docstring).

    Parameters
    ----------
    g : callable(z (m, n_dims), nuisance (m,) object array) -> (m,) float
        The performance function in standard normal coordinates; NaN counts as −inf
        (a point that cannot be evaluated never reaches a level).
    sample_prior : callable(rng, m) -> (z (m, n_dims), nuisance (m,) object array,
        admissible (m,) bool)
        Draws from the prior; ``admissible`` False marks points outside its support
        (rejected: the prior density is 0 there). *z* is ignored for points drawn for the
        nuisance alone (the chains keep their z).
    n : points per level (≥ 20); p0 : conditional probability of a level (n·p0 and 1/p0
        integers); rho : correlation of the chains' moves in (0, 1); max_levels : levels
        after the first before giving up; confidence : of each one-sided bound.
    """
    from scipy.stats import norm

    n_c = int(round(n * p0))
    n_s = int(round(1.0 / p0))
    if n < 20 or n_c * n_s != n or not 0.0 < rho < 1.0:
        raise ValueError(f"subset simulation: n = {n} and p0 = {p0} must make n·p0 and 1/p0 "
                         f"integers with n ≥ 20, and rho = {rho} be in (0, 1); e.g. n = 500, "
                         "p0 = 0.1")
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    log = log or (lambda msg: None)

    def prior(m):
        zs, nus = [], []
        while sum(len(z) for z in zs) < m:
            z, nu, ok = sample_prior(rng, max(m, 8))
            zs.append(z[ok])
            nus.append(nu[ok])
        return np.concatenate(zs)[:m], np.concatenate(nus)[:m]

    def evaluate(z, nu):
        out = np.asarray(g(z, nu), float)
        return np.where(np.isnan(out), -np.inf, out)

    z, nu = prior(n)
    y = evaluate(z, nu)
    evaluations = n
    p_prod, delta2, levels = 1.0, 0.0, []
    indicator_chains = None
    z_lv = norm.ppf(confidence)
    for level in range(max_levels + 1):
        order = np.argsort(-y, kind="stable")
        b = float(y[order[n_c - 1]])
        stalled = bool(levels) and b <= levels[-1]       # the chains no longer climb
        if b >= 1.0 or level == max_levels or stalled:
            hits = y >= 1.0
            share = float(hits.mean())
            gamma = 0.0 if indicator_chains is None else _gamma(indicator_chains >= 1.0)
            if share > 0.0:
                delta2 += (1.0 - share) / (n * share) * (1.0 + gamma)
            reached = b >= 1.0
            break
        levels.append(b)
        p_i = float((y >= b).mean())     # p0, or more when values tie at b
        gamma = 0.0 if indicator_chains is None else _gamma(indicator_chains >= b)
        delta2 += (1.0 - p_i) / (n * p_i) * (1.0 + gamma)
        p_prod *= p_i
        log(f"level {level + 1}: b = {b:.4g} (P ≈ {p_prod:.3g}, {evaluations} runs so far)")
        seeds = order[:n_c]
        cz, cnu, cy = z[seeds].copy(), nu[seeds].copy(), y[seeds].copy()
        chain_z, chain_nu, chain_y = [cz.copy()], [cnu.copy()], [cy.copy()]
        for _ in range(n_s - 1):
            pz, pnu, ok = sample_prior(rng, n_c)     # candidates for the nuisance variables
            move = rng.random(n_c) < 0.5
            cand_nu = np.where(move, pnu, cnu)
            cand_z = rho * cz + math.sqrt(1.0 - rho * rho) * rng.standard_normal(cz.shape)
            # admissibility of the moved point (prior support) is checked by g: −inf/NaN
            cand_y = evaluate(cand_z, cand_nu)
            evaluations += n_c
            accept = cand_y >= b
            cz = np.where(accept[:, None], cand_z, cz)
            cnu = np.where(accept, cand_nu, cnu)
            cy = np.where(accept, cand_y, cy)
            chain_z.append(cz.copy())
            chain_nu.append(cnu.copy())
            chain_y.append(cy.copy())
        z = np.concatenate(chain_z)
        nu = np.concatenate(chain_nu)
        y = np.concatenate(chain_y)
        indicator_chains = np.stack(chain_y, axis=1)          # (n_c, n_s)
    probability = p_prod * share
    if probability > 0.0:
        s = math.sqrt(math.log1p(delta2))
        lower, upper = probability * math.exp(-z_lv * s), probability * math.exp(z_lv * s)
    else:
        lower, upper = 0.0, p_prod * -math.expm1(math.log1p(-confidence) / n)
    return SubsetResult(probability=probability, lower=min(lower, 1.0), upper=min(upper, 1.0),
                        confidence=float(confidence), cov=math.sqrt(delta2),
                        levels=tuple(levels), evaluations=evaluations, reached=bool(reached),
                        stalled=stalled,
                        samples={"z": z, "nuisance": nu, "g": y})
