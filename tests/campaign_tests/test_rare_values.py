"""campaign/evidence/rare.py by value: γ of Au and Beck (2001, eq. 29) written out with
loops, the chains' adaptation groups (a fifth of the chains, at least five of them), the
distinct nuisance values, every level's δ_i and effective sample size from eqs. 27–28,
the defaults and the smallest n, and the diagnostics' table (docs/evidence.md)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from campaign.evidence.rare import (
    GROUP_SHARE,
    SubsetLevel,
    SubsetResult,
    _chain_starts,
    _distinct,
    _gamma,
    _groups,
    _next_threshold,
    subset_simulation,
)


def gamma_by_hand(ind: np.ndarray) -> float:
    """Au and Beck (2001), eqs. 27–29: R_k = 1/(N − k N_c) Σ_j Σ_i I_{j,i} I_{j,i+k} − p²,
    γ = 2 Σ_{k=1}^{N_s−1} (1 − k/N_s) R_k/R_0, R_0 = p(1 − p); clipped at 0 here."""
    n_c, n_s = ind.shape
    p = ind.sum() / (n_c * n_s)
    r0 = p * (1 - p)
    total = 0.0
    for k in range(1, n_s):
        s = sum(ind[j, i] * ind[j, i + k] for j in range(n_c) for i in range(n_s - k))
        total += 2 * (1 - k / n_s) * (s / (n_c * n_s - k * n_c) - p * p) / r0
    return max(total, 0.0)


def test_gamma_is_eq_29_of_au_and_beck():
    # chains that hold their indicator for five states: strongly correlated, γ = 4
    held = np.array([[1] * 10, [0] * 10, [1] * 5 + [0] * 5, [0] * 5 + [1] * 5], float)
    assert _gamma(held) == pytest.approx(gamma_by_hand(held), rel=1e-12)
    assert _gamma(held) == pytest.approx(4.0, rel=1e-12)
    # four sticky chains (each state flipped with probability 0.35): 0 < γ < 1, which
    # tells max(γ, 0) from max(γ, 1)
    sticky = np.array([[0, 0, 1, 1, 1, 1, 0, 0, 0, 0], [1, 1, 1, 1, 1, 1, 0, 0, 0, 0],
                       [1, 1, 1, 1, 1, 0, 1, 1, 1, 1], [1, 1, 1, 1, 1, 0, 0, 0, 1, 1]], float)
    assert 0.0 < gamma_by_hand(sticky) < 1.0
    assert _gamma(sticky) == pytest.approx(gamma_by_hand(sticky), rel=1e-12)
    # alternating chains are anti-correlated: the sum is negative, γ is 0
    alternating = np.array([[1, 0, 1, 0, 1, 0], [0, 1, 0, 1, 0, 1]], float)
    assert _gamma(alternating) == 0.0
    # no variance (every indicator 0 or every 1) and chains of one state: γ = 0
    assert _gamma(np.zeros((3, 4))) == 0.0 and _gamma(np.ones((3, 4))) == 0.0
    assert _gamma(np.array([[1.0], [0.0]])) == 0.0
    # chains of two states (the shortest with a lag): γ = 2·(1 − 1/2)·R_1/R_0 = 1
    pairs = np.array([[1, 1], [0, 0], [1, 1], [0, 0]], float)
    assert _gamma(pairs) == pytest.approx(gamma_by_hand(pairs), rel=1e-12) == 1.0


def test_a_level_runs_its_chains_in_groups_of_a_fifth():
    """Papaioannou et al. (2015, §5): λ adapted after each group of a fifth of the chains;
    fewer than five chains are one group."""
    assert GROUP_SHARE == 0.2
    assert [_groups(n) for n in (1, 4, 5, 6, 50)] == [1, 1, 5, 5, 5]


def test_distinct_nuisance_values_or_0_when_they_cannot_be_hashed():
    a = np.empty(3, dtype=object)
    a[:] = [(0, 7), (1, 7), (0, 7)]
    b = np.empty(2, dtype=object)
    b[:] = [(1, 7), (2, 9)]
    assert _distinct([a, b]) == 3
    lists = np.empty(2, dtype=object)
    lists[:] = [[0, 7], [1, 7]]
    assert _distinct([lists]) == 0


def test_a_levels_diagnostics_start_empty_and_are_read_only():
    lv = SubsetLevel(0.5, 0.1, 0.1, 0.0, 0.3, 20.0)
    assert (lv.seeds, lv.distinct_nuisance) == (0, 0)
    assert math.isnan(lv.acceptance) and math.isnan(lv.acceptance_nuisance)
    with pytest.raises(dataclasses.FrozenInstanceError):
        lv.seeds = 1
    empty = SubsetResult(math.nan, math.nan, math.nan, 0.95, 0.0).to_pandas()
    assert empty.empty and "level" in empty.columns
    for c in ("level", "seeds", "distinct_nuisance"):
        assert empty[c].dtype == np.int64, c


def _normal_prior(d):
    def prior(rng, m):
        return rng.standard_normal((m, d)), np.zeros(m, dtype=object), np.ones(m, bool)
    return prior


def test_every_levels_delta_and_effective_sample_size_follow_eqs_27_and_28():
    """δ_i² = (1 − P_i)/(n P_i)·(1 + γ_i), γ_1 = 0 (independent points), ess = n/(1 + γ_i),
    δ² = Σ δ_i²; the log says each level with its number, from 1."""
    lines = []
    r = subset_simulation(lambda z, nu: z[:, 0] / 3.5, _normal_prior(2), 2, n=100, seed=4,
                          log=lines.append)
    assert r.reached and len(r.diagnostics) >= 3
    first = r.diagnostics[0]
    assert first.gamma == 0.0
    for lv in r.diagnostics:
        p = lv.conditional
        assert lv.cov == pytest.approx(math.sqrt((1 - p) / (100 * p) * (1 + lv.gamma)),
                                       rel=1e-12)
        assert lv.ess == pytest.approx(100 / (1 + lv.gamma), rel=1e-12)
    assert any(lv.gamma > 0 for lv in r.diagnostics[1:])
    assert r.cov == pytest.approx(math.sqrt(sum(lv.cov ** 2 for lv in r.diagnostics)),
                                  rel=1e-12)
    assert [ln.split(":")[0] for ln in lines] == [f"level {i + 1}"
                                                  for i in range(len(r.levels))]
    assert lines[0].startswith(f"level 1: b = {r.levels[0]:.4g} (P ≈ 0.1, 100 runs so far)")


def test_the_defaults_and_the_smallest_number_of_points():
    """n = 500 points a level, at most 8 levels after the first, 95 %, seed 0; n ≥ 20."""
    def g(z, nu):                          # P(z ≥ 100): never reached
        return z[:, 0] / 100.0

    r = subset_simulation(g, _normal_prior(1), 1)
    assert not r.reached and len(r.levels) == 8 and r.confidence == 0.95
    assert r.evaluations == 500 + 8 * 450
    again = subset_simulation(g, _normal_prior(1), 1, n=500, max_levels=8, seed=0)
    assert (again.reached_level, again.reached_probability) == (r.reached_level,
                                                                r.reached_probability)
    small = subset_simulation(g, _normal_prior(1), 1, n=20, max_levels=1)
    assert small.evaluations == 20 + 18
    with pytest.raises(ValueError, match="n = 10 and p0 = 0.1 must make"):
        subset_simulation(g, _normal_prior(1), 1, n=10)


def test_a_result_and_its_table_of_levels():
    r = SubsetResult(0.1, 0.05, 0.2, 0.95, 0.3)
    assert (r.evaluations, r.reached, r.stalled, r.reached_level) == (0, True, False, 1.0)
    assert "samples" not in repr(r)          # the points of the last level: not printed
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.reached = False
    run = subset_simulation(lambda z, nu: z[:, 0] / 3.0, _normal_prior(1), 1, n=40, seed=2)
    table = run.to_pandas()
    assert table.columns[0] == "level"
    assert table["level"].tolist() == list(range(1, len(run.diagnostics) + 1))
    assert table["threshold"].tolist() == [lv.threshold for lv in run.diagnostics]


def test_the_next_threshold_and_the_chains_seeds():
    """The p0-quantile is the n_c-th largest value; on a plateau the smallest value above the
    previous threshold, None when there is none. n_c seeds: a random n_c of the candidates,
    or each in turn when there are fewer."""
    y = np.array([3.0, 9.0, 1.0, 8.0, 5.0, 8.0])
    assert _next_threshold(y, 2, None) == 8.0 and _next_threshold(y, 3, None) == 8.0
    assert _next_threshold(y, 4, 2.0) == 5.0
    assert _next_threshold(y, 2, 8.0) == 9.0 and _next_threshold(y, 1, 9.0) is None
    rng = np.random.default_rng(0)
    starts, seeds = _chain_starts(rng, np.array([4, 7, 9]), 5)
    assert starts.tolist() == [4, 7, 9, 4, 7] and seeds == 3
    # as many candidates as chains: a random order of them, drawn from the generator
    starts, seeds = _chain_starts(np.random.default_rng(3), np.array([4, 7, 9]), 3)
    want = np.random.default_rng(3).permutation(np.array([4, 7, 9]))
    assert starts.tolist() == want.tolist() != [4, 7, 9] and seeds == 3
    starts, seeds = _chain_starts(rng, np.arange(10), 4)
    assert len(set(starts.tolist())) == 4 and seeds == 4


def test_the_prior_is_drawn_once_when_every_point_is_admissible_and_the_share_limits():
    calls = []

    def prior(rng, m):
        calls.append(m)
        return rng.standard_normal((m, 1)), np.zeros(m, dtype=object), np.ones(m, bool)

    subset_simulation(lambda z, nu: z[:, 0] / 3.0, prior, 1, n=20, max_levels=1)
    assert calls == [20]
    for share in (0.0, 0.5):
        subset_simulation(lambda z, nu: z[:, 0] / 3.0, prior, 1, n=20, max_levels=1,
                          nuisance_share=share)
    for share in (1.0, -0.1):
        with pytest.raises(ValueError, match=f"nuisance_share = {share} must be in"):
            subset_simulation(lambda z, nu: z[:, 0] / 3.0, prior, 1, n=20,
                              nuisance_share=share)
    with pytest.raises(TypeError):
        subset_simulation(lambda z, nu: z[:, 0], prior, 1, 20)      # n by name only


def test_a_quantile_at_exactly_1_ends_at_the_first_level():
    """g = 1 on z > 0.5 (P = 0.31), else 0: the p0-quantile of the first points is 1, so
    P̂ is the share of them with g ≥ 1 and there are no intermediate levels; its one-sided
    bounds are P̂·exp(∓z₀.₉₅ √ln(1 + δ²)), δ² = (1 − P̂)/(n P̂)."""
    def g(z, nu):
        return np.where(z[:, 0] > 0.5, 1.0, 0.0)

    r = subset_simulation(g, _normal_prior(1), 1, n=100, seed=3)
    z0 = np.random.default_rng(np.random.SeedSequence(3)).standard_normal((100, 1))
    share = float((z0[:, 0] > 0.5).mean())
    assert r.reached and r.levels == () and r.probability == share
    d2 = (1 - share) / (100 * share)
    s = math.sqrt(math.log1p(d2))
    z95 = 1.6448536269514722
    assert r.cov == pytest.approx(math.sqrt(d2), rel=1e-12)
    assert r.lower == pytest.approx(share * math.exp(-z95 * s), rel=1e-9)
    assert r.upper == pytest.approx(share * math.exp(z95 * s), rel=1e-9)


def test_an_upper_bound_above_1_is_1():
    """19 of the first 20 points at g = 1 (all but the lowest): P̂ = 0.95, δ² = 0.05/19, and
    P̂·exp(z₀.₉₅ √ln(1 + δ²)) = 1.03 is reported as 1."""
    def g(z, nu):
        return np.where(z[:, 0] > z[:, 0].min(), 1.0, 0.0)

    r = subset_simulation(g, _normal_prior(1), 1, n=20, seed=1)
    assert r.reached and r.probability == 0.95 and r.levels == ()
    s = math.sqrt(math.log1p(0.05 / 19))
    assert 0.95 * math.exp(1.6448536269514722 * s) > 1.0
    assert r.upper == 1.0
    assert r.lower == pytest.approx(0.95 * math.exp(-1.6448536269514722 * s), rel=1e-9)


def test_a_plateau_stalls_at_the_level_it_reached():
    """g = min(z/6, 0.5): two levels below the plateau, then the plateau 0.5 as the third
    threshold; no point of the chains lies above it, so the simulation stalls there with
    P̂(g ≥ 0.5) of that level."""
    r = subset_simulation(lambda z, nu: np.minimum(z[:, 0] / 6.0, 0.5), _normal_prior(1), 1,
                          n=100, seed=5)
    assert len(r.levels) >= 3 and r.levels[-1] == 0.5 > r.levels[1]
    assert r.stalled and not r.reached and r.reached_level == 0.5
    assert len(r.diagnostics) == len(r.levels)
    assert r.reached_probability == r.diagnostics[-1].probability > 0.0


def test_no_point_evaluated_is_no_estimate_and_not_a_stall():
    r = subset_simulation(lambda z, nu: np.full(len(z), np.nan), _normal_prior(1), 1, n=20)
    assert not r.reached and not r.stalled and r.reached_level == -math.inf
    assert math.isnan(r.probability) and math.isnan(r.upper) and r.diagnostics == ()


def test_each_levels_acceptance_and_scale_from_the_chains_moves():
    """n = 20: 2 chains of 10 states, one adaptation group. Every evaluation after the first
    20 is a candidate of a chain step (no nuisance moves); level i's acceptance is the share
    of its 18 candidates with g ≥ b_i (ties at b_i accepted: g takes steps of 1/12), and
    λ after it is λ·exp(â_i − 0.44), from 0.6."""
    calls = []

    def g(z, nu):
        y = np.floor(z[:, 0] * 4.0) / 12.0
        calls.append(y)
        return y

    r = subset_simulation(g, _normal_prior(1), 1, n=20, seed=7, max_levels=6)
    assert len(calls[0]) == 20 and all(len(c) == 2 for c in calls[1:])
    chains = [np.concatenate(calls[1 + 9 * i:10 + 9 * i]) for i in range(len(r.levels))]
    scale = 0.6
    ties = 0
    for lv, cand in zip(r.diagnostics, chains):
        assert lv.acceptance == float((cand >= lv.threshold).mean())
        ties += int((cand == lv.threshold).sum())
        scale *= math.exp(lv.acceptance - 0.44)
        assert lv.scale == pytest.approx(scale, rel=1e-12)
    assert ties > 0                          # candidates on a threshold, accepted


def test_the_last_levels_gamma_is_that_of_the_chains_at_the_level_reached():
    """Not reached within one level: the last threshold b* is the p0-quantile of the chains'
    states, and its γ is eq. 29 of their indicators g ≥ b* (a state at b* counts)."""
    r = subset_simulation(lambda z, nu: z[:, 0] / 10.0, _normal_prior(1), 1, n=40, seed=3,
                          max_levels=1)
    assert not r.reached and len(r.diagnostics) == 2
    y = r.samples["g"]
    chains = y.reshape(10, 4).T                      # state s of chain c at s·n_c + c
    top = r.reached_level
    assert (y == top).sum() >= 1
    assert r.diagnostics[-1].gamma == pytest.approx(gamma_by_hand(chains >= top), rel=1e-12)
    assert gamma_by_hand(chains >= top) > 0.0 == gamma_by_hand(chains > top)


def test_a_chains_first_step_is_the_conditional_sampling_move():
    """Papaioannou et al. (2015, §4.2): the first chain of the first level moves its seed z
    to ρ z + σ ξ, σ = min(λ σ̂, 1), ρ = √(1 − σ²), λ = 0.6 and σ̂ the spread of the level's
    five distinct seeds (n = 50: five chains, the fewest whose spread is used); the draws
    are replayed from the generator in the order the simulation makes them (prior, seeds'
    order, ξ, the nuisance coin)."""
    d, n = 2, 50
    seen = []

    def g(z, nu):
        seen.append(z.copy())
        return z.sum(axis=1) / 8.0

    subset_simulation(g, _normal_prior(d), d, n=n, seed=11, max_levels=1)
    rng = np.random.default_rng(np.random.SeedSequence(11))
    z0 = rng.standard_normal((n, d))
    np.testing.assert_array_equal(seen[0], z0)
    y = z0.sum(axis=1) / 8.0
    b = np.sort(y)[::-1][4]                              # the 5th largest of 50
    starts = rng.permutation(np.flatnonzero(y >= b))[:5]
    seeds = z0[starts]
    assert len(np.unique(seeds, axis=0)) == 5
    sigma = np.minimum(0.6 * np.std(seeds, axis=0), 1.0)
    assert (sigma < 1.0).all() and not np.allclose(sigma, 0.6)
    xi = rng.standard_normal((1, d))
    rng.random(1)
    want = np.sqrt(1.0 - sigma ** 2) * seeds[:1] + sigma * xi
    np.testing.assert_allclose(seen[1], want, rtol=1e-14)


def test_no_bound_of_a_probability_exceeds_1():
    """At a confidence below 1/2 the one-sided "lower" bound lies above the estimate; it is
    still a probability: P̂ = 0.95 (19 of 20 points at g = 1) at confidence 0.01 gives
    0.95·exp(2.33 √ln(1 + 0.05/19)) = 1.07, reported as 1."""
    def g(z, nu):
        return np.where(z[:, 0] > z[:, 0].min(), 1.0, 0.0)

    r = subset_simulation(g, _normal_prior(1), 1, n=20, seed=1, confidence=0.01)
    assert r.probability == 0.95 and r.lower == 1.0 and r.upper < 0.95
