"""First alarms at other thresholds, stored with each run: the ``alarm_steps`` result column
(docs/thresholds.md, "Other thresholds from one campaign: tradeoff").

A detector whose decision has a threshold scale
(:attr:`detectors.base.Capabilities.threshold_scale`) raises its alarm at the first step where
its decision statistic reaches 1, and with every threshold multiplied by s at the first step
where it reaches s (:class:`detectors.base.Detection`).
Of a run scored at s = 1 the engine keeps, besides its result row, what fixes its result at
the other scales of :data:`ALARM_SCALES`:

* a **fault-free run** needs nothing more: it alarms at threshold × s exactly when its
  margin (the decision's largest value) is ≥ s — at every s, not only on the grid;
* a **faulty run** alarms before onset at threshold × s exactly when its margin (the largest
  value before onset) is ≥ s, and its first alarm in the detection window [onset, onset +
  window] is the first step k ≥ k_on where the running maximum M_k = max(decision[0..k]) is
  ≥ s (an alarm before onset is latched, so the window's first alarm is then the onset step
  itself, as :func:`reports.scoring.metrics.score_columns` scores it). The column holds, for each
  scale of the grid in ascending order, that step minus the onset step k_on, for the scales
  that detect the run (a prefix of the grid: a higher threshold never alarms earlier), packed
  as unsigned LEB128 varints, the first value then the increments. ``b""``: no scale of the
  grid detects the run; None: not stored (a fault-free run, a run in error, a decision without
  threshold scale, a campaign run before the column existed).

From these, the result row at any scale s of the grid (:func:`scaled_columns`) is the one the
campaign run with ``threshold_scale = s`` gives, to the bit: the step, the time k·Ts, the delay
and the DTP are computed with the operations of :func:`reports.scoring.metrics.score_columns`.

**Exactness.** The false alarms are exact at every s > 0 (margins); detection, misses, DTP and
delays are exact at the scales of :data:`ALARM_SCALES` (and at 1, the row itself) and only
there: the exact first alarm at every s in [0.5, 2] needs the whole staircase of the running
maximum (tens of levels per faulty run for a slowly rising decision, eight bytes each), many
times the size of a result shard, where the grid costs a few bytes per faulty run
(docs/thresholds.md gives the measurements).

A **detection system** alarms at the first alarm of any member, all members at the same
scale: its decision is the largest member decision (:mod:`detectors.system`), so its column
is made from that decision as any detector's, and its first alarm at s is the earliest of its
members' (the upper envelope of their running maxima).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from .metrics import FAULT_FREE, ONSET_TOL_S

__all__ = ["ALARM_SCALES", "ALARM_STEPS_COLUMN", "alarm_offsets", "alarm_steps",
           "decode_steps", "encode_steps", "onset_steps",
           "scaled_columns"]

#: Name of the result column (:data:`reports.scoring.metrics.RESULT_COLUMNS`).
ALARM_STEPS_COLUMN = "alarm_steps"

#: Threshold scales whose first alarm each faulty run stores, ascending: the R10 preferred
#: numbers (ISO 3, as rounded there; ratio 10^0.1 ≈ 1.26) from 0.5 to 2, without 1 (the
#: result row itself). A shard that holds the column records them in its metadata.
ALARM_SCALES: tuple[float, ...] = (0.5, 0.63, 0.8, 1.25, 1.6, 2.0)


# ---- the packed column -----------------------------------------------------------------------
def encode_steps(offsets: Sequence[int]) -> bytes:
    """The stored bytes of non-decreasing step offsets ≥ 0 (one per detecting scale of the
    grid, ascending): the first value, then each increment, as unsigned LEB128 varints."""
    out = bytearray()
    prev = 0
    for value in offsets:
        delta = int(value) - prev
        if delta < 0 or int(value) < 0:
            raise ValueError(f"alarm step offsets must be non-decreasing and ≥ 0, got "
                             f"{list(offsets)}")
        prev = int(value)
        while delta >= 0x80:
            out.append((delta & 0x7F) | 0x80)
            delta >>= 7
        out.append(delta)
    return bytes(out)


def decode_steps(data: bytes) -> list[int]:
    """The step offsets of :func:`encode_steps`' bytes (ValueError on bytes that end
    inside a value)."""
    out, value, shift, total = [], 0, 0, 0
    for byte in data:
        value |= (byte & 0x7F) << shift
        if byte & 0x80:
            shift += 7
            continue
        total += value
        out.append(total)
        value, shift = 0, 0
    if shift:
        raise ValueError("alarm steps: the stored bytes end inside a value (damaged column)")
    return out


# ---- from a decision statistic ---------------------------------------------------------------
def alarm_offsets(decision_row: np.ndarray, k_on: int, k_end: int,
                  scales: Sequence[float] = ALARM_SCALES) -> list[int]:
    """The first alarm of one faulty run in its window [*k_on*, *k_end*) at each of *scales*
    (ascending) that detects it, as a step offset from *k_on*: the first k ≥ k_on where the
    running maximum of *decision_row* from step 0 reaches the scale (NaN: no decision there).
    One run, by a search in its running maximum: the reference :func:`alarm_steps`' batch
    form is tested against."""
    if k_on >= k_end:
        return []
    row = np.asarray(decision_row, dtype=float)
    before = row[:k_on]
    pre = np.fmax.reduce(before) if before.size else np.nan
    running = np.fmax.accumulate(row[k_on:k_end])
    running = np.fmax(running, pre)
    running[np.isnan(running)] = -np.inf            # non-decreasing: searchsorted applies
    found = np.searchsorted(running, np.asarray(scales, dtype=float), side="left")
    return [int(k) for k in found if k < running.size]


def _window_steps(fault, onset_s, ts: float, window_s, n: int, n_steps: int):
    """(faulty, k_on, k_end) of each run as :func:`reports.scoring.metrics.score_columns` finds
    them: steps k with k·Ts ≥ onset − tol, and k·Ts ≤ onset + window + tol."""
    fault = np.asarray(fault).astype(str)
    faulty = fault != FAULT_FREE
    onset = np.broadcast_to(np.asarray(onset_s, dtype=float), (n,))
    window = (np.full(n, np.inf) if window_s is None
              else np.broadcast_to(np.asarray(window_s, dtype=float), (n,)))
    window = np.where(np.isnan(window), np.inf, window)
    onset_eff = np.where(faulty, onset, np.inf)
    t = np.arange(n_steps) * float(ts)
    k_on = np.searchsorted(t, onset_eff - ONSET_TOL_S, side="left")
    k_end = np.searchsorted(t, onset_eff + window + ONSET_TOL_S, side="right")
    return faulty, k_on, k_end


def alarm_steps(decision, *, fault, onset_s, ts: float, window_s=None,
                scales: Sequence[float] = ALARM_SCALES) -> np.ndarray:
    """The ``alarm_steps`` column (object array of bytes or None, one per run) of a
    detection's *decision* (n_runs, n_steps; None: no threshold scale, every value None) on
    runs of fault types *fault* and onsets *onset_s* [s], sampled every *ts* [s], scored in
    the detection window *window_s* [s] (None: the rest of the run) — the arguments of
    :func:`reports.scoring.metrics.score_columns`. Fault-free runs get None. Memory: one run's
    series at a time besides *decision*."""
    fault = np.asarray(fault)
    n = len(fault)
    out = np.full(n, None, dtype=object)
    if decision is None or n == 0:
        return out
    decision = np.asarray(decision, dtype=float)
    faulty, k_on, k_end = _window_steps(fault, onset_s, ts, window_s, n, decision.shape[1])
    rows = np.flatnonzero(faulty)
    if rows.size == 0:
        return out
    # the running maximum from step 0 of every faulty run at once (NaN: no decision yet),
    # and the steps of each run's window; per scale, the window's first step it reaches
    running = np.fmax.accumulate(decision[rows], axis=1)
    k = np.arange(decision.shape[1])
    on, end = k_on[rows, None], k_end[rows, None]
    inside = (k >= on) & (k < end)
    firsts = []
    for s in np.asarray(scales, dtype=float):
        reached = inside & (running >= s)
        firsts.append(np.where(reached.any(axis=1), reached.argmax(axis=1) - on[:, 0], -1))
    for j, i in enumerate(rows):      # the detecting scales form a prefix of the grid
        out[i] = encode_steps([int(f[j]) for f in firsts if f[j] >= 0])
    return out


def onset_steps(onset_s, ts: float) -> np.ndarray:
    """k_on of each onset [s]: the least k ≥ 0 with k·Ts ≥ onset − tol, the step
    :func:`reports.scoring.metrics.score_columns` finds with ``searchsorted`` on the run's times
    (k·Ts computed as there, so the same step, without the run's length); NaN onsets give 0."""
    onset = np.nan_to_num(np.asarray(onset_s, dtype=float), nan=0.0)
    ts = float(ts)
    x = onset - ONSET_TOL_S
    k = np.maximum(np.floor(x / ts), 0).astype(np.int64)
    while True:                          # up to the first k whose time reaches x …
        low = k * ts < x
        if not low.any():
            break
        k[low] += 1
    while True:                          # … and no earlier one does
        high = (k > 0) & ((k - 1) * ts >= x)
        if not high.any():
            break
        k[high] -= 1
    return k


# ---- at another scale --------------------------------------------------------------------
def _scale_index(scale: float, scales: Sequence[float]) -> int:
    for j, s in enumerate(scales):
        if float(s) == float(scale):
            return j
    raise ValueError(f"threshold scale {scale:g} is not stored; the stored scales are "
                     f"{', '.join(f'{s:g}' for s in scales)} (and 1, the campaign's own)")


def scaled_columns(*, scale: float, fault, onset_s, margin, steps, ts: float,
                   required_time_s, scales: Sequence[float] = ALARM_SCALES) -> dict:
    """The scoring columns (``false_alarm``, ``pre_onset_alarm``, ``detected``,
    ``first_alarm_s``, ``delay_s``, ``dtp``, ``margin``) of runs at threshold × *scale* (one
    of *scales*), plus ``known``: whether the run's result at that scale is known.

    fault, onset_s, margin : the runs' fault types, onsets [s] and margins at scale 1
    steps : their ``alarm_steps`` (bytes or None)
    ts : sampling period [s]; required_time_s : each run's required detection time [s]

    A fault-free run is known from its margin (``false_alarm`` = margin ≥ scale; its
    ``first_alarm_s`` is not stored, NaN); a faulty run when its steps are stored. The
    margin at threshold × s is margin / s (the decision divided by s). Rows not known have
    every column False/NaN."""
    j = _scale_index(scale, scales)
    scale = float(scale)
    fault = np.asarray(fault).astype(str)
    n = len(fault)
    margin = np.asarray(margin, dtype=float)
    faulty = fault != FAULT_FREE
    with np.errstate(invalid="ignore"):
        alarm = margin >= scale
    steps = np.asarray(steps, dtype=object) if n else np.zeros(0, dtype=object)
    stored = ~pd.isna(steps)                 # None, or NaN from a frame without the column
    known = ~faulty | stored
    onset = np.asarray(onset_s, dtype=float)
    k_on = onset_steps(np.where(faulty, onset, 0.0), ts)
    step = np.full(n, -1, dtype=np.int64)
    for i in np.flatnonzero(faulty & stored):
        offsets = decode_steps(steps[i])
        if j < len(offsets):
            step[i] = k_on[i] + offsets[j]
    detected = faulty & known & (step >= 0)
    ts = float(ts)
    first = np.where(detected, step * ts, np.nan)
    delay = np.where(detected, first - onset, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        dtp = np.where(detected, delay / np.asarray(required_time_s, dtype=float), np.nan)
    return {"false_alarm": alarm & known, "pre_onset_alarm": alarm & known,
            "detected": detected, "first_alarm_s": first, "delay_s": delay, "dtp": dtp,
            "margin": np.where(known, margin / scale, np.nan), "known": known}
