"""Every registered detector (built-in and installed third-party) passes the public
conformance checks of detectors.testing, one test id per check, and the checks catch
breaches: every breach of a detector is reported, not only the first."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from detectors import Detection, Detector, available_detectors, make_detector
from detectors.base import Capabilities
from detectors.testing import (
    CHECKS,
    DetectorCheckError,
    check_detector,
    detector_checks,
    parametrize_with_checks,
)

#: Every registered detector with its defaults, and the optional variants of
#: vanek-geometric (the [hinf] extra is part of [test]): the LPV filter affine in VCAS and
#: altitude of [VANEK] §5, the H∞ post-filter and the one-step H∞ filter of [VANEK] §3.
CONFORMANCE = {name: make_detector(name) for name in sorted(available_detectors())}
CONFORMANCE["vanek-geometric[optional-variants]"] = make_detector(
    "vanek-geometric", {"variants": ["lpv-affine", "lti-hinf", "one-step"]})
# thresholds calibrated by detectors.calibrate (docs/thresholds.md): the calibration is
# learned state, stored as data
for _name in ("position-monitor", "comb-interval"):
    CONFORMANCE[f"{_name}[evt]"] = make_detector(_name, {"threshold_method": "evt",
                                                         "target_fa_per_run": 0.01})


@parametrize_with_checks(CONFORMANCE)
def test_every_registered_detector_passes_every_check(check):
    check()


class _Peeking(Detector):
    """Breaks causality: its residual at step k uses the maximum of the whole run."""

    capabilities = Capabilities(needs_fit=False)

    def _detect(self, signals):
        r = np.abs(signals.rod_com - signals.command)
        norm = np.broadcast_to(r.max(axis=1, keepdims=True), r.shape).copy()
        return Detection(alarm=norm >= 1.0, residual=norm)


class _BatchDependent(Detector):
    """Breaks batch invariance: normalises by the largest error of the whole batch."""

    capabilities = Capabilities(needs_fit=False)

    def _detect(self, signals):
        r = np.abs(signals.rod_com - signals.command)
        norm = r / r.max()
        return Detection(alarm=norm >= 1.0, residual=norm)


class _Mutating(Detector):
    """Breaks the read-only rule: overwrites the command it is given."""

    capabilities = Capabilities(needs_fit=False)

    def _detect(self, signals):
        signals.command[:, 0] += 1.0
        z = np.zeros(signals.command.shape)
        return Detection(alarm=z > 0, residual=z)


class _ChangesParams(Detector):
    """Breaks the constructor rule: __init__ transforms its parameter."""

    capabilities = Capabilities(needs_fit=False)

    def __init__(self, gain=1.0):
        self.gain = 2.0 * gain

    def _detect(self, signals):
        z = np.zeros(signals.command.shape)
        return Detection(alarm=z > 0, residual=z)


@pytest.mark.parametrize("cls, check", [
    (_Peeking, "causality"),
    (_BatchDependent, "batch invariance"),
    (_Mutating, "modified the signals"),
    (_ChangesParams, "__init__ must store"),
])
def test_check_detector_names_the_broken_rule(cls, check):
    with pytest.raises(DetectorCheckError, match=check):
        check_detector(cls(), duration_s=20.0)


class _TwoBreaches(Detector):
    """Breaks two rules at once: writes into the last sample of the MON rod signal it is
    given (read-only rule) and, from step 50 on, divides its residual by the sum over the
    batch of each run's largest error in steps 0–49 (batch invariance: alone, a run's sum is
    its own maximum). It stays causal (step k uses steps ≤ k) and never alarms."""

    capabilities = Capabilities(needs_fit=False)

    def _detect(self, signals):
        r = np.abs(signals.rod_com - signals.command)
        signals.rod_mon[:, -1] = 0.0
        norm = r.copy()
        norm[:, 50:] /= r[:, :50].max(axis=1).sum()
        return Detection(alarm=np.zeros(r.shape, dtype=bool), residual=norm)


def test_check_detector_reports_every_breach_with_run_and_step():
    with pytest.raises(DetectorCheckError) as info:
        check_detector(_TwoBreaches(), duration_s=20.0)
    err = info.value
    assert [name for name, _ in err.failures] == ["detect_leaves_signals", "batch_invariance"]
    text = str(err)
    assert text.startswith("_TwoBreaches failed 2 checks:")
    # the mutation: the signal, the first run (index and id) and step it changed
    assert "detect() modified the signals it was given (rod_mon, first at run 0 (eval-0), " \
           f"step {2000 - 1})" in text
    # the batch dependence: run 0 alone differs from run 0 in the batch, first at step 50
    assert "batch invariance (run 0 (eval-0) alone): detector residual differs, first at " \
           "run 0 (eval-0), step 50" in text
    # the error crosses process boundaries (workers) intact
    again = pickle.loads(pickle.dumps(err))
    assert again.failures == err.failures and str(again) == text


def test_a_failing_fit_is_reported_in_every_check_that_needs_it():
    class FitFails(_Peeking):
        capabilities = Capabilities(needs_fit=True)

        def _fit(self, signals):
            raise ValueError("no learning today")

    with pytest.raises(DetectorCheckError) as info:
        check_detector(FitFails())
    failed = dict(info.value.failures)
    needs_fit = [n for n in CHECKS if n.startswith(("fit_", "detect_", "output_", "determinism",
                                                     "batch_", "causality", "pickle_",
                                                     "state_"))]
    assert sorted(failed) == sorted(needs_fit)
    assert all("fit() raised ValueError: no learning today" in failed[n] for n in needs_fit)


def test_detector_checks_give_one_named_check_each():
    det = _Peeking()
    checks = dict(detector_checks(det))
    # needs_fit=False: no NotFittedError and no learned-state check
    assert list(checks) == [n for n in CHECKS if n not in ("not_fitted_error",
                                                           "fit_stores_state")]
    checks["determinism"]()                                # passes: raises nothing
    with pytest.raises(DetectorCheckError, match="failed check causality") as info:
        checks["causality"]()
    assert [n for n, _ in info.value.failures] == ["causality"]


def test_parametrize_with_checks_gives_one_test_id_per_check():
    mark = parametrize_with_checks([_Peeking(), _Peeking(), _Mutating()])
    ids = [p.id for p in mark.args[1]]
    assert mark.args[0] == "check"
    assert ids[0] == "_Peeking[0]-init_stores_params"
    assert "_Peeking[1]-causality" in ids and "_Mutating-detect_leaves_signals" in ids
    assert len(ids) == len(set(ids)) == 3 * 14


@pytest.mark.slow
def test_bench_reports_the_cost_of_every_registered_detector():
    from campaign.tools.bench import detector_costs

    from detectors.registry import BUILTIN

    costs = detector_costs(n_runs=2, duration_s=20.0, learning_runs=2)
    assert {(c["detector"], c["engine"]) for c in costs} == {
        (name, engine) for name in BUILTIN for engine in ("compiled", "numpy")}
    assert all(np.isfinite(c["ns_per_run_step"]) and c["ns_per_run_step"] > 0 for c in costs)


class NeedsSurface(Detector):
    """Reads the surface position sensor (module level: the checks pickle it)."""

    capabilities = Capabilities(needs_fit=False, needs_surface_sensor=True)

    def _detect(self, signals):
        r = np.abs(signals.surface) / 100.0
        return Detection(alarm=r >= 1.0, residual=r)


def test_check_detector_applies_the_campaign_compatibility_rule():
    """A detector that needs a surface position sensor is not checked on a surface that has
    none: check_detector says so with the campaign's own message, instead of reporting the
    detector's refusal of NaN signals as breaches."""
    with pytest.raises(RuntimeError, match="'NeedsSurface' needs a surface position sensor, "
                                           "which the aileron has none of"):
        check_detector(NeedsSurface(), surface="aileron")
    check_detector(NeedsSurface(), surface="elevator")      # the elevator has one
