"""The evaluation pipeline: simulate plan rows, run the fitted detectors, score the alarms.

docs/design.md §3, data flow steps 3–5. Every path of the engine that turns run-table rows
into detections or result rows goes through here: the runner's chunks
(:func:`evaluate`), the report's and ``show``'s re-simulation (:func:`simulate_and_detect`),
the learning set (:func:`simulate_signals`), ``bench`` and the studies. The plant is
called in one place (:func:`_simulate`); the scoring rules are those of
:func:`reports.scoring.metrics.score_columns` (behind :func:`reports.scoring.metrics.score_runs`)
and nowhere else.

:func:`evaluate` never raises for a bad run or a failing detector: those runs get result
rows with ``status="error"`` and the message (docs/design.md §9, Non-negotiables). Every
detector reads the signals read-only (:func:`detectors.base.read_only`, zero-copy views):
one that writes into them fails alone, and the others see what the plant produced. This
module does not know where chunks run (:mod:`campaign.execute`) nor where results are
stored (:mod:`campaign.store.directory`).
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from detectors import Detection, as_variants, detection_problems
from detectors.base import at_threshold_scale, read_only, threshold_scale_of, writes_input
from detectors.system import DetectionSystem
from reports.scoring.alarm_steps import ALARM_STEPS_COLUMN, alarm_steps
from reports.scoring.metrics import RESULT_COLUMNS, estimation_errors, score_columns
from scenarios import compiled as kernels
from scenarios.faults import estimation_range_mm
from scenarios.signals import Signals
from scenarios.plants import Plant
from scenarios.simulate import ActuatorPlant

__all__ = ["ChunkSettings", "DetectorContractError", "detect", "detect_runs", "evaluate",
           "failure_message",
           "failure_rows", "score", "simulate_and_detect", "simulate_signals"]


class DetectorContractError(ValueError):
    """A detector's output broke the contract of ``detect`` on the signals it was given
    (:func:`detectors.detection_problems`): wrong dtype, a shape that is not the signals'
    (n_runs, n_steps), ±inf or a NaN after the warm-up in the residual. The message names
    the detector, the rule, the shapes seen and how to find the breach with
    :func:`detectors.testing.check_detector`."""

    def __init__(self, label: str, detector, variant: str, problems: list[str],
                 detection, shape: tuple[int, int]):
        alarm, residual = np.asarray(detection.alarm), np.asarray(detection.residual)
        cls = type(detector).__name__
        seen = (f"seen: alarm {alarm.shape} {alarm.dtype}, residual {residual.shape} "
                f"{residual.dtype}, signals {tuple(shape)}")
        where = "" if variant == label else f" (variant {variant!r})"
        super().__init__(
            f"detector {label!r}{where} broke the output contract of detect(): "
            f"{'; '.join(problems)} ({seen}); its runs are recorded as errors, never scored. "
            f"Find it with: from detectors.testing import check_detector; "
            f"check_detector({cls}(**params)) (docs/write-a-detector.md)")
        self.label, self.variant, self.problems = label, variant, tuple(problems)

    def __reduce__(self):
        return _rebuild_contract_error, (str(self), self.label, self.variant, self.problems)


def _rebuild_contract_error(message, label, variant, problems):
    exc = DetectorContractError.__new__(DetectorContractError)
    ValueError.__init__(exc, message)
    exc.label, exc.variant, exc.problems = label, variant, problems
    return exc


@dataclass(frozen=True)
class ChunkSettings:
    """What a worker needs besides the rows and the fitted detectors (picklable).

    ts : sampling period [s]
    pressure_sensor : whether the chamber pressure sensor is simulated
    required_time_s : fault type → required detection time [s] (the DTP denominator)
    window_s : detection window after onset [s] (None: the rest of the run)
    plant : what the runs are simulated on (a :class:`scenarios.plants.Plant`)
    engine : time-loop kernels, ``"compiled"`` or ``"numpy"`` (:mod:`scenarios.compiled`)
    """

    ts: float
    pressure_sensor: bool
    required_time_s: dict
    window_s: float | None
    plant: Plant = ActuatorPlant()
    engine: str = "compiled"


# ---- the stages ------------------------------------------------------------------------------
def _simulate(rows: pd.DataFrame, settings: ChunkSettings):
    """(Signals, Truth) of plan *rows* on the campaign's plant: the one call of the plant."""
    return settings.plant.simulate(rows, ts=settings.ts, pressure_sensor=settings.pressure_sensor)


def simulate_signals(rows: pd.DataFrame, settings: ChunkSettings) -> Signals:
    """The signals of plan *rows* (what a detector reads), with the kernels of
    ``settings.engine``; used for learning sets and benchmarks."""
    with kernels.use_engine(settings.engine):
        signals_only = getattr(settings.plant, "simulate_signals", None)
        if signals_only is not None:   # a plant that can skip the Truth (aircraft)
            return signals_only(rows, ts=settings.ts, pressure_sensor=settings.pressure_sensor)
        return _simulate(rows, settings)[0]


def detect(signals: Signals, detectors: dict, failures: dict | None = None,
           known: dict | None = None) -> dict:
    """Every fitted detector (label → Detector) on *signals*: {variant name →
    :class:`detectors.base.Detection`}, the names of the result rows
    (:func:`detectors.as_variants`).

    Each detector receives *signals* read-only (:func:`detectors.base.read_only`: views
    whose write flag is off, no copy), so one that writes into its input raises there and
    fails alone, its message saying so; the next detector reads the signals unchanged.
    Each output is checked against the contract (:func:`detectors.detection_problems`:
    dtypes, the signals' exact (n_runs, n_steps) shape, a finite residual but for NaN
    warm-up samples); a breach raises :class:`DetectorContractError`. With a dict
    *failures*, a detector that raises (or breaks the contract) is left out and its
    message stored there under its label instead (the report and ``show`` go on with the
    others).

    A detection system (:class:`detectors.system.DetectionSystem`) is combined from its
    members' detections when they were made before it on the same *signals* — in this
    call, or found in *known* (result name → Detection, filled with what this call makes,
    for a caller that runs the detectors one at a time) — instead of running them again.
    """
    detections = {}
    known = {} if known is None else known
    for label, det in detectors.items():
        try:
            made = _checked(label, det, signals, known)
        except Exception as exc:  # noqa: BLE001 - recorded for the caller when asked to
            if failures is None:
                raise
            failures[label] = failure_message(exc)
            continue
        detections.update(made)
        known.update(made)
    return detections


def detect_runs(signals: Signals, detectors: dict) -> tuple[dict, dict]:
    """:func:`detect` for readers of a campaign (report, ``show``) that must go on when a
    detector fails: a detector that raises on the batch (or breaks the contract) is run
    again run by run, as :func:`evaluate` does.

    Returns ``(detections, failures)``: *detections* as :func:`detect`, where the runs a
    detector failed on have no alarm and an all-NaN residual (left out of every margin);
    *failures* maps a label to {run index → message} of the runs it failed on (a label
    that failed on every run has no detection at all).
    """
    failed: dict = {}
    detections = detect(signals, detectors, failed)
    failures = {}
    for label in failed:
        det, shape = detectors[label], (signals.n_runs, signals.n_steps)
        parts, errors = {}, {}
        for j in range(signals.n_runs):
            try:
                parts[j] = _checked(label, det, signals.take([j]))
            except Exception as exc:  # noqa: BLE001 - recorded per run
                errors[j] = failure_message(exc)
        failures[label] = errors
        names = dict.fromkeys(name for out in parts.values() for name in out)
        for name in names:
            alarm, residual = np.zeros(shape, bool), np.full(shape, np.nan)
            decided = [out[name].decision is not None for out in parts.values() if name in out]
            decision = np.full(shape, np.nan) if decided and all(decided) else None
            for j, out in parts.items():
                if name in out:
                    alarm[j], residual[j] = out[name].alarm[0], out[name].residual[0]
                    if decision is not None:
                        decision[j] = out[name].decision[0]
            detections[name] = Detection(alarm=alarm, residual=residual, decision=decision)
    return detections, failures


def _checked(label: str, det, signals: Signals, known: dict | None = None) -> dict:
    """The variants of *det* on read-only *signals*, each checked against the output
    contract; a detection system's from the members' detections in *known* when they are
    all there (:func:`detect`)."""
    if isinstance(det, DetectionSystem) and known and det.has_members_in(known):
        variants = {label: det.combine(known)}
    else:
        variants = as_variants(label, det.detect(read_only(signals)))
    shape = (signals.n_runs, signals.n_steps)
    scaled = getattr(det.capabilities, "threshold_scale", False)
    for name, detection in variants.items():
        problems = detection_problems(detection, *shape)
        if scaled and detection.decision is None:
            problems.append("decision is missing: the detector declares threshold_scale "
                            "(Capabilities), so each Detection must carry the decision "
                            "statistic its alarm compares with 1")
        if problems:
            raise DetectorContractError(label, det, name, problems, detection, shape)
    # every threshold × the detector's [[detector]] threshold_scale (1: as it gave them)
    return {name: at_threshold_scale(d, threshold_scale_of(det)) for name, d in variants.items()}


def simulate_and_detect(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings,
                        failures: dict | None = None):
    """Simulate plan *rows* and run every fitted detector on them, for callers that need the
    traces (report, ``show``).

    Returns ``(signals, truth, detections)``, *detections* as :func:`detect`. Raises what
    the simulation raises, and what a detector raises unless *failures* is a dict: the
    detectors then run as :func:`detect_runs` says (a failing one run by run) and
    *failures* receives its {label: {run index: message}} (:func:`evaluate` records both
    as result rows instead).
    """
    with kernels.use_engine(settings.engine):
        signals, truth = _simulate(rows, settings)
        if failures is None:
            return signals, truth, detect(signals, detectors)
        detections, failed = detect_runs(signals, detectors)
        failures.update(failed)
        return signals, truth, detections


def _required(fault, settings: ChunkSettings) -> np.ndarray:
    """Required detection time [s] of each run's fault type (NaN when none is set)."""
    return np.array([settings.required_time_s.get(f, np.nan) for f in fault])


def _estimate_columns(detection, truth, range_mm: float) -> dict:
    """The fault-estimation error columns (:data:`reports.scoring.metrics.ESTIMATE_COLUMNS`) of
    *detection* on its runs: over the post-onset samples where the truth defines the fault
    (``Truth.rod_fault_mm``) and the detector gives an estimate; 0 samples otherwise."""
    n = len(truth.fault)
    estimate = getattr(detection, "estimate", None)
    # read only for an estimate: the truth computes it on its first read (Truth.rod_fault_mm)
    fault = None if estimate is None else getattr(truth, "rod_fault_mm", None)
    if estimate is None or fault is None:
        count, mean, var = np.zeros(n, np.int64), np.full(n, np.nan), np.full(n, np.nan)
    else:
        count, mean, var = estimation_errors(estimate, fault)
    return {"est_err_n": count, "est_err_mean_mm": mean, "est_err_var_mm2": var,
            "est_range_mm": np.where(count > 0, float(range_mm), np.nan)}


def _scored(rows: pd.DataFrame, truth, detections: dict, required: np.ndarray,
            settings: ChunkSettings, range_mm: float = np.nan) -> list[pd.DataFrame]:
    """The result rows of *detections* on *rows*, variant after variant, as one table (in a
    list, as the callers concatenate them): assembled from the columns of every variant,
    so a chunk costs one DataFrame per detector, not one per variant and column."""
    if not detections:
        return []
    n = len(rows)
    manoeuvre = rows["manoeuvre"].to_numpy()
    parts: dict[str, list] = {c: [] for c in RESULT_COLUMNS}
    for name, detection in detections.items():
        scored = score_columns(
            run_id=rows["run_id"].to_numpy(), fault=truth.fault, onset_s=truth.onset_s,
            alarm=detection.alarm, residual=detection.margin_statistic, ts=settings.ts,
            required_time_s=required, window_s=settings.window_s)
        scored.update(_estimate_columns(detection, truth, range_mm))
        scored[ALARM_STEPS_COLUMN] = alarm_steps(      # the first alarms at other thresholds
            detection.decision, fault=truth.fault, onset_s=truth.onset_s, ts=settings.ts,
            window_s=settings.window_s)
        scored.update(detector=np.full(n, name, dtype=object),
                      fault=np.asarray(truth.fault), manoeuvre=manoeuvre,
                      status=np.full(n, "ok", dtype=object), error=np.full(n, "", dtype=object))
        for column in RESULT_COLUMNS:
            parts[column].append(scored[column])
    return [pd.DataFrame({c: np.concatenate(v) for c, v in parts.items()})]


def score(rows: pd.DataFrame, truth, detections: dict, settings: ChunkSettings,
          actuator=None) -> pd.DataFrame:
    """Result rows (:data:`reports.scoring.metrics.RESULT_COLUMNS`, ``status="ok"``) of *detections*
    ({variant name → Detection}) on the runs *rows* whose truth is *truth*: one row per
    run × variant, scored by :func:`reports.scoring.metrics.score_runs` with the required detection
    times and window of *settings*. *actuator* (``Signals.actuator``) normalises the
    fault-estimation error (``est_range_mm``; NaN without it)."""
    range_mm = np.nan if actuator is None else estimation_range_mm(actuator)
    frames = _scored(rows, truth, detections, _required(truth.fault, settings), settings,
                     range_mm)
    return pd.concat(frames, ignore_index=True)[list(RESULT_COLUMNS)]


# ---- the robust whole ------------------------------------------------------------------------
def evaluate(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings) -> pd.DataFrame:
    """Simulate, detect and score one chunk of runs; returns its result rows.

    A plant with a ``batch_runs`` attribute (the aircraft plant) is simulated and scored
    in blocks of at most that many runs, one after the other, so that a worker holds the
    signals of one block only; the rows are those of the whole chunk (a run's result never
    depends on its batch).

    Never raises for a bad run or a failing detector: those rows get ``status="error"``.
    A chunk whose simulation fails, or a detector that raises on a chunk, is retried run by
    run, so one bad run does not take the others of its chunk down with it. The kernels
    are those of ``settings.engine``.
    """
    block = getattr(settings.plant, "batch_runs", None)
    with kernels.use_engine(settings.engine):
        if block is None or len(rows) <= block:
            return _evaluate(rows, detectors, settings)
        # memory flat in the chunk size: the plant's signals of one block at a time
        return pd.concat([_evaluate(rows.iloc[s:s + block], detectors, settings)
                          for s in range(0, len(rows), block)], ignore_index=True)


def _evaluate(rows: pd.DataFrame, detectors: dict, settings: ChunkSettings) -> pd.DataFrame:
    try:
        signals, truth = _simulate(rows, settings)
    except Exception as exc:  # noqa: BLE001 - recorded per run, never fatal
        if len(rows) > 1:
            return pd.concat([_evaluate(rows.iloc[[j]], detectors, settings)
                              for j in range(len(rows))], ignore_index=True)
        return pd.concat([_error_rows(rows, label, f"simulation failed: {_describe(exc)}")
                          for label in detectors], ignore_index=True)
    truth = _scoring_truth(truth)
    required = _required(truth.fault, settings)
    range_mm = estimation_range_mm(signals.actuator)
    frames = []
    needed = _system_members(detectors)
    known: dict = {}          # the detections of the block that a system is made of
    for label, det in detectors.items():
        try:
            made = detect(signals, {label: det}, known=known)
            known = {n: d for n, d in known.items() if n.split("[", 1)[0] in needed}
            frames.extend(_scored(rows, truth, made, required, settings, range_mm))
        except Exception as exc:  # noqa: BLE001
            if len(rows) == 1:
                frames.append(_error_rows(rows, label, failure_message(exc)))
                continue
            # run by run, so that only the runs the detector fails on are recorded as errors
            for j in range(len(rows)):
                try:
                    frames.extend(_scored(rows.iloc[[j]], truth.take([j]),
                                          detect(signals.take([j]), {label: det}),
                                          required[[j]], settings, range_mm))
                except Exception as exc_j:  # noqa: BLE001
                    frames.append(_error_rows(rows.iloc[[j]], label,
                                              failure_message(exc_j)))
    return pd.concat(frames, ignore_index=True)[list(RESULT_COLUMNS)]


def _system_members(detectors: dict) -> set[str]:
    """The labels of the detectors some detection system of *detectors* is made of."""
    return {label for det in detectors.values() if isinstance(det, DetectionSystem)
            for label in det.member_labels}


def _scoring_truth(truth):
    """*truth* without its (n, T) true series, which scoring does not read (fault type and
    onset only): their memory is freed before the detectors run. The series become
    all-NaN read-only views of the same shape; the rod fault stays as it was stored
    (computed only if a detector's estimate is scored)."""
    shape = np.shape(truth.rod_mm)
    nan = np.broadcast_to(np.nan, shape)
    return replace(truth, rod_mm=nan, surface_deg=nan, current_mA=nan, aircraft=None,
                   surfaces_deg=None, rod_fault_mm=truth.stored_rod_fault())


# ---- runs that could not be evaluated --------------------------------------------------------
def _error_rows(rows: pd.DataFrame, detector: str, message: str,
                status: str = "error") -> pd.DataFrame:
    n = len(rows)
    return pd.DataFrame({
        "run_id": rows["run_id"].to_numpy(), "detector": detector,
        "fault": rows["fault"].to_numpy(), "manoeuvre": rows["manoeuvre"].to_numpy(),
        "status": status, "error": message,
        "false_alarm": np.zeros(n, bool), "pre_onset_alarm": np.zeros(n, bool),
        "detected": np.zeros(n, bool), "first_alarm_s": np.nan, "delay_s": np.nan,
        "dtp": np.nan, "margin": np.nan,
        "est_err_n": np.zeros(n, np.int64), "est_err_mean_mm": np.nan,
        "est_err_var_mm2": np.nan, "est_range_mm": np.nan, ALARM_STEPS_COLUMN: None,
    })


def failure_message(exc: BaseException) -> str:
    """The ``error`` text of a run a detector failed on: a contract breach as its own
    message (:class:`DetectorContractError`), anything else as ``detector failed: …``."""
    if isinstance(exc, DetectorContractError):
        return str(exc)
    if writes_input(exc):
        return (f"detector failed: it wrote into the signals it was given, which are "
                f"read-only ({_describe(exc)}); a detector works on its own copy "
                "(np.array(signals.rod_com)) (docs/write-a-detector.md, Signals and output)")
    return f"detector failed: {_describe(exc)}"


def _describe(exc: BaseException) -> str:
    last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    where = f" (at {Path(last[0].filename).name}:{last[0].lineno})" if last else ""
    return f"{type(exc).__name__}: {exc}{where}"


def failure_rows(rows: pd.DataFrame, labels, status: str, message: str) -> pd.DataFrame:
    """Result rows of runs that could not be run (*status* ``error`` or ``timeout``), one
    per run × detector label."""
    return pd.concat([_error_rows(rows, label, message, status) for label in labels],
                     ignore_index=True)[list(RESULT_COLUMNS)]
