"""Subset simulation: the probability of a rare event of a simulation, P(g(X) ≥ 1), as a
product of conditional probabilities (docs/evidence.md).

Au, S.-K. and Beck, J. L. (2001), *Estimation of small failure probabilities in high
dimensions by subset simulation*, Probabilistic Engineering Mechanics 16(4), 263–277
(the estimator, eq. 5, and its coefficient of variation, eqs. 27–29); the Markov chains
move in standard normal space by the adaptive conditional sampling of Papaioannou, I.,
Betz, W., Zwirglmaier, K. and Straub, D. (2015), *MCMC algorithms for subset
simulation*, Probabilistic Engineering Mechanics 41, 89–103 (§4.2 and §5: coordinate k
moves to z'_k = ρ_k z_k + σ_k ξ_k, σ_k = min(1, λ σ̂_k), ρ_k = √(1 − σ_k²), which leaves
N(0, I) invariant, accepted when it stays in the current level's domain; σ̂_k is the
spread of the level's seeds in coordinate k and λ is adapted towards an acceptance rate of
0.44: the level's chains run in groups of a fifth of them, one group after the other, each
with λ fixed over its steps, and λ ← λ·exp((â − 0.44)/√i) after the i-th group, â its
acceptance rate; λ is carried from one level to the next). Adapting λ after every step of
all chains at once instead made each chain's kernel depend on its own last states, and on
addsafe-mc the chains drifted below the conditional distribution within a level.

Level 0 draws *n* points from the prior. At each level the p₀-quantile b of g over the
level's points is the next intermediate threshold; the level's conditional probability is
the share of points with g ≥ b (p₀, or more when values tie at b). The points ≥ b seed
n·p₀ chains of ⌊1/p₀⌋ states conditional on g ≥ b (the next *n* points): the seeds in a
random order when there are more of them than chains, each seed starting one or more
chains when there are fewer. Once the p₀-quantile reaches 1, P̂ = Π P_i × (share of the
last level's points with g ≥ 1).

**Plateaus.** When g is constant over a region (a margin that saturates), the p₀-quantile
can equal the previous threshold and the chains stop climbing. The threshold is then the
smallest value above the previous one among the level's points (a conditional probability
below p₀, estimated from fewer points); only when no point lies above the previous
threshold does the simulation stop, *stalled*.

**Nuisance variables.** Besides the standard normal coordinates a point carries
*nuisance* variables drawn by the caller (e.g. which manoeuvre, which noise stream). A
chain step moves either the normal coordinates (with the nuisance held) or, with
probability ``nuisance_share``, the nuisance alone by the caller's ``redraw`` (a proposal
reversible with respect to the nuisance's prior, e.g. a fresh noise stream; accepted when
g stays ≥ b). Both moves leave the prior restricted to the level's domain invariant, so
does their mixture. A nuisance ``redraw`` does not change holds it, e.g. a discrete choice
such as the manoeuvre: the chains then keep their seed's choice, and the share of each
choice at a level is that of its seeds (the estimator stays consistent; the chains do not
mix between choices, which widens its variance).

**When margin 1 is not reached** within ``max_levels`` levels, the result is the highest
level it reached, b*, the p₀-quantile of the last level's points, with P̂(g ≥ b*) =
Π P_i × P_{L+1}: an estimate of that probability, with its bounds, and since g ≥ 1
implies g ≥ b*, its upper bound is an upper bound of P(g ≥ 1) as well. It is never
reported as 0.

The interval: δ² = Σ_i δ_i², δ_i² = (1 − P_i)/(n P_i)·(1 + γ_i) with γ_i from the
correlation of the chains' indicators (Au and Beck 2001, eqs. 27–29; γ_0 = 0; the
effective sample size of a level is n/(1 + γ_i)), the levels taken as uncorrelated (which
understates δ); log P̂ is taken as normal with standard deviation √(ln(1 + δ²)), and each
bound is one-sided at the confidence asked. The estimator is biased by O(1/n) and the
interval is asymptotic: they are a cross-check of the tail fit, not an exact bound.
Deterministic for a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["P0", "SAMPLER_VERSION", "SubsetLevel", "SubsetResult", "subset_simulation"]

#: Version of the chains' moves: the points a seed leads to change with it, so stored
#: evaluations of another version are not reused (``campaign.evidence.certify``'s batch store).
SAMPLER_VERSION = "acs-3"

#: Target acceptance rate of the normal-coordinate moves (Papaioannou et al. 2015, §5:
#: 0.44, the optimum of a one-dimensional random walk, which they found robust).
TARGET_ACCEPTANCE = 0.44

#: Fewest distinct seeds whose spread σ̂_k sets the proposal spreads; with fewer, σ̂_k = 1
#: (the prior's) and λ alone adapts them (est.: the spread of 4 points says little).
MIN_DISTINCT_SEEDS = 5

#: Initial scale λ of the proposal spreads (Papaioannou et al. 2015, §5: 0.6).
INITIAL_SCALE = 0.6


@dataclass(frozen=True)
class SubsetLevel:
    """Diagnostics of one level of :func:`subset_simulation`.

    threshold : b_i (g units); the last level of a result that reached 1 has b = 1
    conditional : P_i, the share of the previous level's points with g ≥ b_i
    probability : P̂(g ≥ b_i) = Π_{j ≤ i} P_j
    gamma : γ_i of Au and Beck (2001), eq. 29 (0 for the first level: i.i.d. points)
    cov : δ_i, the coefficient of variation of P_i (eq. 28)
    ess : effective sample size n/(1 + γ_i) of the points P_i was counted on
    acceptance : acceptance rate of the chains started at this level (NaN when no chain
        was started from it: the last level)
    acceptance_nuisance : that of their nuisance moves alone (NaN without any)
    scale : λ, the scale of the proposal spreads at the level's last step
    seeds : distinct points ≥ b_i the level's chains started from
    distinct_nuisance : distinct nuisance values (e.g. noise streams) among the n points
        the level's chains produced (0 when none were produced): when it collapses, the
        chains explore the normal coordinates for a few nuisance values only and the
        estimate rests on those
    """

    threshold: float
    conditional: float
    probability: float
    gamma: float
    cov: float
    ess: float
    acceptance: float = math.nan
    acceptance_nuisance: float = math.nan
    scale: float = math.nan
    seeds: int = 0
    distinct_nuisance: int = 0


@dataclass(frozen=True)
class SubsetResult:
    """The outcome of :func:`subset_simulation`.

    probability : P̂(g ≥ 1) when ``reached``; NaN otherwise (see ``reached_level``)
    lower, upper : one-sided bounds at *confidence* of P(g ≥ ``reached_level``) — of
        P(g ≥ 1) when ``reached``; otherwise ``upper`` bounds P(g ≥ 1) from above too
    cov : δ, the estimated coefficient of variation of the reported probability
    levels : intermediate thresholds b_1 … b_L (g units)
    evaluations : calls of g (points simulated)
    reached : whether points with g ≥ 1 were found (the estimate of P(g ≥ 1) is complete)
    reached_level : 1 when ``reached``, else b*, the highest level whose probability is
        estimated (module docstring); −inf when no point could be evaluated
    reached_probability : P̂(g ≥ ``reached_level``) (= ``probability`` when reached); > 0
        whenever some point could be evaluated
    stalled : whether the chains stopped climbing (no point above the previous threshold:
        g constant over the region the chains explore)
    diagnostics : one :class:`SubsetLevel` per threshold, including the last
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
    reached_level: float = 1.0
    reached_probability: float = math.nan
    diagnostics: tuple = ()
    samples: dict = field(default_factory=dict, repr=False)

    def to_pandas(self):
        """The levels' diagnostics as a DataFrame, one row per :class:`SubsetLevel`
        (``level`` 1, 2, … in order)."""
        import dataclasses

        import pandas as pd

        names = [f.name for f in dataclasses.fields(SubsetLevel)]
        rows = [dataclasses.asdict(d) for d in self.diagnostics]
        out = pd.DataFrame(rows, columns=names)
        out.insert(0, "level", np.arange(1, len(out) + 1, dtype="int64"))
        for c in ("seeds", "distinct_nuisance"):
            out[c] = out[c].astype("int64")
        return out


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


#: Chains per adaptation group as a share of a level's chains (Papaioannou et al. 2015,
#: §5: 0.1–0.2; 0.2 keeps a batch of runs at 10 for 50 chains).
GROUP_SHARE = 0.2


def _groups(n_c: int) -> int:
    """Number of adaptation groups of *n_c* chains."""
    return max(1, int(round(1.0 / GROUP_SHARE))) if n_c >= 5 else 1


def _distinct(values: list) -> int:
    """Distinct values among the object arrays *values* (0 when they cannot be hashed)."""
    try:
        return len({v for arr in values for v in arr.tolist()})
    except TypeError:
        return 0


def _next_threshold(y: np.ndarray, n_c: int, previous: float | None) -> float | None:
    """The next intermediate threshold: the p₀-quantile of *y* (its n_c-th largest value),
    or, when that does not rise above *previous* (a plateau), the smallest value above
    it; None when no value lies above *previous*."""
    b = float(np.sort(y)[::-1][n_c - 1])
    if previous is None or b > previous:
        return b
    above = y[y > previous]
    return float(above.min()) if above.size else None


def _chain_starts(rng, candidates: np.ndarray, n_c: int) -> tuple[np.ndarray, int]:
    """Indices of the n_c chains' seeds among *candidates* (the points ≥ b): a random
    n_c of them, or each one in turn when there are fewer."""
    if candidates.size >= n_c:
        return rng.permutation(candidates)[:n_c], n_c
    return candidates[np.arange(n_c) % candidates.size], int(candidates.size)


#: Conditional probability of one level of the subset simulation the certificate runs
#: (Au & Beck 2001's usual choice: a level's seeds are the best tenth of its runs).
P0 = 0.1


def subset_simulation(g, sample_prior, n_dims: int, *, n: int = 500, p0: float = P0,
                      max_levels: int = 8, confidence: float = 0.95, seed: int = 0,
                      redraw=None, nuisance_share: float = 0.2, log=None) -> SubsetResult:
    """P(g ≥ 1) by subset simulation (module docstring).

    Parameters
    ----------
    g : callable(z (m, n_dims), nuisance (m,) object array) -> (m,) float
        The performance function in standard normal coordinates; NaN counts as −inf
        (a point that cannot be evaluated, or outside the prior's support, never reaches
        a level).
    sample_prior : callable(rng, m) -> (z (m, n_dims), nuisance (m,) object array,
        admissible (m,) bool)
        Draws from the prior; ``admissible`` False marks points outside its support
        (rejected: the prior density is 0 there).
    redraw : callable(rng, nuisance (m,) object array) -> (m,) object array, optional
        A proposal for the nuisance variables, reversible with respect to their prior
        (e.g. a fresh noise stream, the rest kept); without it the chains hold each
        point's nuisance.
    n : points per level (≥ 20); p0 : conditional probability of a level (n·p0 and 1/p0
        integers); max_levels : levels after the first before giving up; confidence : of
        each one-sided bound; nuisance_share : probability in [0, 1) that a chain step
        moves the nuisance (with *redraw*) instead of the normal coordinates.
    """
    from scipy.stats import norm

    n_c = int(round(n * p0))
    n_s = int(round(1.0 / p0))
    if n < 20 or n_c * n_s != n:
        raise ValueError(f"subset simulation: n = {n} and p0 = {p0} must make n·p0 and 1/p0 "
                         f"integers with n ≥ 20; e.g. n = 500, p0 = 0.1")
    if not 0.0 <= nuisance_share < 1.0:
        raise ValueError(f"subset simulation: nuisance_share = {nuisance_share} must be in "
                         "[0, 1), e.g. 0.2")
    share_nu = nuisance_share if redraw is not None else 0.0
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
    p_prod, delta2, levels, diag = 1.0, 0.0, [], []
    chains_y = None                         # (n_c, n_s) margins of the last level's chains
    scale = INITIAL_SCALE
    stalled = False
    z_lv = norm.ppf(confidence)

    def conditional(b):
        """P_i, δ_i², γ_i of the current points at threshold b."""
        p_i = float((y >= b).mean())
        gamma = 0.0 if chains_y is None else _gamma(chains_y >= b)
        d2 = (1.0 - p_i) / (n * p_i) * (1.0 + gamma) if p_i > 0.0 else math.inf
        return p_i, d2, gamma

    for level in range(max_levels + 1):
        previous = levels[-1] if levels else None
        b = _next_threshold(y, n_c, previous)
        if b is None or not math.isfinite(b):
            stalled = b is None
            break
        if b >= 1.0 or level == max_levels:
            break
        p_i, d2, gamma = conditional(b)
        delta2 += d2
        p_prod *= p_i
        levels.append(b)
        log(f"level {level + 1}: b = {b:.4g} (P ≈ {p_prod:.3g}, {evaluations} runs so far)")
        # -- the chains of this level ----------------------------------------------------
        starts, n_seeds = _chain_starts(rng, np.flatnonzero(y >= b), n_c)
        distinct = np.unique(z[starts], axis=0)
        spread_hat = (np.std(distinct, axis=0) if len(distinct) >= MIN_DISTINCT_SEEDS
                      else np.ones(n_dims))
        st_z = np.empty((n_s, n_c, n_dims))
        st_nu = np.empty((n_s, n_c), dtype=object)
        st_y = np.empty((n_s, n_c))
        st_z[0], st_nu[0], st_y[0] = z[starts], nu[starts], y[starts]
        moved = accepted = moved_nu = accepted_nu = 0
        # groups of chains run one after the other, each with λ fixed over its steps and
        # adapted after it from its acceptance (Papaioannou et al. 2015, §5): a chain's
        # kernel never depends on its own states
        for i_group, group in enumerate(np.array_split(np.arange(n_c), _groups(n_c)), 1):
            sigma = np.minimum(scale * spread_hat, 1.0)
            rho = np.sqrt(1.0 - sigma * sigma)
            cz, cnu, cy = st_z[0, group].copy(), st_nu[0, group].copy(), st_y[0, group].copy()
            g_moved = g_accepted = 0
            for step in range(1, n_s):
                xi = rng.standard_normal(cz.shape)
                which_nu = rng.random(len(group)) < share_nu
                cand_z = np.where(which_nu[:, None], cz, rho * cz + sigma * xi)
                cand_nu = cnu.copy()
                if redraw is not None:
                    fresh = redraw(rng, cnu)
                    cand_nu[which_nu] = fresh[which_nu]
                cand_y = evaluate(cand_z, cand_nu)
                evaluations += len(group)
                accept = cand_y >= b
                cz = np.where(accept[:, None], cand_z, cz)
                cnu = np.where(accept, cand_nu, cnu)
                cy = np.where(accept, cand_y, cy)
                st_z[step, group], st_nu[step, group], st_y[step, group] = cz, cnu, cy
                g_moved += int((~which_nu).sum())
                g_accepted += int((accept & ~which_nu).sum())
                moved_nu += int(which_nu.sum())
                accepted_nu += int((accept & which_nu).sum())
            moved, accepted = moved + g_moved, accepted + g_accepted
            if g_moved:
                scale = math.exp(math.log(scale) + (g_accepted / g_moved - TARGET_ACCEPTANCE)
                                 / math.sqrt(i_group))
        chain_nu = list(st_nu)
        diag.append(SubsetLevel(
            threshold=b, conditional=p_i, probability=p_prod, gamma=gamma,
            cov=math.sqrt(d2), ess=n / (1.0 + gamma),
            acceptance=accepted / moved if moved else math.nan,
            acceptance_nuisance=accepted_nu / moved_nu if moved_nu else math.nan,
            scale=scale, seeds=n_seeds, distinct_nuisance=_distinct(chain_nu)))
        # states of chain c at step s are at s·n_c + c: the chains' states interleaved
        z = st_z.reshape(n_s * n_c, n_dims)
        nu = st_nu.reshape(n_s * n_c)
        y = st_y.reshape(n_s * n_c)
        chains_y = st_y.T                              # (n_c, n_s)

    # -- the last level: g ≥ 1 if any point reached it, else the highest level reached ----
    reached = bool((y >= 1.0).any())
    top = 1.0 if reached else _next_threshold(y, n_c, levels[-1] if levels else None)
    if top is None:                     # nothing above the last threshold: it is the top
        stalled, top = True, levels[-1]
    elif math.isfinite(top):
        p_i, d2, gamma = conditional(top)
        delta2 += d2
        p_prod *= p_i
        diag.append(SubsetLevel(threshold=top, conditional=p_i, probability=p_prod,
                                gamma=gamma, cov=math.sqrt(d2), ess=n / (1.0 + gamma)))
    level_prob = p_prod if math.isfinite(top) else math.nan
    if math.isfinite(level_prob) and level_prob > 0.0:
        s = math.sqrt(math.log1p(delta2))
        lower, upper = level_prob * math.exp(-z_lv * s), level_prob * math.exp(z_lv * s)
    else:
        lower, upper = math.nan, math.nan
    return SubsetResult(probability=level_prob if reached else math.nan,
                        lower=min(lower, 1.0), upper=min(upper, 1.0),
                        confidence=float(confidence), cov=math.sqrt(delta2),
                        levels=tuple(levels), evaluations=evaluations, reached=reached,
                        stalled=stalled, reached_level=top, reached_probability=level_prob,
                        diagnostics=tuple(diag), samples={"z": z, "nuisance": nu, "g": y})
