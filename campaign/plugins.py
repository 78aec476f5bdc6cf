"""The start-up check of third-party detectors: batch invariance on a few learning runs.

A campaign cuts its runs into chunks of any size, so a detector's result for a run must not
depend on the other runs of its chunk. The built-in detectors are checked by the test suite
(:func:`detectors.testing.check_detector`); a third-party detector (:func:`third_party`) is
checked on :data:`BATCH_CHECK_RUNS` learning runs before the campaign starts
(:func:`batch_dependence`; :func:`campaign.runner.check_batch_invariance` refuses what it
finds).
"""

from __future__ import annotations

import numpy as np

from scenarios.signals import Signals

#: Learning runs the sampled batch-invariance check of third-party detectors uses
#: (:func:`batch_dependence`): each alone, together and in reverse order.
BATCH_CHECK_RUNS = 4


def third_party(det) -> bool:
    """Whether *det* is a third-party (plugin) detector: its class lives outside the
    :mod:`detectors` package, whose built-in detectors the test suite checks."""
    return type(det).__module__.split(".")[0] != "detectors"


def batch_check_runs(n: int) -> np.ndarray:
    """Indices of the :data:`BATCH_CHECK_RUNS` runs, spread over a learning plan of *n*
    runs, the check uses."""
    return np.unique(np.linspace(0, n - 1, min(BATCH_CHECK_RUNS, n)).round().astype(int))


def batch_dependence(detectors: dict, signals: Signals, engine: str, *,
                     run_timeout_s: float | None = None, log=print):
    """The first fitted detector of *detectors* (label → Detector) whose result for a run
    of *signals* depends on the other runs of its batch, as ``(label, detector, what
    differs)``; None when none does.

    A sampled check, cheap enough for every campaign start: the runs of *signals* (the
    :func:`batch_check_runs` of the learning set) each alone, all together and in reverse
    order (:func:`detectors.testing.batch_invariance_failure`, the ``batch_invariance``
    check of ``check_detector``), with the kernels of *engine*. It catches what depends on
    the batch as a whole (a normalisation by the chunk's mean or maximum, a state shared
    between runs); it is not a proof. A detector that raises on these runs is left to the
    campaign, which records its failures per run.

    With *run_timeout_s* (``[runner] run_timeout_s``) each detector's check runs in a worker
    process stopped after that limit for each detection of a run (three per run: together,
    alone, in reverse order): a detector that hangs is left to the campaign, whose runs are
    stopped at the limit, and a note on *log* says so (docs/execution.md).
    """
    from detectors.testing import batch_invariance_failure

    from .execute import TimeLimitExceeded, call_bounded

    limit = None if run_timeout_s is None else run_timeout_s * 3 * signals.n_runs
    for label, det in detectors.items():
        try:
            failure = call_bounded(batch_invariance_failure, det, signals, engine,
                                   limit_s=limit)
        except TimeLimitExceeded:
            log(f"note: detector {label!r} did not finish its batch-invariance check within "
                f"{limit:g} s (3 × {signals.n_runs} runs × run_timeout_s = {run_timeout_s:g} "
                "s); left to the campaign, whose runs are stopped at the limit")
            continue
        except Exception:  # noqa: BLE001 - a failing detect is recorded per run later
            continue
        if failure is not None:
            return label, det, failure
    return None
