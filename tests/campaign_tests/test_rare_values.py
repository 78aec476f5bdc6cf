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
    _distinct,
    _gamma,
    _groups,
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
