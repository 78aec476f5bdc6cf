"""False-alarm probability beyond counting (docs/evidence.md): the shared tail fit
(detectors.tail), the certificate (campaign.evidence.certify: exact binomial bound, tail fit,
subset simulation) on a constructed case whose false-alarm probability is known exactly,
the gate's --max-fa-prob check."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, optimize, stats

from campaign import run
from campaign.evidence.certify import CERTIFICATE_COLUMNS, certificate, run_variables
from campaign.cli.commands import main
from campaign.config import CampaignConfig
from campaign.evidence.rare import subset_simulation
from detectors import registry
from detectors.calibrate import calibrate_threshold
from detectors.tail import TailFitError, fit_tail
from reports.scoring.gate import GateInputError, fa_probability_checks


# ---- the tail fit ------------------------------------------------------------------------------
def test_tail_fit_exceedance_probability_of_a_known_tail():
    # exponential values: P(X ≥ x) = e^(−x) exactly, a generalised Pareto tail with ξ = 0
    x = np.random.default_rng(3).exponential(size=1200)
    fit = fit_tail(x)
    assert fit.k == 240 and fit.u == np.sort(x)[::-1][240]
    true = 1e-4
    est = fit.sf(-math.log(true))
    assert est.estimate < est.upper and true <= est.upper < 20 * true
    assert fit.sf(fit.u + 1e-12).estimate == pytest.approx(240 / 1200, rel=1e-6)
    assert abs(fit.shape) < 0.2 and 0.0 < fit.gof_pvalue <= 1.0


def test_quantile_and_exceedance_probability_are_one_fit():
    x = np.abs(np.random.default_rng(4).standard_t(5, size=400))
    fit = fit_tail(x)
    q = fit.quantile(1e-3)
    # the MLE is parametrisation-invariant: the quantile's exceedance probability is p
    assert fit.sf(q.estimate).estimate == pytest.approx(1e-3, rel=0.02)
    # and the upper bound of the quantile is the calibrated threshold of calibrate
    cal = calibrate_threshold(x, 1e-3, 0.95)
    assert cal.method == "gpd" and cal.threshold == q.upper and cal.estimate == q.estimate
    # a larger threshold is less probable
    assert fit.sf(q.upper).estimate < fit.sf(q.estimate).estimate


def test_tail_fit_refuses_too_few_and_degenerate_values():
    with pytest.raises(TailFitError, match="fewer than the 50"):
        fit_tail(np.arange(10.0))
    with pytest.raises(TailFitError, match="degenerate"):
        fit_tail(np.r_[np.zeros(100), np.ones(40)])
    with pytest.raises(ValueError, match="not above the tail threshold"):
        fit_tail(np.random.default_rng(0).exponential(size=100)).sf(0.0)


# ---- subset simulation on an analytic function -------------------------------------------------
def test_subset_simulation_covers_a_known_probability():
    true = stats.norm.sf(3.5)             # P(Z₁ ≥ 3.5): 2.3e-4

    def prior(rng, m):
        return rng.standard_normal((m, 3)), np.zeros(m, dtype=object), np.ones(m, bool)

    r = subset_simulation(lambda z, nu: z[:, 0] / 3.5, prior, 3, n=200, seed=1)
    assert r.reached and len(r.levels) == 3 and r.evaluations == 200 + 3 * 180
    assert r.lower <= true <= r.upper
    again = subset_simulation(lambda z, nu: z[:, 0] / 3.5, prior, 3, n=200, seed=1)
    assert again.probability == r.probability         # deterministic for a seed


# ---- the constructed campaign ------------------------------------------------------------------
def _true_probability(limit, lo, hi, w):
    """P(V·(1 + D) ≥ limit), V ~ U(lo, hi), D ~ U(−w, w) independent."""
    def inner(v):
        return min(max((w - (limit / v - 1.0)) / (2.0 * w), 0.0), 1.0)
    return integrate.quad(inner, lo, hi, limit=200,
                          points=[limit / (1 + w), limit / (1 - w)])[0] / (hi - lo)


@pytest.fixture
def constructed(tmp_path, monkeypatch):
    """A campaign of 400 fault-free runs (i.i.d. random sampling, the whole envelope box)
    whose detector alarms exactly when VCAS·(1 + d_vcas) ≥ limit, the limit set so that
    the per-run false-alarm probability is 2·10⁻³."""
    monkeypatch.setitem(registry.BUILTIN, "schedule-margin", "plugin_detectors:ScheduleMargin")
    lo, hi, w = 160.0, 300.0, 0.10
    true = 2e-3
    limit = optimize.brentq(lambda L: _true_probability(L, lo, hi, w) - true, hi, hi * (1 + w))
    config = CampaignConfig.from_dict({
        "campaign": {"name": "constructed", "seed": 11, "duration_s": 20.0, "ts_s": 0.05,
                     "sampler": "random", "realistic_only": False},
        "envelope": {"vcas_kt": [lo, hi]},
        "uncertainty": {"vcas": w},
        "group": [{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 400}],
        "detector": [{"name": "schedule-margin", "label": "sm", "params": {"limit_kt": limit}}],
        "learning": {"runs_per_manoeuvre": 2, "manoeuvres": ["cruise"]},
    })
    out = tmp_path / "c"
    run(config, out, jobs=1, progress=False, log=lambda m: None)
    return out, true, config


def test_constructed_case_both_estimators_cover_the_true_probability(constructed, capsys):
    out, true, config = constructed
    assert main(["certify", str(out), "--sampling", "200", "--jobs", "1"]) == 0
    cert = pd.read_parquet(out / "certificate.parquet")
    assert list(cert.columns) == list(CERTIFICATE_COLUMNS)
    row = cert.iloc[0]
    assert row["detector"] == "sm" and row["n_runs"] == 400
    assert row["exposure_h"] == pytest.approx(400 * 20.0 / 3600.0)
    # the exact one-sided Clopper–Pearson bound
    k = int(row["fa_count"])
    assert row["fa_upper95_cp"] == pytest.approx(stats.beta.ppf(0.95, k + 1, 400 - k), rel=1e-12)
    assert row["fa_per_hour_upper95"] == pytest.approx(
        -math.log1p(-row["fa_upper95_cp"]) / (20.0 / 3600.0), rel=1e-12)
    # the curve at margin 1: its one-sided bound covers the true probability; the tail fit
    # of the one manoeuvre is reported (its top fifth), whichever bound was the smaller
    assert row["evt_k"] == 80 and np.isfinite(row["fa_prob_evt"])
    assert row["fa_prob_evt"] <= row["fa_prob_evt_upper95"]
    assert true <= row["fa_prob_evt_upper95"]
    # the sampled estimate: its interval covers it
    assert row["sampling_runs"] > 200 and row["sampling_levels"] >= 2
    assert row["sampling_lower95"] <= true <= row["sampling_upper95"]
    printed = capsys.readouterr().out
    assert "sm" in printed and "certificate written to" in printed
    # the sampled variables: the two that vary, the draws found through half_widths
    variables = run_variables(config, pd.read_parquet(out / "plan.parquet"))
    assert variables["vcas_kt"] == (160.0, 300.0) and variables["d_vcas"] == (-0.1, 0.1)
    # the gate reads the certificate
    assert main(["gate", str(out), "--max-fa-prob", "0.5", "--max-fa", "1"]) == 0
    assert main(["gate", str(out), "--max-fa-prob", "1e-9", "--max-fa", "1",
                 "--junit", str(out.parent / "g.xml")]) == 1
    xml = (out.parent / "g.xml").read_text()
    assert 'name="fa_probability[none/all]"' in xml and "false-alarm probability: sm" in xml


@pytest.mark.slow
def test_sampling_resumes_after_a_kill_without_recomputing(constructed, monkeypatch, capsys,
                                                           tmp_path):
    """--sampling evaluates through the runner's pipeline and keeps every batch under
    DIR/sampling/: interrupted after three batches and started again, it simulates only the
    batches not stored, and ends with the certificate of an uninterrupted run (which ran
    on two workers: the result does not depend on --jobs)."""
    import shutil

    import campaign.runner as runner

    out, _, _ = constructed
    fresh = tmp_path / "fresh"
    shutil.copytree(out, fresh)
    real = runner.evaluate_rows
    simulated, calls = [], []

    def counting(setup, rows, detectors, log=None):
        calls.append(len(rows))
        if stop_after is not None and len(calls) > stop_after:
            raise KeyboardInterrupt
        simulated.extend(rows["run_id"])
        return real(setup, rows, detectors, log=log)

    monkeypatch.setattr(runner, "evaluate_rows", counting)
    argv = ["certify", "--sampling", "100", "--jobs", "1", "--seed", "4"]
    stop_after = 3
    assert main([argv[0], str(out), *argv[1:]]) == 130
    stored = sorted((out / "sampling").glob("*/batch-*.parquet"))
    assert len(stored) == 3 and len(simulated) == sum(len(pd.read_parquet(f)) for f in stored)
    assert not (out / "certificate.parquet").exists()
    stop_after = None
    capsys.readouterr()
    assert main([argv[0], str(out), *argv[1:]]) == 0
    assert "ETA" in capsys.readouterr().err
    resumed = pd.read_parquet(out / "certificate.parquet")
    assert len(simulated) == len(set(simulated)) == resumed["sampling_runs"].iloc[0]
    monkeypatch.setattr(runner, "evaluate_rows", real)
    argv[4] = "2"
    assert main([argv[0], str(fresh), *argv[1:]]) == 0
    pd.testing.assert_frame_equal(resumed, pd.read_parquet(fresh / "certificate.parquet"))


def test_certify_refuses_an_unfinished_campaign_and_bad_options(constructed, capsys):
    out, _, _ = constructed
    assert main(["certify", str(out), "--level", "1.5"]) == 2
    assert "--level 1.5: must be a confidence in (0.5, 1)" in capsys.readouterr().err
    assert main(["certify", str(out), "--levels", "0.6,high"]) == 2
    assert "--levels: 'high' is not a number" in capsys.readouterr().err
    assert main(["certify", str(out), "--validate", "50"]) == 2
    assert "--validate 50: the brute-force runs must be ≥ 100" in capsys.readouterr().err
    assert not (out / "certificate.parquet").exists()     # refused before any work
    assert main(["gate", str(out), "--max-fa-prob", "1e-3"]) == 2
    assert f"fdd-campaign certify {out}" in capsys.readouterr().err
    import pyarrow.parquet as pq

    from campaign.store.directory import CampaignDir

    cdir = CampaignDir(out)
    summary, meta = cdir.read_summary()
    cdir.write_summary(summary, cdir.config_path.read_text(), complete=False,
                       runs_done=300, runs_planned=400)
    assert main(["certify", str(out)]) == 2
    err = capsys.readouterr().err
    assert "unfinished (300 of 400 runs done)" in err and "fdd-campaign run" in err
    assert pq.read_metadata(cdir.summary_path) is not None


def test_certificate_counting_bound_equals_the_summary_bound():
    from reports.scoring.summary import summarize

    rng = np.random.default_rng(0)
    n = 300
    results = pd.DataFrame({
        "run_id": [f"r{i}" for i in range(n)], "detector": "d", "fault": "none",
        "manoeuvre": "cruise", "status": "ok", "error": "",
        "false_alarm": rng.random(n) < 0.01, "pre_onset_alarm": False, "detected": False,
        "first_alarm_s": np.nan, "delay_s": np.nan, "dtp": np.nan,
        "margin": rng.exponential(0.2, n)})
    plan = pd.DataFrame({"run_id": results["run_id"], "duration_s": 60.0})
    cert = certificate(results, plan)
    summary = summarize(results)
    assert cert["fa_upper95_cp"].iloc[0] == pytest.approx(summary["fa_upper95"].iloc[0], rel=1e-12)


def test_gate_probability_check_uses_the_larger_model_bound():
    cert = pd.DataFrame({"detector": ["a", "b"], "level": 0.95, "fa_upper95_cp": [0.01, 0.02],
                         "fa_prob_evt_upper95": [1e-6, np.nan],
                         "sampling_upper95": [1e-4, np.nan]})
    a, b = fa_probability_checks(cert, 1e-5)
    assert not a.passed and a.value == 1e-4 and "subset simulation" in a.message
    assert not b.passed and b.value == 0.02 and "counting" in b.message
    assert fa_probability_checks(cert, 0.5)[0].passed
    with pytest.raises(GateInputError, match="per-run probability in"):
        fa_probability_checks(cert, 2.0)


def test_gate_names_a_counted_curve_bound_counting_not_tail_fit():
    """12 fault-free runs (the smoke preset's number), too few for a tail fit, all with
    margins below 1. In two manoeuvres of 6 the curve's bound at margin 1 is the pooled
    counting bound 1 − 0.05^(1/12) (smaller than the manoeuvres' counts mixed,
    ``evt_method`` "counted"); in one manoeuvre it is that manoeuvre's count ("counted per
    manoeuvre"). The gate's message names either a counting bound, never "tail fit"; a
    certificate made before ``evt_method`` existed is read from its note. The limit of the
    runs is named as such."""
    rng = np.random.default_rng(3)
    n = 12
    results = pd.DataFrame({
        "run_id": [f"r{i}" for i in range(n)], "detector": "d", "fault": "none",
        "manoeuvre": np.repeat(["cruise", "pitch"], n // 2), "status": "ok",
        "false_alarm": False, "margin": rng.uniform(0.1, 0.4, n)})
    plan = pd.DataFrame({"run_id": results["run_id"], "duration_s": 60.0})
    one = results.assign(manoeuvre="cruise")
    for res, method, label in (
            (results, "counted", "(counting, Clopper–Pearson, of the margins ≥ 1)"),
            (one, "counted per manoeuvre", "(counting, Clopper–Pearson per manoeuvre")):
        cert = certificate(res, plan)
        [check] = fa_probability_checks(cert, 1e-3)
        assert label in check.message and "(tail fit" not in check.message
        assert not check.passed and check.value == pytest.approx(0.221, abs=5e-4)
        assert cert["fa_prob_evt_upper95"].iloc[0] == pytest.approx(1 - 0.05 ** (1 / n),
                                                                    rel=1e-12)
        assert cert["evt_method"].iloc[0] == method
        [old] = fa_probability_checks(cert.drop(columns="evt_method"), 1e-3)
        assert old.message == check.message
    limit = cert.assign(evt_method="limit of the runs", fa_prob_evt_upper95=2.49e-5)
    [lim] = fa_probability_checks(limit, 1e-3)
    assert "(limit of the runs: the counting (Clopper–Pearson) bound / 100" in lim.message


# ---- detection time as survival data -------------------------------------------------------------
def test_kaplan_meier_keeps_the_misses_at_risk():
    from reports.scoring.survival import kaplan_meier, survival_stats

    delays = np.arange(1.0, 9.0)            # 8 runs detected after 1 … 8 s, 2 missed
    t, f, f_lo, f_hi = kaplan_meier(delays, 2)
    assert np.allclose(f, np.arange(1, 9) / 10.0)
    assert np.all(f_lo <= f + 1e-12) and np.all(f <= f_hi + 1e-12)
    stats_ = survival_stats(delays, delays / 4.0, 2)
    assert stats_["delay_km_median_s"] == 5.0
    assert stats_["delay_km_median_lo_s"] <= 5.0 <= stats_["delay_km_median_hi_s"]
    assert np.isnan(stats_["delay_km_p95_s"])          # the curve stops at 0.8
    assert np.isnan(stats_["dtp_p99_upper95"])          # 10 runs: too few for the bound


def test_tolerance_bound_rule():
    from reports.scoring.survival import survival_stats, tolerance_rank

    assert tolerance_rank(298) is None and tolerance_rank(299) == 299
    r = tolerance_rank(1000)
    assert stats.binom.cdf(r - 1, 1000, 0.99) >= 0.95 > stats.binom.cdf(r - 2, 1000, 0.99)
    d = np.random.default_rng(2).uniform(size=1000)
    assert survival_stats(d, d, 0)["dtp_p99_upper95"] == np.sort(d)[r - 1]
    assert survival_stats(d[:995], d[:995], 5)["dtp_p99_upper95"] == np.inf


def test_summary_appends_the_survival_columns_only():
    from reports.scoring.summary import SUMMARY_COLUMNS, summarize
    from reports.scoring.survival import SURVIVAL_COLUMNS

    assert SUMMARY_COLUMNS[-len(SURVIVAL_COLUMNS):] == SURVIVAL_COLUMNS
    n = 20
    results = pd.DataFrame({
        "run_id": [f"r{i}" for i in range(n)], "detector": "d", "fault": "runaway",
        "manoeuvre": "cruise", "status": "ok", "error": "", "false_alarm": False,
        "pre_onset_alarm": False, "detected": np.arange(n) < 16,
        "first_alarm_s": np.nan, "delay_s": np.where(np.arange(n) < 16, np.arange(n) * 0.1, np.nan),
        "dtp": np.where(np.arange(n) < 16, np.arange(n) * 0.05, np.nan), "margin": 0.1})
    row = summarize(results).iloc[0]
    assert row["md_count"] == 4 and row["delay_km_median_s"] == pytest.approx(0.9)


def test_certify_writes_the_exceedance_curve_and_validates_it(constructed, capsys):
    from campaign.evidence.certify.levels import LEVEL_COLUMNS
    import campaign
    from campaign.store.directory import CampaignDir

    out, true, config = constructed
    assert main(["certify", str(out), "--levels", "0.95,0.9", "--jobs", "1"]) == 0
    levels = pd.read_parquet(out / "certificate-levels.parquet")
    assert list(levels.columns) == list(LEVEL_COLUMNS)
    # one row per detector × level, 1.0 (the false alarm) always among the levels
    assert levels["level"].tolist() == [0.9, 0.95, 1.0] and set(levels["detector"]) == {"sm"}
    assert (levels["n_runs"] == 400).all()
    cert = pd.read_parquet(out / "certificate.parquet")
    at_one = levels[levels["level"] == 1.0].iloc[0]
    assert cert["fa_prob_evt_upper95"].iloc[0] == at_one["p_upper95"]
    # never more than two decades under the counting bound of the runs
    assert (levels["p_upper95"] >= levels["p_counted_upper95"] / 100 * (1 - 1e-12)).all()
    assert true <= at_one["p_upper95"]
    assert CampaignDir(out).verify() == []          # the manifest records the new file
    assert "P(margin ≥ level)" in capsys.readouterr().out
    # the report draws the curve from the file, against the runs' own margins
    from campaign.evidence.figures import evidence_figure_specs
    from reports.render.figures.report import render_png

    spec = next(s for s in evidence_figure_specs(campaign.load(out)) if s[4] == "exceedance")
    assert spec[1] == "sm" and list(spec[5][0]) == [0.9, 0.95, 1.0]
    assert list(spec[5][2]) == levels["p_upper95"].tolist() and len(spec[5][3]) == 400
    assert render_png(*spec[4:]).startswith(b"\x89PNG")
    # the campaign's own seed is refused, before anything runs
    assert main(["certify", str(out), "--validate", "400", "--validate-seed", "11",
                 "--jobs", "1"]) == 2
    assert "the campaign's own seed" in capsys.readouterr().err
    assert main(["certify", str(out), "--levels", "0.95,0.9", "--validate", "400",
                 "--validate-seed", "12", "--jobs", "1"]) == 0
    assert "p_upper95 covers the brute-force frequency" in capsys.readouterr().out
    table = pd.read_parquet(out / "validation" / "seed-12-n400.parquet")
    results = campaign.load(out / "validation" / "seed-12-n400").results
    margins = results.loc[results["fault"] == "none", "margin"].to_numpy(float)
    assert margins.size == 400
    for r in table.to_dict(orient="records"):
        assert r["validation_count"] == int((margins >= r["level"]).sum())
        assert r["tested"] == (r["validation_count"] >= 5)


# ---- one writer of a campaign directory ------------------------------------------------------
def test_only_the_campaign_directory_writes_into_it(constructed, capsys):
    # certify --sampling (the subset simulation's batches and levels) and --validate (a
    # campaign of its own under validation/ and its coverage table) write through
    # CampaignDir; an audit hook records any file written into the directory otherwise
    from directory_audit import writes_outside_the_store

    out, _, _ = constructed
    with writes_outside_the_store(out) as found:
        assert main(["certify", str(out), "--sampling", "100", "--jobs", "1", "--levels",
                     "0.95,0.9", "--validate", "100", "--validate-seed", "12"]) == 0
    written = {p.relative_to(out).parts[0] for p in out.rglob("*.parquet")}
    assert {"sampling", "validation"} <= written     # those writes did happen
    assert found == []
