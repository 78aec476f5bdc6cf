"""Campaign suites (campaign.suite): validation, run, resume, gate, report and plan of several
campaigns run one after the other, and the shipped chen-tables suite."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from campaign.cli.commands import main
from campaign.config import ConfigError, load_config
from campaign.suite import is_suite_dir, list_suites, load_spec, load_suite

CAMPAIGN = """\
[campaign]
name = "{name}"
seed = {seed}
duration_s = 20.0

[faults]
onset_min_s = 5.0
onset_before_end_s = 5.0

[[group]]
name = "ff"
fault = "none"
manoeuvres = ["cruise", "nose_up"]
count = 3

[[group]]
name = "ra"
fault = "runaway"
manoeuvres = ["cruise"]
count = 2

[[detector]]
name = "position-monitor"
{params}
[learning]
runs_per_manoeuvre = {learning}

[runner]
chunk_size = 8
"""

#: thresholds at 1.01 × the largest residual of 1 learning run, no confirmation: far too
#: tight for 6 fault-free evaluation runs at other flight points (as in test_campaign)
SENSITIVE = 'params = { safety = 1.01, confirm_s = 0.0 }\n'


def _campaign(tmp_path, name, seed=7, sensitive=False):
    path = tmp_path / f"{name}.toml"
    path.write_text(CAMPAIGN.format(name=name, seed=seed, params=SENSITIVE if sensitive else "",
                                    learning=1 if sensitive else 2))
    return path


def _suite(tmp_path, members, name="two"):
    text = f'[suite]\nname = "{name}"\ndescription = "two small campaigns"\n'
    for campaign, title in members:
        text += f'\n[[member]]\ncampaign = "{campaign}"\ntitle = "{title}"\n'
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


@pytest.fixture
def two(tmp_path):
    _campaign(tmp_path, "first")
    _campaign(tmp_path, "second", seed=8)
    return _suite(tmp_path, [("first.toml", "Table A"), ("second.toml", "Table B")])


def test_suite_loads_its_members_relative_to_its_file(two):
    suite = load_spec(two)
    assert suite.name == "two"
    assert [m.name for m in suite.members] == ["first", "second"]
    assert [m.title for m in suite.members] == ["Table A", "Table B"]
    # a campaign file is still a campaign, and load_config refuses a suite with directions
    assert load_spec(two.parent / "first.toml").campaign.name == "first"
    with pytest.raises(ConfigError, match="a suite file"):
        load_config(two)


@pytest.mark.parametrize("members, extra, needles", [
    ([], "", ["no [[member]] table"]),
    ([("nowhere.toml", "A")], "", ["member[0] (nowhere.toml)", "file not found"]),
    ([("smoek", "A")], "", ["member[0] (smoek)", "did you mean 'smoke'"]),
    ([("first.toml", "A"), ("first.toml", "B")], "", ["has the campaign name 'first' of "
                                                      "member[0]", "would collide"]),
    ([("first.toml", "")], "", ["member[0].title: required"]),
    ([("chen-tables", "A")], "", ["is itself a suite"]),
    ([("first.toml", "A")], 'colour = "red"\n', ["suite.colour: unknown key"]),
])
def test_bad_suite_files_are_named_with_every_problem(tmp_path, members, extra, needles):
    _campaign(tmp_path, "first")
    path = _suite(tmp_path, members)
    if extra:
        path.write_text(path.read_text().replace('description = "two small campaigns"\n',
                                                 'description = "two small campaigns"\n'
                                                 + extra))
    with pytest.raises(ConfigError) as info:
        load_suite(path)
    for needle in needles:
        assert needle in str(info.value)


def test_a_member_campaign_file_error_is_reported_with_the_member(tmp_path):
    bad = _campaign(tmp_path, "first")
    bad.write_text(bad.read_text().replace("duration_s = 20.0", "duration_s = 5.0"))
    _campaign(tmp_path, "second")
    with pytest.raises(ConfigError) as info:
        load_suite(_suite(tmp_path, [("first.toml", "A"), ("second.toml", "B")]))
    text = str(info.value)
    assert "member[0] (first.toml)" in text and "duration_s" in text
    assert "member[1]" not in text                     # the good member raises nothing


def test_run_gate_report_and_plan_on_a_suite(two, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(two), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    printed = capsys.readouterr().out
    # each member's table under its title, in the suite's order
    assert printed.index("== Table A ==") < printed.index("campaign 'first'") \
        < printed.index("== Table B ==") < printed.index("campaign 'second'")
    assert is_suite_dir(out)
    doc = json.loads((out / "suite.json").read_text())
    assert [(m["campaign"], m["title"], m["complete"]) for m in doc["members"]] == [
        ("first", "Table A", True), ("second", "Table B", True)]
    first = pd.read_parquet(out / "first" / "runs")
    assert len(first) == 8 and (first["status"] == "ok").all()

    # resume: a rerun finds every run done and changes nothing
    assert main(["run", str(two), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    pd.testing.assert_frame_equal(pd.read_parquet(out / "first" / "runs"), first)

    junit = tmp_path / "gate.xml"
    assert main(["gate", str(out), "--max-fa", "0", "--junit", str(junit)]) == 0
    printed = capsys.readouterr().out
    assert "== Table A ==" in printed and "suite gate PASSED: 2 of 2" in printed
    root = ET.parse(junit).getroot()
    assert [s.get("name") for s in root] == ["fdd-campaign gate first",
                                             "fdd-campaign gate second"]
    assert int(root.get("tests")) == sum(int(s.get("tests")) for s in root) > 0

    assert main(["report", str(out), "--no-html"]) == 0
    printed = capsys.readouterr().out
    assert "== Table B ==" in printed and "campaign 'second': 8 of 8 runs" in printed
    assert main(["report", str(out), "--html", str(tmp_path / "r.html")]) == 2
    assert "leave --html out" in capsys.readouterr().err

    plans = tmp_path / "plans"
    assert main(["plan", str(two), "--out", str(plans)]) == 0
    assert len(pd.read_parquet(plans / "second" / "plan.parquet")) == 8


def test_suite_gate_fails_when_one_member_fails(tmp_path, capsys):
    _campaign(tmp_path, "good")
    _campaign(tmp_path, "touchy", sensitive=True)
    suite = _suite(tmp_path, [("good.toml", "Good"), ("touchy.toml", "Touchy")])
    out = tmp_path / "out"
    assert main(["run", str(suite), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["gate", str(out), "--max-fa", "0"]) == 1
    printed = capsys.readouterr().out
    assert "suite gate FAILED: 1 of 2 campaigns passed" in printed and "FAIL" in printed


def test_gate_on_a_suite_directory_with_a_member_not_run_yet(two, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(two), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    import shutil

    shutil.rmtree(out / "second")
    capsys.readouterr()
    assert main(["gate", str(out)]) == 2
    assert "have not run yet" in capsys.readouterr().err


def test_chen_tables_suite_is_shipped_and_listed(capsys):
    assert "chen-tables" in list_suites()
    suite = load_suite("chen-tables")
    assert [m.name for m in suite.members] == ["chen-sweep", "chen-mc"]
    assert "Table 3" in suite.members[0].title and "Table 4" in suite.members[1].title
    assert main(["presets"]) == 0
    assert "chen-tables      (suite)" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="a suite of campaigns"):
        load_config("chen-tables")


@pytest.mark.parametrize("command", ["run", "plan"])
@pytest.mark.parametrize("typed, meant", [("chen-tabels", "chen-tables"), ("smok", "smoke"),
                                          ("vanek-sektion5", "vanek-section5")])
def test_a_misspelt_preset_or_suite_gets_the_closest_of_both(tmp_path, capsys, command, typed,
                                                             meant):
    out = tmp_path / "out"
    assert main([command, typed, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"did you mean {meant!r}?" in err
    listed = err.split("presets:")[1]
    assert "chen-tables" in listed and "vanek-section5" in listed and "smoke" in listed
    assert not out.exists()


def test_vanek_section5_suite_names_its_three_campaigns():
    suite = load_suite("vanek-section5")
    assert [m.name for m in suite.members] == ["vanek-scenarios", "vanek-isolation",
                                               "vanek-isolation-rudder"]
    monitored = [load_config(m.name).plant.monitored_surface for m in suite.members]
    assert monitored == ["left_inboard_aileron", "left_elevator", "rudder"]


def test_show_and_compare_name_the_members_of_a_suite_directory(two, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(two), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["compare", str(out), str(out / "first")]) == 2
    err = capsys.readouterr().err
    assert "suite of campaigns" in err and str(out / "second") in err


def test_a_suite_is_not_run_into_a_campaign_directory(two, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "first.toml"), "--out", str(out), "--jobs", "1",
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["run", str(two), "--out", str(out), "--quiet"]) == 2
    assert "directory of one campaign" in capsys.readouterr().err
    assert not (out / "suite.json").exists()


def test_a_half_finished_suite_resumes_with_its_unfinished_member(two, tmp_path, capsys):
    # the first member finished, the second never ran (as after a kill between members):
    # a rerun keeps the first member's rows and runs the second, rows equal to a fresh run
    import shutil

    out, fresh = tmp_path / "out", tmp_path / "fresh"
    assert main(["run", str(two), "--out", str(fresh), "--jobs", "1", "--quiet"]) == 0
    shutil.copytree(fresh / "first", out / "first")
    shards = {p: p.stat().st_mtime_ns for p in (out / "first" / "runs").glob("*.parquet")}
    assert main(["run", str(two), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    # the finished member's shards are neither rewritten nor added to (nothing re-ran)
    assert {p: p.stat().st_mtime_ns
            for p in (out / "first" / "runs").glob("*.parquet")} == shards
    key = ["run_id", "detector"]
    again = pd.read_parquet(out / "second" / "runs").sort_values(key).reset_index(drop=True)
    ref = pd.read_parquet(fresh / "second" / "runs").sort_values(key).reset_index(drop=True)
    pd.testing.assert_frame_equal(again, ref[again.columns], check_exact=True)
    doc = json.loads((out / "suite.json").read_text())
    assert [m["complete"] for m in doc["members"]] == [True, True]


def test_chen_tables_members_name_their_published_tables():
    suite = load_suite("chen-tables")
    assert [m.reference for m in suite.members] == ["chen-table-3", "chen-table-4"]


def test_an_unknown_reference_table_is_refused(tmp_path):
    _campaign(tmp_path, "first")
    path = _suite(tmp_path, [("first.toml", "A")])
    path.write_text(path.read_text() + 'reference = "chen-table-5"\n')
    with pytest.raises(ConfigError) as info:
        load_suite(path)
    assert "member[0].reference: unknown table 'chen-table-5'" in str(info.value)
    assert "allowed: chen-table-3, chen-table-4" in str(info.value)


def test_a_member_with_a_reference_prints_the_published_table_in_run_and_report(tmp_path,
                                                                                capsys):
    _campaign(tmp_path, "first")
    path = _suite(tmp_path, [("first.toml", "A")])
    path.write_text(path.read_text() + 'reference = "chen-table-4"\n')
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "Beside [CHEN] Table 4" in printed
    # this campaign has no jam: the estimator rows say so, [CHEN]'s rows are still printed
    assert "ours: chen-local[solid]" in printed and "not in this campaign" in printed
    assert "0.001/0.001/0.001" in printed
    assert json.loads((out / "suite.json").read_text())["members"][0]["reference"] == \
        "chen-table-4"
    assert main(["report", str(out), "--no-html"]) == 0
    assert "Beside [CHEN] Table 4" in capsys.readouterr().out


def test_paper_table_puts_our_estimator_row_beside_the_papers():
    from reports.render.table import format_paper_table

    def srow(detector, fault, **kw):
        base = {"detector": detector, "fault": fault, "manoeuvre": "all", "n_runs": 10,
                "fa_rate": 0.0, "md_rate": 0.0, "md_req_rate": 0.0, "dtp_min": np.nan,
                "dtp_mean": np.nan, "dtp_max": np.nan, "est_err_mean": np.nan,
                "est_err_var": np.nan}
        return {**base, **kw}

    summary = pd.DataFrame([
        srow("chen-local[solid]", "none", n_runs=1200),
        srow("chen-local[solid]", "solid_jam", md_req_rate=0.1, dtp_min=0.5, dtp_mean=0.7,
             dtp_max=2.9, delay_min_s=0.09, delay_mean_s=0.4, delay_max_s=3.5,
             est_err_mean=0.00123, est_err_var=4.5e-8),
        srow("chen-local[liquid]", "solid_jam", dtp_min=0.005),     # not the solid row
    ])
    text = format_paper_table(summary, "chen-table-4",
                              {"liquid_jam": 2.0, "solid_jam": 2.0, "disconnection": 1.0})
    lines = text.splitlines()
    ours = next(i for i, line in enumerate(lines) if "ours: chen-local[solid]" in line)
    assert "0.5/0.7/2.9" in lines[ours] and "10.00" in lines[ours]
    # our delays in seconds beside the paper's (0.001 × 120 s = 0.12 s, inferred)
    assert "0.09/0.4/3.5" in lines[ours]
    assert "0.12/0.12/0.12" in lines[ours + 1]
    assert "our required times liquid_jam 2 s, solid_jam 2 s, disconnection 1 s" in text
    assert "not comparable" in text and "12000 steps = 120 s" in text
    # a summary written before delay_min_s/delay_max_s existed: our delays read '-'
    old = format_paper_table(summary.drop(columns=["delay_min_s", "delay_max_s"]),
                             "chen-table-4").splitlines()
    row = next(line for line in old if "ours: chen-local[solid]" in line)
    assert "0.09/" not in row and " - " in row and "0.5/0.7/2.9" in row
    assert "our required times (the campaign's [requirements])" in "\n".join(old)
    assert "0.00123" in lines[ours] and "4.5e-08" in lines[ours]
    assert "(n=1200)" in lines[ours]
    # the next line is [CHEN]'s: DTP 0.001 and the §6.2 error statistics
    assert "[CHEN] Table 4" in lines[ours + 1] and "0.001/0.001/0.001" in lines[ours + 1]
    assert "0.0014" in lines[ours + 1] and "2.7972e-08" in lines[ours + 1]
    assert "normalised by the rod travel of the deflection range" in text


def test_chen_delays_are_the_dtp_times_the_inferred_120_s():
    """[CHEN] prints DTP, not delays: every DTP extreme of Tables 3–4 is a whole multiple of
    1/12000 within the rounding of its six printed digits (a relative error ≤ 5e-6 of the
    printed value), and not of 1/6000; at the 10 ms step that is 12000 steps = 120 s
    (reports.render.paper's docstring), so the delays are the whole steps below."""
    from reports.render.paper import CHEN_DTP_DENOMINATOR_S, PAPER_TABLES

    assert CHEN_DTP_DENOMINATOR_S == pytest.approx(120.0, rel=1e-15)
    steps = {}
    for name, table in PAPER_TABLES.items():
        for fault, row in table.rows.items():
            for which, dtp in (("min", row.dtp[0]), ("max", row.dtp[2])):
                n = dtp * 12000
                assert abs(n - round(n)) <= 5e-6 * n, (name, fault, which, dtp)
                steps[(name, fault, which)] = round(n)
    assert any(abs(dtp * 6000 - round(dtp * 6000)) > 0.4 for table in PAPER_TABLES.values()
               for row in table.rows.values() for dtp in (row.dtp[0], row.dtp[2]))
    assert steps[("chen-table-3", "disconnection", "min")] == 91
    assert steps[("chen-table-3", "disconnection", "max")] == 701
    assert steps[("chen-table-4", "disconnection", "min")] == 96
    assert steps[("chen-table-4", "disconnection", "max")] == 452
    assert steps[("chen-table-4", "liquid_jam", "max")] == 14
    assert steps[("chen-table-4", "solid_jam", "max")] == 12
    t3, t4 = PAPER_TABLES["chen-table-3"], PAPER_TABLES["chen-table-4"]
    assert t4.delays_s("liquid_jam") == (0.14, 0.14, 0.14)
    assert t4.delays_s("solid_jam") == (0.12, 0.12, 0.12)
    assert (t3.delays_s("disconnection")[0], t3.delays_s("disconnection")[2]) == (0.91, 7.01)
    assert (t4.delays_s("disconnection")[0], t4.delays_s("disconnection")[2]) == (0.96, 4.52)
