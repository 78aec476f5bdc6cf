"""The compiled kernels (scenarios/compiled.py) against their NumPy reference."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from campaign.tools.bench import bench_runs
from detectors.builtin.position_monitor import PositionMonitor
from scenarios import compiled as kernels
from scenarios import simulate as sim
from scenarios.params import SENSORS
from scenarios.simulate import prepare, simulate, single_run

FIELDS = ("x", "delta", "i_cmd", "i_app", "y_com")


def every_fault_batch() -> pd.DataFrame:
    """Runs of every fault type (each path of the loop: COM bias, COM replacement, current
    added / forced, jam, disconnection) mixed with fault-free runs, 20 s."""
    faults = ["none", "runaway", "hardover", "liquid_jam", "solid_jam", "disconnection",
              "ofc_liquid", "ofc_solid"]
    rows = [single_run("elevator", man, f, seed=i, onset_s=5.0 + 0.5 * i, duration_s=20.0)
            for i, (f, man) in enumerate(zip(faults * 2, ["cruise", "nose_up"] * 8))]
    frame = pd.concat(rows, ignore_index=True)
    frame["stream"] = np.arange(len(frame))
    frame["run_id"] = [f"k{i}" for i in range(len(frame))]
    return frame


@pytest.fixture
def libm_numpy(libm_numpy, monkeypatch):
    """The conftest fixture (scenarios.servo on the C library's arcsin/cos), and the time loop
    of scenarios.simulate too."""
    from conftest import LibmNumpy

    monkeypatch.setattr(sim, "np", LibmNumpy())


@pytest.fixture(scope="module")
def _every_fault_signals():
    """The signals of :func:`every_fault_batch` simulated once with the NumPy engine on the C
    library's arcsin/cos (the ``libm_numpy`` fixtures' patches): its time loop in Python is
    the slow part of the tests below, and their input is the same for every step, band and
    check."""
    from conftest import LibmNumpy

    from scenarios import servo

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(servo, "np", LibmNumpy())
        patch.setattr(sim, "np", LibmNumpy())
        signals, _ = simulate(every_fault_batch(), engine="numpy")
    return signals


@pytest.fixture
def libm_signals(_every_fault_signals):
    """A fresh copy of the shared signals for each test (a test cannot see another's
    changes)."""
    return copy.deepcopy(_every_fault_signals)


def test_compiled_loop_is_bit_identical_to_numpy_with_the_same_libm(libm_numpy):
    p = prepare(every_fault_batch())
    ref = sim.integrate(p, SENSORS)
    fast = kernels.integrate_compiled(p, SENSORS)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)


@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
def test_compiled_monitor_model_is_bit_identical_to_numpy_with_the_same_libm(
        libm_numpy, libm_signals, step):
    signals = libm_signals
    ref = PositionMonitor.model_output(signals, engine="numpy", model_step=step)
    fast = PositionMonitor.model_output(signals, engine="compiled", model_step=step)
    np.testing.assert_array_equal(fast, ref)


@pytest.mark.slow
@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
def test_compiled_monitor_band_is_bit_identical_to_numpy_with_the_same_libm(
        libm_numpy, libm_signals, step):
    signals = libm_signals
    det = PositionMonitor(hinge_scale=(0.6, 1.6), model_step=step)
    assert len(det.band_corners()) == 9      # the valve and hinge corners (docs/physics.md §6)
    ref = det.model_band(signals, engine="numpy")
    fast = det.model_band(signals, engine="compiled")
    for got, want in zip(fast, ref):
        np.testing.assert_array_equal(got, want)
    assert np.any(fast[1] > fast[0])          # the corners move the models apart


@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
def test_compiled_band_equals_the_hull_of_the_compiled_corner_models(step):
    signals, _ = simulate(every_fault_batch(), engine="compiled")
    det = PositionMonitor(hinge_scale=(1.6, 0.6), model_step=step)
    corners = [(1.0, 1.0, 1.0, 1.0)] + [(v, v, o, d) for v in (0.95, 1.05)
                                        for o in (0.6, 1.6) for d in (0.6, 1.6)]
    outs = [PositionMonitor.model_output(signals, engine="compiled", corner=c,
                                         model_step=step)
            for c in corners]
    lo, hi = det.model_band(signals, engine="compiled")
    np.testing.assert_array_equal(lo, np.minimum.reduce(outs))
    np.testing.assert_array_equal(hi, np.maximum.reduce(outs))


def test_compiled_band_propagates_a_nan_model_like_numpy():
    signals, _ = simulate(every_fault_batch().iloc[:3], engine="compiled")
    nominal = PositionMonitor.model_plant(signals)
    broken = PositionMonitor.model_plant(signals, 1.6)
    broken.hm_0[1] = np.nan                   # run 1 of the second model only
    outs = [kernels.servo_model(signals.command, signals.rod_com[:, 0], p, signals.ts)
            for p in (nominal, broken)]
    lo, hi = kernels.servo_band(signals.command, signals.rod_com[:, 0], [nominal, broken],
                                signals.ts)
    assert np.isnan(outs[1][1, 1:]).all() and not np.isnan(outs[0]).any()
    np.testing.assert_array_equal(lo, np.minimum.reduce(outs))
    np.testing.assert_array_equal(hi, np.maximum.reduce(outs))


#: NumPy model bands of the decision test below, by (corners, step, signals): each is the
#: same for every set of checks with the loop check.
_NUMPY_BANDS: dict = {}


@pytest.fixture
def numpy_band_once(monkeypatch):
    """PositionMonitor.model_band with the NumPy engine computed once per band, model step
    and signals, its arrays reused (read-only) by the next test that asks for them: the
    NumPy band, a Python loop over the steps of nine models, is the slow part of the
    decision test, and the band test above checks it against the compiled one."""
    import hashlib

    from scenarios.compiled import resolve_engine

    real = PositionMonitor.model_band

    def once(self, signals, engine=None):
        if resolve_engine(engine) != "numpy":
            return real(self, signals, engine)
        key = (tuple(self.band_corners()), self.model_step, hashlib.sha256(
            signals.command.tobytes() + signals.rod_com.tobytes()).hexdigest())
        if key not in _NUMPY_BANDS:
            lo, hi = real(self, signals, engine)
            lo.setflags(write=False)
            hi.setflags(write=False)
            _NUMPY_BANDS[key] = lo, hi
        return _NUMPY_BANDS[key]

    monkeypatch.setattr(PositionMonitor, "model_band", once)


@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
@pytest.mark.parametrize("band", [{}, {"band": "paired"}, {"hinge_scale": (1.0, 1.0)},
                                  {"hinge_scale": (1.0, 1.0), "kci_scale": (1.0, 1.0),
                                   "supply_scale": (1.0, 1.0)}])
@pytest.mark.parametrize("checks", [("loop", "com_mon", "surface"), ("loop",), ("com_mon",)])
def test_compiled_monitor_decision_is_bit_identical_to_numpy_with_the_same_libm(
        libm_numpy, libm_signals, numpy_band_once, band, checks, step):
    signals = libm_signals
    det = PositionMonitor(checks=checks, confirm_s=0.03, model_step=step, **band)
    # thresholds a fraction of the largest residuals, so that alarms are raised and cleared
    det.thresholds_mm_ = {name: 0.3 * float(np.max(np.abs(r)))
                          for name, r in det.residuals(signals).items()}
    det.learning_runs_ = 1
    got = {}
    for engine in ("numpy", "compiled"):
        with kernels.use_engine(engine):
            got[engine] = det.detect(signals)
    np.testing.assert_array_equal(got["compiled"].residual, got["numpy"].residual)
    np.testing.assert_array_equal(got["compiled"].alarm, got["numpy"].alarm)
    assert got["numpy"].alarm.any() and not got["numpy"].alarm.all()


def test_compiled_signals_match_plain_numpy_within_last_bit_noise():
    # Tolerance: NumPy's SIMD arcsin/cos differ from the C library by ≤ 1 ulp for some
    # arguments; through the RK4 steps these stay at the 1e-14 mm level (measured ≤ 1e-14
    # mm over 60 s runs). 1e-9 mm is 10⁻⁷ of the 0.01 mm rod quantum, so a sensor sample can
    # only differ when a value sits within 1e-9 mm of a quantisation boundary.
    runs = every_fault_batch()
    sig_n, truth_n = simulate(runs, engine="numpy")
    sig_c, truth_c = simulate(runs, engine="compiled")
    for name in ("rod_mm", "surface_deg", "current_mA"):
        np.testing.assert_allclose(getattr(truth_c, name), getattr(truth_n, name), rtol=0,
                                   atol=1e-9, err_msg=name)
    for name in ("current", "rod_com", "rod_mon"):
        np.testing.assert_allclose(getattr(sig_c, name), getattr(sig_n, name), rtol=0,
                                   atol=1e-9, err_msg=name)


def test_a_run_alone_equals_the_same_run_in_a_block():
    runs = pd.concat([bench_runs(7, 20.0), every_fault_batch()], ignore_index=True)
    runs["stream"] = np.arange(len(runs))
    together, _ = simulate(runs, engine="compiled")
    for j in (0, 9, len(runs) - 1):
        alone, _ = simulate(runs.iloc[[j]], engine="compiled")
        np.testing.assert_array_equal(alone.rod_com[0], together.rod_com[j])
        np.testing.assert_array_equal(alone.current[0], together.current[j])


def test_engine_is_explicit_and_checked():
    with pytest.raises(ValueError, match="unknown engine 'fast'.*compiled, numpy"):
        simulate(single_run(duration_s=20.0), engine="fast")
    with kernels.use_engine("numpy"):
        assert kernels.current_engine() == "numpy"
    assert kernels.current_engine() == "compiled"


#: A test of what numba compiles and loads: nothing is, without numba or under
#: NUMBA_DISABLE_JIT (debugging, mutation testing), in this process or a child it starts.
compiles = pytest.mark.skipif(not kernels.HAVE_NUMBA
                              or __import__("numba").core.config.DISABLE_JIT,
                              reason="NUMBA_DISABLE_JIT set or numba missing: nothing is "
                                     "compiled")


@compiles
def test_warm_up_compiles_every_registered_kernel():
    calls = []
    kernels.register_warmup(lambda: calls.append(1))
    try:
        kernels.warm_up()
    finally:
        kernels._WARMUPS.pop()
    assert calls == [1]
    assert kernels.integrate_block.signatures and kernels.servo_band_block.signatures
    assert kernels.sensor_draws_1.signatures and kernels.filtered_normals_1.signatures


@compiles
def test_warm_up_leaves_the_single_servo_model_to_its_first_call():
    # a fresh process: this one may have called servo_model already. Every kernel whose
    # cache decides whether a start says "compiling kernels" (_KERNELS) is one warm_up
    # loads; one it leaves to its first call would make that note appear at every start
    code = ("from scenarios import compiled as k; k.warm_up(); "
            "print(len(k.servo_model_block.signatures), "
            "*sorted(n for n in k._KERNELS if not getattr(k, n).signatures))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parents[2]).stdout
    assert out.split() == ["0"]


def offset_jam_batch() -> pd.DataFrame:
    """Every fault of :func:`every_fault_batch` and solid jams of the "offset" variant
    (docs/physics.md §5), both signs, one at onset 0 s."""
    rows = [single_run("elevator", "cruise", "solid_jam", seed=40 + i, onset_s=onset,
                       magnitude=mag, duration_s=20.0)
            for i, (onset, mag) in enumerate([(6.0, 1.2), (7.5, -0.9), (0.0, 0.7)])]
    frame = pd.concat([every_fault_batch(), *rows], ignore_index=True)
    frame["stream"] = np.arange(len(frame))
    frame["run_id"] = [f"j{i}" for i in range(len(frame))]
    return frame


def test_compiled_loop_with_offset_jams_is_bit_identical_to_numpy_with_the_same_libm(libm_numpy):
    p = prepare(offset_jam_batch())
    assert (p.faults.jam_offset != 0).sum() == 3
    ref = sim.integrate(p, SENSORS)
    fast = kernels.integrate_compiled(p, SENSORS)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)


def test_an_offset_jam_run_alone_equals_it_inside_a_batch():
    runs = offset_jam_batch()
    together, t_all = simulate(runs, engine="compiled")
    for j in range(len(runs) - 3, len(runs)):
        alone, t_one = simulate(runs.iloc[[j]], engine="compiled")
        np.testing.assert_array_equal(alone.rod_com[0], together.rod_com[j])
        np.testing.assert_array_equal(t_one.rod_mm[0], t_all.rod_mm[j])
        np.testing.assert_array_equal(t_one.rod_fault_mm[0], t_all.rod_fault_mm[j])


@pytest.mark.parametrize("stages", [0, 3, 5, True, 4.5])
def test_servo_models_refuse_a_step_with_another_number_of_stages(stages):
    # 1 (Euler), 2 (Heun) and 4 (RK4) only: any other count would silently take RK4's branch
    signals, _ = simulate(every_fault_batch().iloc[:1], engine="compiled")
    plant = PositionMonitor.model_plant(signals)
    with pytest.raises(ValueError, match="stages"):
        kernels.servo_model(signals.command, signals.rod_com[:, 0], plant, signals.ts, stages)
    with pytest.raises(ValueError, match="stages"):
        kernels.servo_band(signals.command, signals.rod_com[:, 0], [plant, plant], signals.ts,
                           stages)
