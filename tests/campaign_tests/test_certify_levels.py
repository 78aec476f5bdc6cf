"""The certificate's exceedance curve (campaign.evidence.certify.levels, detectors.tail
.exceedance_curve): the mixture of class tails, the limit of the runs, the levels file and
its validation by brute force (campaign.evidence.certify.validate; docs/evidence.md)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from campaign.evidence.certify.levels import (EXTRAPOLATION_DECADES, LEVEL_COLUMNS, detector_rows,
                                     parse_levels, runs_to_carry, sampling_levels_to_reach)
from campaign.evidence.certify.validate import coverage_table
from detectors.tail import exceedance_curve
from reports.scoring.metrics import upper_bound


def _two_class_sample(seed, n_per=400):
    """Class "a": exponential of mean 1; class "b": exponential of mean 2 (the heavier);
    P(X ≥ x) = ½e^(−x) + ½e^(−x/2) for the even mixture."""
    rng = np.random.default_rng(seed)
    x = np.r_[rng.exponential(1.0, n_per), rng.exponential(2.0, n_per)]
    return x, np.repeat(["a", "b"], n_per)


def _true(x):
    return 0.5 * math.exp(-x) + 0.5 * math.exp(-x / 2.0)


def test_mixture_of_class_tails_covers_a_known_mixture():
    levels = (1.0, 8.0, 12.0)            # true 0.49, 9.2e-3, 1.2e-3
    covered = 0
    for seed in range(20):
        x, cls = _two_class_sample(seed)
        curve = exceedance_curve(x, levels, classes=cls)
        # below every class's tail threshold the probability is counted
        assert curve[0].count == int((x >= 1.0).sum())
        assert all(part[1] == "counted" for part in curve[0].parts)
        # the weights are the classes' shares, the estimate their weighted sum
        e = curve[2]
        assert [p[4] for p in e.parts] == [0.5, 0.5]
        if e.method == "mixture":
            assert e.estimate == pytest.approx(sum(p[2] * p[4] for p in e.parts), rel=1e-12)
            assert e.upper == pytest.approx(sum(p[3] * p[4] for p in e.parts), rel=1e-12)
        # never above the pooled counting bound, which is valid for the mixture too
        assert e.upper <= upper_bound(e.count, x.size) * (1 + 1e-12)
        covered += all(c.upper >= _true(c.level) for c in curve)
    # 95 % one-sided bounds; the mixture's is the sum of the class bounds (conservative):
    # at least 17 of 20 samples cover at every level (18 measured; P(≤ 16 of 20 | 0.95) =
    # 1.6 % for one level)
    assert covered >= 17


def test_the_limit_of_the_runs_replaces_a_bound_the_runs_cannot_carry():
    # margins uniform on [0, 0.3] (a bounded tail: the fit's bound at 1.0 is ~0)
    rng = np.random.default_rng(5)
    m = rng.uniform(0.0, 0.3, 1200)
    rows = detector_rows("d", m, np.repeat(["m1", "m2"], 600), (0.2, 1.0))
    at1 = rows[1]
    cp = stats.beta.ppf(0.95, 1, 1200)   # exact CP bound at 0 of 1200: 2.49e-3
    assert at1["p_counted_upper95"] == pytest.approx(cp, rel=1e-9)
    assert at1["p_upper95"] == pytest.approx(cp / 10 ** EXTRAPOLATION_DECADES, rel=1e-9)
    assert at1["method"] == "limit of the runs"
    assert math.isnan(at1["p_estimate"])                    # not given as a number
    assert "run about" in at1["note"] and "--sampling" in at1["note"]
    assert at1["p_model_upper95"] < at1["p_upper95"]
    # at 0.2 a third of the runs are above: counted, the estimate is the share
    assert rows[0]["n_exceed"] == int((m >= 0.2).sum())
    assert rows[0]["p_estimate"] == pytest.approx(rows[0]["n_exceed"] / 1200)
    assert set(rows[0]) == set(LEVEL_COLUMNS)


def test_runs_and_sampling_needed_to_carry_a_bound():
    # n ≥ ln(0.05)/ln(1 − 100 p): 1e-7 → 299 572 runs (≈ 3/(100 p))
    assert runs_to_carry(1e-7) == math.ceil(math.log(0.05) / math.log1p(-1e-5))
    assert 0.95 * 3e5 < runs_to_carry(1e-7) < 1.05 * 3e5
    n = runs_to_carry(1e-7)
    assert upper_bound(0, n) / 100 <= 1e-7 < upper_bound(0, n - 1) / 100
    assert sampling_levels_to_reach(1e-7) == 7 and sampling_levels_to_reach(2e-5) == 5


def test_levels_are_parsed_or_refused_by_name():
    assert parse_levels("1.0,0.6, 0.7") == (0.6, 0.7, 1.0)
    with pytest.raises(ValueError, match="'x' is not a number"):
        parse_levels("0.6,x")
    with pytest.raises(ValueError, match="not a positive margin"):
        parse_levels("0.6,-1")


def test_coverage_counts_the_brute_force_exceedances():
    curve = pd.DataFrame(detector_rows("d", np.linspace(0, 1, 200), ["m"] * 200,
                                       (0.5, 0.9, 0.99)))
    rng = np.random.default_rng(2)
    bf = rng.uniform(0, 1.0, 5000)
    results = pd.DataFrame({"detector": "d", "fault": "none", "status": "ok", "margin": bf})
    table = coverage_table(curve, results, seed=7)
    for r in table.to_dict(orient="records"):
        c = int((bf >= r["level"]).sum())
        assert r["validation_count"] == c and r["validation_runs"] == 5000
        assert r["tested"] == (c >= 5)
        assert r["covered"] == (c / 5000 <= r["p_upper95"])
        # the exact one-sided lower Clopper–Pearson bound
        assert r["validation_lower95"] == pytest.approx(stats.beta.ppf(0.05, c, 5001 - c),
                                                        rel=1e-9)


def test_a_class_too_small_to_fit_is_counted_in_the_mixture():
    # 30 runs of class "s" (fewer than the 50 a tail fit needs) beside 400 of class "l"
    rng = np.random.default_rng(8)
    x = np.r_[rng.exponential(1.0, 400), rng.exponential(1.0, 30)]
    cls = np.r_[["l"] * 400, ["s"] * 30]
    e = exceedance_curve(x, (6.0,), classes=cls)[0]
    parts = {p[0]: p for p in e.parts}
    assert parts["s"][1] == "counted"
    c = int((x[cls == "s"] >= 6.0).sum())
    assert parts["s"][3] == pytest.approx(upper_bound(c, 30), rel=1e-12)
    assert parts["s"][4] == pytest.approx(30 / 430) and parts["l"][1] == "tail"


def test_printed_certificate_never_shows_an_estimate_below_the_limit():
    from campaign.cli.evidence import format_certificate, format_levels
    from campaign.evidence.certify.levels import level_table

    rng = np.random.default_rng(5)
    results = pd.DataFrame({"detector": "d", "fault": "none", "status": "ok",
                            "manoeuvre": np.repeat(["m1", "m2"], 600),
                            "margin": rng.uniform(0.0, 0.3, 1200)})
    curve = level_table(results, (0.6, 1.0))
    assert curve["method"].tolist() == ["limit of the runs"] * 2
    cert = pd.DataFrame([{"detector": "d", "level": 0.95, "n_runs": 1200, "fa_count": 0,
                          "fa_upper95_cp": curve["p_counted_upper95"].iloc[1],
                          "fa_prob_evt": curve["p_estimate"].iloc[1],
                          "fa_prob_evt_upper95": curve["p_upper95"].iloc[1],
                          "evt_note": curve["note"].iloc[1], "sampling_runs": 0,
                          "sampling_prob": math.nan, "sampling_lower95": math.nan,
                          "sampling_upper95": math.nan, "fa_per_hour_upper95": 0.15}])
    text = format_certificate(cert)
    line = text.splitlines()[1]
    # the estimate is "<limit", the bound the limit 2.49e-5, the sampled columns "—"
    assert "<2.5e-05" in line and "2.49e-05" in line and line.count("—") == 2
    assert "e-1" not in line.replace("e-05", "")      # no tiny number such as 7.95e-124
    assert "2.49e-05*" in format_levels(curve)


def test_report_tail_plots_show_the_manoeuvre_that_dominates_the_bound():
    """The mean-excess and QQ figures fit the tail of the curve's dominant manoeuvre at margin
    1 (``tail_class``), not merely the manoeuvre of the largest margin: here "a" holds the
    largest margin but "b" dominates the bound; without a curve the largest margin decides."""
    from campaign.evidence.figures import _tail_specs

    rng = np.random.default_rng(7)
    margins = np.r_[0.1 * rng.exponential(size=200), 5.0, 0.2 * rng.exponential(size=200)]
    g = pd.DataFrame({"margin": margins, "manoeuvre": ["a"] * 201 + ["b"] * 200})
    curve = pd.DataFrame({"detector": ["d", "d"], "level": [0.9, 1.0],
                          "tail_class": ["a", "b"]})
    specs = _tail_specs("d", g, curve)
    assert [s[5][0].size for s in specs[:1]] == [200] and "b (the manoeuvre whose" in specs[0][3]
    assert "a (the manoeuvre of the largest margin)" in _tail_specs("d", g, None)[0][3]


def _loglik_elementwise(y, sigma, xi):
    """The generalised Pareto log-likelihood written elementwise (Coles 2001 eq. 4.10): a
    new array at each step, the support tested on every excess."""
    sigma, xi = np.broadcast_arrays(np.asarray(sigma, float), np.asarray(xi, float))
    q = y / sigma[..., None]
    zero = xi == 0.0
    safe = np.where(zero, 1.0, xi)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = safe[..., None] * q
        inside = (z > -1.0).all(axis=-1) & (sigma > 0.0)
        tail = np.where(zero, q.sum(axis=-1),
                        (1.0 + 1.0 / safe) * np.log1p(np.where(z > -1.0, z, 0.0)).sum(axis=-1))
        ll = -y.size * np.log(sigma) - tail
    return np.where(inside, ll, -np.inf)


def test_the_in_place_log_likelihood_is_the_elementwise_one_to_the_bit():
    from detectors.tail import SHAPES, _loglik

    rng = np.random.default_rng(11)
    for trial in range(60):
        k = int(rng.integers(0, 3)) if trial % 10 == 0 else int(rng.integers(3, 2500))
        # excesses (positive, as the tail fits give them) or any reals (negative values too)
        y = rng.exponential(rng.uniform(0.05, 3.0), k) if trial % 3 else rng.normal(size=k)
        t = rng.uniform(1e-3, 50.0, (3, 1))
        sigma = t / rng.uniform(0.01, 5.0, SHAPES.size)
        # scales at and beyond the edges: zero, negative, infinite, NaN, tiny, huge
        sigma.flat[rng.integers(0, sigma.size, 12)] = rng.choice(
            [0.0, -1.0, np.inf, np.nan, 1e-300, 1e300], 12)
        xi = np.broadcast_to(SHAPES, sigma.shape)     # ξ from −0.5 to 1, ξ = 0 included
        for args in ((y, sigma, xi), (y, sigma[0], SHAPES), (y, sigma[0, 100], 0.0),
                     (y, sigma[1, 7], SHAPES[7])):
            with np.errstate(all="ignore"):
                fast, ref = _loglik(*args), _loglik_elementwise(*args)
            assert fast.shape == ref.shape
            np.testing.assert_array_equal(fast, ref)   # same bits; −inf outside the support
    # the support is decided at the extreme excesses: ξ < 0 with σ just too small for the
    # largest excess is outside, as the elementwise test over every excess says
    y = np.array([0.1, 0.5, 2.0])
    assert _loglik(y, 0.99, -0.5) == -np.inf
    assert np.isfinite(_loglik(y, 1.01, -0.5))


def test_the_curve_of_a_mixture_is_the_same_on_threads():
    x, cls = _two_class_sample(3, n_per=700)
    cls = np.where(np.arange(x.size) % 3 == 0, "c", cls)      # three classes
    levels = (0.5, 6.0, 10.0, 14.0)
    one = exceedance_curve(x, levels, classes=cls)
    assert any(p[1] == "tail" for e in one for p in e.parts)  # the tail fits are exercised
    assert exceedance_curve(x, levels, classes=cls, jobs=2) == one
    # the classes as str objects (as certify holds them) or as numbers named by their str
    assert exceedance_curve(x, levels, classes=cls.astype(object)) == one
    # a → 10, b → 2, c → 3: ordered as str ("10" < "2" < "3"), as a, b, c are, not as numbers
    codes = np.array([10, 2, 3])[np.searchsorted(np.array(["a", "b", "c"]), cls)]
    numbered = exceedance_curve(x, levels, classes=codes)
    assert [[p[0] for p in e.parts] for e in numbered] == [["10", "2", "3"]] * len(levels)
    assert [(e.estimate, e.upper) for e in numbered] == [(e.estimate, e.upper) for e in one]
    rows = detector_rows("d", x, cls, levels)
    assert detector_rows("d", x, cls, levels, jobs=3) == rows


def test_the_log_likelihood_taken_a_block_at_a_time_is_the_same(monkeypatch):
    import detectors.tail as tail

    rng = np.random.default_rng(4)
    y = rng.exponential(0.7, 450)
    sigma = rng.uniform(0.05, 4.0, (3, tail.SHAPES.size))
    xi = np.broadcast_to(tail.SHAPES, sigma.shape)
    whole = tail._loglik(y, sigma, xi)           # 3 × 301 × 450 terms: one block
    monkeypatch.setattr(tail, "LOGLIK_TERMS", 1000)   # two pairs a block, and a remainder
    np.testing.assert_array_equal(tail._loglik(y, sigma, xi), whole)
    monkeypatch.setattr(tail, "LOGLIK_TERMS", 10)     # fewer terms than one pair has
    np.testing.assert_array_equal(tail._loglik(y, sigma, xi), whole)
