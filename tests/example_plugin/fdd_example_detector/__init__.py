"""A complete third-party detector: a filtered loop-error monitor.

The servo-loop error e = u − y_COM (order minus COM rod acquisition) is low-pass filtered,
ε_k = a·ε_{k−1} + (1 − a)·e_k (unit static gain), and compared with a threshold learned on
fault-free runs: τ = safety × max |ε|. A runaway or a jam makes the loop error grow.
"""

import numpy as np
from scipy.signal import lfilter

from detectors import Capabilities, Detection, Detector, confirm


class LoopErrorMonitor(Detector):
    """Filtered loop-error monitor.

    Parameters
    ----------
    pole : float
        Pole a of the first-order residual filter, 0 ≤ a < 1.
    safety : float
        Threshold = safety × largest filtered fault-free loop error (> 1).
    confirm_s : float
        Confirmation time [s].
    """

    capabilities = Capabilities(needs_fit=True, causal=True)

    def __init__(self, pole=0.9, safety=1.5, confirm_s=0.05):
        self.pole = pole
        self.safety = safety
        self.confirm_s = confirm_s

    def validate_params(self):
        if not 0.0 <= self.pole < 1.0:
            raise ValueError(f"pole must be in [0, 1), got {self.pole!r}")
        if not self.safety > 1.0:
            raise ValueError(f"safety must be > 1, got {self.safety!r}")

    def _filtered_error(self, signals):
        error = signals.command - signals.rod_com
        a = self.pole
        return lfilter([1.0 - a], [1.0, -a], error, axis=1)   # causal, per run

    def _fit(self, signals):
        self.threshold_mm_ = float(self.safety * np.max(np.abs(self._filtered_error(signals))))

    def _detect(self, signals):
        norm = np.abs(self._filtered_error(signals)) / self.threshold_mm_
        n_confirm = int(round(self.confirm_s / signals.ts)) + 1
        return Detection(alarm=confirm(norm >= 1.0, n_confirm), residual=norm)
