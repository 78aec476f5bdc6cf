"""A detector that misbehaves on demand, to test how the engine survives faults in the
machinery (tests/campaign_tests/test_machinery_faults.py,
tests/campaign_tests/test_dask_cluster.py).

It raises no alarm, except that on the runs listed in the JSON file *marker* it kills its
own process (``mode="kill"``), raises (``"raise"``) or sleeps ``sleep_s`` seconds
(``"sleep"``). Deleting the marker file makes it well-behaved, so a rerun completes.
Imported by worker processes through ``sys.path`` (loky) or ``PYTHONPATH`` (dask).
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np

from detectors.base import Capabilities, Detection, Detector

MODES = ("kill", "raise", "sleep")


class Misbehaving(Detector):
    """Quiet detector that kills its process, raises or sleeps on the marked runs."""

    capabilities = Capabilities(needs_fit=False)

    def __init__(self, marker="", mode="kill", sleep_s=0.0):
        self.marker = marker
        self.mode = mode
        self.sleep_s = sleep_s

    def validate_params(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")

    def _marked(self, signals) -> list[str]:
        path = Path(self.marker) if self.marker else None
        if path is None or not path.exists():
            return []
        marked = set(json.loads(path.read_text()))
        return [r for r in signals.run_ids if r in marked]

    def _detect(self, signals) -> Detection:
        hit = self._marked(signals)
        if hit and self.mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if hit and self.mode == "raise":
            raise RuntimeError(f"injected failure on {hit}")
        if hit and self.mode == "sleep":
            time.sleep(self.sleep_s)
        shape = (signals.n_runs, signals.n_steps)
        return Detection(alarm=np.zeros(shape, dtype=bool), residual=np.zeros(shape))
