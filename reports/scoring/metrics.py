"""Run-level scoring of alarms: false alarm, missed detection, detection delay, DTP, margin.

The definitions live here and nowhere else (docs/design.md §5, Metrics; [CHEN] §5, the ADDSAFE
industrial evaluation). Inputs are plain arrays: this module knows nothing of how the runs
were simulated or which detector raised the alarms.

Time convention: step ``k`` of a run is at time ``k * ts`` [s], the first sample being at
0 s. A sample is *at or after onset* when ``k * ts >= onset_s - ONSET_TOL_S`` so that an
onset that is an exact multiple of ``ts`` in decimal (0.3 s with ts = 0.1 s) is not lost to
floating-point error.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

__all__ = [
    "FAULT_FREE",
    "ONSET_TOL_S",
    "RESULT_COLUMNS",
    "SCORE_COLUMNS",
    "ESTIMATE_COLUMNS",
    "clopper_pearson",
    "estimation_errors",
    "lower_bound",
    "score_columns",
    "score_runs",
    "upper_bound",
]

#: Value of the ``fault`` column of a fault-free run (docs/design.md §7, Command line).
FAULT_FREE = "none"

#: Tolerance [s] on time comparisons with the onset and the end of the detection window:
#: far below any sampling period (ms), far above the rounding error of ``k * ts``.
ONSET_TOL_S = 1e-9

#: Fault-estimation error of a run, for detectors that estimate the fault ([CHEN] §6.2,
#: :func:`estimation_errors`): ``est_err_n`` samples of f̂ − f after onset (0: none),
#: their mean [mm] and population variance [mm²], and ``est_range_mm``, the rod travel of
#: the deflection range that normalises them (:func:`scenarios.faults.estimation_range_mm`;
#: NaN without samples).
ESTIMATE_COLUMNS: tuple[str, ...] = (
    "est_err_n", "est_err_mean_mm", "est_err_var_mm2", "est_range_mm",
)

#: Columns of a result row: one row per run × detector (docs/design.md §7, Command line minimum
#: columns, plus ``error``, ``pre_onset_alarm``, :data:`ESTIMATE_COLUMNS`, ``alarm_steps``).
RESULT_COLUMNS: tuple[str, ...] = (
    "run_id", "detector", "fault", "manoeuvre", "status", "error",
    "false_alarm", "pre_onset_alarm", "detected", "first_alarm_s", "delay_s", "dtp", "margin",
    *ESTIMATE_COLUMNS, "alarm_steps",
)

#: Columns returned by :func:`score_runs` (the scoring part of a result row).
SCORE_COLUMNS: tuple[str, ...] = (
    "run_id", "false_alarm", "pre_onset_alarm", "detected",
    "first_alarm_s", "delay_s", "dtp", "margin",
)


def _first_true(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the first True per row and whether there is one (index 0 when none)."""
    idx = np.argmax(mask, axis=1)
    has = mask[np.arange(mask.shape[0]), idx] if mask.shape[0] else np.zeros(0, dtype=bool)
    return idx, has


def _per_run(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
    return arr


def score_runs(*, run_id, fault, onset_s, alarm, residual, ts, required_time_s,
               window_s=None) -> pd.DataFrame:
    """Score a batch of runs of one detector (docs/design.md §5, Metrics): the columns of
    :func:`score_columns` as a DataFrame (see there for the parameters and the rules)."""
    return pd.DataFrame(score_columns(
        run_id=run_id, fault=fault, onset_s=onset_s, alarm=alarm, residual=residual, ts=ts,
        required_time_s=required_time_s, window_s=window_s), columns=list(SCORE_COLUMNS))


def score_columns(*, run_id, fault, onset_s, alarm, residual, ts, required_time_s,
                  window_s=None) -> dict[str, np.ndarray]:
    """Score a batch of runs of one detector (docs/design.md §5, Metrics): {column of
    :data:`SCORE_COLUMNS` → (n,) array}, for callers that assemble many batches into one
    table (:func:`campaign.evaluate.evaluate`).

    Parameters
    ----------
    run_id : array-like (n,) of str
        Identity of each run.
    fault : array-like (n,) of str
        Fault type of each run; ``"none"`` for a fault-free run.
    onset_s : array-like (n,) of float [s]
        Fault onset time; ignored (may be NaN) for fault-free runs, must be finite for
        faulty runs.
    alarm : array-like (n, T) of bool
        Alarm flag of the detector at each step.
    residual : array-like (n, T) of float [-]
        The statistic the margin is the largest value of: the detection's decision
        statistic when it gives one (:attr:`detectors.base.Detection.margin_statistic`:
        ≥ 1 exactly where the alarm is first raised, so margin ≥ 1 ⟺ an alarm before
        onset), else its residual normalised by its threshold, |r|/τ, before any
        confirmation logic. NaN samples (a filter warming up, a confirmation window not
        yet full) are ignored by the margin.
    ts : float [s]
        Sampling period; step ``k`` is at ``k * ts``.
    required_time_s : array-like (n,) of float [s]
        Required detection time of the run's fault type (configuration data, the DTP
        denominator); ignored for fault-free runs, must be finite and > 0 for faulty runs.
    window_s : None, float or array-like (n,) of float [s]
        Detection window after onset. ``None`` (or NaN/inf for a run) means the rest of the
        run.

    Returns
    -------
    {column: (n,) array} of :data:`SCORE_COLUMNS`, one value per run, in input order:

    * fault-free run: ``false_alarm`` = any alarm; ``pre_onset_alarm`` = ``false_alarm``;
      ``first_alarm_s`` = first alarm time (NaN if none); ``detected`` False; ``delay_s``
      and ``dtp`` NaN; ``margin`` = max residual over the whole run.
    * faulty run: ``pre_onset_alarm`` = any alarm at t < onset, reported as
      ``false_alarm``; ``detected`` = some alarm at onset ≤ t ≤ onset + window;
      ``first_alarm_s`` = first such alarm (NaN for a miss); ``delay_s`` =
      ``first_alarm_s - onset_s``; ``dtp`` = ``delay_s / required_time_s`` ([CHEN] §5);
      ``margin`` = max residual over t < onset (NaN if no sample precedes onset).

    Raises
    ------
    ValueError
        On inconsistent shapes, a non-positive ``ts``, a faulty run without a finite onset
        or required detection time, or a negative window.
    """
    alarm = np.asarray(alarm)
    residual = np.asarray(residual, dtype=float)
    if alarm.ndim != 2:
        raise ValueError(f"alarm must have shape (n_runs, n_steps), got {alarm.shape}")
    n, n_steps = alarm.shape
    if residual.shape != alarm.shape:
        raise ValueError(f"residual {residual.shape} must have the shape of alarm {alarm.shape}")
    if n_steps == 0 and n > 0:
        raise ValueError("alarm has no time steps: a run must have at least one sample")
    alarm = alarm.astype(bool, copy=False)
    ts = float(ts)
    if not np.isfinite(ts) or ts <= 0:
        raise ValueError(f"ts must be a positive sampling period [s], got {ts}")

    run_id = np.asarray(run_id).astype(str)
    fault = np.asarray(fault).astype(str)
    for name, arr in (("run_id", run_id), ("fault", fault)):
        if arr.shape != (n,):
            raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    onset = _per_run(onset_s, n, "onset_s")
    required = _per_run(required_time_s, n, "required_time_s")
    window = (np.full(n, np.inf) if window_s is None
              else _per_run(window_s, n, "window_s"))
    window = np.where(np.isnan(window), np.inf, window)
    if np.any(window < 0):
        raise ValueError("window_s must be ≥ 0 [s] (None or NaN for the rest of the run)")

    faulty = fault != FAULT_FREE
    bad_onset = faulty & ~np.isfinite(onset)
    if bad_onset.any():
        raise ValueError(
            "onset_s must be finite for faulty runs; missing for run(s) "
            f"{', '.join(run_id[bad_onset][:5])}")
    bad_req = faulty & ~(np.isfinite(required) & (required > 0))
    if bad_req.any():
        kinds = ", ".join(sorted(set(fault[bad_req])))
        raise ValueError(
            "required_time_s must be a positive time [s] for every faulty run; "
            f"missing or invalid for fault type(s): {kinds}")

    # Fault-free runs: the whole run is "before onset" and there is no detection window.
    # As step indices: steps k < k_on are before onset (t_k < onset − ONSET_TOL_S), steps
    # k_on ≤ k < k_end are in the detection window (t_k ≤ onset + window + ONSET_TOL_S);
    # searchsorted on the sorted times gives exactly the steps those comparisons select.
    onset_eff = np.where(faulty, onset, np.inf)
    t = np.arange(n_steps) * ts
    k_on = np.searchsorted(t, onset_eff - ONSET_TOL_S, side="left")
    k_end = np.searchsorted(t, onset_eff + window + ONSET_TOL_S, side="right")

    idx_any, any_alarm = _first_true(alarm)
    # an alarm before onset ⟺ the first alarm is before onset
    pre_onset_alarm = any_alarm & (idx_any < k_on)
    # the first alarm in the window: the run's first alarm when it lies there; after an
    # alarm before onset (a false alarm: few runs), searched for in those runs' windows
    idx_win = idx_any.copy()
    in_window = any_alarm & (idx_any >= k_on) & (idx_any < k_end)
    again = np.flatnonzero(pre_onset_alarm & (k_on < k_end))
    if again.size:
        steps = np.arange(n_steps)
        window_steps = ((steps >= k_on[again, None]) & (steps < k_end[again, None]))
        idx_win[again], in_window[again] = _first_true(alarm[again] & window_steps)
    first_alarm_s = np.where(
        faulty,
        np.where(in_window, idx_win * ts, np.nan),
        np.where(any_alarm, idx_any * ts, np.nan),
    )
    detected = faulty & in_window
    delay_s = np.where(detected, first_alarm_s - onset, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        dtp = np.where(detected, delay_s / required, np.nan)

    # margin: the largest residual before onset, NaN samples left out (NaN when none is
    # left): the whole run's for fault-free runs (and onsets after the run), else the
    # maximum over steps [0, k_on) of the row, all of them in one fmax.reduceat over the
    # flat residual (segments alternate: a run's steps before onset, then the rest)
    margin = np.fmax.reduce(residual, axis=1) if n_steps else np.full(n, np.nan)
    part = np.flatnonzero(k_on < n_steps)
    if part.size:
        starts = part * n_steps
        bounds = np.column_stack([starts, starts + k_on[part]]).ravel()
        margin[part] = np.fmax.reduceat(residual.reshape(-1), bounds)[::2]
        margin[part[k_on[part] == 0]] = np.nan      # no step before onset

    return {
        "run_id": run_id.astype(object),
        "false_alarm": pre_onset_alarm,
        "pre_onset_alarm": pre_onset_alarm,
        "detected": detected,
        "first_alarm_s": first_alarm_s,
        "delay_s": delay_s,
        "dtp": dtp,
        "margin": margin,
    }


def estimation_errors(estimate, fault) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-run statistics of the fault-estimation error e = f̂ − f ([CHEN] §6.2).

    *estimate* f̂ and *fault* f are (n, T) in one unit; the samples where both are finite
    count (f is NaN before onset and for runs without a defined fault, so the window is
    each run's post-onset part). Returns ``(count, mean, variance)``, each (n,): the number
    of samples (int64), their mean and their population variance (1/N, two-pass), NaN
    for a run without samples. Only (n,) values leave this function, so a campaign stores
    three numbers per run, never the series.
    """
    e = np.asarray(estimate, dtype=float) - np.asarray(fault, dtype=float)
    if e.ndim != 2:
        raise ValueError(f"estimate and fault must be (n_runs, n_steps), got {e.shape}")
    valid = np.isfinite(e)
    count = valid.sum(axis=1).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(valid, e, 0.0).sum(axis=1) / count
        var = np.where(valid, (e - mean[:, None]) ** 2, 0.0).sum(axis=1) / count
    empty = count == 0
    return count, np.where(empty, np.nan, mean), np.where(empty, np.nan, var)


def _as_output(x: np.ndarray):
    return float(x) if x.ndim == 0 else x


def _check_counts(k, n, confidence):
    if not 0.0 < float(confidence) < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    k, n = np.broadcast_arrays(np.asarray(k, dtype=float), np.asarray(n, dtype=float))
    bad = (k < 0) | (k > n) | (n < 0)
    if np.any(bad):
        raise ValueError("counts must satisfy 0 ≤ k ≤ n")
    empty = ~(n > 0)  # n == 0 or NaN: no information
    return k, n, empty


def clopper_pearson(k, n, confidence: float = 0.95):
    """Exact (Clopper–Pearson) two-sided interval of a binomial rate k/n.

    ``lower = Beta⁻¹(α/2; k, n−k+1)`` (0 when k = 0), ``upper = Beta⁻¹(1−α/2; k+1, n−k)``
    (1 when k = n), α = 1 − confidence (docs/design.md §5, Metrics). Vectorised over ``k`` and
    ``n``; ``n = 0`` gives NaN. Returns ``(lower, upper)`` as floats or arrays.
    """
    k, n, empty = _check_counts(k, n, confidence)
    alpha = 1.0 - float(confidence)
    with np.errstate(invalid="ignore"):
        lower = np.where(k > 0, stats.beta.ppf(alpha / 2, k, n - k + 1), 0.0)
        upper = np.where(k < n, stats.beta.ppf(1 - alpha / 2, k + 1, n - k), 1.0)
    lower = np.where(empty, np.nan, lower)
    upper = np.where(empty, np.nan, upper)
    return _as_output(lower), _as_output(upper)


def lower_bound(k, n, confidence: float = 0.95):
    """Exact one-sided lower confidence bound of a binomial rate k/n,
    ``Beta⁻¹(1 − confidence; k, n−k+1)`` (0 when k = 0). Vectorised; ``n = 0`` gives NaN."""
    k, n, empty = _check_counts(k, n, confidence)
    with np.errstate(invalid="ignore"):
        lower = np.where(k > 0, stats.beta.ppf(1.0 - float(confidence), k, n - k + 1), 0.0)
    return _as_output(np.where(empty, np.nan, lower))


def upper_bound(k, n, confidence: float = 0.95):
    """Exact one-sided upper confidence bound of a binomial rate k/n.

    ``Beta⁻¹(confidence; k+1, n−k)`` (1 when k = n): with 0 false alarms in 1200 runs the
    rate is ≤ 1 − 0.05^(1/1200) = 0.25 % at 95 % confidence (docs/design.md §5, Metrics).
    Vectorised; ``n = 0`` gives NaN.
    """
    k, n, empty = _check_counts(k, n, confidence)
    with np.errstate(invalid="ignore"):
        upper = np.where(k < n, stats.beta.ppf(float(confidence), k + 1, n - k), 1.0)
    return _as_output(np.where(empty, np.nan, upper))
