"""The detector contract (docs/design.md §4, Contracts), in the manner of scikit-learn estimators.

* ``__init__`` stores keyword parameters only (no work, no validation side effects);
* ``fit(signals)`` learns from fault-free learning runs, stores learned values in
  attributes ending in ``_`` and returns ``self``;
* ``detect(signals)`` returns a :class:`Detection` (or a mapping variant → Detection for a
  detector that runs several variants at once, e.g. several residual-filter poles);
* capabilities are declared as data in :class:`Capabilities`, parameters as data in
  :attr:`Detector.parameters` (:class:`detectors.params.Param`).

A detector never receives the truth of a run: it is only ever handed :class:`Signals`, and
the engine hands them read-only (:func:`read_only`): every detector of a campaign reads the
signals the plant produced, whatever another detector does with its own.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from typing import Mapping

import numpy as np

from scenarios.signals import Signals, read_only_view

from .params import Param, parameter_problems


class FrozenMapping(Mapping):
    """A read-only mapping of read-only arrays (``Signals.schedule``, ``aircraft`` and
    ``rods`` as a detector receives them): item assignment and deletion raise
    ``TypeError``. Unlike :class:`types.MappingProxyType` it pickles and deep-copies (a
    copy is an ordinary writeable dict of writeable arrays: the copy is the reader's
    own)."""

    __slots__ = ("_data",)

    def __init__(self, data: Mapping):
        self._data = dict(data)

    def __getitem__(self, key):
        return self._data[key]

    def __iter__(self) -> Iterator:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"FrozenMapping({self._data!r})"

    def __reduce__(self):
        return dict, (self._data,)

    def __deepcopy__(self, memo):
        import copy

        return {k: copy.deepcopy(v, memo) for k, v in self._data.items()}


def _read_only_array(value):
    """:func:`scenarios.signals.read_only_view` of an array (no copy); other values
    unchanged."""
    return read_only_view(value) if isinstance(value, np.ndarray) else value


def read_only(signals: Signals) -> Signals:
    """*signals* as a detector receives them: the same arrays, as views whose write flag is
    off, and the per-run mappings (``schedule``, ``aircraft``, ``rods``) as
    :class:`FrozenMapping` of such views. No data are copied (a view costs the same for a
    run of any length). A detector that writes into its input (``signals.rod_mon[:] = 0``,
    ``signals.schedule["vcas_kt"] *= 2``) raises ``ValueError: assignment destination is
    read-only`` or ``TypeError`` at that line, inside its own ``fit`` or ``detect``: the
    engine records that as its failure (:func:`campaign.evaluate.detect`) and the other
    detectors read the signals the plant produced (docs/write-a-detector.md, Signals and
    output). A detector that wants to change an array works on its own copy
    (``np.array(signals.rod_com)``)."""
    changes = {}
    for f in fields(signals):
        value = getattr(signals, f.name)
        if isinstance(value, Mapping):
            changes[f.name] = FrozenMapping({k: _read_only_array(v) for k, v in value.items()})
        elif isinstance(value, np.ndarray):
            changes[f.name] = _read_only_array(value)
    return replace(signals, **changes)


def writes_input(exc: BaseException) -> bool:
    """Whether *exc* is what a write into a :func:`read_only` input raises: NumPy's
    ``ValueError: assignment destination is read-only`` (or ``output array is read-only``),
    or the ``TypeError`` of an item assignment into a :class:`FrozenMapping`."""
    text = str(exc)
    return ((isinstance(exc, ValueError) and "read-only" in text)
            or (isinstance(exc, TypeError) and "FrozenMapping" in text))


class NotFittedError(RuntimeError):
    """Raised when ``detect`` is called on a detector that needs ``fit`` first."""


@dataclass(frozen=True)
class Capabilities:
    """What a detector needs and promises, as data the engine checks before a campaign."""

    needs_fit: bool = True
    needs_surface_sensor: bool = False
    needs_pressure_sensor: bool = False
    causal: bool = True
    #: reads the aircraft-level signals (Signals.aircraft, Signals.rods): campaigns must set
    #: [plant] kind = "aircraft" (detectors.compat)
    needs_aircraft: bool = False
    #: the plant surfaces (names of the run rows' ``surface``) whose faults this detector
    #: detects and isolates from every other surface's: in a campaign whose faults are on
    #: another surface, an alarm after onset is an isolation failure, not a detection
    #: (campaign.isolation, reports.scoring.gate). Empty: whatever surface the campaign monitors.
    fault_surfaces: tuple[str, ...] = ()
    #: its ``fit`` touches nothing but the detector itself and its read-only learning signals
    #: (no module-level cache, no solver state shared between instances), so the engine may
    #: fit it on a worker thread while the other detectors fit (campaign.runner.fit_detectors).
    #: False (the default): fitted one at a time, on the thread that runs the campaign.
    fit_concurrently: bool = False
    #: its detections carry an ``estimate`` of the rod fault ([CHEN] eq. 4), scored against
    #: the truth's rod fault, which a healthy servo model of every jam run computes
    #: (scenarios.signals.Truth). Informative: an estimate is scored whenever a detection
    #: gives one; ``fdd-campaign bench`` counts that model in the floor of campaigns with
    #: such a detector.
    estimates_rod_fault: bool = False
    #: its detections carry a ``decision`` statistic (:class:`Detection`): the alarm is
    #: raised at the first step where decision ≥ 1, and with every threshold of the
    #: detector multiplied by s > 0 it would be raised at the first step where decision ≥ s.
    #: A run's margin is then the distance to the alarm decision (margin ≥ s ⟺ an alarm
    #: before onset at threshold × s; docs/design.md §5, Metrics). False (the default of a
    #: plugin): the decision has no threshold scale, and the margin is the largest
    #: normalised residual before any confirmation logic, labelled so.
    threshold_scale: bool = False
    #: the fault types (``scenarios.catalog.FAULT_TYPES``) it is designed to detect, with
    #: ``coverage_reason`` saying why (a source, or what it cannot see): its missed-detection
    #: and detection-time requirements apply to those only, and its runs of other faults
    #: are reported as "not designed for" (:class:`Coverage`, :meth:`Detector.coverage`).
    #: Empty (the default): every fault type.
    covers: tuple[str, ...] = ()
    coverage_reason: str = ""


@dataclass(frozen=True)
class Coverage:
    """What a detector (variant) is designed to detect: the fault types *faults* (None: every
    fault type) and *reason*, the source of that design or what it cannot see. The gate
    holds a detector to its missed-detection and detection-time requirements on the faults
    it covers only (:func:`reports.scoring.gate.evaluate_gate`); the rest are reported, never
    failed."""

    faults: tuple[str, ...] | None = None
    reason: str = ""

    def covers(self, fault: str) -> bool:
        """Whether *fault* (a fault type) is one the detector is designed to detect."""
        return self.faults is None or fault in self.faults

    def union(self, other: "Coverage") -> "Coverage":
        """The coverage of an alarm raised by either detector (a detection system)."""
        if self.faults is None or other.faults is None:
            return Coverage(None, "")
        faults = tuple(dict.fromkeys(self.faults + other.faults))
        return Coverage(faults, "; ".join(r for r in (self.reason, other.reason) if r))


@dataclass(frozen=True)
class Detection:
    """Per-run decision of one detector (variant).

    alarm : ndarray (n_runs, n_steps) of bool
        Alarm flag at each step.
    residual : ndarray (n_runs, n_steps) of float
        The residual normalised by its threshold, |r|/τ: ≥ 1 means alarm (before any
        confirmation logic); used for margins and plots.
    estimate : ndarray (n_runs, n_steps) of float, or None (default)
        For a detector that *estimates* an additive fault on the rod measurement: its
        estimate f̂ [mm] of [CHEN] eq. 4 (e.g. ``chen-local``). The campaign then records the
        mean and variance of f̂ − f over each jam run's post-onset window
        (docs/chen-estimator.md §8). None: the detector gives no estimate.
    decision : ndarray (n_runs, n_steps) of float, or None (default)
        The statistic the alarm decision compares, normalised by the threshold and scaled
        as 1/s when every threshold is multiplied by s: the alarm is raised at the first
        step where decision ≥ 1 (after the confirmation logic: for a confirmation over n
        steps, the least normalised residual of the last n, :func:`windowed_min`), and
        would be raised at the first step where decision ≥ s at threshold × s. NaN: no
        decision possible at that step (no alarm at any scale). The run's margin is its
        largest value before onset (:func:`reports.scoring.metrics.score_columns`), so margin ≥ 1
        exactly when the run alarms before onset; the engine checks that the first alarm
        is the first step with decision ≥ 1 (:func:`detection_problems`). None: the
        decision has no threshold scale (``Capabilities.threshold_scale`` False) and the
        margin is the residual's.
    """

    alarm: np.ndarray
    residual: np.ndarray
    estimate: np.ndarray | None = None
    decision: np.ndarray | None = None

    @property
    def margin_statistic(self) -> np.ndarray:
        """What a run's margin is the largest value of before onset: ``decision`` when the
        detection gives one, else ``residual`` (docs/design.md §5, Metrics)."""
        return self.residual if self.decision is None else self.decision

    def __post_init__(self):
        alarm = np.asarray(self.alarm)
        residual = np.asarray(self.residual)
        if alarm.dtype != np.bool_:
            raise TypeError(f"Detection.alarm must be a bool array, got dtype {alarm.dtype}")
        if alarm.shape != residual.shape or alarm.ndim != 2:
            raise ValueError(
                f"Detection.alarm {alarm.shape} and residual {residual.shape} must both be "
                "(n_runs, n_steps)"
            )


class Detector:
    """Base class of every detector. Subclasses set :attr:`capabilities` and implement
    :meth:`_fit` (when ``needs_fit``) and :meth:`_detect`."""

    capabilities = Capabilities()

    #: The keyword parameters of ``__init__`` declared as data (type, range or choices,
    #: unit, doc): :meth:`validate_params`, the campaign-file validation and the reference
    #: docs/detectors.md read them. A detector that declares nothing has its values
    #: unchecked (its unknown parameter names are still refused).
    parameters: tuple[Param, ...] = ()

    # ---- parameters (scikit-learn style) ------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p.name for p in sig.parameters.values()
                if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self) -> dict:
        """The keyword parameters this detector was built with."""
        return {name: getattr(self, name) for name in self._param_names()}

    def validate_params(self) -> None:
        """Raise ``ValueError`` listing every parameter whose value breaks its declaration
        in :attr:`parameters` (:func:`detectors.params.parameter_problems`). Called by the
        registry before a campaign starts and by :meth:`fit`. A subclass with a check the
        declarations cannot express overrides this, calls ``super().validate_params()``
        first, then raises ``ValueError`` for its own check."""
        problems = parameter_problems(type(self), self.get_params())
        if len(problems) == 1:
            raise ValueError(f"{type(self).__name__}: {problems[0]}")
        if problems:
            raise ValueError(f"{type(self).__name__} has {len(problems)} invalid parameters:\n"
                             + "\n".join(f"  - {msg}" for msg in problems))

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def coverage(self, variant: str | None = None) -> Coverage:
        """The fault types this detector (its variant *variant*, the name inside the
        brackets of a result name) is designed to detect: by default what
        :attr:`Capabilities.covers` declares (every fault type when it declares none). A
        detector whose coverage depends on its parameters or variants overrides this."""
        caps = self.capabilities
        covers = tuple(getattr(caps, "covers", ()) or ())
        return Coverage(covers or None, getattr(caps, "coverage_reason", "") or "")

    def variant_names(self) -> tuple[str, ...] | None:
        """The variant names (inside the brackets of ``label[variant]``) that :meth:`detect`
        gives, when its parameters fix them before it runs (a campaign file's ``[[system]]``
        members are checked against them before any work); None (the default): not known
        until it runs, or a single Detection."""
        return None

    # ---- learning and detection --------------------------------------------------------
    @property
    def is_fitted(self) -> bool:
        return (not self.capabilities.needs_fit) or bool(self.fitted_state())

    def fitted_state(self) -> dict:
        """Learned attributes (names ending in ``_``), for storage with the results."""
        return {k: v for k, v in vars(self).items() if k.endswith("_") and not k.startswith("_")}

    def fit(self, signals: Signals) -> "Detector":
        """Learn from fault-free runs; returns ``self``. Checks the parameters
        (:meth:`validate_params`) and the signals (:meth:`check_signals`) first."""
        self.validate_params()
        self.check_signals(signals)
        self._fit(signals)
        return self

    def detect(self, signals: Signals) -> Detection | Mapping[str, Detection]:
        """Alarms and normalised residuals for each run of *signals*."""
        if not self.is_fitted:
            raise NotFittedError(
                f"{type(self).__name__}.detect() called before fit(): this detector learns "
                "its thresholds from fault-free runs; call fit(learning_signals) first"
            )
        self.check_signals(signals)
        return self._detect(signals)

    def check_signals(self, signals: Signals) -> None:
        """Raise ``ValueError`` if *signals* lack what this detector needs."""
        caps = self.capabilities
        if caps.needs_surface_sensor and not signals.has_surface_sensor:
            raise ValueError(
                f"{type(self).__name__} needs a surface position sensor, but the "
                "simulated surface has none (surface signal is NaN)"
            )
        if caps.needs_pressure_sensor and not signals.has_pressure_sensor:
            raise ValueError(
                f"{type(self).__name__} needs the chamber pressure sensor; enable it in the "
                "campaign file ([campaign] pressure_sensor = true)"
            )
        if caps.needs_aircraft and (signals.aircraft is None or signals.rods is None):
            raise ValueError(
                f"{type(self).__name__} needs the aircraft-level signals (Signals.aircraft and "
                "Signals.rods), which only the aircraft plant gives: set [plant] kind = "
                "\"aircraft\" in the campaign file (or run with --plant aircraft)"
            )

    def _fit(self, signals: Signals) -> None:  # pragma: no cover - overridden when needed
        return None

    def _detect(self, signals: Signals):
        raise NotImplementedError(f"{type(self).__name__} must implement _detect(signals)")


def detection_problems(detection: Detection, n_runs: int, n_steps: int) -> list[str]:
    """Every rule of the output contract *detection* breaks for signals of *n_runs* runs of
    *n_steps* samples, one message each (empty: it keeps the contract).

    The rules (docs/write-a-detector.md, Signals and output), the same for the engine's
    check after every ``detect`` (:func:`campaign.evaluate.detect`) and for
    :func:`detectors.testing.check_detector`:

    * ``alarm`` is a bool array and ``residual`` a float array, both exactly
      (n_runs, n_steps), the shape of the signals (and ``estimate``, when given);
    * ``residual`` is finite, except NaN samples at the start of a run (a filter warming
      up: "no residual yet"), which scoring ignores (the margin of
      :func:`reports.scoring.metrics.score_runs` skips NaN); a NaN after the first non-NaN sample
      of a run, or ±inf anywhere, is a breach.
    """
    alarm, residual = np.asarray(detection.alarm), np.asarray(detection.residual)
    want = (int(n_runs), int(n_steps))
    problems = []
    estimate = getattr(detection, "estimate", None)
    if estimate is not None and np.shape(estimate) != want:
        problems.append(f"estimate, when given, must have the shape of the signals (n_runs, "
                        f"n_steps) = {want}, got {np.shape(estimate)}")
    if alarm.dtype != np.bool_:
        problems.append(f"alarm must be a bool array, got dtype {alarm.dtype}")
    if alarm.shape != want:
        problems.append(f"alarm must have the shape of the signals (n_runs, n_steps) = "
                        f"{want}, got {alarm.shape}")
    if not np.issubdtype(residual.dtype, np.floating):
        problems.append(f"residual must be a float array, got dtype {residual.dtype}")
        return problems
    if residual.shape != want:
        problems.append(f"residual must have the shape of the signals (n_runs, n_steps) = "
                        f"{want}, got {residual.shape}")
        return problems
    bad = residual_breaches(residual)
    if bad.any():
        i, k = (int(v) for v in np.argwhere(bad)[0])
        value = residual[i, k]
        what = ("±inf is never allowed" if np.isinf(value) else
                "NaN is allowed only before the first non-NaN sample of a run (warm-up)")
        problems.append(f"residual must be finite floats ({what}): got {value} at run {i}, "
                        f"step {k} ({int(bad.any(axis=1).sum())} of {want[0]} runs affected)")
    decision = getattr(detection, "decision", None)
    if decision is not None and alarm.shape == want and alarm.dtype == np.bool_:
        problems.extend(decision_problems(alarm, np.asarray(decision), want))
    return problems


def decision_problems(alarm: np.ndarray, decision: np.ndarray,
                      want: tuple[int, int]) -> list[str]:
    """The rules a ``decision`` breaks (:func:`detection_problems`): a float array of the
    signals' shape, never ±inf, whose first step ≥ 1 in each run is the run's first alarm
    (no such step: no alarm). This is what makes the margin the distance to the alarm:
    margin ≥ 1 exactly when the run alarms before onset."""
    if not np.issubdtype(decision.dtype, np.floating):
        return [f"decision, when given, must be a float array, got dtype {decision.dtype}"]
    if decision.shape != want:
        return [f"decision, when given, must have the shape of the signals (n_runs, n_steps) "
                f"= {want}, got {decision.shape}"]
    if np.isinf(decision).any():
        i, k = (int(v) for v in np.argwhere(np.isinf(decision))[0])
        return [f"decision must not be ±inf (NaN: no decision at that step): got "
                f"{decision[i, k]} at run {i}, step {k}"]
    first_alarm = first_steps(alarm)
    first_decision = first_steps(decision_reached(decision))
    differ = first_alarm != first_decision
    if not differ.any():
        return []
    i = int(np.flatnonzero(differ)[0])

    def at(k):
        return "never" if k < 0 else f"step {k}"

    return [f"alarm and decision disagree: the first alarm must be the first step where "
            f"decision ≥ 1; run {i}: first alarm {at(first_alarm[i])}, decision ≥ 1 "
            f"{at(first_decision[i])} ({int(differ.sum())} of {want[0]} runs affected)"]


def first_steps(mask: np.ndarray) -> np.ndarray:
    """(n_runs,) index of the first True step of each run of *mask* (n_runs, n_steps), −1
    where there is none."""
    mask = np.asarray(mask, dtype=bool)
    if mask.shape[1] == 0:
        return np.full(mask.shape[0], -1)
    idx = np.argmax(mask, axis=1)
    return np.where(mask[np.arange(mask.shape[0]), idx], idx, -1)


def decision_reached(decision: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(n_runs, n_steps) bool: where *decision* ≥ *scale* (NaN: False)."""
    with np.errstate(invalid="ignore"):
        return np.asarray(decision) >= scale


def decide(decision: np.ndarray) -> np.ndarray:
    """The latched alarm of a *decision* statistic (:class:`Detection`): raised at the first
    step where decision ≥ 1 and kept until the end of the run."""
    return np.logical_or.accumulate(decision_reached(decision), axis=1)


def at_threshold_scale(detection: Detection, scale: float) -> Detection:
    """*detection* as its detector would give it with every threshold multiplied by *scale*
    (> 0): the decision and the normalised residual divided by *scale*, the alarm raised at
    the first step where the scaled decision reaches 1 and latched (:func:`decide`); the
    estimate unchanged. Since ``d/s ≥ 1`` exactly when ``d ≥ s`` (a correctly rounded
    division by s > 0 is monotone and 1 is a double), the alarm is raised at the first step
    where the decision reaches *scale*, the rule of :class:`Detection`. Scale 1 (or a
    detection without a decision) returns *detection* itself."""
    scale = float(scale)
    if scale == 1.0 or detection.decision is None:
        return detection
    decision = np.asarray(detection.decision, dtype=float) / scale
    return Detection(alarm=decide(decision), residual=np.asarray(detection.residual) / scale,
                     estimate=detection.estimate, decision=decision)


def set_threshold_scale(detector: "Detector", scale: float) -> "Detector":
    """Make the engine multiply every threshold of *detector* by *scale* (> 0) when it
    runs it (:func:`threshold_scale_of`, :func:`at_threshold_scale`; a campaign file's
    ``[[detector]] threshold_scale``); returns *detector*. Nothing of the detector changes
    but this mark, which is not a learned attribute: its stored fitted state is the same at
    every scale. ``ValueError`` for a scale that is not a finite number > 0 or a detector
    whose capabilities do not declare ``threshold_scale``."""
    scale = float(scale)
    if not (np.isfinite(scale) and scale > 0.0):
        raise ValueError(f"threshold scale must be a finite number > 0, got {scale!r}")
    if scale != 1.0 and not getattr(detector.capabilities, "threshold_scale", False):
        raise ValueError(f"{type(detector).__name__} has no threshold scale (its "
                         "Capabilities.threshold_scale is False: its alarm is not a decision "
                         "statistic compared with 1), so its thresholds cannot be scaled")
    vars(detector)["_threshold_scale"] = scale
    return detector


def set_threshold_scales(detectors: Mapping, scales: Mapping) -> Mapping:
    """:func:`set_threshold_scale` on each of *detectors* (label → Detector) that *scales*
    (label → factor) names; returns *detectors*. ``ValueError`` naming the label of a
    detector that cannot take its factor."""
    for label, scale in scales.items():
        if label in detectors:
            try:
                set_threshold_scale(detectors[label], scale)
            except ValueError as exc:
                raise ValueError(f"detector {label!r}: threshold_scale = {float(scale):g}: "
                                 f"{exc}") from None
    return detectors


def threshold_scale_of(detector) -> float:
    """The factor the engine multiplies *detector*'s thresholds by (1 unless
    :func:`set_threshold_scale` set another)."""
    return float(vars(detector).get("_threshold_scale", 1.0)) if hasattr(
        detector, "__dict__") else 1.0


def windowed_min(statistic: np.ndarray, n: int) -> np.ndarray:
    """The least value of *statistic* (n_runs, n_steps) over each step's last *n* steps
    [k − n + 1, k] (n ≥ 1), NaN before a full window exists (k < n − 1) and wherever the
    window holds a NaN: the decision statistic of a confirmation over n steps. With it,
    ``confirm(statistic >= 1, n)`` is ``decide(windowed_min(statistic, n))``, and the
    alarm at threshold × s is raised where ``windowed_min`` first reaches s (the least of
    the window scales with the threshold as each sample does)."""
    statistic = np.asarray(statistic, dtype=float)
    n = max(int(n), 1)
    out = statistic.copy()
    for j in range(1, min(n, out.shape[1] + 1)):
        np.minimum(out[:, j:], statistic[:, :-j], out=out[:, j:])
    out[:, :n - 1] = np.nan
    return out


def residual_breaches(residual: np.ndarray) -> np.ndarray:
    """(n_runs, n_steps) bool: the samples of *residual* the output contract refuses (±inf,
    and NaN after the first non-NaN sample of its run; :func:`detection_problems`)."""
    residual = np.asarray(residual, dtype=float)
    if np.isfinite(residual).all():     # the usual case, in one pass: nothing refused
        return np.zeros(residual.shape, dtype=bool)
    nan = np.isnan(residual)
    started = np.logical_or.accumulate(~nan, axis=1) if residual.ndim == 2 else ~nan
    return np.isinf(residual) | (nan & started)


def as_variants(name: str, output) -> dict[str, Detection]:
    """Normalise ``detect`` output to ``{detector_variant_name: Detection}``."""
    if isinstance(output, Detection):
        return {name: output}
    if isinstance(output, Mapping):
        out = {}
        for variant, det in output.items():
            if not isinstance(det, Detection):
                raise TypeError(f"detector {name!r} variant {variant!r} returned "
                                f"{type(det).__name__}, expected Detection")
            out[f"{name}[{variant}]"] = det
        return out
    raise TypeError(f"detector {name!r} returned {type(output).__name__}; expected a "
                    "Detection or a mapping of variant name to Detection")


def confirm(raw: np.ndarray, n_confirm: int) -> np.ndarray:
    """Latching confirmation: alarm from the step where *raw* has been true for *n_confirm*
    consecutive steps (n_confirm ≥ 1), kept until the end of the run. Causal and
    vectorised over runs (axis 0)."""
    raw = np.asarray(raw, dtype=bool)
    n_confirm = max(int(n_confirm), 1)
    if n_confirm == 1:
        confirmed = raw
    else:
        # length of the current run of consecutive True values, per step
        idx = np.arange(raw.shape[1])
        last_false = np.where(~raw, idx, -1)
        np.maximum.accumulate(last_false, axis=1, out=last_false)
        confirmed = (idx - last_false) >= n_confirm
    return np.logical_or.accumulate(confirmed, axis=1)


#: Runs a built-in detector's ``fit`` carries through its residuals at once
#: (:func:`per_run_maxima`). A learning set of an aircraft campaign holds ~1 MB per run and
#: a fit's residuals several series per run more, so the whole set at once added 90–140 MB
#: to the campaign's peak (`fdd-campaign bench --campaign chen-mc`); 25 runs add a twelfth.
FIT_BLOCK_RUNS = 25


def per_run_maxima(signals: Signals, statistics, block_runs: int | None = None
                   ) -> dict[str, np.ndarray]:
    """{name: (n_runs,) array} of *statistics*, a function of a block of runs returning
    {name: (runs, n_steps) series}, each reduced to its maximum over the run's steps.

    The runs are taken *block_runs* (default :data:`FIT_BLOCK_RUNS`) at a time (views of
    *signals*), so only one block's series exist at once. Each run's maximum is the one the
    whole set at once gives: a built-in detector's residual of a run never depends on the
    other runs of its batch (the batch invariance the engine relies on at any ``--jobs``,
    docs/design.md §4)."""
    block_runs = max(int(FIT_BLOCK_RUNS if block_runs is None else block_runs), 1)
    parts: dict[str, list] = {}
    for start in range(0, signals.n_runs, block_runs):
        block = signals.take(slice(start, start + block_runs))
        for name, series in statistics(block).items():
            parts.setdefault(name, []).append(np.max(series, axis=1))
    return {name: np.concatenate(p) for name, p in parts.items()}
