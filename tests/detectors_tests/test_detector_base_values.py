"""detectors/base.py by value, on hand-built inputs: the latching confirmation every built-in
decision ends with, the per-run maxima of the fits, the output contract's rules and the
messages of the base class (docs/design.md §4, docs/write-a-detector.md). Fast: it leads
detectors/base.py's mutation mapping (docs/testing.md)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from detectors import base
from detectors.base import (Capabilities, Detection, Detector, NotFittedError, as_variants,
                            confirm, detection_problems, per_run_maxima, residual_breaches)
from detectors.params import Param
from scenarios.signals import Signals


def _signals(n=3, T=6, surface=np.nan, pressure=np.nan, aircraft=False):
    rng = np.random.default_rng(3)
    full = lambda v: np.full((n, T), v)  # noqa: E731
    return Signals(ts=0.01, command=rng.normal(size=(n, T)), current=full(0.0),
                   rod_com=rng.normal(size=(n, T)), rod_mon=full(0.0), surface=full(surface),
                   pressure=full(pressure), run_ids=np.array([f"r{i}" for i in range(n)]),
                   aircraft={"p": full(0.0)} if aircraft else None,
                   rods={"x": full(0.0)} if aircraft else None)


# ---- confirm: n consecutive steps, then latched --------------------------------------------
def _confirm_by_hand(raw, n):
    out = np.zeros(raw.shape, dtype=bool)
    for i, row in enumerate(raw):
        run, latched = 0, False
        for k, v in enumerate(row):
            run = run + 1 if v else 0
            latched = latched or run >= max(n, 1)
            out[i, k] = latched
    return out


@pytest.mark.parametrize("n", [0, 1, 2, 3, 5])
def test_confirm_equals_a_plain_loop_on_every_pattern_of_seven_steps(n):
    raw = np.array(list(itertools.product([False, True], repeat=7)))      # 128 runs
    got = confirm(raw, n)
    assert got.dtype == np.bool_ and got.shape == raw.shape
    np.testing.assert_array_equal(got, _confirm_by_hand(raw, n))


def test_confirm_boundary_n_minus_one_against_n_steps_and_latching():
    raw = np.array([[0, 1, 1, 0, 1, 1, 1, 0, 0],           # 2 then 3 steps beyond
                    [1, 1, 1, 0, 0, 0, 0, 0, 0],           # 3 at once, then never again
                    [0, 0, 0, 0, 0, 0, 1, 1, 1]], bool)    # 3 at the very end
    got = confirm(raw, 3)
    assert got[0].tolist() == [False] * 6 + [True] * 3      # alarm on the 3rd step, latched
    assert got[1].tolist() == [False, False] + [True] * 7   # kept after raw falls back
    assert got[2].tolist() == [False] * 8 + [True]          # an alarm at the last step
    assert not confirm(raw, 4)[0].any() and not confirm(raw, 4)[2].any()


# ---- per_run_maxima ------------------------------------------------------------------------
def test_per_run_maxima_reduces_each_run_over_its_steps_in_blocks():
    sig = _signals(n=5, T=4)
    blocks = []

    def stats(block):
        blocks.append(block.run_ids.tolist())
        return {"c": block.command, "neg": -block.rod_com}

    got = per_run_maxima(sig, stats, block_runs=2)
    assert blocks == [["r0", "r1"], ["r2", "r3"], ["r4"]]
    np.testing.assert_array_equal(got["c"], sig.command.max(axis=1))
    np.testing.assert_array_equal(got["neg"], (-sig.rod_com).max(axis=1))
    blocks.clear()
    per_run_maxima(sig, stats)                                # the module's default block
    assert blocks == [[f"r{i}" for i in range(5)]] and base.FIT_BLOCK_RUNS == 25
    blocks.clear()
    per_run_maxima(sig, stats, block_runs=-3)                 # at least one run a block
    assert len(blocks) == 5


# ---- the output contract -------------------------------------------------------------------
def test_residual_breaches_allow_leading_nan_only():
    r = np.array([[np.nan, np.nan, 1.0, 2.0],
                  [1.0, np.nan, 1.0, 1.0],
                  [np.nan, np.nan, np.nan, np.nan],
                  [0.0, np.inf, -np.inf, 0.0]])
    np.testing.assert_array_equal(residual_breaches(r), [[0, 0, 0, 0], [0, 1, 0, 0],
                                                         [0, 0, 0, 0], [0, 1, 1, 0]])
    np.testing.assert_array_equal(residual_breaches(np.array([np.nan, 1.0, np.inf])),
                                  [False, False, True])
    # an all-finite residual (the usual case, checked in one pass): nothing refused
    finite = residual_breaches(np.array([[0.0, -1e300, 5.0], [1e-300, 2.0, 0.5]]))
    assert finite.dtype == np.bool_ and finite.shape == (2, 3) and not finite.any()


def test_detection_problems_name_each_rule_broken():
    ok = Detection(alarm=np.zeros((2, 3), bool), residual=np.zeros((2, 3)))
    assert detection_problems(ok, 2, 3) == []
    assert detection_problems(Detection(alarm=ok.alarm, residual=ok.residual,
                                        estimate=np.zeros((2, 3))), 2, 3) == []
    wrong = detection_problems(ok, 2, 4)
    assert len(wrong) == 2 and "alarm must have the shape" in wrong[0] \
        and "(2, 4), got (2, 3)" in wrong[0] and "residual must have the shape" in wrong[1]
    est = Detection(alarm=ok.alarm, residual=ok.residual, estimate=np.zeros((2, 2)))
    assert detection_problems(est, 2, 3) == [
        "estimate, when given, must have the shape of the signals (n_runs, n_steps) = "
        "(2, 3), got (2, 2)"]
    ints = type("D", (), {"alarm": np.zeros((2, 3), int), "residual": np.zeros((2, 3), int)})()
    got = detection_problems(ints, 2, 3)
    assert got == ["alarm must be a bool array, got dtype int64",
                   "residual must be a float array, got dtype int64"]
    r = np.zeros((2, 3))
    r[1, 1], r[1, 2] = np.nan, np.inf
    nan = detection_problems(Detection(alarm=ok.alarm, residual=r), 2, 3)
    assert nan == ["residual must be finite floats (NaN is allowed only before the first "
                   "non-NaN sample of a run (warm-up)): got nan at run 1, step 1 (1 of 2 runs "
                   "affected)"]
    r[1, 1] = 0.0
    r[0, 0] = np.inf
    inf = detection_problems(Detection(alarm=ok.alarm, residual=r), 2, 3)
    assert inf == ["residual must be finite floats (±inf is never allowed): got inf at run 0, "
                   "step 0 (2 of 2 runs affected)"]


def test_detection_checks_its_own_arrays():
    with pytest.raises(TypeError, match="bool array, got dtype float64"):
        Detection(alarm=np.zeros((1, 2)), residual=np.zeros((1, 2)))
    with pytest.raises(ValueError, match=r"alarm \(1, 2\) and residual \(1, 3\)"):
        Detection(alarm=np.zeros((1, 2), bool), residual=np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"must both be \(n_runs, n_steps\)"):
        Detection(alarm=np.zeros(2, bool), residual=np.zeros(2))
    assert Detection(alarm=np.zeros((1, 2), bool), residual=np.zeros((1, 2))).estimate is None


def test_as_variants_names_each_variant_under_its_detector():
    d = Detection(alarm=np.zeros((1, 2), bool), residual=np.zeros((1, 2)))
    assert as_variants("m", d) == {"m": d}
    assert list(as_variants("m", {"a": d, "b": d})) == ["m[a]", "m[b]"]
    with pytest.raises(TypeError, match="detector 'm' variant 'b' returned int, expected "
                                        "Detection"):
        as_variants("m", {"a": d, "b": 3})
    with pytest.raises(TypeError, match="detector 'm' returned list; expected a Detection or "
                                        "a mapping"):
        as_variants("m", [d])


# ---- the base class ------------------------------------------------------------------------
class _Learner(Detector):
    capabilities = Capabilities(needs_surface_sensor=True)
    parameters = (Param("gain", "float", gt=0.0, doc="a gain"),
                  Param("width", "int", ge=1, doc="a width"))

    def __init__(self, gain=1.0, width=2):
        self.gain, self.width = gain, width

    def _fit(self, signals):
        self.level_ = float(np.max(signals.command))
        self._scratch = 1

    def _detect(self, signals):
        r = signals.command / self.level_
        return Detection(alarm=r > 1.0, residual=r)


class _NoFit(Detector):
    capabilities = Capabilities(needs_fit=False, needs_pressure_sensor=True,
                                needs_aircraft=True)


def test_the_base_class_fits_then_detects_and_says_what_is_missing():
    det = _Learner(gain=2.0)
    assert det.get_params() == {"gain": 2.0, "width": 2}
    assert repr(det) == "_Learner(gain=2.0, width=2)"
    assert not det.is_fitted and det.fitted_state() == {}
    with pytest.raises(NotFittedError, match=r"_Learner.detect\(\) called before fit\(\)"):
        det.detect(_signals(surface=0.0))
    with pytest.raises(ValueError, match="needs a surface position sensor"):
        det.fit(_signals())                                   # surface all NaN
    sig = _signals(surface=0.0)
    assert det.fit(sig) is det and det.is_fitted
    assert det.fitted_state() == {"level_": float(np.max(sig.command))}   # not _scratch
    out = det.detect(sig)
    np.testing.assert_array_equal(out.residual, sig.command / det.level_)
    with pytest.raises(ValueError, match=r"^_Learner: gain"):
        _Learner(gain=-1.0).fit(sig)
    with pytest.raises(ValueError, match=r"^_Learner has 2 invalid parameters:\n  - gain"):
        _Learner(gain=-1.0, width=0).fit(sig)


def test_a_detector_without_fit_checks_pressure_and_aircraft_signals():
    det = _NoFit()
    assert det.is_fitted and det.get_params() == {}
    with pytest.raises(ValueError, match=r"chamber pressure sensor; enable it"):
        det.detect(_signals(aircraft=True))
    with pytest.raises(ValueError, match=r"needs the aircraft-level signals"):
        det.detect(_signals(pressure=1.0))
    with pytest.raises(NotImplementedError, match="_NoFit must implement _detect"):
        det.detect(_signals(pressure=1.0, aircraft=True))
    assert Capabilities() == Capabilities(needs_fit=True, needs_surface_sensor=False,
                                          needs_pressure_sensor=False, causal=True,
                                          needs_aircraft=False)


def test_capabilities_and_detections_are_frozen_and_half_an_aircraft_is_refused():
    from dataclasses import FrozenInstanceError, replace

    with pytest.raises(FrozenInstanceError):
        Capabilities().needs_fit = False
    d = Detection(alarm=np.zeros((1, 2), bool), residual=np.zeros((1, 2)))
    with pytest.raises(FrozenInstanceError):
        d.alarm = d.alarm
    full = _signals(pressure=1.0, aircraft=True)
    for half in (replace(full, rods=None), replace(full, aircraft=None)):
        with pytest.raises(ValueError, match=r"needs the aircraft-level signals"):
            _NoFit().detect(half)
