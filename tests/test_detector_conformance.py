"""Every registered detector (built-in and installed third-party) passes the public
conformance checks of detectors.testing.check_detector, and the checks catch breaches."""

from __future__ import annotations

import numpy as np
import pytest

from detectors import Detection, Detector, available_detectors, make_detector
from detectors.base import Capabilities
from detectors.testing import DetectorCheckError, check_detector


@pytest.mark.parametrize("name", sorted(available_detectors()))
def test_every_registered_detector_passes_check_detector(name):
    check_detector(make_detector(name))


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


def test_bench_reports_the_cost_of_every_registered_detector():
    from campaign.bench import detector_costs

    from detectors.registry import BUILTIN

    costs = detector_costs(n_runs=2, duration_s=20.0, learning_runs=2)
    assert {(c["detector"], c["engine"]) for c in costs} == {
        (name, engine) for name in BUILTIN for engine in ("compiled", "numpy")}
    assert all(np.isfinite(c["ns_per_run_step"]) and c["ns_per_run_step"] > 0 for c in costs)


def test_vanek_optional_variants_pass_check_detector():
    # the optional variants of vanek-geometric (the [hinf] extra is part of [test]): the LPV
    # filter affine in VCAS and altitude of [VANEK] §5, the H∞ post-filter and the one-step
    # H∞ filter of [VANEK] §3
    check_detector(make_detector("vanek-geometric",
                                 {"variants": ["lpv-affine", "lti-hinf", "one-step"]}))
