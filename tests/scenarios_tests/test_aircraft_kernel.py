"""The compiled aircraft loop (scenarios/aircraft/kernel.py) against its NumPy reference
(scenarios.aircraft.loop.integrate_reference): the same numbers, bit for bit."""

import numpy as np
import pandas as pd
import pytest

from scenarios import compiled as kernels
from scenarios.aircraft import kernel, loop
from scenarios.simulate import single_run

FAULTS = ("none", "liquid_jam", "solid_jam", "disconnection", "runaway", "hardover",
          "ofc_liquid", "ofc_solid")

needs_kernel = pytest.mark.skipif(not kernel.available(),
                                  reason="NumPy's inner loops or BLAS not found, or "
                                         "NUMBA_DISABLE_JIT set: the NumPy reference runs "
                                         "instead (tested there)")


def _batch(surface, kind, manoeuvres=("cruise", "turn_coordination")):
    rows = [single_run(kind, man, f, duration_s=6.0, onset_s=2.0 + 0.25 * i, seed=i)
            for i, (f, man) in enumerate((f, m) for f in FAULTS for m in manoeuvres)]
    runs = pd.concat(rows, ignore_index=True)
    runs["surface"] = surface
    runs["stream"] = np.arange(len(runs))
    runs["run_id"] = [f"a{i}" for i in range(len(runs))]
    return runs


@needs_kernel
@pytest.mark.parametrize("surface, kind", [("left_inboard_aileron", "aileron"),
                                           ("left_elevator", "elevator")])
def test_compiled_aircraft_loop_is_bit_identical_to_the_reference(surface, kind):
    p = loop.prepare_aircraft(_batch(surface, kind))
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    # the batch exercises what the kernel branches on
    assert (p.faults.k_jam < 10 ** 9).any() and (p.faults.k_disc < 10 ** 9).any()
    assert not np.array_equal(ref.x[0], ref.x[2])


@needs_kernel
def test_compiled_loop_equals_the_reference_while_the_rate_limiters_act():
    """docs/aircraft.md §4.4: with rate limits of 2 °/s on every surface (12 to 14 times below
    the laws' own) the limiters of the orders and of the spoilers, and the pitch integrator's
    stop, act most of the time; the kernel still gives the reference's numbers bit for bit."""
    from dataclasses import replace

    from scenarios.aircraft.data import LAWS

    slow = replace(LAWS, elevator_rate_deg_s=2.0, aileron_rate_deg_s=2.0, rudder_rate_deg_s=2.0)
    runs = _batch("left_elevator", "elevator", manoeuvres=("turn_coordination", "nose_up"))
    p = loop.prepare_aircraft(runs.iloc[:6], law_params=slow)
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    # the limiters act: the spoilers' order moves at its limit, 2 °/s, in some periods
    step = np.abs(np.diff(np.degrees(ref.spoiler), axis=1))
    assert np.isclose(step, 2.0 * p.ts, rtol=1e-9).mean() > 0.05


@needs_kernel
def test_engine_numpy_runs_the_reference_and_gives_the_same_signals():
    runs = _batch("left_inboard_aileron", "aileron", manoeuvres=("cruise",))
    with kernels.use_engine("numpy"):
        sig_n, truth_n = loop.simulate_aircraft(runs)
    sig_c, truth_c = loop.simulate_aircraft(runs)
    for name in ("command", "current", "rod_com", "rod_mon"):
        np.testing.assert_array_equal(getattr(sig_c, name), getattr(sig_n, name), err_msg=name)
    for name, series in sig_n.aircraft.items():
        np.testing.assert_array_equal(sig_c.aircraft[name], series, err_msg=name)
    np.testing.assert_array_equal(truth_c.rod_mm, truth_n.rod_mm)


@needs_kernel
def test_numpy_inner_loops_called_from_the_kernel_equal_numpy():
    rng = np.random.default_rng(3)
    v = rng.uniform(-1.0, 1.0, 1000)
    out = np.empty_like(v)
    kernel._asin(kernel.LOOPS, v, out, v.size, np.zeros(8, np.int64))
    np.testing.assert_array_equal(out, np.arcsin(v))
    kernel._pow_scalar(kernel.LOOPS, v, np.full(1, 3.0), out, v.size, np.zeros(8, np.int64))
    np.testing.assert_array_equal(out, v ** 3)


def test_blocks_of_runs_give_the_batch_results(monkeypatch):
    """A batch simulated in blocks (AircraftPlant.batch_runs) equals it simulated at once,
    Signals and Truth alike, and simulate_signals gives simulate's signals."""
    runs = _batch("left_inboard_aileron", "aileron", manoeuvres=("cruise",)).iloc[:7]
    whole_sig, whole_truth = loop.simulate_aircraft(runs)
    monkeypatch.setattr(loop.AircraftPlant, "batch_runs", 3)
    sig, truth = loop.simulate_aircraft(runs)
    only = loop.AircraftPlant().simulate_signals(runs)
    for got in (sig, only):
        for name in ("command", "current", "rod_com", "rod_mon", "surface", "pressure"):
            np.testing.assert_array_equal(getattr(got, name), getattr(whole_sig, name),
                                          err_msg=name)
        for group in ("aircraft", "rods", "schedule"):
            ref = getattr(whole_sig, group)
            assert list(getattr(got, group)) == list(ref)
            for k, v in ref.items():
                np.testing.assert_array_equal(getattr(got, group)[k], v, err_msg=f"{group} {k}")
        np.testing.assert_array_equal(got.run_ids, whole_sig.run_ids)
    for name in ("rod_mm", "surface_deg", "current_mA", "fault", "onset_s", "magnitude",
                 "rod_fault_mm"):
        np.testing.assert_array_equal(getattr(truth, name), getattr(whole_truth, name),
                                      err_msg=name)
    for group in ("aircraft", "surfaces_deg", "flight"):
        for k, v in getattr(whole_truth, group).items():
            np.testing.assert_array_equal(getattr(truth, group)[k], v, err_msg=f"{group} {k}")
    # the blocks differ in their faults: a jam in one block only, NaN elsewhere
    assert np.isnan(truth.rod_fault_mm[0]).all() and np.isfinite(truth.rod_fault_mm[2, -1])


def test_without_jit_the_aircraft_plant_runs_the_numpy_loop():
    """NUMBA_DISABLE_JIT (debugging, mutation testing) leaves the compiled intrinsics without
    an interpreted form: the plant must fall back to the NumPy loop, not crash."""
    import subprocess
    import sys

    code = ("from scenarios.aircraft import kernel; from scenarios.aircraft.loop import "
            "_warm_kernel; assert not kernel.available(); _warm_kernel(); print('ok')")
    env = {**__import__("os").environ, "NUMBA_DISABLE_JIT": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def _bundled_openblas() -> list[str]:
    """The OpenBLAS libraries NumPy's wheel bundles (numpy.libs), found without the kernel
    module's own look-up, so a fault in that look-up fails the test instead of skipping it."""
    import glob
    import os

    root = os.path.dirname(os.path.dirname(np.__file__))
    return glob.glob(os.path.join(root, "numpy.libs", "*openblas*"))


@pytest.mark.skipif(not _bundled_openblas() or not kernel._jit_enabled(),
                    reason="another NumPy build (no bundled OpenBLAS) or NUMBA_DISABLE_JIT: "
                           "the NumPy reference runs instead")
def test_where_numpy_s_loops_and_blas_are_found_the_kernel_runs():
    """The compiled loop is not silently turned off on a NumPy build that has what it needs:
    the arcsin and power inner loops and dgemv resolved to addresses, NumPy's sin and cos
    equal to the C library's on the sample, the kernel available."""
    loops = kernel.LOOPS
    assert loops is not None and len(loops) == 7
    assert loops[0] and loops[3] and loops[6]          # arcsin, power, dgemv
    assert kernel._self_check()
    assert kernel.available()


def test_the_self_check_refuses_a_cosine_one_ulp_off(monkeypatch):
    """Either function differing from NumPy's on the sample turns the kernel off: here the
    cosine, one ulp off for negative arguments only, which the sample over [-1.5, 1.5]
    includes."""
    import math
    import types

    def off(a):
        return math.nextafter(math.cos(a), 2.0) if a < 0.0 else math.cos(a)

    monkeypatch.setattr(kernel, "math", types.SimpleNamespace(sin=math.sin, cos=off))
    assert not kernel._self_check()


@needs_kernel
@pytest.mark.parametrize("loaded", [True, False], ids=["loaded", "disconnected"])
def test_rod_rates_at_the_stops_equal_the_servo_model(loaded):
    """docs/physics.md §3: at a stop the rod does not move further into it, and it leaves it
    at its own rate however slowly. Rods on either stop with currents for ±0.5 mm/s unloaded
    (below any constant a rate test might compare with, such as 1 mm/s), and with a fast
    current, give scenarios.servo.rod_rate's rates exactly, the kernel's row layout
    included."""
    from scenarios import compiled
    from scenarios.servo import rod_rate

    p = loop.prepare_aircraft(_batch("left_elevator", "elevator", ("cruise",)).iloc[:1])
    pl = p.plant
    n = len(pl.K)
    at_min = np.arange(n) % 2 == 0
    x = np.where(at_min, pl.x_min, pl.x_max)
    # leaving the lower stop, the upper, into the lower, into the upper, ...; one row in
    # eight fast (200 mm/s unloaded)
    direction = np.where(at_min, 1.0, -1.0) * np.tile([1.0, 1.0, -1.0, -1.0], n)[:n]
    speed = np.where(np.arange(n) % 8 == 1, 200.0, 0.5)
    cur = direction * speed / pl.Kci
    flags = np.full(n, loaded)
    want = rod_rate(x, cur, pl, flags)
    out, s, asn = np.empty(n), np.empty(n), np.empty(n)
    kernel._rod_rates(kernel.LOOPS, x, cur, compiled.plant_matrix(pl), flags, out, s, asn,
                      np.zeros(8, np.int64))
    np.testing.assert_array_equal(out, want)
    # the cases are there: slow rods leaving either stop, rods held at either stop
    leaving = (want != 0.0) & (np.abs(want) < 1.0)
    assert (leaving & at_min).any() and (leaving & ~at_min).any()
    assert ((want == 0.0) & at_min).any() and ((want == 0.0) & ~at_min).any()


@needs_kernel
@pytest.mark.parametrize("faults", [("ofc_solid", "hardover"), ("ofc_liquid", "liquid_jam")],
                         ids=["com_osc+cur_force", "cur_add+com_add"])
def test_batches_with_some_fault_inputs_equal_the_reference(faults):
    """The kernel reads each fault input only where its batch has it (flags as
    scenarios.compiled.integrate_block): two batches that each have two of the four (the COM
    oscillation and the forced current; the added current and the added COM) give the
    reference's numbers bit for bit, so no input is read under another's flag."""
    runs = _batch("left_inboard_aileron", "aileron", ("turn_coordination",))
    p = loop.prepare_aircraft(runs[runs.fault.isin(faults)])
    fa = p.faults
    have = [a is not None for a in (fa.com_add, fa.com_osc, fa.cur_add, fa.cur_force)]
    assert have == ([False, True, False, True] if "ofc_solid" in faults
                    else [True, False, True, False])
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)


@needs_kernel
def test_the_spoilers_order_at_the_roll_limit_equals_the_reference(monkeypatch):
    """docs/aircraft.md §4.4: the spoilers follow the aileron order clipped to the aileron's
    travel. The laws never order the full 25° in these manoeuvres (9.3° at most), so the
    travel is cut to 1° here: the spoilers' order then sits on the limit in about half the
    periods, and the kernel gives the reference's numbers bit for bit."""
    from dataclasses import replace

    from scenarios.aircraft.data import AIRCRAFT_ACTUATORS

    monkeypatch.setitem(AIRCRAFT_ACTUATORS, "aileron",
                        replace(AIRCRAFT_ACTUATORS["aileron"], delta_max_deg=1.0))
    runs = _batch("left_elevator", "elevator", ("turn_coordination",)).iloc[:2]
    p = loop.prepare_aircraft(runs)
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    assert np.isclose(np.abs(ref.spoiler), np.radians(1.0), rtol=1e-12).mean() > 0.2


@pytest.mark.parametrize("error", [AttributeError, TypeError, ValueError])
def test_a_numpy_build_without_the_inner_loop_api_turns_the_kernel_off(monkeypatch, error):
    """On a NumPy build whose ufuncs lack the NEP 43 calls (``_resolve_dtypes_and_context``,
    ``_get_strided_loop``) or refuse float64, the look-up of the inner loops gives no
    addresses, so the NumPy reference runs; it does not fail the import."""
    def missing(ufunc, nin):
        raise error("not on this build")

    monkeypatch.setattr(kernel, "_ufunc_loop", missing)
    assert kernel._resolve() == (None, ())


def test_an_unreadable_blas_library_is_passed_over_for_the_next(monkeypatch):
    """_numpy_blas tries numpy.libs' OpenBLAS libraries in name order and keeps the first
    that loads: one that raises OSError is passed over; none loading gives None."""
    tried = []

    def cdll(path):
        tried.append(path)
        if path.endswith("a-openblas.so"):
            raise OSError("unreadable")
        return ("loaded", path)

    monkeypatch.setattr(kernel.glob, "glob", lambda pattern: ["/x/b-openblas.so",
                                                              "/x/a-openblas.so"])
    monkeypatch.setattr(kernel.ctypes, "CDLL", cdll)
    assert kernel._numpy_blas() == ("loaded", "/x/b-openblas.so")
    assert tried == ["/x/a-openblas.so", "/x/b-openblas.so"]
    monkeypatch.setattr(kernel.glob, "glob", lambda pattern: ["/x/a-openblas.so"])
    assert kernel._numpy_blas() is None


def test_without_blas_gemv_the_kernel_is_turned_off(monkeypatch):
    """NumPy's inner loops found but no OpenBLAS (another build): no addresses."""
    monkeypatch.setattr(kernel, "_numpy_blas", lambda: None)
    assert kernel._resolve() == (None, ())


@needs_kernel
def test_a_sideslip_order_and_a_one_millimetre_offset_jam_equal_the_reference():
    """Two inputs the other batches leave at a value where a sign or a constant cannot
    show: the sideslip order of yaw_angle_mode (zero in every other manoeuvre, so the sign
    of the laws' sideslip error β − β_c is seen only here) and an "offset" solid jam of
    exactly +1 mm (the rod jumps at onset, docs/physics.md §5). Kernel and reference bit
    for bit."""
    rows = [single_run("aileron", "yaw_angle_mode", "none", duration_s=8.0, seed=3),
            single_run("aileron", "cruise", "solid_jam", duration_s=8.0, onset_s=1.0, seed=4)]
    runs = pd.concat(rows, ignore_index=True)
    runs.loc[1, "magnitude"] = 1.0
    runs["surface"] = "left_inboard_aileron"
    runs["stream"] = [0, 1]
    runs["run_id"] = ["b0", "b1"]
    p = loop.prepare_aircraft(runs)
    assert np.abs(p.beta_c[0]).max() > np.radians(1.0)
    ref = loop.integrate_reference(p)
    fast = loop.integrate_aircraft(p, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    k0 = int(round(1.0 / p.ts))
    # the jump plus the rod's own motion over one period (under 0.1 mm)
    assert ref.x[1, k0] - ref.x[1, k0 - 1] == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize("missing", ["arcsin", "power"])
def test_a_null_inner_loop_of_either_ufunc_turns_the_kernel_off(monkeypatch, missing):
    """BLAS found, but one of the two inner loops resolved to a NULL address (another
    build): no addresses, whichever of the two it is."""
    real = kernel._ufunc_loop

    def one_null(ufunc, nin):
        info, fields = real(ufunc, nin)
        return info, ([0, *fields[1:]] if ufunc.__name__ == missing else fields)

    monkeypatch.setattr(kernel, "_ufunc_loop", one_null)
    assert kernel._resolve() == (None, ())


@needs_kernel
def test_a_coarser_rod_quantisation_equals_the_reference():
    """The COM acquisitions' quantum is a sensor parameter, 0.01 mm by default, the same
    number as the 0.01 s period: at 0.02 mm the kernel still gives the reference's numbers
    bit for bit, so neither is read for the other."""
    from dataclasses import replace

    from scenarios.params import SENSORS

    coarse = replace(SENSORS, rod_quant_mm=0.02)
    p = loop.prepare_aircraft(_batch("left_elevator", "elevator", ("cruise",)).iloc[:2])
    ref = loop.integrate_reference(p, coarse)
    fast = loop.integrate_aircraft(p, coarse, engine="compiled")
    for name in loop.AircraftTrajectory.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
    steps = np.round(ref.y_com[0] / 0.02, 6)           # the fault-free run's acquisitions
    assert (steps == np.round(steps)).all()
