"""``fdd-campaign bench``: the structure of what it reports (never its timings)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from campaign.plant_setup import resolve
from campaign.tools import bench as bench_module
from campaign.tools.bench import (RUN_IMPORTS, arithmetic_floor, bench_runs, import_seconds,
                            floor_ratios, print_floor, print_stages, rate_evaluations, stage_costs,
                            yardstick_pairs)
from campaign.cli.commands import main
from campaign.config import load_config
from campaign.plan import build_learning_plan, build_plan
from detectors.builtin.position_monitor import PositionMonitor
from scenarios.simulate import simulate, single_run

SMOKE_STAGES = ("learning set: simulation", "fit position-monitor", "preparation", "plant",
                "sensors and truth", "detect position-monitor", "scoring",
                "I/O (Parquet shard)")


@pytest.fixture(scope="module")
def smoke_costs():
    return stage_costs("smoke", sample_runs=4, learning_runs=6, imports=False)


def test_stage_costs_name_every_stage_once(smoke_costs):
    names = [s["stage"] for s in smoke_costs["stages"]]
    assert names == list(SMOKE_STAGES)


def test_stage_costs_scale_to_the_plan(smoke_costs):
    assert smoke_costs["campaign"] == "smoke"
    assert smoke_costs["runs"] == len(build_plan(load_config("smoke")))
    assert smoke_costs["sampled_runs"] == 4
    assert smoke_costs["learning_runs"] == 6


def test_stage_shares_add_up_to_one(smoke_costs):
    seconds = [s["seconds"] for s in smoke_costs["stages"]]
    shares = [s["share"] for s in smoke_costs["stages"]]
    assert all(math.isfinite(v) and v >= 0.0 for v in seconds)
    assert math.isclose(sum(shares), 1.0, rel_tol=1e-12)
    assert math.isclose(sum(seconds), smoke_costs["total_s"], rel_tol=1e-12)
    for s in smoke_costs["stages"]:
        assert math.isclose(s["share"], s["seconds"] / smoke_costs["total_s"], rel_tol=1e-12)


def test_print_stages_one_line_per_stage_and_a_total(smoke_costs):
    lines = []
    print_stages(smoke_costs, echo=lines.append)
    assert len(lines) == len(SMOKE_STAGES) + 2
    assert "smoke" in lines[0] and "4 of" in lines[0]
    for name, line in zip(SMOKE_STAGES, lines[1:-1]):
        assert line.strip().startswith(name) and line.rstrip().endswith("%")
    assert "total" in lines[-1]


def test_stage_costs_of_an_aircraft_campaign_time_its_plant_as_one_stage(tmp_path):
    """On a plant other than the built-in servo-loop (here the aircraft) the simulation is one
    stage, timed with the campaign's sampling period and pressure sensor, scaled to the
    plan like the others."""
    campaign = tmp_path / "tiny-aircraft.toml"
    campaign.write_text(
        '[campaign]\nname = "tiny-aircraft"\nseed = 3\nsurface = "aileron"\n'
        'duration_s = 20.0\ndesign = "mc"\n\n[plant]\nkind = "aircraft"\n'
        'monitored_surface = "left_inboard_aileron"\n\n'
        '[[group]]\nfault = "none"\nmanoeuvres = ["cruise"]\ncount = 4\n\n'
        '[[detector]]\nname = "position-monitor"\n\n[learning]\nruns_per_manoeuvre = 1\n')
    costs = stage_costs(str(campaign), sample_runs=2, learning_runs=6, imports=False)
    names = [s["stage"] for s in costs["stages"]]
    assert names[:2] == ["learning set: simulation", "fit position-monitor"]
    assert "simulation" in names and "plant" not in names
    assert costs["runs"] == 4 and costs["sampled_runs"] == 2
    assert math.isclose(sum(s["share"] for s in costs["stages"]), 1.0, rel_tol=1e-12)


def test_import_seconds_is_a_wall_time_of_a_fresh_interpreter():
    assert "campaign.runner" in RUN_IMPORTS
    seconds = import_seconds(modules=("json",))
    assert isinstance(seconds, float) and math.isfinite(seconds) and seconds > 0.0


def test_simulate_timings_leave_the_result_unchanged():
    runs = single_run("elevator", "nose_up", "solid_jam", seed=3, duration_s=20.0)
    laps = {}
    sig_t, truth_t = simulate(runs, timings=laps)
    sig, truth = simulate(runs)
    assert list(laps) == ["preparation", "plant", "sensors and truth"]
    assert all(v >= 0.0 for v in laps.values())
    for name in ("command", "current", "rod_com", "rod_mon"):
        np.testing.assert_array_equal(getattr(sig_t, name), getattr(sig, name))
    np.testing.assert_array_equal(truth_t.rod_fault_mm, truth.rod_fault_mm)


@pytest.mark.parametrize("argv, message", [
    (["bench", "--stage-runs", "0"], "--stage-runs 0"),
    # once an internal error (max() of no chunk) and a division by zero: the user's values
    (["bench", "--runs", "0", "--reference-runs", "0"],
     "--runs 0: must be an integer ≥ 1 (runs simulated); fix: e.g. --runs 2200; "
     "--reference-runs 0: must be an integer ≥ 1"),
    (["bench", "--duration", "5"], "--duration 5: a run lasts 20 to 3600 s"),
    (["bench", "--campaign", "no-such-preset", "--no-detectors"], "no-such-preset"),
    (["bench", "--pairs", "0"], "--pairs 0"),
    (["bench", "--yardstick", "no-such-command-xyz run"], "no-such-command-xyz"),
    (["bench", "--yardstick-dir", "."], "--yardstick-dir without --yardstick"),
    (["bench", "--yardstick", "python -c pass", "--yardstick-dir", "/no/such/dir"],
     "/no/such/dir"),
])
def test_bench_bad_input_exits_2_before_any_work(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


QUICK_BENCH = ["bench", "--runs", "4", "--duration", "20", "--reference-runs", "1",
               "--campaign", "none", "--no-cold", "--no-detectors"]


def test_bench_announces_each_measurement_on_stderr_unless_quiet(capsys):
    """Progress: one stderr line per measurement as it starts (the figures stay on stdout),
    none with --quiet, which leaves the figures as they are."""
    assert main(QUICK_BENCH) == 0
    out, err = capsys.readouterr()
    steps = [line for line in err.splitlines() if line.startswith("bench [")]
    assert [s.split("] ", 1)[1] for s in steps] == [
        "simulating 4 runs…", "timing the per-run reference on 1 run(s)…",
        "timing the plants (actuator, aircraft)…", "done"]
    assert "vectorised simulation" in out and "bench [" not in out
    assert main([*QUICK_BENCH, "--quiet"]) == 0
    quiet_out, quiet_err = capsys.readouterr()
    assert "bench [" not in quiet_err
    labels = [line.split(":")[0] for line in out.splitlines()]
    assert [line.split(":")[0] for line in quiet_out.splitlines()] == labels


# ---- the arithmetic floor ----------------------------------------------------------------------
def test_rate_evaluations_of_smoke_count_each_part_over_its_runs_and_steps():
    """smoke: the actuator plant's RK4 (4 per step) on the plan and the learning set and the
    position monitor's band of nine Euler models (9 per step, its default: the nominal model
    and the eight valve and hinge corners) on both sets (it
    is fitted); no detector estimates the rod fault, so the jam runs' healthy rod model is
    never computed nor counted."""
    config = load_config("smoke")
    resolved = resolve(config)
    plan, learning = build_plan(resolved), build_learning_plan(resolved)
    steps = round(config.campaign.duration_s / config.campaign.ts_s)
    jams = int(plan["fault"].isin(["liquid_jam", "solid_jam"]).sum())
    counts = rate_evaluations("smoke")
    assert counts["steps"] == steps and counts["uncounted"] == []
    assert jams > 0
    assert counts["parts"] == {
        "plant (actuator)": 4 * (len(plan) + len(learning)) * steps,
        "detect position-monitor": 9 * (len(plan) + len(learning)) * steps}


def test_rate_evaluations_count_the_healthy_rod_model_when_a_detector_estimates_it():
    # chen-local estimates the rod fault: the healthy RK4 rod model of each jam run of the
    # plan is counted (4 evaluations per step), beside the plant's
    config = load_config("chen-local")
    plan = build_plan(config)
    steps = round(config.campaign.duration_s / config.campaign.ts_s)
    jams = int(plan["fault"].isin(["liquid_jam", "solid_jam"]).sum())
    assert jams > 0
    assert rate_evaluations("chen-local")["parts"]["healthy rod model of the jam runs"] == (
        4 * jams * steps)


#: the band of one model (every range at 1)
_PLAIN = {"hinge_scale": (1.0, 1.0), "kci_scale": (1.0, 1.0), "supply_scale": (1.0, 1.0)}


@pytest.mark.parametrize("params, count", [
    ({}, 9), ({"model_step": "heun"}, 18), ({"model_step": "rk4"}, 36),
    ({"model_step": "euler"}, 9),
    ({"band": "paired"}, 5), ({"model_step": "euler", "hinge_scale": (1.0, 1.0)}, 3),
    ({"model_step": "euler", **_PLAIN}, 1),
    ({"checks": ("com_mon", "surface")}, 0),
    ({"model_step": "euler", "checks": "loop", **_PLAIN, "hinge_scale": (1.0, 2.0)}, 4),
    ({**_PLAIN, "hinge_scale": (1.0, 2.0), "band": "paired"}, 2),
    ({**_PLAIN, "model_step": "rk4", "hinge_scale": (1.0, 2.0), "band": "paired"}, 8),
    ({**_PLAIN, "model_step": "heun", "hinge_scale": (1.0, 2.0), "band": "paired"}, 4),
])
def test_position_monitor_declares_its_evaluations_per_model_and_step(params, count):
    # one rate-law evaluation per model of the band and Euler step, two per Heun step,
    # four per RK4 step
    assert PositionMonitor(**params).rate_evaluations_per_step() == count


def test_floor_is_evaluations_times_cost_spread_over_the_workers_after_the_imports():
    floor = arithmetic_floor("smoke", jobs=2, cost_s=10e-9, imports_s=1.5)
    n = sum(floor["parts"].values())
    assert floor["evaluations"] == n
    assert floor["cpu_s"] == pytest.approx(n * 10e-9, rel=1e-12)
    assert floor["wall_s"] == pytest.approx(1.5 + n * 10e-9 / 2, rel=1e-12)
    lines = []
    print_floor(floor, echo=lines.append)
    assert len(lines) == 1                            # no campaign run: no ratio line
    floor = floor_ratios(floor, {"wall_s_campaign": 2 * floor["wall_s"], "cpu_s_campaign": 3.0})
    lines = []
    print_floor(floor, echo=lines.append)
    assert floor["ratio_wall"] == pytest.approx(2.0, rel=1e-12)
    assert floor["ratio_cpu"] == pytest.approx(3.0 / (floor["cpu_s"] + 1.5), rel=1e-12)
    assert len(lines) == 2 and "10.0 ns" in lines[0] and "2.00 x in wall time" in lines[1]


def test_yardstick_pairs_time_both_back_to_back_and_take_the_medians(monkeypatch):
    seen = []

    def campaign_run(campaign, jobs):
        seen.append((campaign, jobs))
        return {"wall_s": 3.0 * len(seen), "cpu_s": 1.0, "peak_rss_mb": 100.0}

    monkeypatch.setattr(bench_module, "run_campaign_process", campaign_run)
    monkeypatch.setattr(bench_module, "modules_without_bytecode", lambda: ([], 70))
    lines = []
    out = yardstick_pairs("smoke", 2, [sys.executable, "-c", "pass"], pairs=3,
                          echo=lines.append)
    assert seen == [("smoke", 2)] * 3
    for k, pair in enumerate(out["pairs"], 1):
        assert pair["yard_wall_s"] > 0.0 and pair["wall_s"] == 3.0 * k
        assert pair["ratio_wall"] == pytest.approx(3.0 * k / pair["yard_wall_s"], rel=1e-12)
    assert out["median_ratio_wall"] == pytest.approx(
        sorted(p["ratio_wall"] for p in out["pairs"])[1], rel=1e-12)
    assert len(lines) == 5 and lines[-1].strip().startswith("median ratio")


def test_modules_without_bytecode_are_those_whose_cache_file_is_missing(tmp_path):
    import importlib.util
    import py_compile

    from campaign.tools.bench import modules_without_bytecode

    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    for name in ("__init__.py", "a.py", "sub/__init__.py", "sub/b.py"):
        (pkg / name).write_text("x = 1\n")
    assert modules_without_bytecode([pkg]) == (sorted(pkg.rglob("*.py")), 4)
    py_compile.compile(str(pkg / "a.py"), cfile=importlib.util.cache_from_source(
        str(pkg / "a.py")))
    missing, total = modules_without_bytecode([pkg])
    assert total == 4 and pkg / "a.py" not in missing and len(missing) == 3


def test_yardstick_pairs_say_when_the_projects_modules_are_compiled_at_each_start(
        monkeypatch):
    monkeypatch.setattr(bench_module, "run_campaign_process",
                        lambda campaign, jobs: {"wall_s": 2.0, "cpu_s": 1.0,
                                                "peak_rss_mb": 1.0})
    monkeypatch.setattr(bench_module, "modules_without_bytecode",
                        lambda: ([Path("campaign/runner.py")] * 3, 70))
    lines = []
    yardstick_pairs("smoke", 2, [sys.executable, "-c", "pass"], pairs=1, echo=lines.append)
    assert lines[-1].strip().startswith("note: 3 of the project's 70 modules have no bytecode")
    assert "python -m compileall -q " in lines[-1]


def test_the_timed_rate_law_is_the_rate_law():
    """What the floor times (kernels.loaded_rates_all, step-major samples over blocks of runs)
    is the rod's rate law, scenarios.servo.rod_rate of a loaded rod, on 70 runs (more than
    one block of 64) at positions across the stroke and currents across ±i_max. Tolerance
    1e-12 relative: the same formula; NumPy's arcsin may differ from the C library's in the
    last bit (docs/execution.md)."""
    from scenarios import compiled as kernels
    from scenarios.servo import PlantArrays, rod_rate
    from scenarios.simulate import prepare

    plant = prepare(bench_runs(70, 30.0, seed=4), pressure_sensor=False).plant
    rng = np.random.default_rng(7)
    frac = rng.uniform(0.0, 1.0, (5, 70))
    x = plant.x_min + frac * (plant.x_max - plant.x_min)              # (samples, runs) [mm]
    i = rng.uniform(-1.0, 1.0, (5, 70)) * plant.i_max                  # [mA]
    out = np.empty_like(x)
    kernels.loaded_rates_all(x, i, kernels.plant_fields(plant), out)
    rows = PlantArrays(**{k: np.broadcast_to(np.asarray(v), (5, 70))
                          for k, v in vars(plant).items()})
    want = rod_rate(x, i, rows, np.ones((5, 70), bool))
    assert np.any(want != 0.0) and np.all(np.isfinite(out))
    np.testing.assert_allclose(out, want, rtol=1e-12, atol=0.0)


@pytest.mark.skipif(not sys.platform.startswith("linux"),
                    reason="malloc_trim is a glibc (Linux) function; elsewhere nothing is trimmed "
                           "to check")
def test_returning_freed_memory_starts_no_child_process(monkeypatch):
    """The bench's peak sums the resident memory of the campaign's process tree: a child
    forked from the campaign (ctypes.util.find_library runs ldconfig) would show the
    campaign's memory twice. The C library's malloc_trim is found without one."""
    import subprocess

    from scenarios import memory

    spawned = []

    def spawn(self, *args, **kwargs):
        spawned.append(args or kwargs)
        raise OSError("no child process in this test")   # as a failed start: callers go on

    monkeypatch.setattr(subprocess.Popen, "__init__", spawn)
    memory._malloc_trim.cache_clear()
    try:
        memory.release_freed_memory()
        assert memory._malloc_trim() is not None and spawned == []
    finally:
        memory._malloc_trim.cache_clear()


def test_the_jsbsim_plant_is_timed_against_its_737_alone():
    """``bench --plant jsbsim``'s load is fault-free at realistic points (each trims), and
    the figures are the plant's CPU time per run, the same per simulated second, and the
    floor's; no timing is asserted, only what each figure is."""
    pytest.importorskip("jsbsim")
    from campaign.tools.plant_bench import _realistic_fault_free, jsbsim_cost
    from scenarios import envelope

    runs = bench_runs(2, 20.0, seed=3)
    load = _realistic_fault_free(runs)
    assert (load["fault"] == "none").all() and load["onset_s"].isna().all()
    pts = envelope.realistic_points()
    realistic = pts[pts["realistic"]][list(envelope.FLIGHT_COLUMNS)].to_numpy()
    for row in load[list(envelope.FLIGHT_COLUMNS)].to_numpy():
        assert (realistic == row).all(axis=1).any()
    lines = []
    got = jsbsim_cost(runs, echo=lines.append)
    assert got["jsbsim_runs"] == 2
    assert got["jsbsim_cpu_s_per_simulated_s"] == pytest.approx(
        got["jsbsim_cpu_s_per_run"] / 20.0, rel=1e-12)
    assert got["jsbsim_over_floor"] == pytest.approx(
        got["jsbsim_cpu_s_per_run"] / got["jsbsim_floor_cpu_s_per_run"], rel=1e-12)
    assert lines and "plant/floor" in lines[0]
