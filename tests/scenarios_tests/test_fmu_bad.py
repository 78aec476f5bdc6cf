"""FMUs that cannot serve as a plant: every kind fmpy can tell apart is refused before any
work with an :class:`FmuError` naming the file and the fix, and a plant that diverges
during a run ends that run with a message naming the FMU, the output and the time."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import fmpy
import pandas as pd
import pytest

from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import load_config
from campaign.plan import build_plan
from campaign.evaluate import evaluate
from campaign.runner import build_detectors, settings_of
from scenarios.fmu import FmuError, FmuPlant, FmuRunError
from scenarios.plants import simulate
from scenarios.simulate import single_run

from conftest import edit_fmu

BIN2 = f"binaries/{fmpy.platform}/fdd_servo.so"
BIN3 = f"binaries/{fmpy.platform_tuple}/fdd_servo.so"
LFS_POINTER = ("version https://git-lfs.github.com/spec/v1\n"
               "oid sha256:4d7a214614ab2935c943f9e0ff69d22eadbb8f32b1258daaa5e2ca24d17e2393\n"
               "size 48213\n")


def _to_model_exchange(xml: bytes) -> bytes:
    text = xml.decode()
    text = re.sub(r"<CoSimulation\s", "<ModelExchange ", text)
    text = text.replace("</CoSimulation>", "</ModelExchange>")
    text = re.sub(r'\s(canHandleVariableCommunicationStepSize'
                  r'|canNotUseMemoryManagementFunctions)="true"', "", text)
    return text.encode()


def _to_scheduled_execution(xml: bytes) -> bytes:
    text = xml.decode()
    text = re.sub(r"<CoSimulation\s", "<ScheduledExecution ", text)
    text = re.sub(r'\s(canHandleVariableCommunicationStepSize|hasEventMode)="\w+"', "", text)
    return text.encode()


def _write(data: bytes):
    def make(fmu2: Path, fmu3: Path, dst: Path) -> Path:
        dst.write_bytes(data)
        return dst
    return make


def _edit(fmi: str, **edits):
    def make(fmu2: Path, fmu3: Path, dst: Path) -> Path:
        return edit_fmu(fmu2 if fmi == "2" else fmu3, dst, **edits)
    return make


def _fmi3_library_in_fmi2(fmu2: Path, fmu3: Path, dst: Path) -> Path:
    with zipfile.ZipFile(fmu3) as z:
        lib3 = z.read(BIN3)
    return edit_fmu(fmu2, dst, replace={BIN2: lib3})


#: kind of bad FMU → (how to make it from the built servo FMUs, what the message says)
CASES = {
    "empty file": (_write(b""), r"is an empty file \(0 bytes\), not an FMU"),
    "text file": (_write(b"fmu = servo\n# not a model\n"),
                  r"is a text file, not an FMU \(a zip archive\); it starts with 'fmu = servo'"),
    "Git LFS pointer": (_write(LFS_POINTER.encode()),
                        r"is a text file.*a Git LFS pointer: fetch the file itself with "
                        r"'git lfs pull'"),
    "garbage bytes": (_write(bytes(range(1, 256)) * 8), r"is not a zip archive, so not an FMU"),
    "truncated zip": (lambda f2, f3, dst: _write(f2.read_bytes()[: f2.stat().st_size // 2])(
        f2, f3, dst), r"is a truncated or damaged zip archive"),
    "zip without model description": (_edit("2", drop=("modelDescription.xml",)),
                                      r"a zip archive without modelDescription\.xml \(it "
                                      r"holds: .*\), so not an FMU"),
    "unreadable model description": (
        _edit("2", replace={"modelDescription.xml": b"<fmiModelDescription fmiVersion="}),
        r"its modelDescription\.xml cannot be read"),
    "FMI 1.0": (_edit("2", replace={"modelDescription.xml": lambda x: x.replace(
        b'fmiVersion="2.0"', b'fmiVersion="1.0"')}), r"FMI version 1\.0 is not supported"),
    "binary for another platform only": (
        _edit("2", drop=("sources/",), rename={BIN2: "binaries/win64/fdd_servo.dll"}),
        rf"no binary for this platform \({re.escape(BIN2)} is missing; it has: win64\); "
        rf"fix: export the FMU for {fmpy.platform}$"),
    "no binary, sources": (_edit("3", drop=("binaries/",)),
                           r"no binary for this platform .* it has: no binaries\); fix: .*"
                           r"'python -m fmpy compile .*bad\.fmu'"),
    "model exchange only": (_edit("2", replace={"modelDescription.xml": _to_model_exchange}),
                            r"not a co-simulation FMU \(model exchange only\); .* no ODE "
                            r"solver"),
    "scheduled execution only": (
        _edit("3", replace={"modelDescription.xml": _to_scheduled_execution}),
        r"not a co-simulation FMU \(scheduled execution only\); .* no clocks"),
    "garbage binary": (_edit("2", replace={BIN2: b"\x7fELF broken"}),
                       rf"its binary {re.escape(BIN2)} fails to load .*: it is not a shared "
                       r"library for this platform"),
    "binary of another FMI version": (_fmi3_library_in_fmi2,
                                      r"its binary .* does not export the FMI 2\.0 functions"),
    "wrong guid": (_edit("2", replace={"modelDescription.xml": lambda x: re.sub(
        rb'guid="[^"]+"', b'guid="{00000000-0000-0000-0000-000000000000}"', x)}),
        r"fails to instantiate: fmi2Instantiate returned no instance.*a guid in "
        r"modelDescription\.xml \(\{00000000-0000-0000-0000-000000000000\}\) that is not the "
        r"one its binary was built with"),
    "wrong instantiationToken": (_edit("3", replace={"modelDescription.xml": lambda x: re.sub(
        rb'instantiationToken="[^"]+"', b'instantiationToken="{0-0}"', x)}),
        r"fmi3InstantiateCoSimulation returned no instance.*an instantiationToken in "
        r"modelDescription\.xml \(\{0-0\}\)"),
}


@pytest.fixture
def bad_fmu(request, servo_fmu, servo_fmu3, tmp_path):
    """(path, expected message) of the bad FMU named by the test's parameter."""
    make, expected = CASES[request.param]
    return make(servo_fmu, servo_fmu3, tmp_path / "bad.fmu"), expected


@pytest.mark.parametrize("bad_fmu", list(CASES), indirect=True)
def test_bad_fmu_is_refused_before_any_work(bad_fmu, tmp_path):
    path, expected = bad_fmu
    cwd = Path.cwd()
    with pytest.raises(FmuError) as err:
        FmuPlant.of(path).check()
    msg = str(err.value)
    assert msg.startswith(f"FMU {path}") and "fix:" in msg
    assert re.search(expected, msg, re.S), msg
    assert Path.cwd() == cwd          # fmpy's library loading did not leave us elsewhere


@pytest.mark.parametrize("bad_fmu", list(CASES), indirect=True)
def test_run_cli_with_bad_fmu_exits_2_and_writes_nothing(bad_fmu, tmp_path, capsys):
    path, expected = bad_fmu
    out = tmp_path / "d"
    code = main(["run", "smoke", "--plant", str(path), "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 2
    assert re.search(expected, captured.err, re.S), captured.err
    assert str(path) in captured.err
    assert "Traceback" not in captured.err + captured.out
    assert not out.exists()


# ---------------------------------------------------------------------------------------
# a plant that diverges during a run
# ---------------------------------------------------------------------------------------
#: The servo FMU made unstable: the stops moved out of reach, no damping neighbour and an
#: absurd valve gain: the first period with a current sends the rod ~1e302 mm away, a
#: finite value whose COM acquisition (x·(1 + s) + b) / q would overflow.
DIVERGING = {"x_min": -1e308, "x_max": 1e308, "Ka": 0.0, "Kci": 1e307}


def test_diverging_fmu_ends_the_run_naming_the_output_and_time(servo_fmu):
    spec = FmuPlant.of(servo_fmu, {"surface": ""}, parameters=DIVERGING)
    spec.check()   # a trial step at rest passes: the divergence needs a current
    runs = single_run("elevator", "cruise", "none", seed=1, duration_s=20.0)
    with pytest.raises(FmuRunError) as err:
        simulate(runs, plant=spec)
    msg = str(err.value)
    assert re.search(r"servo\.fmu: output 'x_mm' \(rod\) is -?\d\.\d+e\+\d+ at t = 0\.0\d s "
                     r"\(beyond ±240 mm = 2 r: the plant diverged or failed\); the run is "
                     r"stopped", msg), msg
    assert "FMI call" not in msg and "Overflow" not in msg
    # a surface output that is not a number names the surface
    spec = FmuPlant.of(servo_fmu, parameters={**DIVERGING, "Kci": -50.0})
    with pytest.raises(FmuRunError, match=r"output 'delta_deg' \(surface\) is nan at "
                                          r"t = \d+\.\d\d s \(not a number"):
        simulate(runs, plant=spec)


def test_diverging_fmu_of_a_campaign_file_gives_error_rows(servo_fmu, tmp_path):
    # the overrides come from [plant] parameters; the runs of a chunk end as error rows
    # (the detectors are fitted on the built-in plant: on this FMU the learning set itself
    # would diverge, which stops the campaign with the same message)
    overrides = ", ".join(f"{k} = {v!r}" for k, v in DIVERGING.items())
    f = tmp_path / "c.toml"
    f.write_text(f'[campaign]\nname = "t"\nduration_s = 20.0\n[[group]]\nfault = "none"\n'
                 f'count = 2\n[[detector]]\nname = "position-monitor"\n'
                 f'[plant]\nfmu = "{servo_fmu}"\nparameters = {{ {overrides} }}\n'
                 f'[plant.variables]\nsurface = ""\n')
    config = load_config(f)
    settings = settings_of(resolve(config))
    assert dict(settings.plant.parameters) == DIVERGING
    detectors = build_detectors(config)
    learning = pd.concat([single_run("elevator", m, "none", seed=s, duration_s=20.0)
                          for s, m in enumerate(["cruise", "nose_up"])], ignore_index=True)
    sig, _ = simulate(learning)
    for d in detectors.values():
        d.fit(sig)
    plan = build_plan(config)
    res = evaluate(plan, detectors, settings)
    assert len(res) == len(plan) > 0 and (res["status"] == "error").all()
    assert res["error"].str.contains(r"servo\.fmu: output 'x_mm' \(rod\) is \S+ at "
                                     r"t = 0\.0\d s \(beyond ±240 mm").all()
