"""Third-party detectors that break the contract in one way each, to test what the engine
does with them (tests/campaign_tests/test_plugin_contract.py). Registered per test through
``detectors.registry.BUILTIN`` with their ``module:Class`` text; their module lives outside
the ``detectors`` package, so the runner treats them as third-party detectors."""

from __future__ import annotations

import threading
import time

import numpy as np

from detectors.base import Capabilities, Detection, Detector


class _Quiet(Detector):
    """No alarm, residual 0.5 everywhere (well-behaved base of the others)."""

    capabilities = Capabilities(needs_fit=False)

    def _output(self, signals) -> tuple[np.ndarray, np.ndarray]:
        shape = (signals.n_runs, signals.n_steps)
        return np.zeros(shape, dtype=bool), np.full(shape, 0.5)

    def _detect(self, signals) -> Detection:
        alarm, residual = self._output(signals)
        return Detection(alarm=alarm, residual=residual)


class Subsampled(_Quiet):
    """Returns every *every*-th sample (a decimating detector that forgot to hold its
    output), or all but the last *cut* samples."""

    def __init__(self, every=1, cut=0):
        self.every = every
        self.cut = cut

    def _output(self, signals):
        alarm, residual = super()._output(signals)
        keep = slice(0, signals.n_steps - self.cut, self.every)
        return alarm[:, keep], residual[:, keep]


class BadResidual(_Quiet):
    """Residual with NaN for the first *warm_up* steps of every run (allowed), and
    *value* (a number, or ``"inf"``, ``"nan"``: campaign files hold finite numbers only)
    at step *step* of the runs of ids *runs* (every run when empty): a breach unless
    *value* is finite."""

    def __init__(self, warm_up=0, value=0.5, step=100, runs=()):
        self.warm_up = warm_up
        self.value = value
        self.step = step
        self.runs = runs

    def _output(self, signals):
        alarm, residual = super()._output(signals)
        residual[:, :self.warm_up] = np.nan
        hit = np.ones(signals.n_runs, bool)
        if self.runs and signals.run_ids is not None:
            hit = np.isin(np.asarray(signals.run_ids).astype(str), list(self.runs))
        residual[hit, self.step] = float(self.value)
        return alarm, residual


class NaNLater(_Quiet):
    """A numerical blow-up: the residual of every run turns NaN from the middle of the run
    on, and stays so (a breach: NaN is allowed only before a run's first value); no alarm."""

    def _output(self, signals):
        alarm, residual = super()._output(signals)
        residual[:, signals.n_steps // 2:] = np.nan
        return alarm, residual


class BatchMean(_Quiet):
    """Normalises each run's loop error by the mean over the batch: its results depend on
    which runs share a chunk."""

    def _output(self, signals):
        alarm, _ = super()._output(signals)
        error = np.abs(np.asarray(signals.command) - np.asarray(signals.rod_com))
        return alarm, error / (2.0 * error.mean() + 1e-9)


class Offline(_Quiet):
    """Declares itself non-causal (an offline method)."""

    capabilities = Capabilities(needs_fit=False, causal=False)


class FitFails(_Quiet):
    """Needs fit, and its fit raises a RuntimeError (not a ValueError)."""

    capabilities = Capabilities(needs_fit=True)

    def _fit(self, signals):
        raise RuntimeError("singular matrix in the threshold estimate")


class FitFailsLate(_Quiet):
    """Fits on a worker thread beside the others (``fit_concurrently``), and its fit raises
    after 0.5 s: later than a fit that fails at once."""

    capabilities = Capabilities(needs_fit=True, fit_concurrently=True)

    def _fit(self, signals):
        time.sleep(0.5)
        raise RuntimeError("late failure of a concurrent fit")


#: Met by two fits at once (:class:`FitsTogether`); a test resets it before use.
FIT_BARRIER = threading.Barrier(2, timeout=20)


class FitsTogether(_Quiet):
    """Fits on a worker thread (``fit_concurrently``) and waits in its fit for a second
    detector's fit to reach :data:`FIT_BARRIER`: two of them fit only when they fit at the
    same time (one at a time, the first raises threading.BrokenBarrierError)."""

    capabilities = Capabilities(needs_fit=True, fit_concurrently=True)

    def _fit(self, signals):
        FIT_BARRIER.wait()


class ScheduleMargin(_Quiet):
    """A margin that is an analytic function of the run variables: |r|/τ = measured VCAS /
    *limit_kt* at every sample (measured VCAS = VCAS·(1 + d_vcas), docs/physics.md §4),
    alarm where it is ≥ 1; so a fault-free run alarms exactly when
    VCAS·(1 + d_vcas) ≥ *limit_kt*, a probability known in closed form over the campaign's
    envelope box (tests/campaign_tests/test_certify.py)."""

    def __init__(self, limit_kt=300.0):
        self.limit_kt = limit_kt

    def _output(self, signals):
        shape = (signals.n_runs, signals.n_steps)
        ratio = np.asarray(signals.schedule["vcas_kt"], float) / float(self.limit_kt)
        residual = np.broadcast_to(ratio[:, None], shape).copy()
        return residual >= 1.0, residual


class SignalWriter(_Quiet):
    """Writes into the signals it is given in ``detect`` (zeroes the rod positions and the
    command, as a detector "cleaning" its input in place would) and raises no alarm: with
    writeable inputs, every detector run after it in the same chunk would read zeros."""

    def _output(self, signals):
        for name in ("rod_mon", "rod_com", "command"):
            getattr(signals, name)[:] = 0.0
        return super()._output(signals)


class ScheduleWriter(_Quiet):
    """Changes the measured schedule in ``detect``: ``how="scale"`` multiplies its arrays in
    place, ``how="assign"`` replaces an entry of the mapping."""

    def __init__(self, how="scale"):
        self.how = how

    def _output(self, signals):
        if self.how == "assign":
            signals.schedule["qbar_pa"] = np.asarray(signals.schedule["qbar_pa"]) * 50.0
        else:
            for values in signals.schedule.values():
                values *= 50.0
        return super()._output(signals)


class FitWriter(_Quiet):
    """Needs fit, and its fit writes into the learning signals (removes their mean in
    place)."""

    capabilities = Capabilities(needs_fit=True)

    def _fit(self, signals):
        rod = signals.rod_com
        rod -= rod.mean(axis=1, keepdims=True)
        self.level_ = 0.5


class FitSleeps(_Quiet):
    """Needs fit, and its fit sleeps *sleep_s* seconds (a fit that hangs)."""

    capabilities = Capabilities(needs_fit=True)

    def __init__(self, sleep_s=3600.0):
        self.sleep_s = sleep_s

    def _fit(self, signals):
        import time

        time.sleep(float(self.sleep_s))
        self.level_ = 0.5
