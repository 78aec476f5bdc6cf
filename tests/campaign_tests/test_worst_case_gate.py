"""``fdd-campaign gate DIR --worst-case N`` (campaign/evidence/worst_case.py): exit 1 on a
false alarm the search finds, naming the run and the command that replays it (which confirms
it), exit 0 when none; a stored search reused, not run again; the corpus of earlier searches
replayed first; one JUnit testcase per detector; bad options refused before any work."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd
import pytest

from campaign.cli.commands import main
from campaign.config import load_config
from campaign.config.text import toml_value
from campaign.store.directory import CampaignDir

BUDGET = "30"


def _smoke_with(tmp: Path, params: dict | None) -> Path:
    """The smoke campaign (its position monitor with *params*) run into a directory."""
    data = load_config("smoke").to_dict()
    if params:
        data["detector"][0]["params"] = params
    lines = []
    for sec, value in data.items():
        for table in value if isinstance(value, list) else [value]:
            lines.append(f"[[{sec}]]" if isinstance(value, list) else f"[{sec}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    path = tmp / "campaign.toml"
    path.write_text("\n".join(lines) + "\n")
    out = tmp / "dir"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    return out


@pytest.fixture(scope="module")
def quiet_dir(tmp_path_factory):
    """Smoke as shipped: the 30-run search at seed 0 finds no false alarm (worst margin
    about 1.01, shorter than the monitor's confirmation)."""
    return _smoke_with(tmp_path_factory.mktemp("quiet"), None)


@pytest.fixture(scope="module")
def alarm_dir(tmp_path_factory):
    """Smoke with the monitor's thresholds at 1.01 × the largest learning value: no false
    alarm in its 20 runs, but the search finds some."""
    return _smoke_with(tmp_path_factory.mktemp("alarm"),
                       {"threshold_method": "max", "safety": 1.01})


def _gate(directory, *more, capsys):
    code = main(["gate", str(directory), "--worst-case", BUDGET, "--jobs", "1", *more])
    out, err = capsys.readouterr()
    return code, out, err


def _search_dir(directory, seed=0) -> Path:
    return CampaignDir(directory).worst_case_search_dir("position-monitor", int(BUDGET), seed)


@pytest.fixture(scope="module")
def alarm_gate(alarm_dir):
    """The first worst-case gate of *alarm_dir* (no corpus yet), its exit code and output."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["gate", str(alarm_dir), "--worst-case", BUDGET, "--jobs", "1",
                     "--junit", str(alarm_dir.parent / "gate.xml")])
    return code, out.getvalue(), err.getvalue()


def test_a_found_false_alarm_fails_naming_the_run_and_its_replay(alarm_dir, alarm_gate):
    code, out, _ = alarm_gate
    search = pd.read_parquet(_search_dir(alarm_dir) / "search.parquet")
    alarms = search[search["false_alarm"]].sort_values("margin", ascending=False)
    assert len(alarms) >= 1 and code == 1
    first = alarms.iloc[0]
    worst_toml = _search_dir(alarm_dir) / "worst.toml"
    assert f"FAIL worst case: position-monitor: {len(alarms)} false alarm(s)" in out
    assert f"run {first['run_id']} ({first['manoeuvre']}, {first['alt_ft']:.0f} ft" in out
    assert (f"replay: fdd-campaign run {worst_toml} --fitted-from {alarm_dir} --out "
            f"{alarm_dir}-worst-position-monitor/") in out
    assert "gate FAILED" in out
    # without --worst-case the same directory passes: its 20 runs hold no false alarm
    assert main(["gate", str(alarm_dir)]) == 0


def test_the_replay_command_confirms_the_false_alarm(alarm_dir, alarm_gate, tmp_path):
    search = pd.read_parquet(_search_dir(alarm_dir) / "search.parquet")
    named = search[search["false_alarm"]].sort_values("margin", ascending=False).iloc[0]
    out = tmp_path / "replay"
    assert main(["run", str(_search_dir(alarm_dir) / "worst.toml"), "--fitted-from",
                 str(alarm_dir), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    rows = CampaignDir(out).read_results().set_index("run_id")
    assert bool(rows.loc[named["run_id"], "false_alarm"])
    assert rows.loc[named["run_id"], "margin"] == named["margin"]
    assert main(["gate", str(out)]) == 1


def test_junit_has_one_worst_case_testcase_per_detector(alarm_dir, alarm_gate):
    root = ET.parse(alarm_dir.parent / "gate.xml").getroot()
    cases = [c for c in root.iter("testcase") if c.get("name").startswith("worst_case")]
    assert [(c.get("classname"), c.get("name")) for c in cases] == [
        ("gate.position-monitor", "worst_case[none/all]")]
    failure = cases[0].find("failure")
    assert failure is not None and "false alarm(s)" in failure.get("message")
    assert "fdd-campaign run" in failure.get("message")


def test_no_false_alarm_passes(quiet_dir, capsys):
    code, out, _ = _gate(quiet_dir, capsys=capsys)
    search = pd.read_parquet(_search_dir(quiet_dir) / "search.parquet")
    assert not search["false_alarm"].any()
    assert code == 0
    assert "PASS worst case: position-monitor: no false alarm in a 30-run search" in out
    assert "gate PASSED" in out


def test_a_stored_search_is_reused_not_recomputed(quiet_dir, capsys):
    stored = _search_dir(quiet_dir) / "search.parquet"
    if not stored.exists():
        assert _gate(quiet_dir, capsys=capsys)[0] == 0
    before = stored.stat().st_mtime_ns
    code, out, err = _gate(quiet_dir, capsys=capsys)
    assert code == 0
    assert stored.stat().st_mtime_ns == before
    assert "reused, not run again" in err and "searching" not in err
    assert "search (stored, reused): 30 runs" in out


def test_a_search_cut_before_its_worst_toml_is_run_again(quiet_dir, tmp_path, capsys):
    copy = tmp_path / "copy"
    shutil.copytree(quiet_dir, copy)
    if not (_search_dir(copy) / "worst.toml").exists():
        assert _gate(copy, capsys=capsys)[0] == 0
    (_search_dir(copy) / "worst.toml").unlink()          # killed after search.parquet
    code, _, err = _gate(copy, capsys=capsys)
    assert code == 0 and "searching 30 fault-free runs" in err
    assert (_search_dir(copy) / "worst.toml").exists()


def test_the_corpus_is_replayed_first_and_catches_what_a_new_search_misses(
        alarm_dir, alarm_gate, monkeypatch, capsys):
    import campaign.evidence.worst_case as wc

    first = alarm_gate[1]
    assert "corpus:" not in first           # the first gate had no corpus
    real = wc.falsify

    def finds_nothing(*args, **kwargs):     # a new search that misses every false alarm
        result = real(*args, **kwargs)
        result.search["false_alarm"] = False
        return result

    monkeypatch.setattr(wc, "falsify", finds_nothing)
    code, out, err = _gate(alarm_dir, "--worst-case-seed", "1", capsys=capsys)
    assert code == 1
    assert err.index("replaying the corpus first") < err.index("searching 30 fault-free runs")
    assert "corpus: 10 runs of 1 stored search(es) replayed first" in out
    assert "FALSE ALARM (corpus)" in out and "FALSE ALARM (search)" not in out
    # the new search joined the corpus: the next gate replays both searches' runs first
    code, out, _ = _gate(alarm_dir, "--worst-case-seed", "1", capsys=capsys)
    assert code == 1 and "of 2 stored search(es) replayed first" in out


@pytest.mark.parametrize("value, needle", [
    ("0", "--worst-case 0: the search needs at least 10 runs"),
    ("-3", "--worst-case -3: the search needs at least 10 runs"),
    ("9", "--worst-case 9: the search needs at least 10 runs"),
    ("abc", "--worst-case 'abc': not a whole number of runs"),
    ("2.5", "--worst-case '2.5': not a whole number of runs"),
])
def test_bad_budget_exits_2_before_any_work(quiet_dir, tmp_path, capsys, value, needle):
    copy = tmp_path / "c"
    shutil.copytree(quiet_dir, copy)
    shutil.rmtree(copy / "worst-case", ignore_errors=True)
    assert main(["gate", str(copy), "--worst-case", value]) == 2
    err = capsys.readouterr().err
    assert needle in err and "fix: " in err and "--worst-case 300" in err
    assert not (copy / "worst-case").exists()


@pytest.mark.parametrize("argv, needle", [
    (["--worst-case-seed", "3"], "--worst-case-seed applies to the worst-case search"),
    (["--worst-case", "30", "--worst-case-detector", "pm"],
     "--worst-case-detector pm: not a detector of these results; choose among "
     "position-monitor"),
    (["--worst-case", "30", "--worst-case-seed", "-1"], "--worst-case-seed -1: must be ≥ 0"),
    (["--worst-case", "30", "--jobs", "0"], "--jobs 0: must be ≥ 1"),
])
def test_bad_options_exit_2_before_any_work(quiet_dir, tmp_path, capsys, argv, needle):
    copy = tmp_path / "c"
    shutil.copytree(quiet_dir, copy)
    shutil.rmtree(copy / "worst-case", ignore_errors=True)
    assert main(["gate", str(copy), *argv]) == 2
    assert needle in capsys.readouterr().err
    assert not (copy / "worst-case").exists()


def test_only_the_directory_classes_write_into_a_campaign_directory(quiet_dir, tmp_path,
                                                                    capsys):
    # the search of a worst-case gate (its runs, Monte Carlo, worst.toml and runner
    # directory under worst-case/) and the corpus replay write through campaign.store
    from directory_audit import writes_outside_the_store

    directory = tmp_path / "dir"
    shutil.copytree(quiet_dir, directory)
    with writes_outside_the_store(directory) as found:
        code, _, _ = _gate(directory, "--worst-case-seed", "5", capsys=capsys)
    assert code == 0
    assert (_search_dir(directory, 5) / "worst.toml").is_file()   # the search was written
    assert found == []

