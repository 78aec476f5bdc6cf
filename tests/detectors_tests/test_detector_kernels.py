"""The compiled recursions of the comb-interval and chen-local detectors against their NumPy
reference (detectors/builtin/comb_interval.py, detectors/builtin/chen_local.py)."""

from __future__ import annotations


import numpy as np
import pandas as pd
import pytest

from detectors.registry import make_detector
from scenarios import compiled as kernels
from scenarios.catalog import MANOEUVRES
from scenarios.simulate import simulate, single_run

FAULTS = ["none", "runaway", "hardover", "liquid_jam", "solid_jam", "disconnection",
          "ofc_liquid", "ofc_solid"]


@pytest.fixture(scope="module")
def batch():
    """(learning signals, evaluation signals): 8 fault-free learning runs and 16 runs of
    every fault type (each alarm path) mixed with fault-free runs, 20 s."""
    rows = [single_run("elevator", man, f, seed=i, onset_s=5.0 + 0.5 * i, duration_s=20.0)
            for i, (f, man) in enumerate(zip(FAULTS * 2, ["cruise", "nose_up"] * 8))]
    ev = pd.concat(rows, ignore_index=True)
    ev["stream"] = np.arange(len(ev))
    ev["run_id"] = [f"e{i}" for i in range(len(ev))]
    learn = pd.concat([single_run("elevator", man, "none", seed=100 + i, duration_s=20.0)
                       for i, man in enumerate(MANOEUVRES + MANOEUVRES[:2])],
                      ignore_index=True)
    learn["stream"] = np.arange(len(learn))
    learn["run_id"] = [f"l{i}" for i in range(len(learn))]
    return simulate(learn)[0], simulate(ev)[0]


def _both(det, call):
    """call(det) with the NumPy reference, then compiled."""
    with kernels.use_engine("numpy"):
        ref = call(det)
    with kernels.use_engine("compiled"):
        fast = call(det)
    return ref, fast


@pytest.fixture(scope="module")
def interval(batch):
    learn, _ = batch
    with kernels.use_engine("numpy"):
        return make_detector("comb-interval").fit(learn)


def test_interval_predictor_is_bit_identical_to_numpy_with_the_same_libm(batch, interval,
                                                                          libm_numpy):
    # same operations in the same order (g^c through the plant's rate law, eq. 14–15, the
    # dead zone of eq. 18, the F_a filter as scipy's lfilter evaluates it): equal bits
    _, ev = batch
    (y0, xc0, xr0), (y1, xc1, xr1) = _both(interval, lambda d: d.predict(ev))
    np.testing.assert_array_equal(y1, y0)
    np.testing.assert_array_equal(xc1, xc0)
    np.testing.assert_array_equal(xr1, xr0)
    r0, r1 = _both(interval, lambda d: d.interval_residual(ev))
    np.testing.assert_array_equal(r1, r0)
    assert np.count_nonzero(r0) > 0          # the residual is exercised, not all in the dead zone
    d0, d1 = _both(interval, lambda d: d.detect(ev))
    assert list(d1) == list(d0)
    for name in d0:
        np.testing.assert_array_equal(d1[name].residual, d0[name].residual, err_msg=name)
        np.testing.assert_array_equal(d1[name].alarm, d0[name].alarm, err_msg=name)
    assert any(d0[name].alarm[:, -1].any() for name in d0)     # alarms are compared too


def test_interval_compiled_matches_plain_numpy_within_last_bit_noise(batch, interval):
    # NumPy's SIMD arcsin (inside the hinge moment of g^c) may differ from the C library's
    # by 1 ulp; the predictor is contracting (eq. 17) so the difference stays at the 1e-15 mm
    # level (measured ≤ 1e-14 of the normalised residual). 1e-9 is far below any threshold
    # crossing that matters; alarms are compared exactly.
    _, ev = batch
    d0, d1 = _both(interval, lambda d: d.detect(ev))
    for name in d0:
        np.testing.assert_allclose(d1[name].residual, d0[name].residual, rtol=0, atol=1e-9,
                                   err_msg=name)
        np.testing.assert_array_equal(d1[name].alarm, d0[name].alarm, err_msg=name)


def test_interval_run_alone_equals_the_same_run_in_a_block(batch, interval):
    _, ev = batch
    with kernels.use_engine("compiled"):
        block = interval.detect(ev)
        for j in (0, 5, ev.n_runs - 1):
            alone = interval.detect(ev.take([j]))
            for name in block:
                np.testing.assert_array_equal(alone[name].residual[0], block[name].residual[j])


@pytest.fixture(scope="module")
def chen(batch):
    learn, _ = batch
    with kernels.use_engine("numpy"):
        return make_detector("chen-local").fit(learn)


def test_chen_estimator_is_bit_identical_to_numpy(batch, chen):
    # the estimator uses no transcendental function: + − × ÷ in the reference's order give
    # the same bits whatever NumPy's SIMD routines
    _, ev = batch
    f0, f1 = _both(chen, lambda d: d.estimate(ev))
    np.testing.assert_array_equal(f1, f0)
    assert np.max(np.abs(f0)) > chen.thresholds_["solid"]    # faults move the estimate
    d0, d1 = _both(chen, lambda d: d.detect(ev))
    for name in d0:
        np.testing.assert_array_equal(d1[name].residual, d0[name].residual, err_msg=name)
        np.testing.assert_array_equal(d1[name].alarm, d0[name].alarm, err_msg=name)


def test_chen_run_alone_equals_the_same_run_in_a_block(batch, chen):
    _, ev = batch
    with kernels.use_engine("compiled"):
        block = chen.estimate(ev)
        for j in (0, 3, ev.n_runs - 1):
            np.testing.assert_array_equal(chen.estimate(ev.take([j]))[0], block[j])


@pytest.mark.parametrize("checks", [("loop", "com_mon", "surface"), ("surface",), ("com_mon",)])
def test_position_monitor_decision_is_bit_identical_to_numpy(batch, checks, libm_numpy):
    # |r|/τ, the maximum over the checks and the confirmation counter: the same operations
    # as the NumPy path; its nominal model agrees bit for bit with the same arcsin
    # (tests/scenarios_tests/test_kernels.py)
    learn, ev = batch
    with kernels.use_engine("numpy"):
        det = make_detector("position-monitor", {"checks": list(checks)}).fit(learn)
    d0, d1 = _both(det, lambda d: d.detect(ev))
    np.testing.assert_array_equal(d1.residual, d0.residual)
    np.testing.assert_array_equal(d1.alarm, d0.alarm)
    assert d0.alarm[:, -1].any() and not d0.alarm[:, -1].all()   # both outcomes compared
