"""campaign/evidence/certify/estimate.py by value: the certificate's columns recomputed from
their formulas on hand-made result rows (the counting bound, the exposure and the Poisson
rate per hour, the level-1 row of the curve and the tail fit of its dominant manoeuvre, the
note when the bound is below the observed rate, at its boundary), the run variables sampled,
the sampled runs as the runner gets them, the sampling columns and note, and the options of
``certify`` on both sides of each limit (docs/evidence.md, "False-alarm probability
certificates (certify)")."""

from __future__ import annotations

import hashlib
import math
import shutil

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.config import CampaignConfig
from campaign.evidence.certify import (
    CERTIFICATE_COLUMNS,
    SAMPLING_STREAM_BASE,
    CertifyError,
    certificate,
    certify,
    evt_estimate,
    run_variables,
    sample_fa_probability,
)
from campaign.evidence.certify.estimate import (
    _BatchStore,
    _work_name,
    fill_sampling_columns,
    sampling_note,
    write_sampling_levels,
)
from campaign.evidence.certify.levels import detector_rows, level_table
from campaign.evidence.rare import SAMPLER_VERSION, SubsetLevel, SubsetResult
from campaign.plan import run_id
from campaign.store.directory import CampaignDir
from detectors.tail import CURVE_SHAPES, fit_tail
from reports.scoring.metrics import upper_bound
from scenarios import envelope
from small_campaigns import small_campaign
from test_certify_level_rows_values import maxima


# ---- evt_estimate ------------------------------------------------------------------------
def test_few_margins_are_counted_per_manoeuvre_without_a_tail_fit():
    """Five finite margins of one class (the NaN is not a run): the mixture of one counted
    manoeuvre, 1 of 5 at or above 1, no tail fit to report."""
    out = evt_estimate([0.1, 0.2, 0.3, np.nan, 0.4, 1.2])
    assert out["fa_prob_evt"] == 0.2
    assert out["fa_prob_evt_upper95"] == pytest.approx(float(upper_bound(1, 5)), rel=1e-12)
    assert (out["evt_method"], out["evt_k"]) == ("counted per manoeuvre", 0)
    assert out["evt_note"] == ("mixture: mixture of 1 manoeuvres by their shares of the runs; "
                               "every manoeuvre counted")
    assert all(math.isnan(out[k]) for k in ("evt_u", "evt_shape", "evt_scale",
                                            "evt_gof_pvalue"))
    # two classes: the pooled count of 1 in 5 is the smaller bound
    counted = evt_estimate([0.1, 0.2, 0.3, np.nan, 0.4, 1.2], list("aaabbb"))
    assert (counted["evt_method"], counted["evt_note"]) == (
        "counted", "counted: 1 of 5 runs at or above 1 (exact Clopper–Pearson bound)")


def test_a_tail_fitted_class_reports_its_fit():
    m = maxima(1, 300, 1 / 3.5)
    out = evt_estimate(m)
    row = detector_rows("", m, ["all"] * 300, (1.0,))[0]
    fit = fit_tail(m, shapes=CURVE_SHAPES)
    assert (out["fa_prob_evt"], out["fa_prob_evt_upper95"], out["evt_method"]) == \
        (row["p_estimate"], row["p_upper95"], "mixture")
    assert (out["evt_k"], out["evt_u"], out["evt_shape"], out["evt_scale"],
            out["evt_gof_pvalue"]) == (fit.k, fit.u, fit.shape, fit.scale, fit.gof_pvalue)
    assert out["evt_note"] == (
        f"mixture: {row['note']}; dominant manoeuvre all: top {fit.k} of 300 margins above "
        f"u = {fit.u:.4g}, ξ = {fit.shape:.3g}, σ = {fit.scale:.3g}, KS p = "
        f"{fit.gof_pvalue:.2g}")


def test_a_level_one_row_given_is_used_as_it_is():
    """*at_one* (the curve's level-1 row, already computed) is taken, not computed again;
    a row without a note gives the method alone; a dominant class too small to fit leaves
    the fit's columns empty."""
    m = maxima(1, 300, 1 / 3.5)
    given = {"p_estimate": 0.125, "p_upper95": 0.25, "method": "limit of the runs",
             "note": "", "tail_class": ""}
    out = evt_estimate(m, None, 0.95, given)
    assert (out["fa_prob_evt"], out["fa_prob_evt_upper95"], out["evt_note"],
            out["evt_method"], out["evt_k"]) == (0.125, 0.25, "limit of the runs",
                                                 "limit of the runs", 0)
    cls = np.array(["big"] * 297 + ["tiny"] * 3)
    tiny = evt_estimate(m, cls, 0.95, {**given, "method": "mixture", "note": "n",
                                       "tail_class": "tiny"})
    assert (tiny["evt_k"], tiny["evt_note"], tiny["evt_method"]) == (0, "mixture: n", "mixture")
    assert math.isnan(tiny["evt_u"])


# ---- certificate -------------------------------------------------------------------------
def results_and_plan(m_a, m_b, alarms_a, duration_a=30.0, duration_b=60.0):
    """Fault-free ok rows of detectors "a" (margins *m_a*, alarms *alarms_a*, two manoeuvres
    alternating) and "b" (margins *m_b*, no alarm), a failed run and a faulty run, and the
    plan's durations [s]."""
    n_a, n_b = len(m_a), len(m_b)
    ids = [f"r{i}" for i in range(n_a + n_b + 2)]
    results = pd.DataFrame({
        "run_id": ids,
        "detector": ["a"] * n_a + ["b"] * n_b + ["a", "a"],
        "fault": ["none"] * (n_a + n_b + 1) + ["runaway"],
        "manoeuvre": (["cruise", "nose_up"] * n_a)[:n_a] + ["cruise"] * (n_b + 2),
        "status": ["ok"] * (n_a + n_b) + ["error", "ok"],
        "margin": [*m_a, *m_b, 50.0, 50.0],
        "false_alarm": [*alarms_a, *([False] * n_b), True, True],
        "detected": [False] * (n_a + n_b + 1) + [True],
        "dtp": [np.nan] * (n_a + n_b + 1) + [0.5]})
    plan = pd.DataFrame({"run_id": ids,
                         "duration_s": [duration_a] * n_a + [duration_b] * n_b + [1.0, 1.0]})
    return results, plan


def test_the_certificate_columns_from_their_formulas():
    m_a = maxima(3, 400, 1 / 3.0)
    alarms = m_a >= 1.0
    m_b = maxima(4, 50, 1 / 4.0)
    results, plan = results_and_plan(m_a, m_b, alarms)
    cert = certificate(results, plan, 0.9)
    assert list(cert.columns) == list(CERTIFICATE_COLUMNS)
    assert cert["detector"].tolist() == ["a", "b"]
    a, b = cert.to_dict(orient="records")
    k = int(alarms.sum())
    assert 0 < k < 400
    cp = float(upper_bound(k, 400, 0.9))
    assert (a["level"], a["n_runs"], a["fa_count"], a["fa_rate"]) == (0.9, 400, k, k / 400)
    assert a["fa_upper95_cp"] == pytest.approx(cp, rel=1e-12)
    assert a["exposure_h"] == pytest.approx(400 * 30.0 / 3600.0, rel=1e-12)
    assert a["run_duration_s"] == pytest.approx(30.0, rel=1e-12)
    # the Poisson exposure model: λ = −ln(1 − p)/d, d the runs' duration in hours
    assert a["fa_per_hour_upper95"] == pytest.approx(-math.log1p(-cp) / (30.0 / 3600.0),
                                                     rel=1e-12)
    row = detector_rows("a", m_a, np.array(["cruise", "nose_up"] * 200), (1.0,), 0.9)[0]
    assert (a["fa_prob_evt"], a["fa_prob_evt_upper95"]) == (row["p_estimate"],
                                                            row["p_upper95"])
    assert a["fa_per_hour_evt_upper95"] == pytest.approx(
        -math.log1p(-row["p_upper95"]) / (30.0 / 3600.0), rel=1e-12)
    assert a["worst_margin"] == m_a.max()
    assert (b["n_runs"], b["fa_count"], b["fa_rate"], b["worst_margin"]) == (50, 0, 0.0,
                                                                             m_b.max())
    assert b["exposure_h"] == pytest.approx(50 * 60.0 / 3600.0, rel=1e-12)
    assert b["fa_upper95_cp"] == pytest.approx(1 - 0.1 ** (1 / 50), rel=1e-12)  # k = 0
    # the sampling columns: none sampled yet
    assert (a["sampling_runs"], a["sampling_levels"], a["sampling_note"]) == (0, 0, "")
    assert all(math.isnan(a[c]) for c in ("sampling_prob", "sampling_lower95",
                                          "sampling_upper95", "sampling_cov",
                                          "sampling_reached_level", "sampling_reached_prob"))
    for c in ("n_runs", "fa_count", "evt_k", "sampling_runs", "sampling_levels"):
        assert cert[c].dtype == np.int64, c


def test_a_curve_given_supplies_the_level_one_rows_and_the_rate_note_at_its_boundary():
    """The curve's level-1 rows are used as given; a bound below the observed rate k/n gets
    the note that the tail model does not describe the runs, a bound equal to it does not."""
    m_a = np.linspace(0.0, 1.5, 40)                 # 14 of 40 at or above 1 … see below
    alarms = np.zeros(40, bool)
    alarms[:10] = True                              # k/n = 10/40 = 0.25
    results, plan = results_and_plan(m_a, [0.5] * 30, alarms)
    curve = level_table(results, (0.8, 1.0))
    at_one = curve["level"] == 1.0
    note = "the bound is below the observed rate 10/40"
    for bound, noted in ((0.25, False), (np.nextafter(0.25, 0.0), True)):
        given = curve.copy()
        given.loc[at_one & (given["detector"] == "a"), "p_upper95"] = bound
        cert = certificate(results, plan, 0.95, given)
        a, b = cert.to_dict(orient="records")
        assert a["fa_prob_evt_upper95"] == bound
        assert (note in a["evt_note"]) is noted
        assert note.split(" 10/40")[0] not in b["evt_note"]       # b has no alarm
    # a curve of level 1 alone is used as given too
    only = curve[at_one].copy()
    only.loc[only["detector"] == "a", "p_upper95"] = 0.5
    assert certificate(results, plan, 0.95, only)["fa_prob_evt_upper95"].iloc[0] == 0.5
    # a curve without level 1 is completed with it: the same certificate as none given
    pd.testing.assert_frame_equal(certificate(results, plan, 0.95, curve[~at_one]),
                                  certificate(results, plan))


@pytest.mark.filterwarnings("ignore:Mean of empty slice:RuntimeWarning")
def test_a_detector_without_a_finite_margin_or_a_duration():
    results, plan = results_and_plan([np.nan, np.nan], [0.5], [False, True])
    cert = certificate(results, plan[plan["run_id"] != "r2"])     # b's one run not planned
    a, b = cert.to_dict(orient="records")
    assert math.isnan(a["worst_margin"]) and (a["n_runs"], a["fa_count"]) == (2, 1)
    assert a["evt_method"] == "none" and math.isnan(a["fa_prob_evt_upper95"])
    assert math.isnan(b["exposure_h"] * 0 + b["run_duration_s"])
    assert b["exposure_h"] == 0.0 and math.isnan(b["fa_per_hour_upper95"])


def test_no_fault_free_run_is_an_empty_certificate_with_its_integer_columns():
    results, plan = results_and_plan([0.5], [0.5], [False])
    cert = certificate(results[results["fault"] != "none"], plan)
    assert cert.empty and list(cert.columns) == list(CERTIFICATE_COLUMNS)
    for c in ("n_runs", "fa_count", "evt_k", "sampling_runs", "sampling_levels"):
        assert cert[c].dtype == np.int64, c


# ---- what is sampled ---------------------------------------------------------------------
def config(manoeuvres=None, **campaign) -> CampaignConfig:
    """The small campaign with the mass held at 150 t and no airspeed uncertainty; with
    *manoeuvres*, one fault-free run of each instead of its three of cruise and nose_up."""
    cfg = small_campaign("v", 21, [])
    cfg["campaign"].update(campaign)
    if manoeuvres:
        cfg["group"][0].update(manoeuvres=list(manoeuvres), count=1)
    cfg["envelope"] = {"mass_t": [150.0]}
    cfg["uncertainty"] = {"vcas": 0.0, "alt": 0.1}
    return CampaignConfig.from_dict(cfg, source="v.toml")


def test_the_run_variables_are_those_that_vary_among_the_fault_free_runs():
    """A flight column is sampled when the fault-free runs take more than one value of it (a
    faulty run's values do not count), a draw column when its half-width is above 0."""
    cfg = config()
    plan = pd.DataFrame({"fault": ["none", "none", "runaway"],
                         "alt_ft": [9000.0, 9000.0, 30000.0],      # one value: fixed
                         "vcas_kt": [200.0, 250.0, 250.0],         # two: sampled
                         "cg_pct": [20.0, 30.0, 20.0],
                         "d_vcas": [0.0, 0.0, 0.0], "d_alt": [0.01, -0.02, 0.0],
                         "d_cx": [0.01, 0.0, 0.0]})
    assert run_variables(cfg, plan) == {"vcas_kt": (160.0, 300.0), "cg_pct": (17.0, 41.0),
                                        "d_alt": (-0.1, 0.1), "d_cx": (-0.05, 0.05)}


def test_a_sampling_work_is_named_by_the_detector_and_what_decides_its_runs():
    key = hashlib.sha256(f"pm[0.1]/x|500|3|0.95|{SAMPLER_VERSION}".encode()).hexdigest()
    assert _work_name("pm[0.1]/x", 500, 3, 0.95) == f"pm_0.1__x-{key[:12]}"


def test_a_stored_batch_is_read_back_only_for_the_same_runs(tmp_path):
    store = _BatchStore(CampaignDir(tmp_path), "w", "{}")
    assert store.get(0, ["a", "b"]) is None
    store.put(0, ["a", "b"], np.array([0.25, -np.inf]))
    assert store.get(0, ["a", "b"]).tolist() == [0.25, -np.inf] and store.reused == 2
    assert store.get(0, ["a", "c"]) is None and store.get(1, ["a", "b"]) is None
    assert store.reused == 2


def subset_result(reached: bool, **kw) -> SubsetResult:
    levels = (SubsetLevel(0.5, 0.1, 0.1, 0.0, 0.3, 20.0, acceptance=0.5, seeds=2,
                          distinct_nuisance=0),
              SubsetLevel(0.6, 0.1, 0.01, 1.0, 0.5, 9.0, acceptance=0.4, seeds=2,
                          distinct_nuisance=9),
              SubsetLevel(0.8, 0.1, 0.001, 1.5, 0.6, 8.0, acceptance=0.25, seeds=2,
                          distinct_nuisance=17),
              SubsetLevel(1.0, 0.2, 0.0002, 2.0, 0.7, 6.5, seeds=2, distinct_nuisance=12))
    base = dict(probability=0.002 if reached else math.nan, lower=0.0005, upper=0.006,
                confidence=0.95, cov=0.91, levels=(0.5, 0.6, 0.8, 1.0), evaluations=74,
                reached=reached, reached_level=1.0 if reached else 0.8,
                reached_probability=0.002 if reached else 0.01, diagnostics=levels)
    return SubsetResult(**{**base, **kw})


def test_the_sampling_note_says_what_was_estimated_with_the_chains_diagnostics():
    head = ("subset simulation, seed 3, 20 runs per level, p0 = 0.1, 4 levels, 74 runs; "
            "acceptance per level 0.50, 0.40, 0.25; smallest effective sample size 6; "
            "δ = 0.91; "
            "distinct (manoeuvre, noise stream) pairs at the last level 12 of 20")
    assert sampling_note(subset_result(True), seed=3, n=20) == head
    assert sampling_note(subset_result(False), seed=3, n=20) == (
        head + "; margin 1 not reached: the highest level reached is 0.8 with "
        "P(margin ≥ 0.8) ≈ 0.01, ≤ 0.006, which bounds P(margin ≥ 1) from above; more "
        "levels (--max-levels) would go further")
    assert sampling_note(subset_result(False, stalled=True), seed=3, n=20).endswith(
        "from above (the chains stopped climbing: no run above the last level)")
    none = subset_result(False, reached_level=-math.inf, diagnostics=(), levels=())
    assert sampling_note(none, seed=3, n=20) == (
        "subset simulation, seed 3, 20 runs per level, p0 = 0.1, 0 levels, 74 runs; "
        "acceptance per level ; smallest effective sample size nan; δ = 0.91; no sampled run "
        "could be evaluated: no estimate")


def test_the_sampling_columns_of_a_reached_and_an_unreached_level(tmp_path):
    results, plan = results_and_plan([0.5, 0.6], [0.5], [False, False])
    cert = certificate(results, plan)
    found = {"b": subset_result(False), "a": subset_result(True)}
    fill_sampling_columns(cert, found, seed=3, n=20)
    a, b = cert.to_dict(orient="records")
    assert (a["sampling_prob"], a["sampling_lower95"], a["sampling_upper95"],
            a["sampling_cov"], a["sampling_reached_level"], a["sampling_reached_prob"],
            a["sampling_runs"], a["sampling_levels"]) == (0.002, 0.0005, 0.006, 0.91, 1.0,
                                                          0.002, 74, 4)
    assert a["sampling_note"] == sampling_note(found["a"], seed=3, n=20)
    # not reached: no estimate of P(margin ≥ 1) and no lower bound of it
    assert math.isnan(b["sampling_prob"]) and math.isnan(b["sampling_lower95"])
    assert (b["sampling_upper95"], b["sampling_reached_level"], b["sampling_reached_prob"]) \
        == (0.006, 0.8, 0.01)
    assert "margin 1 not reached" in b["sampling_note"]
    # the levels of both, detector first; nothing written when nothing was sampled
    write_sampling_levels(tmp_path, {}, "{}")
    assert not (tmp_path / "sampling").exists()
    write_sampling_levels(tmp_path, found, "{}")
    levels = pd.read_parquet(next((tmp_path / "sampling").glob("*.parquet")))
    assert levels.columns[0] == "detector" and levels.columns[1] == "level"
    assert levels["detector"].tolist() == ["b"] * 4 + ["a"] * 4
    assert levels["level"].tolist() == [1, 2, 3, 4] * 2
    assert levels["threshold"].tolist() == [0.5, 0.6, 0.8, 1.0] * 2


# ---- the command -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished small campaign (6 fault-free runs of the position monitor ``pm``, two
    runaways), never certified."""
    out = tmp_path_factory.mktemp("certify") / "c"
    run(config(), out, jobs=1, progress=False, log=lambda m: None)
    return out


THREE = ("cruise", "nose_up", "aoa_protection")


@pytest.fixture(scope="module")
def finished_anywhere(tmp_path_factory):
    """The campaign with flight points outside the realistic envelope allowed and one
    fault-free run of each of three manoeuvres."""
    out = tmp_path_factory.mktemp("certify") / "c"
    run(config(THREE, realistic_only=False), out, jobs=1, progress=False,
        log=lambda m: None)
    return out


@pytest.fixture
def fresh(finished, tmp_path):
    out = tmp_path / "c"
    shutil.copytree(finished, out)
    return out


@pytest.mark.parametrize("options, message", [
    ({"level": 0.5}, "level=0.5: must be a confidence in (0.5, 1); fix: e.g. level=0.95"),
    ({"level": 1.0}, "level=1.0: must be a confidence in (0.5, 1)"),
    ({"level": "0.9"}, "level='0.9': must be a confidence"),
    ({"sampling": 10}, "sampling=10: runs per level of the subset simulation must be a "
                       "multiple of 10 and ≥ 20 (p0 = 0.1); fix: e.g. sampling=500"),
    ({"sampling": 25}, "sampling=25: runs per level"),
    ({"jobs": 0}, "jobs=0: must be ≥ 1; fix: e.g. jobs=2"),
    ({"max_levels": 0}, "max_levels=0: levels of the subset simulation after the first, in "
                        "[1, 30] (p0 = 0.1: 12 reach 1e-12); fix: e.g. max_levels=12"),
    ({"max_levels": 31}, "max_levels=31:"),
    ({"levels": "0.6,x"}, "levels: 'x' is not a number"),
])
def test_certify_refuses_an_option_outside_its_limits_before_any_work(fresh, options,
                                                                      message):
    with pytest.raises(CertifyError) as exc:
        certify(fresh, log=lambda m: None, **options)
    assert message in str(exc.value)
    assert not (fresh / "certificate.parquet").exists()


def test_certify_accepts_the_options_at_their_limits(fresh):
    cert = certify(fresh, level=0.51, max_levels=30, jobs=1, log=lambda m: None,
                   levels="0.9")
    assert cert.level == 0.51 and cert.table["level"].tolist() == [0.51]
    assert cert.levels["level"].tolist() == [0.9, 1.0]       # 1.0 always among them
    assert cert.table["fa_upper95_cp"].iloc[0] == pytest.approx(
        float(upper_bound(0, 6, 0.51)), rel=1e-12)
    pd.testing.assert_frame_equal(pd.read_parquet(fresh / "certificate.parquet"), cert.table,
                                  check_exact=True)
    pd.testing.assert_frame_equal(pd.read_parquet(fresh / "certificate-levels.parquet"),
                                  cert.levels, check_exact=True)
    hazard = pd.read_parquet(fresh / "certificate-hazard.parquet")
    pd.testing.assert_frame_equal(hazard, cert.hazard, check_exact=True)
    assert hazard.loc[hazard["fault"] == "runaway", "n_runs"].tolist() == [2]
    assert not (fresh / "sampling").exists()
    with pytest.raises(CertifyError, match="detectors='nope': no such detector in .*; choose "
                                           "among pm"):
        certify(fresh, detectors=["nope"], log=lambda m: None)


@pytest.mark.parametrize("complete, done", [(False, 8), (True, 7)])
def test_certify_refuses_an_unfinished_campaign(fresh, complete, done):
    cdir = CampaignDir(fresh)
    summary, _ = cdir.read_summary()
    cdir.write_summary(summary, cdir.config_path.read_text(), complete=complete,
                       runs_done=done, runs_planned=8)
    with pytest.raises(CertifyError, match=f"the campaign is unfinished \\({done} of 8 runs "
                                           "done\\)"):
        certify(fresh, log=lambda m: None)


def test_sampling_refuses_a_grid_and_a_plan_without_fault_free_runs(fresh):
    from campaign import load

    loaded = load(fresh)
    grid = small_campaign("g", 1, [])
    grid["campaign"]["design"] = "grid"
    for g in grid["group"]:
        g.pop("count")
    with pytest.raises(CertifyError, match="sampling: the campaign's design is 'grid'"):
        sample_fa_probability(fresh, CampaignConfig.from_dict(grid), loaded.plan, ["pm"])
    faulty = loaded.plan[loaded.plan["fault"] != "none"]
    with pytest.raises(CertifyError, match="no fault-free run to sample around"):
        sample_fa_probability(fresh, loaded.config, faulty, ["pm"])


def test_the_sampled_runs_are_fault_free_runs_of_the_prior(fresh, monkeypatch):
    """Each batch the runner gets: fault-free rows of a plan manoeuvre, the run variables
    inside their ranges and every other column that of the manoeuvre's plan rows, fresh
    noise streams from SAMPLING_STREAM_BASE on, realistic flight points (the campaign has
    realistic_only), and their run ids; the margins stored are the runner's."""
    import campaign.runner as runner
    from campaign import load

    assert SAMPLING_STREAM_BASE == 2 ** 40
    real, batches = runner.evaluate_rows, []

    def spy(setup, rows, detectors, log=None):
        res = real(setup, rows, detectors, log=log)
        batches.append((rows.copy(), res))
        return res

    monkeypatch.setattr(runner, "evaluate_rows", spy)
    loaded = load(fresh)
    lines = []
    cert = certify(fresh, sampling=20, max_levels=1, seed=3, jobs=1, log=lambda m: None,
                   progress=lines.append)
    row = cert.table.iloc[0]
    plan, cfg = loaded.plan, loaded.config
    variables = run_variables(cfg, plan)
    assert set(variables) >= {"alt_ft", "vcas_kt", "d_alt"} and "d_vcas" not in variables
    sampled = pd.concat([rows for rows, _ in batches], ignore_index=True)
    # 20 + 18 points of one level; those outside the realistic envelope are not simulated
    # (some chain candidates are, at this seed: the envelope check below has points to
    # tell apart)
    assert row["sampling_runs"] == 38 and 0 < len(sampled) < 38, len(sampled)
    assert list(sampled.columns) == list(plan.columns)
    ff = plan[plan["fault"] == "none"]
    assert set(sampled["manoeuvre"]) == set(ff["manoeuvre"]) == {"cruise", "nose_up"}
    for col, (lo, hi) in variables.items():
        assert sampled[col].between(lo, hi).all(), col
        assert sampled[col].nunique() > 10, col
    fixed = [c for c in plan.columns
             if c not in variables and c not in ("run_id", "stream", "group")]
    for m, rows in sampled.groupby("manoeuvre"):
        template = ff[ff["manoeuvre"] == m].iloc[0]
        want = pd.DataFrame([template[fixed]] * len(rows)).reset_index(drop=True)
        pd.testing.assert_frame_equal(rows[fixed].reset_index(drop=True), want,
                                      check_dtype=False)
    assert (sampled["group"] == "certify-sampling").all()
    # the first batch: the 20 admissible prior points, a stream each drawn in order from
    # the base on (a rejected draw uses one up); the chains' points keep or redraw theirs
    first = batches[0][0]["stream"].to_numpy()
    assert len(first) == 20 and (np.diff(first) > 0).all()
    assert first[0] >= SAMPLING_STREAM_BASE and first[-1] < SAMPLING_STREAM_BASE + 2 ** 20
    assert (sampled["stream"] >= SAMPLING_STREAM_BASE).all()
    assert sampled["run_id"].tolist() == [run_id({**r, "run_id": ""})
                                          for r in sampled.to_dict(orient="records")]
    points = sampled[list(envelope.FLIGHT_COLUMNS)]
    assert envelope.realistic_rule(points, cfg.uncertainty)["realistic"].all()
    # the stored batches hold the runner's margins of the sampled runs, in their order
    stored = sorted((fresh / "sampling").glob("pm-*/batch-*.parquet"))
    assert len(stored) == len(batches)
    for path, (rows, res) in zip(stored, batches):
        got = pd.read_parquet(path)
        want = res[res["detector"] == "pm"].set_index("run_id")["margin"]
        assert got["run_id"].tolist() == rows["run_id"].tolist()
        np.testing.assert_array_equal(got["margin"].to_numpy(),
                                      want.reindex(rows["run_id"]).to_numpy())
    assert row["sampling_levels"] == 1 and row["sampling_note"].startswith(
        "subset simulation, seed 3, 20 runs per level, p0 = 0.1, 1 levels, 38 runs")
    # one line a batch: the runs done of the most one level after the first can take
    # (20 × 2), the batch, none read back
    bars = [ln for ln in lines if ln.startswith("sampling pm: ")]
    assert len(bars) == len(batches) and bars[0].startswith("sampling pm: 20/40 runs")
    assert " (batch 1, 0 read back; at most this many runs" in bars[0]
    assert f"(batch {len(batches)}, 0 read back;" in bars[-1]
    # started again: every batch read back, none simulated, the same certificate; no run
    # computed, so no rate and no time left
    lines.clear()
    again = certify(fresh, sampling=20, max_levels=1, seed=3, jobs=1, log=lambda m: None,
                    progress=lines.append)
    assert len(stored) == len(batches)
    pd.testing.assert_frame_equal(again.table, cert.table)
    bars = [ln for ln in lines if ln.startswith("sampling pm: ")]
    assert len(bars) == len(batches) and all("ETA   nan s" in ln for ln in bars)
    assert f"(batch {len(batches)}, {len(sampled)} read back;" in bars[-1]


def test_without_realistic_only_every_sampled_point_is_simulated(finished_anywhere, tmp_path,
                                                                 monkeypatch):
    import campaign.runner as runner

    out = tmp_path / "c"
    shutil.copytree(finished_anywhere, out)
    real, sampled = runner.evaluate_rows, []

    def spy(setup, rows, detectors, log=None):
        sampled.append(rows)
        return real(setup, rows, detectors, log=log)

    monkeypatch.setattr(runner, "evaluate_rows", spy)
    cert = certify(out, sampling=20, max_levels=1, seed=3, jobs=1, log=lambda m: None,
                   progress=lambda m: None)
    rows = pd.concat(sampled, ignore_index=True)
    assert len(rows) == cert.table["sampling_runs"].iloc[0] == 38
    assert (rows["mass_t"] == 150.0).all()
    # each manoeuvre drawn, its other columns those of its one fault-free run
    assert set(rows["manoeuvre"]) == set(THREE)
    plan = pd.read_parquet(out / "plan.parquet")
    ff = plan[plan["fault"] == "none"].set_index("manoeuvre")
    for col in ("duration_s", "manoeuvre_set", "fault", "mass_t"):
        assert (rows[col].to_numpy() == ff.loc[rows["manoeuvre"], col].to_numpy()).all(), col
    assert rows["vcas_kt"].nunique() > 10


def test_sampling_takes_any_multiple_of_ten_runs_from_20(fresh, monkeypatch):
    import campaign.evidence.certify.estimate as estimate

    asked = []
    monkeypatch.setattr(estimate, "sample_fa_probability",
                        lambda *a, **kw: asked.append(kw["n"]) or {})
    for n in (20, 30):
        certify(fresh, sampling=n, log=lambda m: None)
    assert asked == [20, 30]


@pytest.mark.parametrize("function, first", [
    (certify, "level"), (sample_fa_probability, "n"), (fill_sampling_columns, "seed"),
    (sampling_note, "seed")])
def test_the_options_are_named_never_positional(function, first):
    """A seed, a run count or a level passed by position would be taken for another option:
    every parameter from the first option on is keyword-only."""
    import inspect

    params = list(inspect.signature(function).parameters.values())
    start = [p.name for p in params].index(first)
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[start:])
    assert all(p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD for p in params[:start])


def test_the_defaults_of_certify_and_of_its_sampling(fresh, monkeypatch):
    """docs/evidence.md (the synopsis of certify): a 95 % certificate at the default levels,
    sampling seed 0 and at most 12 levels after the first; 500 runs a level (the default of
    sample_fa_probability called alone), p0 = 0.1. The subset simulation's arguments are
    recorded, then it runs one level of 20."""
    import campaign.evidence.rare as rare
    from campaign import load
    from campaign.evidence.certify.levels import DEFAULT_LEVELS

    real, asked = rare.subset_simulation, []

    def recorded(g, prior, dims, **kw):
        asked.append(kw)
        return real(g, prior, dims, **{**kw, "n": 20, "max_levels": 1})

    monkeypatch.setattr(rare, "subset_simulation", recorded)
    cert = certify(fresh, log=lambda m: None)
    assert (cert.level, cert.sampling_seed) == (0.95, 0)
    assert tuple(cert.levels["level"]) == DEFAULT_LEVELS and asked == []
    certify(fresh, sampling=20, jobs=1, log=lambda m: None, progress=lambda m: None)
    loaded = load(fresh)
    # a name no detector owns is passed over, and the names after it still sampled
    sample_fa_probability(fresh, loaded.config, loaded.plan, ["nobody", "pm"], jobs=1,
                          progress=lambda m: None)
    keys = ("n", "p0", "max_levels", "confidence", "seed")
    assert [tuple(kw[k] for k in keys) for kw in asked] == [(20, 0.1, 12, 0.95, 0),
                                                            (500, 0.1, 12, 0.95, 0)]


def test_a_sampled_run_without_a_margin_reaches_no_level(fresh, monkeypatch):
    """A sampled run whose margin is not finite (it could not be evaluated) counts as never
    reaching a level: with none evaluated there is no estimate."""
    import campaign.runner as runner

    def no_margin(setup, rows, detectors, log=None):
        return pd.DataFrame({"run_id": rows["run_id"], "detector": "pm", "margin": np.nan})

    monkeypatch.setattr(runner, "evaluate_rows", no_margin)
    cert = certify(fresh, sampling=20, max_levels=1, jobs=1, log=lambda m: None,
                   progress=lambda m: None)
    row = cert.table.iloc[0]
    assert math.isnan(row["sampling_prob"]) and row["sampling_levels"] == 0
    assert row["sampling_note"].endswith("no sampled run could be evaluated: no estimate")


def test_a_sampled_point_outside_the_realistic_envelope_is_not_simulated(fresh, monkeypatch):
    """The performance function the subset simulation gets: a point of the prior whose
    flight point is not realistic (the campaign has realistic_only) has margin −∞ without
    a run; a realistic one is simulated, at the values u = Φ(z) maps it to."""
    import campaign.evidence.rare as rare
    import campaign.runner as runner
    from scipy.stats import norm

    from campaign import load

    loaded = load(fresh)
    variables = run_variables(loaded.config, loaded.plan)
    cols = list(variables)
    lo = np.array([variables[c][0] for c in cols])
    hi = np.array([variables[c][1] for c in cols])
    z = np.random.default_rng(5).standard_normal((200, len(cols)))
    v = lo + (hi - lo) * norm.cdf(z)
    points = pd.DataFrame({c: v[:, cols.index(c)] if c in cols else 150.0
                           for c in envelope.FLIGHT_COLUMNS})
    ok = envelope.realistic_rule(points, loaded.config.uncertainty)["realistic"].to_numpy()
    pick = np.concatenate([np.flatnonzero(ok)[:2], np.flatnonzero(~ok)[:2]])
    assert ok[pick].tolist() == [True, True, False, False]
    real_sim, real_eval, got, simulated = rare.subset_simulation, runner.evaluate_rows, [], []

    def first_call_g(g, prior, dims, **kw):
        nu = np.empty(4, dtype=object)
        nu[:] = [(0, SAMPLING_STREAM_BASE + 10 ** 6 + i) for i in range(4)]
        got.append(g(z[pick], nu))
        return real_sim(g, prior, dims, **kw)

    def spy(setup, rows, detectors, log=None):
        simulated.append(rows)
        return real_eval(setup, rows, detectors, log=log)

    monkeypatch.setattr(rare, "subset_simulation", first_call_g)
    monkeypatch.setattr(runner, "evaluate_rows", spy)
    certify(fresh, sampling=20, max_levels=1, jobs=1, log=lambda m: None,
            progress=lambda m: None)
    margins = got[0]
    assert np.isfinite(margins[:2]).all() and (margins[2:] == -np.inf).all()
    rows = simulated[0]
    assert len(rows) == 2 and rows["stream"].tolist() == [SAMPLING_STREAM_BASE + 10 ** 6,
                                                          SAMPLING_STREAM_BASE + 10 ** 6 + 1]
    for c in cols:
        np.testing.assert_allclose(rows[c].to_numpy(float), v[pick[:2], cols.index(c)],
                                   rtol=1e-15, err_msg=c)
