"""The command line on what newcomers and plugin authors run into: a detector that raises
on some runs (report, show, compare and gate show those runs and never crash), runner
options out of the schema's range, output paths that cannot be written, --version, help
on every argument, compare naming the keys that differ."""

from __future__ import annotations

import argparse
import json
import os

import pytest

from campaign import run
from campaign.cli.commands import build_parser, main
from campaign.config import CampaignConfig
from campaign.plan import build_plan
from detectors import registry


def _config(marker, *, seed=5) -> dict:
    return {
        "campaign": {"name": "flaky", "seed": seed, "duration_s": 20.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 3},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": [{"name": "position-monitor", "label": "pm"},
                     {"name": "misbehaving", "label": "flaky",
                      "params": {"marker": str(marker), "mode": "raise"}}],
        "learning": {"runs_per_manoeuvre": 2, "manoeuvres": ["cruise", "nose_up"]},
        "runner": {"chunk_size": 4},
    }


@pytest.fixture
def flaky_campaign(tmp_path, monkeypatch):
    """A finished campaign whose detector 'flaky' raised on runs 0 and 5 of its plan."""
    monkeypatch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")
    marker = tmp_path / "marker.json"
    cfg = _config(marker)
    plan = build_plan(CampaignConfig.from_dict(cfg))
    bad = [str(plan["run_id"].iloc[0]), str(plan["run_id"].iloc[5])]
    marker.write_text(json.dumps(bad))
    out = tmp_path / "out"
    run(CampaignConfig.from_dict(cfg), out, jobs=1, progress=False, log=lambda m: None)
    return out, bad, marker


def test_commands_survive_a_flaky_detector(flaky_campaign, tmp_path, capsys):
    out, bad, _ = flaky_campaign
    assert main(["report", str(out), "--jobs", "1"]) == 0
    printed = capsys.readouterr().out
    assert "flaky: 2 run(s) did not finish (2 error)" in printed
    assert "RuntimeError: injected failure" in printed
    page = (out / "report.html").read_text()
    assert "2 run(s) did not finish" in page and "injected failure" in page
    # the gate fails on them, naming the count and the first message
    assert main(["gate", str(out), "--junit", str(tmp_path / "g.xml")]) == 1
    printed = capsys.readouterr().out
    assert "FAIL run errors: flaky: 2 run(s) did not finish" in printed
    assert f"first: run {bad[0]}: detector failed: RuntimeError" in printed
    assert "injected failure" in (tmp_path / "g.xml").read_text()
    # show a run it failed on: the stored error and the re-simulated failure
    assert main(["show", str(out), bad[0], "--plot", str(tmp_path / "r.png")]) == 0
    printed = capsys.readouterr().out
    assert "flaky: stored status error: detector failed: RuntimeError" in printed
    assert "re-simulated: detector failed: RuntimeError" in printed
    assert (tmp_path / "r.png").exists()
    assert main(["compare", str(out), str(out)]) == 0
    printed = capsys.readouterr().out
    assert "A: flaky: 2 run(s) did not finish" in printed
    assert "B: flaky: 2 run(s) did not finish" in printed


def test_report_when_a_detector_fails_on_every_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")
    marker = tmp_path / "marker.json"
    cfg = _config(marker)
    plan = build_plan(CampaignConfig.from_dict(cfg))
    marker.write_text(json.dumps(list(plan["run_id"].astype(str))))
    out = tmp_path / "out"
    run(CampaignConfig.from_dict(cfg), out, jobs=1, progress=False, log=lambda m: None)
    assert main(["report", str(out), "--jobs", "1"]) == 0
    assert main(["gate", str(out)]) == 1
    printed = capsys.readouterr().out
    assert f"flaky: {len(plan)} run(s) did not finish" in printed
    assert (out / "report.html").exists()


# ---- runner options --------------------------------------------------------------------------
@pytest.mark.parametrize("size", ["-5", "0", "20000"])
def test_chunk_size_out_of_range(tmp_path, capsys, size):
    out = tmp_path / "out"
    assert main(["run", "smoke", "--chunk-size", size, "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--chunk-size {size}: out of range" in err and "1 ≤ chunk size ≤ 10000" in err
    assert not out.exists()


def test_jobs_below_one(tmp_path, capsys):
    assert main(["run", "smoke", "--jobs", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--jobs 0: must be ≥ 1" in capsys.readouterr().err


def test_run_api_checks_chunk_size(tmp_path):
    from campaign.config import load_config
    from campaign.runner import CampaignSetupError

    with pytest.raises(CampaignSetupError, match="out of range"):
        run(load_config("smoke"), tmp_path / "o", chunk_size=0, progress=False)


# ---- unwritable paths ------------------------------------------------------------------------
def test_output_below_a_file(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    for argv in (["run", "smoke", "--out", "afile/x"],
                 ["simulate", "--out", "afile/a.parquet"],
                 ["simulate", "--plot", "afile/a.png"],
                 ["init", "afile/c.toml"],
                 ["run", "smoke", "--out", "afile"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "afile" in err and "fix:" in err and "Traceback" not in err, argv
        # what is wrong is the file, not a permission: no hint about writable locations
        assert "writable" not in err and "permission" not in err, argv
        assert ("is a file, not a directory; fix: pass a directory" in err
                if argv[-1] == "afile" else "is a file, not a folder" in err), argv


def test_a_file_option_into_a_missing_folder_creates_the_folder(flaky_campaign, tmp_path,
                                                                capsys, monkeypatch):
    # every file option (--junit, --html, --plot, --out of a file, init's file) writes into
    # folders that do not exist yet, as mkdir -p: no error about a temporary file's name
    out, bad, _ = flaky_campaign
    monkeypatch.chdir(tmp_path)
    for path, argv in (
            ("m1/d/gate.xml", ["gate", str(out), "--allow-errors", "--junit", "m1/d/gate.xml"]),
            ("m2/d/r.html", ["report", str(out), "--envelope-runs", "1", "--jobs", "1",
                             "--html", "m2/d/r.html"]),
            ("m3/d/r.png", ["show", str(out), bad[0], "--plot", "m3/d/r.png"]),
            ("m4/d/a.parquet", ["simulate", "--duration", "20", "--out", "m4/d/a.parquet"]),
            ("m5/d/c.toml", ["init", "m5/d/c.toml"])):
        assert main(argv) == 0, argv
        assert ".tmp" not in capsys.readouterr().err, argv
        assert (tmp_path / path).is_file(), argv


def _read_only_dir(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.access(ro, os.W_OK):
        ro.chmod(0o755)
        pytest.skip("chmod has no effect here (running as root): a read-only directory "
                    "cannot be made; the path checks are covered by test_output_below_a_file")
    return ro


def test_unwritable_paths(tmp_path, capsys, flaky_campaign):
    out, bad, _ = flaky_campaign
    ro = _read_only_dir(tmp_path)
    try:
        for option, argv in (
                ("--out", ["run", "smoke", "--out", str(ro / "x")]),
                ("--out", ["simulate", "--out", str(ro / "a.parquet")]),
                ("--plot", ["simulate", "--plot", str(ro / "a.png")]),
                ("--junit", ["gate", str(out), "--junit", str(ro / "g.xml")]),
                ("--html", ["report", str(out), "--html", str(ro / "r.html")]),
                ("--plot", ["show", str(out), bad[0], "--plot", str(ro / "r.png")]),
                ("--out", ["show", str(out), bad[0], "--out", str(ro / "r.parquet")])):
            assert main(argv) == 2, argv
            err = capsys.readouterr().err
            assert f"{option} {ro}" in err and "not writable" in err and "fix:" in err, argv
    finally:
        ro.chmod(0o755)


# ---- small ones ------------------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.startswith("fdd-campaign ")


def test_every_argument_has_help():
    missing = []

    def walk(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, [*path, name])
            elif not action.help and not isinstance(action, argparse._HelpAction):
                missing.append(f"{' '.join(path)} {action.dest}")

    walk(build_parser(), ["fdd-campaign"])
    assert missing == []


def test_compare_names_the_differing_keys(tmp_path, capsys):
    from campaign.config import load_config, with_overrides

    a, b = tmp_path / "a", tmp_path / "b"
    run(load_config("smoke"), a, jobs=1, progress=False, log=lambda m: None)
    run(with_overrides(load_config("smoke"), seed=3), b, jobs=1, progress=False,
        log=lambda m: None)
    assert main(["compare", str(a), str(b)]) == 0
    assert "the campaign files differ in: campaign.seed: 0 → 3" in capsys.readouterr().out


def test_preset_refused_on_a_plant_it_is_not_valid_on(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", "addsafe-mc", "--plant", "aircraft", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "preset 'addsafe-mc' is valid on the actuator plant only" in err
    assert "eq. 17" in err and "kappa = [0.01, 0.002, 0.012]" in err
    assert not out.exists()


def test_unwritable_folder_message(tmp_path, capsys, monkeypatch):
    """The message for a folder the user may not write in (os.access stubbed, so that it
    is checked also where the tests run as root)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(ro)
                        else real(p, mode))
    assert main(["simulate", "--out", str(ro / "a.parquet")]) == 2
    err = capsys.readouterr().err
    assert f"--out {ro / 'a.parquet'}: cannot create it, the folder {ro} is not writable" in err
    assert f"chmod u+w {ro}" in err
    assert main(["run", "smoke", "--out", str(ro)]) == 2
    assert f"--out {ro}: not writable (permission denied)" in capsys.readouterr().err


def test_a_failure_inside_a_library_is_an_internal_error(tmp_path, capsys, monkeypatch):
    """A ValueError raised inside pyarrow's Parquet writer is no mistake of the user: exit 3
    (not 2, bad input), the error named on one line and its traceback kept in the file the
    message names."""
    import tempfile

    import campaign.store.files as files

    def broken(*args, **kwargs):
        raise ValueError("planted failure in write_table")

    monkeypatch.setattr(files.pq.ParquetWriter, "write_table", broken)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))     # the traceback file lands here
    code = main(["run", "smoke", "--jobs", "1", "--quiet", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 3
    assert "internal error: ValueError: planted failure in write_table" in err
    assert "not of your input" in err and "please report it" in err
    kept = list(tmp_path.glob("fdd-campaign-error-*.txt"))
    assert len(kept) == 1 and str(kept[0]) in err
    text = kept[0].read_text()
    assert text.startswith(f"fdd-campaign run smoke --jobs 1 --quiet --out {tmp_path / 'out'}\n")
    # the whole traceback: from the command down to the planted call
    assert "Traceback (most recent call last)" in text and "in broken" in text
    assert "ValueError: planted failure in write_table" in text


def test_an_input_error_from_deep_inside_stays_bad_input(tmp_path, capsys):
    """The user's mistakes that are found below the command line (a significance level
    checked by the comparison, a suite directory whose members are missing) keep exit 2
    with their message, and no traceback file."""
    out = tmp_path / "a"
    assert main(["plan", "smoke", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["compare", str(out), str(out), "--alpha", "2"]) == 2
    assert "--alpha 2.0: a significance level in (0, 1)" in capsys.readouterr().err
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "suite.json").write_text("{not json")
    assert main(["report", str(suite), "--no-html"]) == 2
    err = capsys.readouterr().err
    assert "suite.json is damaged" in err and "internal error" not in err


INPUT_ERRORS = [   # (module, class, the builtin its callers catch)
    ("campaign.cli.common", "UsageError", ValueError),
    ("campaign.config", "ConfigError", ValueError),
    ("campaign.store.directory", "CampaignDirError", ValueError),
    ("campaign.store.directory", "ManifestError", ValueError),
    ("campaign.store.lock", "CampaignLockedError", ValueError),
    ("campaign.runner", "CampaignSetupError", ValueError),
    ("campaign.execute", "ClusterError", ValueError),
    ("campaign.evidence.certify", "CertifyError", ValueError),
    ("campaign.evidence.falsify", "FalsifyError", ValueError),
    ("detectors.registry", "DetectorSpecError", ValueError),
    ("detectors.state", "StateTypeError", TypeError),
    ("detectors.state", "StateFormatError", ValueError),
    ("detectors.synthesis.geometric", "GeometricDesignError", ValueError),
    ("detectors.synthesis.lpv_synthesis", "LMIInfeasibleError", ValueError),
    ("detectors.synthesis.vanek_hinf", "HinfUnavailableError", ImportError),
    ("scenarios.runs", "RunSpecError", ValueError),
    ("scenarios.fmu_files", "FmuError", ValueError),
    ("scenarios.fmu", "FmuRunError", RuntimeError),
    ("scenarios.fmu_build", "FmuBuildError", RuntimeError),
    ("scenarios.fmu_build", "FmuOptionError", ValueError),
    ("reports.scoring.gate", "GateInputError", ValueError),
]


@pytest.mark.parametrize("module,name,builtin", INPUT_ERRORS,
                         ids=[name for _, name, _ in INPUT_ERRORS])
def test_the_input_errors_are_one_family_and_keep_their_builtin(module, name, builtin):
    # exit 2 is decided on the family (cli.main catches InputError), and a caller's
    # `except ValueError` (or the class's own builtin) must still catch the error
    import importlib

    from scenarios.errors import InputError

    cls = getattr(importlib.import_module(module), name)
    assert issubclass(cls, InputError) and issubclass(cls, builtin)


@pytest.mark.parametrize("module,name", [
    ("detectors.base", "NotFittedError"),            # the engine's misuse of a detector: a bug
    ("campaign.evaluate", "DetectorContractError"),  # a plugin's breach: recorded per run
    ("campaign.execute", "TimeLimitExceeded"),        # a plugin over its limit: recorded per run
    ("detectors.testing", "DetectorCheckError"),     # a failed conformance test (pytest's)
])
def test_what_is_not_the_users_input_stays_out_of_the_family(module, name):
    import importlib

    from scenarios.errors import InputError

    assert not issubclass(getattr(importlib.import_module(module), name), InputError)


# ---- simulate: the fault options follow the campaign file's rules -------------------------
def _group_errors(fault: str, magnitude: float, extra: dict | None = None) -> list[str]:
    """The campaign file's problems with one [[group]] of *fault* at *magnitude*."""
    from campaign.config import ConfigError

    cfg = _config("unused")
    cfg["detector"] = [{"name": "position-monitor"}]
    cfg["group"] = [{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 1},
                    {"name": "f", "fault": fault, "manoeuvres": ["cruise"], "count": 1,
                     "magnitude": magnitude, **(extra or {})}]
    try:
        CampaignConfig.from_dict(cfg)
    except ConfigError as exc:
        return exc.errors
    return []


@pytest.mark.parametrize("fault", ["runaway", "liquid_jam", "solid_jam", "ofc_liquid",
                                   "ofc_solid"])
def test_simulate_refuses_the_magnitudes_a_campaign_file_refuses(fault, capsys):
    # just above each fault's [faults.*] bound, zero and negative: refused by the file and by
    # simulate (exit 2, naming --magnitude and the allowed range), before any simulation
    from campaign.config.rules import magnitude_spec

    spec = magnitude_spec(fault)
    extra = {"variant": "offset"} if fault == "solid_jam" else {}
    cli_extra = ["--variant", "offset"] if fault == "solid_jam" else []
    for value in (spec.upper * 1.01, 0.0, -1.0):
        assert _group_errors(fault, value, extra), (fault, value)
        assert main(["simulate", "--fault", fault, "--magnitude", repr(value),
                     *cli_extra]) == 2, (fault, value)
        err = capsys.readouterr().err
        assert f"--magnitude {value:g}: out of range for {fault}" in err, err
        assert spec.range_text("magnitude") in err and "fix:" in err
    # the bound itself is accepted by both
    assert _group_errors(fault, spec.upper, extra) == []
    from campaign.config.rules import single_fault_problems
    from campaign.cli.tool_commands import _SIMULATE_NAMES

    assert single_fault_problems(fault, magnitude=spec.upper, variant=extra.get("variant"),
                                 sign=None, onset_s=10.0, duration_s=30.0,
                                 names=_SIMULATE_NAMES) == []


@pytest.mark.parametrize("argv, needle", [
    (["--fault", "disconnection", "--magnitude", "3"],
     "--magnitude 3: fault 'disconnection' has no magnitude"),
    (["--fault", "solid_jam", "--magnitude", "3"],
     "--magnitude 3: fault 'solid_jam' has no magnitude with --variant seized (the default); "
     "fix: leave it out, or add --variant offset"),
    (["--fault", "liquid_jam", "--variant", "offset"],
     "--variant offset: fault 'liquid_jam' has no variants"),
    (["--fault", "ofc_solid", "--sign", "negative"],
     "--sign negative: fault 'ofc_solid' has no direction"),
    (["--fault", "runaway", "--magnitude", "-3"], "fix: --magnitude 3 --sign negative"),
    (["--fault", "runaway", "--onset", "40"],
     "--onset 40: the fault's onset must fall within the run; allowed: 0 ≤ --onset < "
     "--duration = 30 s"),
    (["--fault", "runaway", "--onset", "-1", "--duration", "20"],
     "allowed: 0 ≤ --onset < --duration = 20 s"),
])
def test_simulate_names_the_option_that_is_wrong(argv, needle, tmp_path, capsys):
    out = tmp_path / "run.parquet"
    assert main(["simulate", *argv, "--out", str(out)]) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists()


def test_simulate_reads_a_magnitude_in_the_campaign_files_unit(tmp_path, capsys):
    # a liquid jam's --magnitude is % of the deflection range, as a [[group]] magnitude: the
    # run table holds its rod bias in mm (r·sin(p·Δδ)), in the direction of --sign
    import pyarrow.parquet as pq

    from scenarios.faults import liquid_jam_bias_mm
    from scenarios.params import ACTUATORS

    out = tmp_path / "run.parquet"
    assert main(["simulate", "--fault", "liquid_jam", "--magnitude", "2", "--sign",
                 "negative", "--duration", "20", "--out", str(out)]) == 0
    runs = json.loads(pq.read_schema(out).metadata[b"fdd_campaign"])
    # rel 1e-9: the metadata's JSON keeps 10 decimals (pandas' to_json)
    assert runs[0]["magnitude"] == pytest.approx(-liquid_jam_bias_mm(ACTUATORS["elevator"], 2.0),
                                                 rel=1e-9)
    assert 1.5 < -runs[0]["magnitude"] < 2.5      # mm: not the 2 % taken as 2 mm
