"""Third-party detectors at the start of a campaign: their fit, and a batch-invariance
check on a few learning runs, both bounded by ``[runner] run_timeout_s`` when it is set.

A campaign cuts its runs into chunks of any size, so a detector's result for a run must not
depend on the other runs of its chunk. The built-in detectors are checked by the test suite
(:func:`detectors.testing.check_detector`); a third-party detector (:func:`third_party`) is
checked on :data:`BATCH_CHECK_RUNS` learning runs before the campaign starts
(:func:`batch_dependence`; :func:`campaign.runner.check_batch_invariance` refuses what it
finds). With a time limit, what runs a third-party detector's code before the first chunk
(:func:`fit_detector`, the check) runs in a worker process that is stopped at the limit, so
that a detector that hangs cannot hang the start (docs/execution.md).
"""

from __future__ import annotations

import numpy as np

from detectors.base import read_only
from scenarios import compiled as kernels
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


def fit_detector(det, signals: Signals, engine: str, run_timeout_s: float | None = None):
    """*det* fitted on the learning *signals*, handed read-only
    (:func:`detectors.base.read_only`), with the kernels of *engine*; returns the fitted
    detector. With *run_timeout_s*, a third-party detector is fitted in a worker process
    stopped after that limit for each learning run, and the fitted detector comes back from
    it (a detector pickles: the workers receive it so); over the limit,
    :class:`campaign.execute.TimeLimitExceeded`. Raises what ``fit`` raises."""
    from .execute import TimeLimitExceeded, call_bounded

    if run_timeout_s is None or not third_party(det):
        return _fitted(det, signals, engine)
    limit = run_timeout_s * signals.n_runs
    try:
        return call_bounded(_fitted, det, signals, engine, limit_s=limit)
    except TimeLimitExceeded:
        raise TimeLimitExceeded(f"fit did not finish within {limit:g} s (run_timeout_s = "
                                f"{run_timeout_s:g} s for each of the {signals.n_runs} "
                                "learning runs); its worker process was stopped") from None


def _fitted(det, signals: Signals, engine: str):
    """*det* fitted on read-only *signals* with the kernels of *engine* (returned, so that
    it can come back from a worker process)."""
    with kernels.use_engine(engine):
        det.fit(read_only(signals))
    return det
