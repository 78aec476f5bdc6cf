"""``check_detector``: the public conformance checks of the detector contract.

Any third party can test a plugin with::

    from detectors.testing import check_detector
    check_detector(MyDetector())

It simulates a small batch of fault-free learning runs and mixed evaluation runs (with the
aircraft in the loop for a detector whose capabilities declare ``needs_aircraft``), then
checks, on any detector (docs/design.md §4, Contracts):

* ``detect`` before ``fit`` raises :class:`~detectors.NotFittedError` (when it needs fit),
  with a message that says to call ``fit``;
* ``__init__`` stores its parameters unchanged: rebuilding the detector from
  ``get_params()`` gives the same parameters, and the defaults pass ``validate_params``;
* ``fit`` returns ``self`` and stores learned state only in attributes ending in ``_``;
  it leaves ``get_params`` unchanged; neither ``fit`` nor ``detect`` modifies the signals
  it is given;
* shapes and dtypes: alarm bool, residual float, both (n_runs, n_steps), residual finite;
* determinism: detecting twice gives identical output, and so does a second detector
  fitted afresh on the same learning set;
* batch invariance: a run's result does not depend on the other runs of the batch;
* causality: truncating the future never changes past alarms or residuals;
* picklability: a fitted detector survives a pickle round trip with identical output
  (workers receive detectors pickled).

A failed check raises :class:`DetectorCheckError` naming the check and what differed.
"""

from __future__ import annotations

import copy
import functools
import pickle

import numpy as np
import pandas as pd

from scenarios.signals import SIGNAL_UNITS

from .base import Detection, Detector, NotFittedError, as_variants


class DetectorCheckError(AssertionError):
    """A detector broke its contract; the message names the check."""


def _batch(surface: str, duration_s: float, aircraft: bool = False) -> tuple:
    """Fresh copies of the (cached) learning and evaluation signals."""
    make = _aircraft_batch if aircraft else _simulated_batch
    return tuple(copy.deepcopy(s) for s in make(surface, float(duration_s)))


#: Monitored surface of the aircraft-level batch when the detector needs the aircraft plant.
AIRCRAFT_SURFACE = "left_inboard_aileron"


#: Manoeuvres of the fault-free learning runs of the conformance batches.
LEARNING_MANOEUVRES = ("cruise", "nose_up", "turn_coordination")

#: Evaluation runs: (manoeuvre, fault, keywords of single_run).
ACTUATOR_CASES = (
    ("cruise", "none", {"vcas_kt": 220.0}),
    ("nose_up", "runaway", {"onset_s": 8.0}),
    ("aoa_protection", "solid_jam", {"onset_s": 6.0, "alt_ft": 18000.0}),
    ("cruise", "liquid_jam", {"onset_s": 9.0}),
)
AIRCRAFT_CASES = (
    ("cruise", "none", {"vcas_kt": 220.0}),
    ("yaw_angle_mode", "none", {}),
    ("cruise", "disconnection", {"onset_s": 8.0, "alt_ft": 18000.0}),
    ("aoa_protection", "solid_jam", {"onset_s": 6.0}),
)


def _signals_of(surface: str, duration_s: float, cases, plant: str) -> tuple:
    """Learning and evaluation signals: fault-free learning runs of
    :data:`LEARNING_MANOEUVRES` (seed 11), evaluation runs of *cases* (seed 12)."""
    from scenarios.plants import simulate
    from scenarios.simulate import single_run

    learn = pd.concat([single_run(surface, m, "none", seed=11, duration_s=duration_s)
                       .assign(stream=j, run_id=f"learn-{j}")
                       for j, m in enumerate(LEARNING_MANOEUVRES)], ignore_index=True)
    evaluation = pd.concat([single_run(surface, m, fault, seed=12, duration_s=duration_s, **kw)
                            for m, fault, kw in cases], ignore_index=True)
    evaluation["stream"] = np.arange(len(evaluation))
    evaluation["run_id"] = [f"eval-{j}" for j in range(len(evaluation))]
    return simulate(learn, plant=plant)[0], simulate(evaluation, plant=plant)[0]


@functools.lru_cache(maxsize=2)
def _aircraft_batch(surface: str, duration_s: float) -> tuple:
    """Learning and evaluation signals at the aircraft plant level (monitored *surface*)."""
    return _signals_of(surface, duration_s, AIRCRAFT_CASES, "aircraft")


@functools.lru_cache(maxsize=4)
def _simulated_batch(surface: str, duration_s: float) -> tuple:
    """Learning and evaluation signals at the actuator level."""
    return _signals_of(surface, duration_s, ACTUATOR_CASES, "actuator")


def _variants(det, signals) -> dict[str, Detection]:
    return as_variants("detector", det.detect(signals))


def _same(a: dict, b: dict, what: str, sl=slice(None), row: int | None = None) -> None:
    """Raise unless *b* equals *a* (restricted to columns *sl*, and to run *row* of *a*)."""
    if set(a) != set(b):
        raise DetectorCheckError(f"{what}: variants differ ({sorted(a)} vs {sorted(b)})")
    rows = slice(None) if row is None else slice(row, row + 1)
    for name in a:
        for field in ("alarm", "residual"):
            x = getattr(a[name], field)[rows, sl]
            y = getattr(b[name], field)[:, sl]
            if not np.array_equal(x, y, equal_nan=True):
                raise DetectorCheckError(f"{what}: {name} {field} differs")


def check_detector(detector: Detector, *, surface: str = "elevator",
                   duration_s: float = 20.0) -> None:
    """Run every contract check on *detector*; raises :class:`DetectorCheckError`.

    A detector whose capabilities say ``needs_aircraft`` is checked on aircraft-plant
    signals (monitored surface :data:`AIRCRAFT_SURFACE` unless *surface* names an aircraft
    surface)."""
    if not isinstance(detector, Detector):
        raise DetectorCheckError(f"{type(detector).__name__} does not subclass detectors.Detector")
    params = detector.get_params()
    try:
        rebuilt = type(detector)(**params)
    except TypeError as exc:
        raise DetectorCheckError(f"__init__ must accept its own get_params() as keywords: {exc}")
    if rebuilt.get_params() != params:
        raise DetectorCheckError("__init__ must store its keyword parameters unchanged "
                                 "(type(det)(**det.get_params()).get_params() differs)")
    try:
        rebuilt.validate_params()
    except ValueError as exc:
        raise DetectorCheckError(f"validate_params() rejects the detector's own parameters: {exc}")
    aircraft = bool(getattr(detector.capabilities, "needs_aircraft", False))
    if aircraft:
        from scenarios.aircraft.data import AIRCRAFT_SURFACES

        surface = surface if surface in AIRCRAFT_SURFACES else AIRCRAFT_SURFACE
    learn, ev = _batch(surface, duration_s, aircraft)
    det = copy.deepcopy(detector)

    if det.capabilities.needs_fit:
        try:
            det.detect(ev)
        except NotFittedError as exc:
            if "fit" not in str(exc):
                raise DetectorCheckError("the NotFittedError of detect() before fit() must say "
                                         f"to call fit(); got: {exc}")
        else:
            raise DetectorCheckError("detect() before fit() must raise NotFittedError")
    before = {name: np.array(getattr(learn, name), copy=True) for name in SIGNAL_UNITS}
    returned = det.fit(learn)
    for name, arr in before.items():
        if not np.array_equal(arr, getattr(learn, name), equal_nan=True):
            raise DetectorCheckError(f"fit() modified the learning signals ({name})")
    if returned is not det:
        raise DetectorCheckError("fit() must return self")
    if det.get_params() != params:
        raise DetectorCheckError("fit() changed the constructor parameters (get_params)")
    if det.capabilities.needs_fit and not det.fitted_state():
        raise DetectorCheckError("fit() stored no learned attribute ending in '_'")

    before = {name: np.array(getattr(ev, name), copy=True) for name in SIGNAL_UNITS}
    out = _variants(det, ev)
    for name, arr in before.items():
        if not np.array_equal(arr, getattr(ev, name), equal_nan=True):
            raise DetectorCheckError(f"detect() modified the signals it was given ({name})")
    for name, d in out.items():
        if d.alarm.dtype != np.bool_ or d.alarm.shape != ev.command.shape:
            raise DetectorCheckError(f"{name}: alarm must be bool of shape {ev.command.shape}")
        if not np.issubdtype(d.residual.dtype, np.floating) or not np.isfinite(d.residual).all():
            raise DetectorCheckError(f"{name}: residual must be finite floats")

    _same(out, _variants(det, ev), "determinism")
    refit = copy.deepcopy(detector).fit(learn)
    _same(out, _variants(refit, ev), "determinism (fitted again on the same learning set)")

    for j in range(ev.n_runs):
        alone = _variants(det, ev.take([j]))
        _same(out, alone, f"batch invariance (run {j} alone)", row=j)
    reordered = _variants(det, ev.take(np.arange(ev.n_runs)[::-1]))
    for name in out:
        for field in ("alarm", "residual"):
            if not np.array_equal(getattr(out[name], field)[::-1], getattr(reordered[name], field),
                                  equal_nan=True):
                raise DetectorCheckError(f"batch invariance: {name} {field} depends on run order")

    if det.capabilities.causal:
        for cut in (ev.n_steps // 3, ev.n_steps // 2 + 7):
            part = _variants(det, ev.truncate(cut))
            _same(out, part, f"causality (truncated at step {cut})", sl=slice(0, cut))

    clone = pickle.loads(pickle.dumps(det))
    _same(out, _variants(clone, ev), "pickle round trip")
