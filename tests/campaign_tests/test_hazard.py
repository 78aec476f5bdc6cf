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
                             HAZARD_COLUMNS, hazard_table, meets)


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
    # 1e-6 × 0.0312 = 3.1e-8 ≤ 1e-7: hazardous met, catastrophic (1e-9) not
    assert h.loc["runaway", "meets"] == "hazardous"
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
    assert h.loc["none", "meets"] == "none"          # ≈ 0.95 per hour


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
    assert rates["runaway"] == 3e-5 and rates["solid_jam"] == DEFAULT_FAULT_RATES_PER_FH["solid_jam"]
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
    assert row["per_fh"].iloc[0] == pytest.approx(4e-6 * missed / 2, abs=1e-20)
    assert set(hazard["fault"]) == {"runaway", "liquid_jam", "solid_jam", "disconnection",
                                    "all", "none"}


def test_the_report_section_lists_every_row_and_assumption():
    """The page shows the hazard table (one row per detector × fault type, the total and the
    false alarms), the budgets and every assumption, before the runs, with a link to it;
    without a hazard table there is no such section."""
    from campaign.evidence.hazard import ASSUMPTIONS, report_section
    from reports.html import hazard_section, render_report
    from reports.summary import summarize

    results, plan = _results()
    table = hazard_table(results, plan, {"runaway": 1e-6, "solid_jam": 2e-6})
    section = hazard_section(*report_section(table))
    assert section.count("<tr") == 1 + len(table)
    assert "false alarm" in section and "all faults (undetected)" in section
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