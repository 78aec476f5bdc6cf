"""Hazard per flight hour (campaign.evidence.hazard): the combination of fault-mode rates with the
missed-detection probabilities, checked against hand arithmetic; the AMC 25.1309
categories; the [requirements] fault_rate_per_fh key's validation."""

from __future__ import annotations

import html
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from campaign.config import CampaignConfig, ConfigError
from campaign.evidence.hazard import (AMC_25_1309_BUDGETS_PER_FH, DEFAULT_FAULT_RATES_PER_FH,
                                     HAZARD_COLUMNS, RATE_GIVEN, RATE_PLACEHOLDER, credit,
                                     hazard_table, meets, with_claims)


def _results():
    """Detector d: runaway 200 runs, 2 missed, 3 late (DTP > 1); solid_jam 100 runs, none
    missed; 300 fault-free runs of 60 s, 1 false alarm."""
    rows = []
    for i in range(200):
        missed, late = i < 2, 2 <= i < 5
        rows.append(("runaway", not missed, 1.5 if late else (np.nan if missed else 0.5), False))
    rows += [("solid_jam", True, 0.3, False)] * 100
    rows += [("none", False, np.nan, i == 0) for i in range(300)]
    out = pd.DataFrame(rows, columns=["fault", "detected", "dtp", "false_alarm"])
    out["run_id"] = [f"r{i}" for i in range(len(out))]
    out["detector"] = "d"
    out["status"] = "ok"
    plan = pd.DataFrame({"run_id": out["run_id"], "duration_s": 60.0})
    return out, plan


def test_undetected_fault_rates_against_hand_arithmetic():
    results, plan = _results()
    rates = {"runaway": 1e-6, "solid_jam": 2e-6}
    table = hazard_table(results, plan, rates, 0.95)
    assert list(table.columns) == list(HAZARD_COLUMNS)
    assert list(table["fault"]) == ["runaway", "solid_jam", "all", "none"]
    h = table.set_index("fault")
    # runaway: P_MD = 2/200, bound Beta⁻¹(0.95; 3, 198) (exact one-sided Clopper–Pearson)
    up = stats.beta.ppf(0.95, 3, 198)
    assert h.loc["runaway", "p_run"] == 0.01
    assert h.loc["runaway", "p_run_upper95"] == pytest.approx(up, rel=1e-12)
    assert h.loc["runaway", "per_fh"] == pytest.approx(1e-8, rel=1e-12)
    assert h.loc["runaway", "per_fh_upper95"] == pytest.approx(1e-6 * up, rel=1e-12)
    # 1e-6 × 0.0312 = 3.1e-8 ≤ 1e-7: hazardous met, catastrophic (1e-9) not; without the
    # detector 1e-6 (major): the detector is credited hazardous
    assert h.loc["runaway", "meets_with"] == "hazardous"
    assert h.loc["runaway", "without_per_fh"] == 1e-6
    assert h.loc["runaway", "meets_without"] == "major"
    assert h.loc["runaway", "credited"] == "hazardous"
    assert h.loc["runaway", "bound"] == "counting (Clopper–Pearson)"
    # in time: 2 missed + 3 late of 200
    assert h.loc["runaway", "late_or_missed"] == 5
    assert h.loc["runaway", "in_time_per_fh_upper95"] == pytest.approx(
        1e-6 * stats.beta.ppf(0.95, 6, 195), rel=1e-12)
    # solid_jam: 0 of 100, bound 1 − 0.05^(1/100)
    assert h.loc["solid_jam", "per_fh"] == 0.0
    assert h.loc["solid_jam", "per_fh_upper95"] == pytest.approx(
        2e-6 * (1 - 0.05 ** (1 / 100)), rel=1e-12)
    # all: Σ λ_f P_MD,f, bound Σ λ_f P_MD,f^up at 1 − 0.05/2 each (Bonferroni, 2 types)
    assert h.loc["all", "per_fh"] == pytest.approx(1e-8, rel=1e-12)
    total = 1e-6 * stats.beta.ppf(0.975, 3, 198) + 2e-6 * (1 - 0.025 ** (1 / 100))
    assert h.loc["all", "per_fh_upper95"] == pytest.approx(total, rel=1e-12)
    assert h.loc["all", "n_runs"] == 300 and h.loc["all", "events"] == 2
    # false alarms: 1 of 300 runs of 60 s: λ = −ln(1 − p)/(1/60 h)
    p_up = stats.beta.ppf(0.95, 2, 299)
    assert h.loc["none", "per_fh"] == pytest.approx(-math.log1p(-1 / 300) * 60, rel=1e-12)
    assert h.loc["none", "per_fh_upper95"] == pytest.approx(-math.log1p(-p_up) * 60, rel=1e-12)
    assert h.loc["none", "meets_with"] == "none"          # ≈ 0.95 per hour
    # false alarms are no credit of the detector, and none happen without it
    assert h.loc["none", "credited"] == "n/a" and h.loc["none", "without_per_fh"] == 0.0
    assert h.loc["none", "bound"].startswith("counting (Clopper–Pearson)")


def test_a_missing_rate_and_a_bad_level_are_refused():
    results, plan = _results()
    with pytest.raises(ValueError, match="solid_jam.*fault_rate_per_fh"):
        hazard_table(results, plan, {"runaway": 1e-6})
    with pytest.raises(ValueError, match="confidence in"):
        hazard_table(results, plan, DEFAULT_FAULT_RATES_PER_FH, 1.2)


def test_amc_categories_at_their_budgets():
    assert AMC_25_1309_BUDGETS_PER_FH == {"major": 1e-5, "hazardous": 1e-7,
                                          "catastrophic": 1e-9}
    assert meets(1e-9) == "catastrophic" and meets(1.01e-9) == "hazardous"
    assert meets(1e-7) == "hazardous" and meets(1e-6) == "major"
    assert meets(1e-5) == "major" and meets(1.01e-5) == "none"
    assert meets(0.0) == "catastrophic" and meets(math.nan) == "n/a"


def _faulty(fault: str, n: int, missed: int, detector: str = "d") -> pd.DataFrame:
    """*n* faulty runs of type *fault*, the first *missed* of them never detected, the
    others detected in time (DTP 0.5)."""
    detected = np.arange(n) >= missed
    return pd.DataFrame({"run_id": [f"{detector}-{fault}-{i}" for i in range(n)],
                         "detector": detector, "fault": fault, "status": "ok",
                         "detected": detected, "dtp": np.where(detected, 0.5, np.nan),
                         "false_alarm": False})


def test_a_detector_that_detected_none_of_its_runs_is_credited_nothing():
    """The measured case of addsafe-mc: every comb-interval variant misses all 334
    disconnections; at the default 1e-7/FH the undetected rate is the fault rate, at the
    hazardous budget: met by the fault rate alone, and the detector gets no credit (the
    old table said "meets hazardous" for it)."""
    table = hazard_table(_faulty("disconnection", 334, 334), None,
                         DEFAULT_FAULT_RATES_PER_FH)
    h = table.set_index("fault")
    for fault in ("disconnection", "all"):
        assert h.loc[fault, "events"] == 334 and h.loc[fault, "p_run_upper95"] != 0.0
        assert h.loc[fault, "without_per_fh"] == 1e-7
        assert h.loc[fault, "per_fh_upper95"] == pytest.approx(1e-7, rel=1e-12)
        assert h.loc[fault, "credited"] == "none"
        assert h.loc[fault, "credited_in_time"] == "none"
        assert "detected none of its 334 runs" in h.loc[fault, "claim"]
        assert "met by the fault rate alone (hazardous), no credit" in h.loc[fault, "claim"]
        assert h.loc[fault, "rate_source"] == RATE_PLACEHOLDER
    # the rule holds whatever the rate: never a category for a detector that caught nothing
    for lam in (1e-12, 1e-8, 5e-6, 1e-3):
        assert credit(20, 20, 1.0, lam, lam)[0] == "none"
    assert "no credit: detected none of its 20 runs" in credit(20, 20, 1.0, 1e-3, 1e-3)[1]


def test_a_bound_above_one_half_shows_no_category():
    """2 runs of a fault, both detected: the counting bound of the missed share is
    1 − 0.05^(1/2) = 0.776. At a rate of 1.2e-7/FH (major alone) the bound with the
    detector, 9.3e-8/FH, is under the hazardous budget, but the runs cannot tell a detector
    that misses most faults from one that misses none: not shown, no credit."""
    table = hazard_table(_faulty("runaway", 2, 0), None, {"runaway": 1.2e-7})
    h = table.set_index("fault")
    p_up = 1 - 0.05 ** 0.5
    assert h.loc["runaway", "p_run_upper95"] == pytest.approx(p_up, rel=1e-12)
    assert h.loc["runaway", "per_fh_upper95"] == pytest.approx(1.2e-7 * p_up, rel=1e-12)
    assert h.loc["runaway", "meets_with"] == "hazardous"
    assert h.loc["runaway", "meets_without"] == "major"
    assert h.loc["runaway", "credited"] == "none"
    assert "not shown" in h.loc["runaway", "claim"] and "0.776" in h.loc["runaway", "claim"]
    assert h.loc["runaway", "rate_source"] == RATE_GIVEN
    # the total: Σ λ_f P_f^up / Σ λ_f = 0.776 too (one type, Bonferroni over one)
    assert h.loc["all", "credited"] == "none" and "not shown" in h.loc["all", "claim"]
    # at the limit: 0.5 is still shown, just above it is not
    assert credit(10, 1, 0.5, 1.2e-7, 6e-8)[0] == "hazardous"
    assert credit(10, 1, 0.5000001, 1.2e-7, 6e-8)[0] == "none"


def test_a_category_met_by_the_fault_rate_alone_is_no_credit():
    """Disconnection at 1e-7/FH is within the hazardous budget with no detector at all; a
    detector missing 1 of 100 (bound 0.0466, 4.7e-9/FH) stays in it: met by the fault rate
    alone, no credit, not shown. Runaway at 1e-6/FH (major alone), 0 of 300 missed (bound
    0.00994, 9.9e-9/FH): the detector brings it under the hazardous budget, credited."""
    results = pd.concat([_faulty("disconnection", 100, 1), _faulty("runaway", 300, 0)])
    h = hazard_table(results, None, DEFAULT_FAULT_RATES_PER_FH).set_index("fault")
    d = h.loc["disconnection"]
    assert d["p_run_upper95"] == pytest.approx(stats.beta.ppf(0.95, 2, 99), rel=1e-12)
    assert (d["meets_without"], d["meets_with"], d["credited"]) == (
        "hazardous", "hazardous", "none")
    assert d["claim"].startswith("met by the fault rate alone (hazardous), no credit")
    assert "not shown" in d["claim"]
    r = h.loc["runaway"]
    assert r["per_fh_upper95"] == pytest.approx(1e-6 * (1 - 0.05 ** (1 / 300)), rel=1e-12)
    assert (r["meets_without"], r["credited"]) == ("major", "hazardous")
    assert r["claim"].startswith("credited hazardous")
    # a mode that cannot occur (rate 0) is met alone, never credited
    assert credit(50, 0, 0.058, 0.0, 0.0) == (
        "none", "met by the fault rate alone (catastrophic), no credit; fault rate 0 (the "
        "mode cannot occur)")


def test_the_claims_of_a_table_stored_before_them_are_derived_when_shown():
    """A hazard table written before the claim columns existed (its counted columns and
    the old ``meets``) is shown with them: the same claims as a table made now."""
    results, plan = _results()
    table = hazard_table(results, plan, {"runaway": 1e-6, "solid_jam": 2e-6})
    old = table[list(HAZARD_COLUMNS[:12])].assign(meets=table["meets_with"])
    pd.testing.assert_frame_equal(with_claims(old), table)
    with pytest.raises(ValueError, match="lacks column.*late_or_missed"):
        with_claims(old.drop(columns="late_or_missed"))


def test_the_printed_table_shows_both_rates_the_credit_and_the_placeholder():
    from campaign.cli.evidence import format_hazard

    results = pd.concat([_faulty("disconnection", 334, 334), _faulty("runaway", 300, 0)])
    text = format_hazard(hazard_table(results, None, dict(DEFAULT_FAULT_RATES_PER_FH,
                                                          runaway=2e-6)))
    lines = {ln.split()[1]: ln for ln in text.splitlines() if ln.startswith("d ")}
    # disconnection: without = the placeholder 1e-7, with = 1e-7, no credit
    assert "1e-07 (est.)" in lines["disconnection"]
    assert " none " in lines["disconnection"]
    assert "detected none of its 334 runs" in lines["disconnection"]
    # runaway: a given rate, unmarked; the detector is credited hazardous
    assert "2e-06 " in lines["runaway"] and "(est.)" not in lines["runaway"]
    assert "credited hazardous" in lines["runaway"]
    assert "(est.): a placeholder: set [requirements] fault_rate_per_fh" in text
    assert "P ≤ (CP)" in text and "Clopper–Pearson" in text


def _config(**requirements):
    return {
        "campaign": {"name": "h", "seed": 1, "duration_s": 20.0},
        "group": [{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 2}],
        "detector": [{"name": "position-monitor"}],
        "requirements": requirements,
    }


def test_fault_rates_key_defaults_merge_and_validation():
    # left out: the defaults, every fault type
    c = CampaignConfig.from_dict(_config())
    assert dict(c.requirements.fault_rate_per_fh) == DEFAULT_FAULT_RATES_PER_FH
    # entries given replace the defaults', the others keep theirs
    c = CampaignConfig.from_dict(_config(fault_rate_per_fh={"runaway": 3e-5}))
    rates = dict(c.requirements.fault_rate_per_fh)
    assert (rates["runaway"] == 3e-5
            and rates["solid_jam"] == DEFAULT_FAULT_RATES_PER_FH["solid_jam"])
    assert CampaignConfig.from_dict(c.to_dict()) == c
    # a misspelt mode, a negative rate, a rate above 1/FH, a string: one report, every one
    with pytest.raises(ConfigError) as err:
        CampaignConfig.from_dict(_config(fault_rate_per_fh={
            "runawy": 1e-6, "solid_jam": -1e-6, "hardover": 2.0, "disconnection": "low"}))
    msg = str(err.value)
    assert "requirements.fault_rate_per_fh.runawy: unknown name 'runawy'" in msg
    assert "did you mean 'runaway'" in msg
    assert "fault_rate_per_fh.solid_jam: -1e-06 is out of range" in msg
    assert "1/FH" in msg
    assert "fault_rate_per_fh.hardover: 2 is out of range" in msg
    assert "fault_rate_per_fh.disconnection: expected a number" in msg


def test_certify_writes_and_prints_the_hazard_table(tmp_path, capsys):
    """``certify`` on the smoke campaign with given fault rates: the hazard table is
    written (recorded in the manifest), printed with its assumptions, and holds, per
    fault type, λ_f times the share of missed runs."""
    from campaign import run
    from campaign.cli.commands import main
    from campaign.config import load_config
    from campaign.store.directory import CampaignDir

    config = load_config("smoke")
    data = config.to_dict()
    data["requirements"]["fault_rate_per_fh"] = {"runaway": 4e-6}
    config = CampaignConfig.from_dict(data)
    out = tmp_path / "smoke"
    run(config, out, jobs=1, progress=False, log=lambda m: None)
    capsys.readouterr()
    assert main(["certify", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Hazard per flight hour" in printed and "Assumptions:" in printed
    assert "independent Poisson processes" in printed
    cdir = CampaignDir(out)
    hazard = cdir.read_hazard()
    assert cdir.verify() == []
    import campaign

    results = campaign.load(out).results
    runaway = results[(results["fault"] == "runaway") & (results["status"] == "ok")]
    row = hazard[(hazard["detector"] == "position-monitor") & (hazard["fault"] == "runaway")]
    missed = int((~runaway[runaway["detector"] == "position-monitor"]["detected"]).sum())
    assert row["rate_per_fh"].iloc[0] == 4e-6
    # the given rate is the campaign file's, the defaults are placeholders, in the file too
    assert row["rate_source"].iloc[0] == RATE_GIVEN
    jam = hazard[(hazard["detector"] == "position-monitor") & (hazard["fault"] == "solid_jam")]
    assert jam["rate_source"].iloc[0] == RATE_PLACEHOLDER
    assert "(est.): a placeholder" in printed
    # 2 runs of a type: a counting bound above 0.5, no category credited anywhere
    faulty = hazard[~hazard["fault"].isin(["none"])]
    assert (faulty["credited"] == "none").all()
    assert row["per_fh"].iloc[0] == pytest.approx(4e-6 * missed / 2, abs=1e-20)
    assert set(hazard["fault"]) == {"runaway", "liquid_jam", "solid_jam", "disconnection",
                                    "all", "none"}


def test_the_report_section_lists_every_row_and_assumption():
    """The page shows the hazard table (one row per detector × fault type, the total and the
    false alarms), the budgets and every assumption, before the runs, with a link to it;
    without a hazard table there is no such section."""
    from campaign.evidence.hazard import ASSUMPTIONS, report_section
    from reports.render.html import hazard_section, render_report
    from reports.scoring.summary import summarize

    results, plan = _results()
    table = hazard_table(results, plan, {"runaway": 1e-6, "solid_jam": 2e-6})
    section = hazard_section(*report_section(table))
    assert section.count("<tr") == 1 + len(table)
    assert "false alarm" in section and "all faults (undetected)" in section
    # both rates, the credit and its claim; runaway's 1e-6 is the placeholder, marked
    assert "without detector" in section and "credited to the detector" in section
    assert "1e-06 (est.)" in section and "2e-06 (est.)" not in section
    assert html.escape(table.set_index("fault").loc["runaway", "claim"]) in section
    assert "set [requirements] fault_rate_per_fh from your safety assessment" in section
    assert all(html.escape(a) in section for a in ASSUMPTIONS)
    assert report_section(None) is None
    runs = results.assign(manoeuvre="cruise", delay_s=np.nan, margin=0.5, alt_ft=0.0,
                          vcas_kt=0.0, mass_t=0.0, cg_pct=0.0, onset_s=np.nan)
    page = render_report(meta={"name": "t"}, summary=summarize(runs), gate=None,
                         requirements={}, runs=runs, figures=[],
                         hazard=report_section(table))
    assert section in page and page.index('id="hazard"') < page.index('id="runs"')
    assert '<a href="#hazard">' in page
    page = render_report(meta={"name": "t"}, summary=summarize(runs), gate=None,
                         requirements={}, runs=runs, figures=[])
    assert 'id="hazard"' not in page and '<a href="#hazard">' not in page
