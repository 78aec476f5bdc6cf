"""``fdd-campaign gate`` and the verdict of ``run`` on real campaign directories: never green
on part of the evidence, failures that name a run to replay, and directories without results
answered in user words."""

import shutil
import xml.etree.ElementTree as ET

import pytest

from campaign.cli.commands import main
from campaign.config import load_config
from campaign.runner import finalize
from campaign.store.directory import CampaignDir


@pytest.fixture(scope="module")
def smoke_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("gate") / "smoke"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    return out


def _interrupted(smoke_dir, tmp_path, keep: int):
    """A copy of *smoke_dir* as a campaign stopped (Ctrl-C) after its first *keep* runs: the
    runner's own finalisation of an incomplete campaign."""
    copy = tmp_path / "partial"
    shutil.copytree(smoke_dir, copy)
    cdir = CampaignDir(copy)
    config, plan = load_config("smoke"), cdir.read_plan()
    results = cdir.read_results()
    for path in cdir.shard_paths():
        cdir.remove(path)
    if keep:
        cdir.write_shard(results[results["run_id"].isin(plan["run_id"].iloc[:keep])],
                         config.to_json())
    finalize(cdir, config, plan, False, 0.0)
    return copy, len(plan)


@pytest.mark.parametrize("keep", [5, 0])
def test_gate_never_passes_an_interrupted_campaign(smoke_dir, tmp_path, capsys, keep):
    copy, planned = _interrupted(smoke_dir, tmp_path, keep)
    junit = tmp_path / "gate.xml"
    assert main(["gate", str(copy), "--junit", str(junit)]) == 1
    out = capsys.readouterr().out
    assert "PASSED" not in out
    assert f"incomplete: {keep} of {planned} runs done" in out
    root = ET.parse(junit).getroot()
    assert int(root.get("failures")) >= 1
    messages = [f.get("message") for f in root.iter("failure")]
    assert any(f"incomplete: {keep} of {planned} runs done" in m for m in messages)


def test_allow_incomplete_gates_the_part_that_is_done(smoke_dir, tmp_path, capsys):
    copy, planned = _interrupted(smoke_dir, tmp_path, 5)
    assert main(["gate", str(copy), "--allow-incomplete"]) == 0
    assert f"PASS (allowed) coverage: incomplete: 5 of {planned} runs done" in \
        capsys.readouterr().out


def test_gate_on_a_finished_campaign_counts_its_coverage(smoke_dir, capsys):
    assert main(["gate", str(smoke_dir)]) == 0
    out = capsys.readouterr().out
    assert "PASS coverage: all 20 runs of the plan done" in out and "gate PASSED" in out


def test_a_false_alarm_names_the_run_and_the_show_command(smoke_dir, tmp_path, capsys):
    # a stricter detector label on the same runs: flip one fault-free row to a false alarm
    copy = tmp_path / "alarm"
    shutil.copytree(smoke_dir, copy)
    cdir = CampaignDir(copy)
    config, plan = load_config("smoke"), cdir.read_plan()
    results = cdir.read_results()
    row = results.index[(results["fault"] == "none")][2]
    results.loc[row, "false_alarm"] = True
    for path in cdir.shard_paths():
        cdir.remove(path)
    cdir.write_shard(results, config.to_json())
    finalize(cdir, config, plan, True, 0.0)
    assert main(["gate", str(copy)]) == 1
    out = capsys.readouterr().out
    run_id = results.loc[row, "run_id"]
    assert f"runs: {run_id}" in out
    assert f"replay one: fdd-campaign show {copy} {run_id} --plot run.png" in out


@pytest.mark.parametrize("state, needle", [
    ("missing", "does not exist; run a campaign into it first"),
    ("empty", "it is not a campaign directory written by 'fdd-campaign run'"),
    ("killed", "the campaign was stopped before it wrote one; finish it by running the same "
               "'fdd-campaign run' command again"),
])
def test_gate_without_results_says_what_is_missing(smoke_dir, tmp_path, capsys, state,
                                                   needle):
    target = tmp_path / "d"
    if state == "empty":
        target.mkdir()
    elif state == "killed":                 # killed before finalising: plan, no summary
        shutil.copytree(smoke_dir, target)
        (target / "summary.parquet").unlink()
    assert main(["gate", str(target)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_run_ends_with_the_gate_verdict_and_the_next_command(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    verdict, others = capsys.readouterr().out.strip().splitlines()[-2:]
    # smoke: 12 fault-free and 8 faulty runs, one detector; 16 checks: coverage, 14
    # false-alarm cells (6 fault-free manoeuvres, 8 fault × manoeuvre cells before onset)
    # and run errors
    assert verdict == (f"verdict: the gate passes (0 false alarms in 20 runs; all 16 checks); "
                       f"next: fdd-campaign gate {out} --junit gate.xml, or fdd-campaign report "
                       f"{out}")
    # the file's MD and DTP limits, one check of each per fault type (4 faults)
    assert others == (f"MD and DTP limits met (MD ≤ 0 %, DTP ≤ 1, 8 checks) (fdd-campaign "
                      f"gate {out} --all-requirements)")


def test_report_of_an_interrupted_campaign_says_so_in_the_terminal(smoke_dir, tmp_path,
                                                                   capsys):
    # the first line and the last (below the long tables) say it, with the command that
    # finishes it: the preset's name, since the directory holds the preset as shipped
    copy, planned = _interrupted(smoke_dir, tmp_path, 5)
    assert main(["report", str(copy), "--no-html"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    said = (f"report of an unfinished campaign: 5 of {planned} runs done (the tables and rates "
            f"cover those runs only); finish it with: fdd-campaign run smoke --out {copy}")
    assert said in lines[0] and said in lines[-1]
    assert main(["report", str(smoke_dir), "--no-html"]) == 0
    assert "unfinished" not in capsys.readouterr().out


def test_the_command_that_finishes_a_campaign_keeps_its_seed_or_names_its_file(tmp_path,
                                                                                capsys):
    from types import SimpleNamespace

    from campaign.cli.result_commands import _resume_command
    from campaign.config import with_overrides

    seeded = SimpleNamespace(name="smoke", config=with_overrides(load_config("smoke"), seed=3))
    assert _resume_command(seeded, "D") == "fdd-campaign run smoke --seed 3 --out D"
    edited = SimpleNamespace(name="smoke", config=with_overrides(
        load_config("smoke"), values={"campaign.duration_s": 40.0}))
    assert _resume_command(edited, "D").startswith("fdd-campaign run CAMPAIGN.toml --out D")
