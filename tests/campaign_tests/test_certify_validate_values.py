"""campaign/evidence/certify/validate.py by value: the coverage table of a curve against
brute-force margins at the decision boundaries (a margin equal to the level exceeds it, five
exceedances are tested and four are not, a frequency or its lower bound equal to p_upper95
covers it), the summary in words, the validation options checked before any work and the
validation campaign's configuration (docs/evidence.md, "Validation by brute force")."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from campaign import run
from campaign.config import CampaignConfig
from campaign.evidence.certify import CertifyError
from campaign.evidence.certify.rows import CertifyRows
from campaign.evidence.certify.validate import (
    MIN_VALIDATION_EXCEEDANCES,
    VALIDATION_COLUMNS,
    check_validation,
    coverage_table,
    summarise,
    validate,
    validate_levels,
    validation_config,
)
from reports.scoring.metrics import lower_bound
from small_campaigns import small_campaign


def curve(*points) -> pd.DataFrame:
    """Rows of certificate-levels.parquet: (detector, level, p_upper95) each, at 95 %."""
    return pd.DataFrame([{"detector": d, "level": lv, "p_estimate": p / 2, "p_upper95": p,
                          "method": "mixture", "n_runs": 400, "confidence": 0.95}
                         for d, lv, p in points])


def brute(detector: str, margins) -> pd.DataFrame:
    """Fault-free ok result rows of *detector* with *margins*."""
    m = np.asarray(margins, float)
    return pd.DataFrame({"detector": detector, "fault": "none", "status": "ok", "margin": m})


def test_five_exceedances_are_tested_four_are_not():
    """docs/evidence.md: a level is tested when the brute force shows ≥ 5 exceedances; a
    margin equal to the level exceeds it."""
    assert MIN_VALIDATION_EXCEEDANCES == 5
    m = [1.0] * 5 + [0.5] * 15            # 5 of 20 at exactly 1.0, none above
    table = coverage_table(curve(("d", 1.0, 0.5), ("d", 1.0 + 1e-12, 0.5)), brute("d", m), 3)
    at1, above = table.to_dict(orient="records")
    assert (at1["validation_count"], at1["validation_runs"], at1["tested"]) == (5, 20, True)
    assert (above["validation_count"], above["tested"]) == (0, False)
    table = coverage_table(curve(("d", 1.0, 0.5)), brute("d", m[1:]), 3)
    assert (table["validation_count"].iloc[0], table["tested"].iloc[0]) == (4, False)


def test_a_frequency_equal_to_the_bound_is_covered_and_just_above_it_is_not():
    m = [1.0] * 5 + [0.0] * 15            # f = 5/20 = 0.25 exactly
    lo = float(lower_bound(5, 20, 0.95))
    table = coverage_table(curve(("d", 1.0, 0.25), ("d", 1.0, 0.25 - 1e-12), ("d", 1.0, lo),
                                 ("d", 1.0, lo - 1e-12)), brute("d", m), 3)
    assert table["validation_freq"].tolist() == [0.25] * 4
    assert table["covered"].tolist() == [True, False, False, False]
    # consistent: the frequency's own lower Clopper–Pearson bound at most p_upper95
    assert table["consistent"].tolist() == [True, True, True, False]
    assert table["validation_lower95"].tolist() == pytest.approx([lo] * 4, rel=1e-15)
    # Beta⁻¹(0.05; 5, 16) is the p at which 5 or more of 20 exceed with probability 0.05
    assert stats.binom.sf(4, 20, lo) == pytest.approx(0.05, rel=1e-9)


def test_the_coverage_row_carries_the_curve_and_the_brute_force():
    rng = np.random.default_rng(8)
    m = rng.uniform(0.0, 1.2, 300)
    m[:3] = [np.nan, np.inf, -np.inf]     # not finite: not runs of the brute force
    levels = curve(("d", 0.9, 0.3), ("e", 0.9, 0.3))
    table = coverage_table(levels, brute("d", m), seed=41)
    assert list(table.columns) == list(VALIDATION_COLUMNS)
    d, e = table.to_dict(orient="records")
    finite = m[3:]
    c = int((finite >= 0.9).sum())
    assert d["validation_runs"] == 297 and d["validation_count"] == c
    assert d["validation_freq"] == pytest.approx(c / 297, rel=1e-15)
    assert d["validation_lower95"] == pytest.approx(float(lower_bound(c, 297, 0.95)),
                                                    rel=1e-15)
    assert (d["p_estimate"], d["p_upper95"], d["method"], d["n_runs"], d["validation_seed"]) \
        == (0.15, 0.3, "mixture", 400, 41)
    # a detector the brute force did not run: nothing counted, nothing covered
    assert (e["validation_runs"], e["validation_count"], e["tested"], e["covered"],
            e["consistent"]) == (0, 0, False, False, False)
    assert math.isnan(e["validation_freq"]) and math.isnan(e["validation_lower95"])
    # the same from the rows gathered a batch at a time
    rows = CertifyRows()
    for part in np.array_split(np.arange(300), 3):
        rows.add(brute("d", m[part]))
    pd.testing.assert_frame_equal(coverage_table(levels, rows, seed=41), table)


def test_no_exceedance_has_a_zero_lower_bound():
    table = coverage_table(curve(("d", 2.0, 0.01)), brute("d", [0.5] * 100), 1)
    r = table.iloc[0]
    assert (r["validation_count"], r["validation_freq"], r["validation_lower95"]) == (0, 0, 0)
    assert bool(r["covered"]) and bool(r["consistent"]) and not bool(r["tested"])


def test_an_empty_curve_keeps_the_integer_columns():
    table = coverage_table(curve(), brute("d", [0.5]), 1)
    assert table.empty and list(table.columns) == list(VALIDATION_COLUMNS)
    for col in ("n_runs", "validation_runs", "validation_count", "validation_seed"):
        assert table[col].dtype == np.int64, col


def test_the_summary_names_the_points_covered_consistent_and_missed():
    m = [1.0] * 6 + [0.0] * 14           # 6 of 20 at 1.0: f = 0.3
    table = coverage_table(curve(("a", 1.0, 0.5), ("b", 1.0, 0.2), ("b", 1.0, 0.1),
                                 ("b", 2.0, 0.5)),
                           pd.concat([brute("a", m), brute("b", m)]), seed=9)
    lo = float(lower_bound(6, 20, 0.95))
    assert 0.1 < lo < 0.2                 # consistent at 0.2, not at 0.1
    assert summarise(table) == (
        "validation (20 runs, seed 9): p_upper95 covers the brute-force frequency at 1 of 3 "
        "detector × level points with ≥ 5 exceedances; 2 of 3 consistent (the frequency's own "
        "lower bound under p_upper95)"
        f"\n  not covered: b at 1: 6/20 = 0.3 (lower bound {lo:.3g}) > p_upper95 0.2"
        f"\n  not covered: b at 1: 6/20 = 0.3 (lower bound {lo:.3g}) > p_upper95 0.1")


def test_the_summary_of_nothing_tested_says_so_with_the_runs():
    table = coverage_table(curve(("a", 1.0, 0.5)), brute("a", [1.0] * 4 + [0.0] * 96), 2)
    assert summarise(table) == (
        "validation: no detector × level has ≥ 5 exceedances in the 100 runs; nothing to test "
        "(more runs, or lower levels)")
    one = coverage_table(curve(("a", 1.0, 0.5)), brute("a", [1.0] * 5 + [0.0] * 95), 2)
    assert summarise(one) == (
        "validation (100 runs, seed 2): p_upper95 covers the brute-force frequency at 1 of 1 "
        "detector × level points with ≥ 5 exceedances; 1 of 1 consistent (the frequency's own "
        "lower bound under p_upper95)")
    assert summarise(table.iloc[:0]).startswith("validation: no detector × level has ≥ 5 "
                                                "exceedances in the 0 runs;")


def config(design: str = "mc", seed: int = 21) -> CampaignConfig:
    cfg = small_campaign("v", seed, [])
    if design == "grid":
        cfg["campaign"]["design"] = "grid"
        for g in cfg["group"]:
            g.pop("count")
    return CampaignConfig.from_dict(cfg, source="v.toml")


def test_the_validation_options_are_checked_before_any_work():
    cfg = config()
    assert check_validation(cfg, 100, None) == 22          # the campaign's seed + 1
    assert check_validation(cfg, 100, 5) == 5
    with pytest.raises(CertifyError, match=r"n=99: the brute-force runs must be ≥ "
                                           r"100 \(a level is tested only where they show ≥ 5 "
                                           r"exceedances\); fix: e.g. n=60000$"):
        check_validation(cfg, 99, 5)
    with pytest.raises(CertifyError, match="seed=21: the campaign's own seed.*"
                                           "seed=22"):
        check_validation(cfg, 100, 21)
    with pytest.raises(CertifyError, match="n: the campaign's design is 'grid'"):
        check_validation(config("grid"), 100, 5)


def test_the_validation_campaign_is_the_fault_free_groups_at_another_seed():
    cfg = config()
    v = validation_config(cfg, 200, 33)
    assert (v.campaign.seed, v.campaign.name, v.campaign.design) == (33, "v-validation", "mc")
    # the fault-free group alone, 200 runs over its two manoeuvres
    assert [(g.name, g.fault, g.count) for g in v.groups] == [("ff", "none", 100)]
    assert v.source == "v.toml (validation, seed 33)"


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished small campaign that was never certified."""
    out = tmp_path_factory.mktemp("validate") / "c"
    run(config(), out, jobs=1, progress=False, log=lambda m: None)
    return out


def test_validate_refuses_an_uncertified_directory_and_a_bad_seed(finished):
    with pytest.raises(CertifyError, match="has no certificate-levels.parquet; certify it "
                                           f"first \\(fdd-campaign certify {finished}\\)"):
        validate(finished, 100, seed=5)
    with pytest.raises(CertifyError, match="seed=21: the campaign's own seed"):
        validate(finished, 100, seed=21)
    assert not (finished / "validation").exists()


def test_validate_runs_the_brute_force_and_writes_its_coverage(finished, tmp_path):
    """After certify, ``validate`` runs the fault-free groups at the validation seed with the
    campaign's fitted detectors and counts their margins against the stored curve."""
    import shutil

    import campaign
    from campaign.evidence.certify import certify

    out = tmp_path / "c"
    shutil.copytree(finished, out)
    cert = certify(out, jobs=1, log=lambda m: None, levels=(0.5, 1.0))
    table = validate(out, 100, seed=7, jobs=1, log=lambda m: None)
    assert table.equals(pd.read_parquet(out / "validation" / "seed-7-n100.parquet"))
    done = campaign.load(out / "validation" / "seed-7-n100")
    assert done.config.campaign.seed == 7
    results = done.results
    assert set(results["fault"]) == {"none"}
    # the curve's points, each counted against the 100 brute-force margins of its detector
    assert table[["detector", "level"]].values.tolist() == \
        cert.levels[["detector", "level"]].values.tolist()
    for r in table.to_dict(orient="records"):
        m = results.loc[results["detector"] == r["detector"], "margin"].to_numpy(float)
        m = m[np.isfinite(m)]
        assert r["validation_runs"] == m.size == 100
        assert r["validation_count"] == int((m >= r["level"]).sum())
        assert r["validation_seed"] == 7


@pytest.mark.parametrize("function, first", [(validate, "seed"), (validate_levels, "seed")])
def test_the_validation_options_are_named_never_positional(function, first):
    """A seed or a worker count passed by position would be taken for another option: every
    parameter from the seed on is keyword-only."""
    import inspect

    params = list(inspect.signature(function).parameters.values())
    start = [p.name for p in params].index(first)
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[start:])
    assert all(p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD for p in params[:start])
