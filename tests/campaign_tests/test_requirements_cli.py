"""A campaign file's requirements from the command line: every problem found before anything
is simulated, the file ``fdd-campaign init`` writes runs as written, ``run`` ends with the gate
and what else the requirements say, and a finished campaign is gated and reported against
corrected requirements (``--requirements FILE``) without being run again."""

import re

import pytest

from campaign.cli.commands import main
from campaign.config import load_config
from campaign.config.load import shipped_dir

SMOKE = shipped_dir("presets").joinpath("smoke.toml").read_text()


def _campaign(tmp_path, requirements: str, name: str = "c.toml"):
    """The smoke preset with a [requirements] table, as a file."""
    path = tmp_path / name
    path.write_text(SMOKE + "\n[requirements]\n" + requirements + "\n")
    return path


@pytest.fixture(scope="module")
def unevaluable(tmp_path_factory):
    """A campaign run whose file names a variant its detector does not have (only the
    results can tell): the run keeps its results and says how to gate them."""
    tmp = tmp_path_factory.mktemp("req")
    path = _campaign(tmp, 'detector_max_fa_rate = { "position-monitor[strict]" = 0.1 }')
    out = tmp / "out"
    code = main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"])
    return code, out


def test_init_writes_a_file_that_runs_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["init", "my-campaign.toml"]) == 0
    hint = capsys.readouterr().out
    # the hint names an output directory of its own, not the README's results/
    assert "--out my-campaign/" in hint and "results/" not in hint
    config = load_config("my-campaign.toml")
    # the example of detector_max_fa_rate (a detector the file has not) is commented out
    assert config.requirements.detector_max_fa_rate == ()
    assert re.search(r"^# e\.g\. detector_max_fa_rate = ", (tmp_path / "my-campaign.toml")
                     .read_text(), re.M)
    assert main(["run", "my-campaign.toml", "--out", "my-campaign/", "--quiet",
                 "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "my-campaign" / "summary.parquet").exists()
    assert "verdict: the gate passes" in out


@pytest.mark.parametrize("command", ["plan", "run"])
def test_a_requirement_naming_no_detector_is_refused_before_anything_runs(tmp_path, capsys,
                                                                          command):
    path = _campaign(tmp_path, 'detector_max_fa_rate = { "chen-local[solid]" = 0.3, '
                     '"position-monitr" = 0.1 }')
    out = tmp_path / "out"
    options = ["--quiet", "--jobs", "1"] if command == "run" else []
    assert main([command, str(path), "--out", str(out), *options]) == 2
    err = capsys.readouterr().err
    # both wrong names, each with the key, the detectors that exist and a suggestion
    assert ('requirements.detector_max_fa_rate."chen-local[solid]": names no detector of this '
            "campaign; its detectors ([[detector]] labels): position-monitor") in err
    assert ("requirements.detector_max_fa_rate.position-monitr: names no detector of this "
            "campaign (did you mean 'position-monitor'?)") in err
    # nothing was planned or simulated: the output directory was not even made
    assert not out.exists()


def test_run_ends_with_the_gate_then_what_else_the_requirements_say(tmp_path, capsys):
    path = _campaign(tmp_path, "max_dtp = 0.1")
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    verdict, others = capsys.readouterr().out.strip().splitlines()[-2:]
    assert verdict.startswith("verdict: the gate passes (0 false alarms in 20 runs; ")
    head = "MD and DTP limits (MD ≤ 0 %, DTP ≤ 0.1) not met: "
    assert others.startswith(head)
    assert others.endswith(f" (fdd-campaign gate {out} --all-requirements)")
    # the line names the same failures as the command it points to
    assert main(["gate", str(out), "--all-requirements"]) == 1
    failed = re.findall(r"^  FAIL detection time: ([\w-]+), (\w+): max DTP ([\d.]+) > 0\.1",
                        capsys.readouterr().out, re.M)
    assert failed, "smoke's runaways and jams take longer than 0.1 of their required time"
    named = re.findall(r"([\w-]+) ([\w ]+?) DTP ([\d.]+) > 0\.1", others.removeprefix(head))
    assert [(d, f.replace(" ", "_"), v) for d, f, v in named] == failed[:4]


@pytest.mark.parametrize("requirements", ["max_dtp = 0.1", "max_fa_rate = 0.0\nmax_md_rate = 1.0",
                                          'detector_max_fa_rate = { "position-monitor" = 0.5 }'])
def test_the_verdict_lines_from_one_gate_evaluation_are_those_of_two(tmp_path, requirements):
    """``run`` evaluates the gate of all the requirements once and reads the gate's own
    verdict from its checks other than MD and DTP: the same checks, in the same order, and
    the same two lines as two evaluations (MD and DTP limits met and not met)."""
    import campaign
    from reports.scoring.gate import GateResult

    from campaign.cli.requirements import (MD_DTP_CHECKS, gate_of, other_requirements,
                                           verdict)

    path = _campaign(tmp_path, requirements)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    config, result = load_config(path), campaign.load(out)
    full = gate_of(config, result, all_requirements=True)
    own = gate_of(config, result)
    assert full.checks != own.checks          # the MD and DTP checks are there
    part = GateResult([c for c in full.checks if c.name not in MD_DTP_CHECKS])
    assert part.checks == own.checks
    assert verdict(config, result, full=full) == verdict(config, result)
    assert other_requirements(config, result, full=full) == other_requirements(config, result)


def test_a_resume_that_computes_nothing_says_so(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    capsys.readouterr()
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("campaign "))
    assert line == (f"campaign 'smoke': nothing to compute, all 20 runs of the plan were "
                    f"already done -> {out}")


def test_an_unknown_variant_keeps_the_results_and_says_how_to_gate_them(unevaluable, capsys):
    code, out = unevaluable
    assert code == 2                      # the file's requirements are wrong: bad input
    assert (out / "summary.parquet").exists()
    assert main(["gate", str(out)]) == 2
    err = capsys.readouterr().err
    assert "'position-monitor[strict]', which is no detector of these results" in err
    assert "--requirements FILE" in err


def test_gate_and_report_take_corrected_requirements_without_running_again(unevaluable,
                                                                         tmp_path, capsys):
    _, out = unevaluable
    shards = sorted(p.stat().st_mtime_ns for p in (out / "runs").glob("*.parquet"))
    fixed = _campaign(tmp_path, "max_dtp = 0.1", "fixed.toml")
    # the false-alarm gate passes with the corrected file ...
    assert main(["gate", str(out), "--requirements", str(fixed)]) == 0
    text = capsys.readouterr().out
    # what changed is said first, then the gate
    assert text.startswith(f"requirements: those of {fixed} in place of the campaign's; "
                           "detector_max_fa_rate = {} (was {'position-monitor[strict]': 0.1}), "
                           "max_dtp = 0.1 (was 1.0)\n")
    assert "gate PASSED" in text
    # ... and its new DTP limit holds with --all-requirements, naming runs to replay
    assert main(["gate", str(out), "--requirements", str(fixed), "--all-requirements"]) == 1
    text = capsys.readouterr().out
    assert "FAIL detection time: position-monitor" in text and "> 0.1" in text
    assert f"replay one: fdd-campaign show {out} " in text
    # a file holding only the table works too; limits it leaves out take their defaults
    # (max_dtp 1: smoke's slowest detection has DTP 0.695)
    only = tmp_path / "only.toml"
    only.write_text("[requirements]\nmax_md_rate = 0.5\n")
    assert main(["gate", str(out), "--requirements", str(only), "--all-requirements"]) == 0
    assert main(["report", str(out), "--no-html", "--requirements", str(fixed)]) == 0
    # nothing was computed again
    assert sorted(p.stat().st_mtime_ns for p in (out / "runs").glob("*.parquet")) == shards


@pytest.mark.slow
def test_report_page_follows_the_corrected_requirements(unevaluable, tmp_path):
    _, out = unevaluable
    strict = _campaign(tmp_path, "max_dtp = 0.1", "strict.toml")
    html = tmp_path / "r.html"
    assert main(["report", str(out), "--html", str(html), "--jobs", "1",
                 "--requirements", str(strict)]) == 0
    page = html.read_text()
    # the campaign ran with max_dtp = 1 and its slowest detection has DTP 0.695: a failed
    # detection-time check on the page can only come from the corrected limit
    assert re.search(r"FAIL detection time: position-monitor, \w+: max DTP [\d.]+ &gt; 0\.1",
                     page)


@pytest.mark.parametrize("table, needle", [
    ("detection_time_s = { runaway = 0.1 }",
     "requirements.detection_time_s: runaway = 0.1 (the campaign's: 0.5); it decides how each "
     "run was scored"),
    ('detector_max_fa_rate = { "position-monitr" = 0.1 }',
     "requirements.detector_max_fa_rate.position-monitr: names no detector of this campaign "
     "(did you mean 'position-monitor'?)"),
    ("max_fa_rate = 2.0", "requirements.max_fa_rate: "),
])
def test_corrected_requirements_are_checked_before_they_are_used(unevaluable, tmp_path,
                                                                 capsys, table, needle):
    _, out = unevaluable
    path = tmp_path / "r.toml"
    path.write_text("[requirements]\n" + table + "\n")
    assert main(["gate", str(out), "--requirements", str(path)]) == 2
    assert needle in capsys.readouterr().err


def test_a_requirements_file_without_the_table_is_refused(unevaluable, tmp_path, capsys):
    _, out = unevaluable
    path = tmp_path / "r.toml"
    path.write_text("[requirement]\nmax_dtp = 0.5\n")          # not the table's name
    assert main(["gate", str(out), "--requirements", str(path)]) == 2
    assert "no [requirements] table" in capsys.readouterr().err
    # a campaign file that leaves the table out takes every default
    path.write_text(SMOKE)
    assert main(["gate", str(out), "--requirements", str(path)]) == 0
    assert "detector_max_fa_rate = {} (was {'position-monitor[strict]': 0.1})" in \
        capsys.readouterr().out
    assert main(["gate", str(out), "--requirements", str(tmp_path / "nope.toml")]) == 2
    assert "file not found" in capsys.readouterr().err


def test_a_resume_with_other_limits_only_points_to_requirements(tmp_path, capsys):
    path = _campaign(tmp_path, "max_dtp = 1.0")
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    capsys.readouterr()
    path.write_text(path.read_text().replace("max_dtp = 1.0", "max_dtp = 0.5"))
    assert main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert ("holds this campaign already run with other [requirements] limits (max_dtp); "
            "limits do not change any result") in err
    assert f"fdd-campaign gate {out} --requirements {path}" in err


@pytest.mark.parametrize("command", ["gate", "report"])
def test_requirements_of_one_campaign_are_refused_on_a_suite(tmp_path, capsys, command):
    """A suite's campaigns have detectors of their own: --requirements names one campaign's,
    so a suite directory is refused before anything is read, naming the directory to give."""
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "suite.json").write_text("{}")         # what makes a directory a suite's
    path = _campaign(tmp_path, "max_dtp = 0.5")
    assert main([command, str(suite), "--requirements", str(path)]) == 2
    assert (f"--requirements: {suite} is a suite; its campaigns have their own detectors: "
            f"give the directory of one of its campaigns ({suite}/NAME)") in \
        capsys.readouterr().err


def test_a_directory_run_with_a_requirement_naming_no_detector_is_corrected_in_place(
        tmp_path, capsys):
    """A directory whose campaign names a detector it does not have in [requirements] (as
    an earlier version let a run finish): read back, replayed, gated and reported against the
    corrected file; a resume with that file points to --requirements."""
    import tomllib

    import pandas as pd

    import campaign
    from campaign.config import CampaignConfig

    bad = _campaign(tmp_path, 'detector_max_fa_rate = { "chen-local[solid]" = 0.3 }')
    out = tmp_path / "old"
    # the Python API with a configuration validated as a stored one (names not checked)
    config = CampaignConfig.from_dict(tomllib.loads(bad.read_text()), source=str(bad))
    assert campaign.run(config, out, jobs=1, progress=False).complete
    fixed = _campaign(tmp_path, "", "fixed.toml")
    assert main(["gate", str(out)]) == 2
    capsys.readouterr()
    assert main(["gate", str(out), "--requirements", str(fixed)]) == 0
    assert main(["report", str(out), "--no-html", "--requirements", str(fixed)]) == 0
    run_id = str(pd.read_parquet(out / "plan.parquet")["run_id"].iloc[0])
    assert main(["show", str(out), run_id]) == 0
    capsys.readouterr()
    assert main(["run", str(fixed), "--out", str(out), "--quiet", "--jobs", "1"]) == 2
    assert (f"limits (detector_max_fa_rate); limits do not change any result, so nothing needs "
            f"to run again: fdd-campaign gate {out} --requirements {fixed}") in \
        capsys.readouterr().err
