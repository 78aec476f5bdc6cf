"""A library function names its bad arguments as Python names them; the command line
names its options (scenarios.errors.ArgumentError), exit 2 either way."""

from __future__ import annotations

import pickle

import pytest

from campaign.cli.commands import main
from campaign.config import load_config
from campaign.runner import CampaignSetupError, RunOptionError, check_run_options
from campaign.tools.bench import bench
from scenarios.errors import ArgumentError


def test_run_options_are_named_as_python_arguments():
    config = load_config("smoke")
    with pytest.raises(RunOptionError) as caught:
        check_run_options(config, jobs=1, chunk_size=0)
    message = str(caught.value)
    assert message.startswith("chunk_size=0: out of range") and "--" not in message
    assert "fix: e.g. chunk_size=100" in message
    # still the setup error a caller of campaign.run catches
    assert isinstance(caught.value, CampaignSetupError)
    assert caught.value.for_command_line().startswith("--chunk-size 0: out of range")
    with pytest.raises(RunOptionError, match=r"^jobs=0: must be an integer ≥ 1"):
        check_run_options(config, jobs=0, chunk_size=None)


def test_bench_names_every_bad_argument_and_the_command_line_its_options(capsys):
    with pytest.raises(ArgumentError) as caught:
        bench(n_runs=0, duration_s=0.5, jobs=1)
    assert [p[0] for p in caught.value.problems] == ["n_runs", "duration_s"]
    assert str(caught.value).startswith("n_runs=0: must be an integer ≥ 1")
    assert main(["bench", "--runs", "0", "--duration", "0.5"]) == 2
    err = capsys.readouterr().err
    assert "--runs 0: must be an integer ≥ 1" in err and "--duration 0.5: a run lasts" in err
    assert "n_runs" not in err and "duration_s" not in err


def test_other_arguments_in_the_text_follow_the_caller():
    exc = ArgumentError.of("yardstick_dir", None, "without {yardstick}", None,
                           "name {yardstick} too")
    assert str(exc) == "yardstick_dir without yardstick; fix: name yardstick too"
    assert exc.for_command_line() == ("--yardstick-dir without --yardstick; fix: name "
                                      "--yardstick too")
    value = ArgumentError.of("duration_s", 5.0, "too short", 60.0)
    assert str(value) == "duration_s=5.0: too short; fix: e.g. duration_s=60.0"
    assert value.for_command_line({"duration_s": "--duration"}) == (
        "--duration 5: too short; fix: e.g. --duration 60")
    # crosses process boundaries (loky workers) whole
    again = pickle.loads(pickle.dumps(exc))
    assert type(again) is ArgumentError and str(again) == str(exc)


def test_falsify_and_certify_name_their_python_arguments_and_the_cli_its_options(
        capsys, tmp_path):
    from campaign.evidence.certify import CertifyError, certify
    from campaign.evidence.falsify import FalsifyError, check_label
    from campaign.evidence.worst_case import WorstCaseError, check_budget

    with pytest.raises(FalsifyError) as caught:
        check_label(load_config("smoke"), "nope")
    assert str(caught.value).startswith("label='nope': not a detector of campaign 'smoke'")
    assert "--" not in str(caught.value)
    assert main(["falsify", "smoke", "--detector", "nope", "--budget", "40",
                 "--out", str(tmp_path / "out")]) == 2
    assert "--detector nope: not a detector of campaign 'smoke'" in capsys.readouterr().err
    # every bad option of certify at once, before the directory is read
    with pytest.raises(CertifyError) as caught:
        certify(tmp_path / "none", level=1.5, max_levels=0, levels="0.6,x")
    assert str(caught.value) == (
        "level=1.5: must be a confidence in (0.5, 1); fix: e.g. level=0.95; "
        "max_levels=0: levels of the subset simulation after the first, in [1, 30] "
        "(p0 = 0.1: 12 reach 1e-12); fix: e.g. max_levels=12; "
        "levels: 'x' is not a number; give margins separated by commas, e.g. levels "
        "0.6,0.7,0.8,0.9,1.0")
    # a value with braces is written as given, the argument names still filled in
    with pytest.raises(WorstCaseError) as caught:
        check_budget("{x}")
    assert caught.value.for_command_line({"budget": "--worst-case"}).startswith(
        "--worst-case '{x}': not a whole number of runs")
    assert str(caught.value).endswith("e.g. budget 300")


def test_fitted_from_is_named_as_the_argument_of_run(tmp_path, capsys):
    import campaign

    with pytest.raises(RunOptionError) as caught:
        campaign.run(load_config("smoke"), tmp_path / "out", fitted_from=tmp_path)
    assert str(caught.value).startswith(f"fitted_from={str(tmp_path)!r}: not a campaign "
                                        "directory (no campaign.json); give the out directory")
    assert main(["run", "smoke", "--fitted-from", str(tmp_path), "--out",
                 str(tmp_path / "out2"), "--quiet"]) == 2
    assert (f"--fitted-from {tmp_path}: not a campaign directory (no campaign.json); give "
            "the --out directory") in capsys.readouterr().err


def test_scales_tls_and_build_options_are_named_as_python_arguments():
    from campaign.execute import ClusterError, TlsFiles, connect, time_limit_refusal
    from campaign.tradeoff import TradeoffError, parse_scale_options, parse_scales
    from scenarios.fmu_build import FmuOptionError, build_servo_fmu

    with pytest.raises(TradeoffError) as caught:
        parse_scales("0.8,x")
    assert str(caught.value).startswith("scales: 'x' is not a number")
    with pytest.raises(TradeoffError) as caught:
        parse_scale_options(["pm=1.1"])
    # the gate's option (gate --threshold-scale D=S gives at_threshold_scales its scales)
    assert caught.value.for_command_line({"scales": "--threshold-scale"}).startswith(
        "--threshold-scale pm=1.1: 1.1 is not a stored threshold scale")
    assert "run the campaign with [[detector]] threshold_scale = s and fitted_from this " \
           "directory" in str(caught.value)
    with pytest.raises(ClusterError) as caught:
        connect("tcp://127.0.0.1:1", tls=TlsFiles(cert="c.pem"))
    assert str(caught.value).startswith("tls_cert apply to a tls:// scheduler")
    assert caught.value.for_command_line().startswith("--tls-cert apply to a tls:// scheduler")
    text, values = time_limit_refusal(2.0, backend=None, scheduler="tcp://h:{1}")
    refusal = RunOptionError.said(text, **values)
    assert str(refusal).startswith("[runner] run_timeout_s = 2 s cannot be enforced with "
                                   "scheduler tcp://h:{1}: a task running")
    assert "leave out --scheduler" in refusal.for_command_line()
    with pytest.raises(FmuOptionError, match=r"^out='servo\.zip': an FMU file name must end "
                                             r"in \.fmu; fix: e\.g\. out='servo\.fmu'$"):
        build_servo_fmu("servo.zip")
