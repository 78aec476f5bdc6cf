"""The FMU plant back end: the servo-loop built as a C-source FMI 2.0 co-simulation FMU,
cross-checked against the built-in Python plant, and the clear failures of bad FMUs."""

from __future__ import annotations

import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pandas as pd
import pytest

from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import load_config, with_overrides
from campaign.evaluate import evaluate
from campaign.runner import ChunkSettings, run, settings_of
from scenarios.catalog import FAULTS
from scenarios.fmu import (_CACHE, FmuError, FmuRunError, FmuPlant, inspect_fmu, instance,
                           probe)
from scenarios.fmu_build import start_values
from scenarios.params import SENSORS
from scenarios.plants import simulate
from scenarios.simulate import integrate, prepare, single_run

from conftest import edit_fmu as _zip_with

#: Agreement required between the two back ends [mm, mA]. Both run the same equations in
#: the same order in IEEE double precision (the C code is compiled without FMA
#: contraction or fast-math), so they differ at most by the rounding of libm versus
#: numpy's transcendental functions, ~1e-15 relative; 1e-9 mm is 3·10⁷ times smaller than
#: the rod-sensor noise σ = 0.03 mm, so any modelling difference would show.
TOL_MM = 1e-9
#: Surface agreement [deg]: the FMU returns degrees, converted back to radians once more.
TOL_DEG = 1e-9


def _runs(surface: str, duration_s: float = 20.0) -> pd.DataFrame:
    """One run of every fault type at two flight points, with their own noise seeds."""
    rows = []
    points = [dict(alt_ft=8000.0, vcas_kt=300.0, mass_t=230.0, cg_pct=20.0, d_ch0=0.15, d_cha=0.15,
                   d_chd=0.15),
              dict(alt_ft=36000.0, vcas_kt=200.0, mass_t=130.0, cg_pct=40.0, d_kci=-0.04)]
    for i, fault in enumerate(FAULTS):
        for j, point in enumerate(points):
            rows.append(single_run(surface, "nose_up" if j else "cruise", fault, seed=7,
                                   onset_s=4.0, duration_s=duration_s, **point))
    runs = pd.concat(rows, ignore_index=True)
    runs["stream"] = np.arange(len(runs))
    runs["run_id"] = [f"{r}-{k}" for k, r in enumerate(runs["run_id"])]
    return runs


# ---------------------------------------------------------------------------------------
# the built FMU
# ---------------------------------------------------------------------------------------
def test_built_fmu_validates_and_carries_the_parameter_table(servo_fmu):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(servo_fmu)) == []
    md = read_model_description(str(servo_fmu))
    assert md.fmiVersion == "2.0" and md.coSimulation is not None
    assert md.modelExchange is None
    names = {v.name: v for v in md.modelVariables}
    # start values are the shared parameter table (scenarios.params), not copies
    for name, value in start_values("elevator").items():
        assert float(names[name].start) == value, name
    assert names["i_mA"].causality == "input" and names["x_mm"].causality == "output"
    with zipfile.ZipFile(servo_fmu) as z:
        members = set(z.namelist())
    assert {"modelDescription.xml", f"binaries/{fmpy.platform}/fdd_servo.so",
            "sources/servo_model.c",
            "sources/fmi2_servo.c"} <= members


def test_fmi3_build_validates(servo_fmu3):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(servo_fmu3)) == []
    md = read_model_description(str(servo_fmu3))
    assert md.fmiVersion == "3.0" and md.coSimulation is not None
    with zipfile.ZipFile(servo_fmu3) as z:
        assert f"binaries/{fmpy.platform_tuple}/fdd_servo.so" in z.namelist()


#: Communication steps of another tool driving the FMU [s] (multiples of its 0.01 s
#: sub-step h_max_s), and steps that are not multiples of it.
STEPS_S = (0.01, 0.1, 0.5, 2.0)
ODD_STEPS_S = (0.015, 0.025, 0.7)
#: Agreement required between communication steps [mm]. A step that is a multiple m of
#: h_max_s integrates the same m RK4 sub-steps of 0.01 s as m steps of 0.01 s: the results
#: agree to rounding (measured ≤ 1.1e-14 mm), hence TOL_MM. Other steps take shorter equal
#: sub-steps, a different discretisation: the RK4 error at 0.01 s is largest where the rod
#: stalls against the hinge-moment load, whose speed law has a square root (measured:
#: ≤ 3.0e-3 mm from a 1e-4 s reference, ≤ 2.5e-3 mm between steps); they must agree within
#: the rod acquisition's quantisation step (SENSORS.rod_quant_mm = 0.01 mm), below which
#: no detector sees a difference. Before the sub-steps the 0.5 s step ended 4.9 mm away.
TOL_ODD_STEP_MM = SENSORS.rod_quant_mm


def _drive(fmu: Path, h: float, current_mA: float, **start) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], rod [mm]) of *fmu* driven by fmpy alone at communication step *h* with the
    current held at *current_mA* for 10 s."""
    res = fmpy.simulate_fmu(str(fmu), stop_time=10.0, output_interval=h, output=["x_mm"],
                            start_values={"i_mA": current_mA, **start})
    return res["time"], res["x_mm"]


@pytest.mark.parametrize("fmi", ["2", "3"])
@pytest.mark.parametrize("current_mA", [10.0, 2.0, -10.0])
def test_built_fmu_converges_at_any_communication_step(request, fmi, current_mA):
    fmu = request.getfixturevalue("servo_fmu" if fmi == "2" else "servo_fmu3")
    from fmpy import read_model_description

    h_max = {v.name: v for v in read_model_description(str(fmu)).modelVariables}["h_max_s"]
    assert h_max.causality == "parameter" and float(h_max.start) == 0.01
    t_ref, x_ref = _drive(fmu, 0.01, current_mA)
    t_fine, x_fine = _drive(fmu, 0.01, current_mA, h_max_s=1e-4)
    assert np.array_equal(t_ref, t_fine) and t_ref[-1] == 10.0
    # the rod moved, and 0.01 s sub-steps are accurate: within a quantisation step of the
    # converged trajectory (sub-steps of 1e-4 s)
    assert np.ptp(x_ref) > 5.0
    assert np.abs(x_ref - x_fine).max() <= SENSORS.rod_quant_mm
    for h in STEPS_S + ODD_STEPS_S:
        t, x = _drive(fmu, h, current_mA)
        k = t / 0.01
        on_ref = np.abs(k - np.round(k)) < 1e-6          # the points both grids share
        assert on_ref.sum() >= 6 and t[-1] == 10.0, h
        diff = np.abs(x[on_ref] - x_ref[np.round(k[on_ref]).astype(int)]).max()
        tol = TOL_MM if h in STEPS_S else TOL_ODD_STEP_MM
        assert diff <= tol, (h, diff)


def test_one_communication_step_of_ts_is_the_builtin_plant_rk4_step(servo_fmu, libm_numpy):
    # with the C library's arcsin/cos in the built-in plant, both do the same arithmetic
    # operation for operation: a doStep(Ts) of the FMU is exactly one RK4 step of the
    # built-in plant (its sub-stepping changes nothing at the engine's period)
    runs = _runs("elevator")
    _, tru_b = simulate(runs)
    _, tru_f = simulate(runs, plant=FmuPlant.of(servo_fmu))
    assert np.array_equal(tru_b.rod_mm, tru_f.rod_mm)
    assert np.array_equal(tru_b.current_mA, tru_f.current_mA)


@pytest.mark.parametrize("fmi", ["2", "3"])
def test_built_fmus_recompile_with_fmpy(request, tmp_path, fmi):
    import subprocess
    import sys

    from scenarios.fmu_build import FmuBuildError, find_compiler

    try:
        find_compiler()
    except FmuBuildError as exc:
        pytest.skip(f"no C compiler on this machine ({exc})")
    fmu = request.getfixturevalue("servo_fmu" if fmi == "2" else "servo_fmu3")
    plat = fmpy.platform if fmi == "2" else fmpy.platform_tuple
    binary = f"binaries/{plat}/fdd_servo.so"
    # the FMU as shipped to a platform it has no binary for: sources only. (Without the
    # binary, fmpy's CMake install step must copy the new one: over an existing binary
    # extracted in the same second it may report "Up-to-date" and keep the old one.)
    copy = _zip_with(fmu, tmp_path / f"copy{fmi}.fmu", drop=("binaries/",))
    with pytest.raises(FmuError, match=r"no binary for this platform.*python -m fmpy compile"):
        inspect_fmu(FmuPlant.of(copy))
    proc = subprocess.run([sys.executable, "-m", "fmpy", "compile", str(copy)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    with zipfile.ZipFile(copy) as z:
        assert binary in z.namelist()
        assert ("sources/buildDescription.xml" in z.namelist()) == (fmi == "3")
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(copy)) == []
    probe(FmuPlant.of(copy))
    t0, x0 = _drive(fmu, 0.1, 4.0)
    t1, x1 = _drive(copy, 0.1, 4.0)
    assert np.array_equal(t0, t1) and np.abs(x0 - x1).max() <= TOL_MM


def test_fmu_build_command(tmp_path, capsys):
    out = tmp_path / "aileron.fmu"
    assert main(["fmu", "build", "--out", str(out), "--surface", "aileron"]) == 0
    assert "validated" in capsys.readouterr().out
    from fmpy import read_model_description

    r = {v.name: v.start for v in read_model_description(str(out)).modelVariables}
    assert float(r["r_mm"]) == 70.0  # the aileron lever arm of scenarios.params
    assert main(["fmu", "build", "--out", str(tmp_path / "servo.zip")]) == 2
    assert ".fmu" in capsys.readouterr().err


# ---------------------------------------------------------------------------------------
# cross-check against the built-in plant
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("surface, fmi", [("elevator", "2"), ("aileron", "2"),
                                          ("elevator", "3")])
def test_fmu_matches_builtin_plant_for_every_fault(request, surface, fmi):
    fmu = request.getfixturevalue("servo_fmu" if fmi == "2" else "servo_fmu3")
    runs = _runs(surface)
    spec = FmuPlant.of(fmu)
    assert inspect_fmu(spec).version == f"{fmi}.0"
    sig_b, tru_b = simulate(runs)
    sig_f, tru_f = simulate(runs, plant=spec)
    assert set(tru_b.fault) == set(FAULTS)
    for name in ("rod_mm", "current_mA"):
        diff = np.abs(getattr(tru_b, name) - getattr(tru_f, name)).max(axis=1)
        assert (diff <= TOL_MM).all(), (name, dict(zip(tru_b.fault, diff)))
    d_surf = np.abs(tru_b.surface_deg - tru_f.surface_deg).max(axis=1)
    assert (d_surf <= TOL_DEG).all(), dict(zip(tru_b.fault, d_surf))
    # what the detectors see: the same acquisitions (same noise, same quantisation)
    for name in ("rod_com", "rod_mon", "current"):
        assert np.abs(getattr(sig_b, name) - getattr(sig_f, name)).max() <= TOL_MM, name
    # the faults did act (a check that cannot pass on two idle plants)
    jam = list(tru_b.fault).index("solid_jam")
    k0 = int(round(4.0 / sig_b.ts)) + 1
    assert np.ptp(tru_f.rod_mm[jam, k0:]) == 0.0 and np.ptp(tru_f.rod_mm[jam, :k0]) > 0.0
    disc = list(tru_b.fault).index("disconnection")
    assert np.abs(tru_f.surface_deg[disc] - np.degrees(np.arcsin(
        tru_f.rod_mm[disc] / (120.0 if surface == "elevator" else 70.0)))).max() > 0.5


def test_jam_emulated_by_the_engine_when_the_fmu_has_no_jam_input(servo_fmu):
    runs = _runs("elevator")
    runs = runs[runs["fault"] == "solid_jam"]
    p = prepare(runs)
    with_input = simulate(runs, plant=FmuPlant.of(servo_fmu))[1]
    emulated = simulate(runs, plant=FmuPlant.of(servo_fmu, {"jam": ""}))[1]
    builtin = integrate(p, SENSORS)
    assert np.abs(emulated.rod_mm - with_input.rod_mm).max() <= TOL_MM
    assert np.abs(emulated.rod_mm - builtin.x).max() <= TOL_MM


def test_one_instance_per_process_reset_between_runs(servo_fmu):
    spec = FmuPlant.of(servo_fmu)
    runs = _runs("elevator")
    both = simulate(runs, plant=spec)[1]
    _, inst = instance(spec)
    assert sum(1 for k in _CACHE if k[-1] == spec) == 1
    # a run after many others equals the same run alone: reset() leaves nothing behind
    last = simulate(runs.iloc[[-1]], plant=spec)[1]
    assert instance(spec)[1] is inst
    assert np.array_equal(last.rod_mm[0], both.rod_mm[-1])


# ---------------------------------------------------------------------------------------
# campaigns
# ---------------------------------------------------------------------------------------
def test_smoke_campaign_identical_on_both_back_ends(servo_fmu, tmp_path):
    config = load_config("smoke")
    builtin = run(config, tmp_path / "builtin", jobs=1, progress=False, log=lambda m: None)
    fmu_cfg = with_overrides(config, values={"plant.fmu": str(servo_fmu)})
    assert settings_of(resolve(fmu_cfg)).plant is not None
    on_fmu = run(fmu_cfg, tmp_path / "fmu", jobs=2, progress=False, log=lambda m: None)
    assert on_fmu.complete and (on_fmu.results["status"] == "ok").all()
    cols = ["run_id", "detector", "false_alarm", "pre_onset_alarm", "detected",
            "first_alarm_s", "delay_s", "dtp"]
    pd.testing.assert_frame_equal(builtin.results[cols], on_fmu.results[cols])
    pd.testing.assert_frame_equal(builtin.summary, on_fmu.summary)
    # the faulty runs were detected (FA/MD/DTP that mean something)
    faulty = on_fmu.results[on_fmu.results["fault"] != "none"]
    assert faulty["detected"].any()


def test_fmu_plant_runs_on_worker_processes_never_shared_threads(servo_fmu, tmp_path):
    from campaign.runner import CampaignSetupError

    fmu_cfg = with_overrides(load_config("smoke"), values={"plant.fmu": str(servo_fmu)})
    with pytest.raises(CampaignSetupError, match="use backend loky .* or jobs 1"):
        run(fmu_cfg, tmp_path / "t", jobs=2, backend="threading", progress=False,
            log=lambda m: None)
    assert not (tmp_path / "t").exists()   # refused before anything was written


def test_run_cli_with_plant(servo_fmu, tmp_path, capsys):
    assert main(["run", "smoke", "--plant", str(servo_fmu), "--out", str(tmp_path / "r"),
                 "--jobs", "1", "--quiet"]) == 0
    assert "20 of 20 runs" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------
# bad FMUs: a clear message before the campaign, or a per-run error
# ---------------------------------------------------------------------------------------
def test_missing_fmu_file(tmp_path, capsys):
    with pytest.raises(FmuError, match=r"nothere\.fmu: file not found.*fmu build"):
        inspect_fmu(FmuPlant.of(tmp_path / "nothere.fmu"))
    code = main(["run", "smoke", "--plant", str(tmp_path / "nothere.fmu"),
                 "--out", str(tmp_path / "r"), "--quiet"])
    assert code == 2 and "nothere.fmu: file not found" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()  # refused before anything was written


def test_unmapped_and_wrong_variables_are_named(servo_fmu):
    with pytest.raises(FmuError) as err:
        inspect_fmu(FmuPlant.of(servo_fmu, {"rod": "x_pos", "current": "x_mm"}))
    msg = str(err.value)
    assert "rod = 'x_pos'" in msg and "no variable 'x_pos'" in msg and "x_mm" in msg
    assert "current = 'x_mm'" in msg and "is a(n) output" in msg
    assert str(servo_fmu) in msg
    with pytest.raises(FmuError, match=r"current is not mapped.*i_mA"):
        inspect_fmu(FmuPlant.of(servo_fmu, {"current": ""}))
    with pytest.raises(FmuError, match=r"disconnect is not mapped.*disconnection runs"):
        inspect_fmu(FmuPlant.of(servo_fmu, {"disconnect": ""}), faults={"disconnection"})
    with pytest.raises(FmuError, match=r"parameter override 'Kx'.*real parameters: .*Ka"):
        inspect_fmu(FmuPlant.of(servo_fmu, parameters={"Kx": 1.0}))


def test_nan_mid_run_is_a_per_run_error(servo_fmu):
    # a negative damping coefficient makes the rod-speed denominator negative once the
    # current is large: the hardover at 3 s drives sqrt() of a negative number → NaN
    spec = FmuPlant.of(servo_fmu, parameters={"Ka": -1000.0})
    ok = single_run("elevator", "cruise", "none", seed=1, duration_s=20.0)
    bad = single_run("elevator", "cruise", "hardover", seed=2, onset_s=3.0, duration_s=20.0)
    with pytest.raises(FmuRunError, match=r"servo\.fmu: output 'x_mm' \(rod\) is nan at t = 3\.0"):
        simulate(bad, plant=spec)
    rows = pd.concat([ok, bad], ignore_index=True)
    rows["stream"] = [0, 1]
    from campaign.runner import build_detectors

    det = build_detectors(load_config("smoke"))
    from scenarios.simulate import simulate as sim

    sig, _ = sim(pd.concat([single_run("elevator", m, "none", seed=s, duration_s=20.0)
                            for s, m in enumerate(["cruise", "nose_up"])], ignore_index=True))
    for d in det.values():
        d.fit(sig)
    settings = ChunkSettings(ts=0.01, pressure_sensor=False, required_time_s={"hardover": 0.2},
                             window_s=None, plant=spec)
    res = evaluate(rows, det, settings).set_index("run_id")
    assert res.loc[ok["run_id"][0], "status"] == "ok"
    err = res.loc[bad["run_id"][0]]
    assert err["status"] == "error" and "'x_mm' (rod) is nan" in err["error"]
    assert "servo.fmu" in err["error"]


def test_campaign_file_plant_section(servo_fmu, tmp_path):
    from campaign.config import ConfigError

    base = """
[campaign]
name = "t"
[[group]]
fault = "none"
count = 1
[[detector]]
name = "position-monitor"
"""
    # an FMU key without an FMU is an error, not silently ignored
    f = tmp_path / "a.toml"
    f.write_text(base + '[plant.variables]\nrod = "pos"\n')
    with pytest.raises(ConfigError, match=r"plant\.variables\.rod: only used with an FMU"):
        load_config(f)
    # a wrong variable in the file is refused before anything is written
    f.write_text(base + f'[plant]\nfmu = "{servo_fmu}"\n[plant.variables]\nrod = "pos"\n')
    config = load_config(f)
    assert settings_of(resolve(config)).plant.mapping["rod"] == "pos"
    with pytest.raises(FmuError, match=r"rod = 'pos'.*no variable 'pos'"):
        run(config, tmp_path / "out", jobs=1, progress=False, log=lambda m: None)
    assert not (tmp_path / "out").exists()


def test_campaign_file_plant_parameters(servo_fmu, tmp_path):
    from campaign.config import ConfigError
    from campaign.plant_setup import plant_of

    base = ('[campaign]\nname = "t"\n[[group]]\nfault = "none"\ncount = 1\n'
            '[[detector]]\nname = "position-monitor"\n')
    f = tmp_path / "p.toml"
    # FMU parameter overrides mean nothing without an FMU
    f.write_text(base + '[plant]\nparameters = { h_max_s = 0.005 }\n')
    with pytest.raises(ConfigError, match=r"plant\.parameters: only used with an FMU"):
        load_config(f)
    # numbers only, each named
    f.write_text(base + f'[plant]\nfmu = "{servo_fmu}"\n'
                 'parameters = { h_max_s = "fine", Kci = true }\n')
    with pytest.raises(ConfigError) as err:
        load_config(f)
    assert "plant.parameters.h_max_s: expected a number, got string" in str(err.value)
    assert "plant.parameters.Kci: expected a number, got boolean" in str(err.value)
    # passed to the FMU plant, kept by the canonical form of the campaign
    f.write_text(base + f'[plant]\nfmu = "{servo_fmu}"\n'
                 'parameters = { h_max_s = 0.005, Ka = 2 }\n')
    config = load_config(f)
    plant = plant_of(config)
    assert plant.parameters == (("Ka", 2.0), ("h_max_s", 0.005))
    assert config.to_dict()["plant"]["parameters"] == {"Ka": 2.0, "h_max_s": 0.005}
    assert settings_of(resolve(config)).plant == plant
    # and set into the FMU: Ka, a pushed parameter, now holds for every run
    runs = _runs("elevator").iloc[:2]
    moved = simulate(runs, plant=plant)[1].rod_mm
    assert not np.array_equal(moved, simulate(runs, plant=FmuPlant.of(servo_fmu))[1].rod_mm)
    # a misspelt parameter is refused before anything is written, with a suggestion
    f.write_text(base + f'[plant]\nfmu = "{servo_fmu}"\nparameters = {{ Kcj = 1.0 }}\n')
    with pytest.raises(FmuError, match=r"parameter override 'Kcj' \(\[plant\] parameters\): "
                                       r".*no variable 'Kcj' \(did you mean 'Kci'\?\)"):
        run(load_config(f), tmp_path / "out", jobs=1, progress=False, log=lambda m: None)
    assert not (tmp_path / "out").exists()
    # an output is no parameter
    with pytest.raises(FmuError, match=r"'x_mm' .* is a\(n\) output .*only real parameters"):
        inspect_fmu(FmuPlant.of(servo_fmu, parameters={"x_mm": 1.0}))


def test_offset_jam_is_emulated_with_or_without_a_jam_input(servo_fmu):
    # docs/physics.md §5: the "offset" solid jam is always emulated by the engine (an FMU's
    # jam input seizes the rod where it stands); it matches the built-in plant
    runs = _runs("elevator")
    runs = runs[runs["fault"] == "solid_jam"].copy()
    runs["magnitude"] = -1.7
    p = prepare(runs)
    builtin = integrate(p, SENSORS)
    for variables in ({}, {"jam": ""}):
        fmu = simulate(runs, plant=FmuPlant.of(servo_fmu, variables or None))[1]
        assert np.abs(fmu.rod_mm - builtin.x).max() <= TOL_MM
    k0 = int(p.faults.k_jam[0])
    assert builtin.x[0, k0] - builtin.x[0, k0 - 1] < -1.5            # the jump
    assert np.ptp(builtin.x[0, k0:]) == 0.0                          # then seized
