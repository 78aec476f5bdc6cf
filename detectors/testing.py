"""``check_detector``: the public conformance checks of the detector contract.

Any third party can test a plugin with::

    from detectors.testing import check_detector
    check_detector(MyDetector())

or, with one pytest test id per check (as scikit-learn's ``parametrize_with_checks``)::

    from detectors.testing import parametrize_with_checks

    @parametrize_with_checks([MyDetector(), MyDetector(pole=0.5)])
    def test_my_detector(check):
        check()

It simulates a small batch of fault-free learning runs and mixed evaluation runs (with the
aircraft in the loop for a detector whose capabilities declare ``needs_aircraft``), then
checks, on any detector (docs/design.md §4, Contracts):

* ``detect`` before ``fit`` raises :class:`~detectors.NotFittedError` (when it needs fit),
  with a message that says to call ``fit``;
* ``__init__`` stores its parameters unchanged: rebuilding the detector from
  ``get_params()`` gives the same parameters, and they pass ``validate_params``;
* the parameter declarations (``Detector.parameters``) name ``__init__`` keywords, once
  each, and the defaults satisfy them;
* ``fit`` returns ``self`` and stores learned state only in attributes ending in ``_``;
  it leaves ``get_params`` unchanged; neither ``fit`` nor ``detect`` modifies the signals
  it is given: both receive them read-only, as in a campaign
  (:func:`detectors.base.read_only`); one that writes into them (and so raises) is run
  again on a copy of its own, so that ``fit_leaves_signals`` or ``detect_leaves_signals``
  names the signal, run and step it wrote and the other checks still judge its output;
* shapes and dtypes: alarm bool, residual float, both (n_runs, n_steps), residual finite
  but for NaN warm-up samples at the start of a run — the rule the engine applies to every
  ``detect`` of a campaign (:func:`detectors.detection_problems`);
* determinism: detecting twice gives identical output, and so does a second detector
  fitted afresh on the same learning set;
* batch invariance: a run's result does not depend on the other runs of the batch;
* causality: truncating the future never changes past alarms or residuals;
* picklability: a fitted detector survives a pickle round trip with identical output
  (workers receive detectors pickled);
* stored as data: its parameters and learned attributes are plain data
  (:mod:`detectors.state`), and the detector rebuilt from them — made afresh from its
  parameters, the learned attributes set, as a campaign directory reads it back without
  unpickling — gives bit-identical output.

Every check runs, also after another failed: :func:`check_detector` raises one
:class:`DetectorCheckError` listing every failed check, each with the run (index and run
id) and the first step that differ where that applies. :func:`detector_checks` gives the
checks one by one.
"""

from __future__ import annotations

import copy
import functools
import io
import json
import pickle
from collections.abc import Callable, Iterator, Mapping, Sequence

import numpy as np
import pandas as pd

from scenarios.plants import get_plant
from scenarios.signals import SIGNAL_UNITS

from .base import (
    Detection,
    Detector,
    NotFittedError,
    as_variants,
    detection_problems,
    read_only,
    writes_input,
)
from .compat import incompatibilities
from .params import declared_parameters, parameter_problems, signature_defaults
from .state import StateTypeError, decode, encode


class DetectorCheckError(AssertionError):
    """A detector broke its contract. The message names each failed check;
    :attr:`failures` holds them as (check name, what went wrong)."""

    def __init__(self, message: str, failures: Sequence[tuple[str, str]] = ()):
        super().__init__(message)
        self.failures = tuple(tuple(f) for f in failures)

    def __reduce__(self):
        return type(self), (self.args[0], self.failures)


def _batch(surface: str, duration_s: float, aircraft: bool = False,
           pressure: bool = False) -> tuple:
    """Fresh copies of the (cached) learning and evaluation signals (*pressure*: with the
    chamber pressure sensor)."""
    make = _aircraft_batch if aircraft else _simulated_batch
    return tuple(copy.deepcopy(s) for s in make(surface, float(duration_s), bool(pressure)))


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


def _signals_of(surface: str, duration_s: float, cases, plant: str, pressure: bool) -> tuple:
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
    return (simulate(learn, plant=plant, pressure_sensor=pressure)[0],
            simulate(evaluation, plant=plant, pressure_sensor=pressure)[0])


@functools.lru_cache(maxsize=2)
def _aircraft_batch(surface: str, duration_s: float, pressure: bool) -> tuple:
    """Learning and evaluation signals at the aircraft plant level (monitored *surface*)."""
    return _signals_of(surface, duration_s, AIRCRAFT_CASES, "aircraft", pressure)


@functools.lru_cache(maxsize=4)
def _simulated_batch(surface: str, duration_s: float, pressure: bool) -> tuple:
    """Learning and evaluation signals at the actuator level."""
    return _signals_of(surface, duration_s, ACTUATOR_CASES, "actuator", pressure)


def _on(method, signals):
    """``method(signals)`` (a detector's ``fit`` or ``detect``) with the signals read-only,
    as a campaign hands them; a detector that writes into them (and so raises there) is
    called again on *signals* themselves, a copy the check owns, so that the write is
    reported where it happens (:func:`_unchanged`) and the other checks see its output."""
    try:
        return method(read_only(signals))
    except Exception as exc:
        if not writes_input(exc):
            raise
        return method(signals)


def _variants(det, signals) -> dict[str, Detection]:
    """The variants of fitted *det* on *signals* (:func:`_on`)."""
    return as_variants("detector", _on(det.detect, signals))


def _run_text(signals, j: int) -> str:
    """The text ``run j (run id)`` of run *j* of *signals*."""
    ids = getattr(signals, "run_ids", None)
    return f"run {j} ({ids[j]})" if ids is not None and j < len(ids) else f"run {j}"


def _first_difference(x: np.ndarray, y: np.ndarray) -> tuple[int, int] | None:
    """(row, step) of the first element where *x* and *y* differ (NaN equals NaN), or None."""
    x, y = np.asarray(x), np.asarray(y)
    differ = x != y
    if np.issubdtype(x.dtype, np.floating) and np.issubdtype(y.dtype, np.floating):
        differ &= ~(np.isnan(x) & np.isnan(y))
    hit = np.argwhere(np.atleast_2d(differ))
    return None if len(hit) == 0 else (int(hit[0][0]), int(hit[0][-1]))


def _same(a: dict, b: dict, what: str, signals, runs: Sequence[int], sl=slice(None)) -> None:
    """Raise unless the variants *b* equal those of *a*: row ``i`` of *b* is run
    ``runs[i]`` of *a* (and of *signals*), compared over the steps *sl*."""
    if set(a) != set(b):
        raise DetectorCheckError(f"{what}: variants differ ({sorted(a)} vs {sorted(b)})")
    for name in a:
        for field in ("alarm", "residual"):
            x = getattr(a[name], field)[list(runs), sl]
            y = getattr(b[name], field)[:, sl]
            if x.shape != y.shape:
                raise DetectorCheckError(f"{what}: {name} {field} has shape {y.shape}, "
                                         f"expected {x.shape}")
            hit = _first_difference(x, y)
            if hit is not None:
                i, k = hit
                step = k + (sl.start or 0)
                raise DetectorCheckError(
                    f"{what}: {name} {field} differs, first at {_run_text(signals, runs[i])}, "
                    f"step {step}: {_value(x[i, k])} vs {_value(y[i, k])}")


def _value(v) -> str:
    """A NumPy scalar as its plain Python repr."""
    return repr(v.item() if isinstance(v, np.generic) else v)


def _snapshot(signals) -> dict[str, np.ndarray]:
    return {name: np.array(getattr(signals, name), copy=True) for name in SIGNAL_UNITS}


def _unchanged(before: dict, signals, what: str) -> None:
    """Raise if a signal of *signals* differs from its copy in *before*."""
    for name, arr in before.items():
        now = np.asarray(getattr(signals, name))
        if arr.shape != now.shape:
            raise DetectorCheckError(f"{what} ({name}: shape {arr.shape} became {now.shape})")
        hit = _first_difference(arr, now)
        if hit is not None:
            i, k = hit
            where = f", first at {_run_text(signals, i)}, step {k}" if arr.ndim == 2 else ""
            raise DetectorCheckError(f"{what} ({name}{where}); a campaign hands them "
                                     "read-only: there the write raises and the detector's "
                                     "runs are errors (work on a copy: "
                                     "np.array(signals.rod_com))")


class _NotRun(Exception):
    """A stage a check needs failed (fit or detect raised): the check cannot run."""


class _SetupError(RuntimeError):
    """The conformance signals could not be simulated: not the detector's fault."""


class _Context:
    """What the checks of one detector share, computed once and on demand: the signals,
    the detector fitted on the learning runs and its output on the evaluation runs. The
    checks never modify it: each works on fresh copies of the signals."""

    def __init__(self, detector: Detector, surface: str, duration_s: float):
        self.detector = detector
        self.surface = surface
        self.duration_s = float(duration_s)
        self._stages: dict[str, object] = {}

    def _stage(self, key: str, make: Callable[[], object]):
        if key not in self._stages:
            try:
                self._stages[key] = ("ok", make())
            except (DetectorCheckError, _NotRun, _SetupError):
                raise
            except Exception as exc:        # the detector's own failure, reported per check
                self._stages[key] = ("error", f"{type(exc).__name__}: {exc}")
        status, value = self._stages[key]
        if status == "error":
            raise _NotRun(f"{key} raised {value}")
        return value

    @property
    def params(self) -> dict:
        return self._stage("get_params()", self.detector.get_params)

    def signals(self) -> tuple:
        """Fresh copies of the (learning, evaluation) signals."""
        def make():
            caps = self.detector.capabilities
            aircraft = bool(getattr(caps, "needs_aircraft", False))
            pressure = bool(getattr(caps, "needs_pressure_sensor", False))
            plant = get_plant("aircraft" if aircraft else "actuator")
            surface = self.surface
            if aircraft and surface not in plant.surfaces:
                surface = AIRCRAFT_SURFACE
            # the campaign's compatibility rule: signals this detector cannot read are a
            # choice of the check, not a breach of the detector
            problems = incompatibilities({type(self.detector).__name__: caps}, plant, surface,
                                         pressure_sensor=pressure)
            if problems:
                raise ValueError("; ".join(problems) + " (check_detector's surface= "
                                 "chooses the simulated surface)")
            return _batch(surface, self.duration_s, aircraft, pressure)

        if "signals" not in self._stages:
            try:
                self._stages["signals"] = ("ok", make())
            except Exception as exc:
                raise _SetupError(f"cannot simulate the conformance signals: {exc}") from exc
        return tuple(copy.deepcopy(s) for s in self._stages["signals"][1])

    def fitted(self) -> dict:
        """The fit of a copy of the detector on the learning signals: the detector, what
        fit returned, the learning signals before and after."""
        def make():
            learn, _ = self.signals()
            det = copy.deepcopy(self.detector)
            before = _snapshot(learn)
            returned = _on(det.fit, learn)
            return {"det": det, "returned": returned, "before": before, "learn": learn}

        return self._stage("fit()", make)

    def output(self) -> dict:
        """The fitted detector's output on the evaluation signals, and those signals before
        and after detect."""
        def make():
            det = self.fitted()["det"]
            _, ev = self.signals()
            before = _snapshot(ev)
            return {"out": _variants(det, ev), "before": before, "ev": ev}

        self.fitted()                  # a failed fit is reported as such, not as detect's
        return self._stage("detect()", make)


# ---- the checks (each takes the shared context, raises DetectorCheckError) -------------
def _check_init_stores_params(ctx: _Context) -> None:
    det = ctx.detector
    params = ctx.params
    try:
        rebuilt = type(det)(**params)
    except TypeError as exc:
        raise DetectorCheckError(f"__init__ must accept its own get_params() as keywords: {exc}")
    if rebuilt.get_params() != params:
        changed = sorted(k for k, v in rebuilt.get_params().items() if params.get(k) != v)
        raise DetectorCheckError("__init__ must store its keyword parameters unchanged "
                                 "(type(det)(**det.get_params()).get_params() differs"
                                 f"{': ' + ', '.join(changed) if changed else ''})")


def _check_params_validate(ctx: _Context) -> None:
    det = ctx.detector
    try:
        det = type(det)(**ctx.params)
    except TypeError:           # reported by init_stores_params; validate the detector itself
        det = copy.deepcopy(det)
    try:
        det.validate_params()
    except ValueError as exc:
        raise DetectorCheckError(f"validate_params() rejects the detector's own parameters: {exc}")


def _check_declared_params(ctx: _Context) -> None:
    cls = type(ctx.detector)
    known = signature_defaults(cls)
    names = [p.name for p in declared_parameters(cls)]
    unknown = [n for n in names if n not in known]
    repeated = sorted({n for n in names if names.count(n) > 1})
    problems = []
    if unknown:
        problems.append(f"{', '.join(unknown)} declared but not keywords of __init__ "
                        f"({', '.join(known) or 'none'})")
    if repeated:
        problems.append(f"{', '.join(repeated)} declared more than once")
    if not problems:
        problems += parameter_problems(cls, {})
    if problems:
        raise DetectorCheckError("the parameter declarations (parameters) do not match "
                                 "__init__: " + "; ".join(problems))


def _check_not_fitted_error(ctx: _Context) -> None:
    det = copy.deepcopy(ctx.detector)
    _, ev = ctx.signals()
    try:
        det.detect(read_only(ev))
    except NotFittedError as exc:
        if "fit" not in str(exc):
            raise DetectorCheckError("the NotFittedError of detect() before fit() must say "
                                     f"to call fit(); got: {exc}")
    except Exception as exc:
        raise DetectorCheckError("detect() before fit() must raise NotFittedError, not "
                                 f"{type(exc).__name__}: {exc}")
    else:
        raise DetectorCheckError("detect() before fit() must raise NotFittedError")


def _check_fit_leaves_signals(ctx: _Context) -> None:
    f = ctx.fitted()
    _unchanged(f["before"], f["learn"], "fit() modified the learning signals")


def _check_fit_returns_self(ctx: _Context) -> None:
    f = ctx.fitted()
    if f["returned"] is not f["det"]:
        raise DetectorCheckError(f"fit() must return self, got {type(f['returned']).__name__}")


def _check_fit_keeps_params(ctx: _Context) -> None:
    now = ctx.fitted()["det"].get_params()
    if now != ctx.params:
        changed = sorted(k for k in now if ctx.params.get(k) != now[k])
        raise DetectorCheckError("fit() changed the constructor parameters (get_params: "
                                 f"{', '.join(changed)})")


def _check_fit_stores_state(ctx: _Context) -> None:
    if not ctx.fitted()["det"].fitted_state():
        raise DetectorCheckError("fit() stored no learned attribute ending in '_'")


def _check_detect_leaves_signals(ctx: _Context) -> None:
    o = ctx.output()
    _unchanged(o["before"], o["ev"], "detect() modified the signals it was given")


def _check_output_types(ctx: _Context) -> None:
    o = ctx.output()
    ev = o["ev"]
    problems = [f"{name}: {msg}" for name, d in o["out"].items()
                for msg in detection_problems(d, ev.n_runs, ev.n_steps)]
    if problems:
        raise DetectorCheckError("; ".join(problems))


def _check_determinism(ctx: _Context) -> None:
    o = ctx.output()
    _, ev = ctx.signals()
    _same(o["out"], _variants(ctx.fitted()["det"], ev), "determinism", ev, range(ev.n_runs))


def _check_determinism_refit(ctx: _Context) -> None:
    o = ctx.output()
    learn, ev = ctx.signals()
    refit = _on(copy.deepcopy(ctx.detector).fit, learn)
    _same(o["out"], _variants(refit, ev),
          "determinism (fitted again on the same learning set)", ev, range(ev.n_runs))


def _check_batch_invariance(ctx: _Context) -> None:
    out = ctx.output()["out"]
    det = ctx.fitted()["det"]
    _, ev = ctx.signals()
    _batch_invariant(det, ev, out)


def _batch_invariant(det, signals, out: dict) -> None:
    """Raise :class:`DetectorCheckError` unless fitted *det* gives each run of *signals*
    alone, and the runs in reverse order, what it gave them together (*out*)."""
    for j in range(signals.n_runs):
        alone = _variants(det, signals.take([j]))
        _same(out, alone, f"batch invariance ({_run_text(signals, j)} alone)", signals, [j])
    order = np.arange(signals.n_runs)[::-1]
    reordered = _variants(det, signals.take(order))
    _same(out, reordered, "batch invariance (runs in reverse order)", signals, list(order))


def batch_invariance_failure(detector: Detector, signals, engine: str | None = None
                             ) -> str | None:
    """The ``batch_invariance`` check of :data:`CHECKS` on the given *signals*: what differs
    when the fitted *detector* sees each run alone, or the runs in reverse order, instead
    of all of them together (None: nothing; a run's result must not depend on the other
    runs of its batch, since a campaign cuts its runs into chunks of any size). The
    detector is not modified (it runs on copies). Used by the runner on a few learning
    runs of every third-party detector before a campaign starts, with the kernels of
    *engine* (``[runner] engine``; None: the current ones)."""
    from scenarios import compiled as kernels

    det = copy.deepcopy(detector)
    signals = read_only(signals)    # shared by the detectors checked: a write raises here
    try:
        with kernels.use_engine(kernels.resolve_engine(engine)):
            _batch_invariant(det, signals, _variants(det, signals))
    except DetectorCheckError as exc:
        return str(exc)
    return None


def _check_causality(ctx: _Context) -> None:
    out = ctx.output()["out"]
    det = ctx.fitted()["det"]
    _, ev = ctx.signals()
    for cut in (ev.n_steps // 3, ev.n_steps // 2 + 7):
        part = _variants(det, ev.truncate(cut))
        _same(out, part, f"causality (truncated at step {cut})", ev, range(ev.n_runs),
              sl=slice(0, cut))


def _check_pickle_round_trip(ctx: _Context) -> None:
    out = ctx.output()["out"]
    clone = pickle.loads(pickle.dumps(ctx.fitted()["det"]))
    _, ev = ctx.signals()
    _same(out, _variants(clone, ev), "pickle round trip", ev, range(ev.n_runs))


def _check_state_round_trip(ctx: _Context) -> None:
    fitted = ctx.fitted()["det"]
    out = ctx.output()["out"]
    try:
        params, arrays = encode(fitted.get_params(), "parameter ")
        learned, arrays = encode(fitted.fitted_state(), "learned attribute ", arrays)
    except StateTypeError as exc:
        raise DetectorCheckError(f"a campaign directory cannot store it as data: {exc}",
                                 []) from None
    text = json.dumps({"params": params, "learned": learned}, allow_nan=False)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    buf.seek(0)
    with np.load(buf, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    doc = json.loads(text)
    clone = type(fitted)(**decode(doc["params"], arrays))
    vars(clone).update(decode(doc["learned"], arrays))
    _, ev = ctx.signals()
    _same(out, _variants(clone, ev), "rebuilt from its stored parameters and learned state",
          ev, range(ev.n_runs))


#: Every check, in the order they run: name → (check, applies to the detector?).
CHECKS: dict[str, tuple[Callable[[_Context], None], Callable[[Detector], bool]]] = {
    "init_stores_params": (_check_init_stores_params, lambda d: True),
    "params_validate": (_check_params_validate, lambda d: True),
    "declared_params": (_check_declared_params, lambda d: True),
    "not_fitted_error": (_check_not_fitted_error, lambda d: d.capabilities.needs_fit),
    "fit_leaves_signals": (_check_fit_leaves_signals, lambda d: True),
    "fit_returns_self": (_check_fit_returns_self, lambda d: True),
    "fit_keeps_params": (_check_fit_keeps_params, lambda d: True),
    "fit_stores_state": (_check_fit_stores_state, lambda d: d.capabilities.needs_fit),
    "detect_leaves_signals": (_check_detect_leaves_signals, lambda d: True),
    "output_types": (_check_output_types, lambda d: True),
    "determinism": (_check_determinism, lambda d: True),
    "determinism_refit": (_check_determinism_refit, lambda d: True),
    "batch_invariance": (_check_batch_invariance, lambda d: True),
    "causality": (_check_causality, lambda d: d.capabilities.causal),
    "pickle_round_trip": (_check_pickle_round_trip, lambda d: True),
    "state_round_trip": (_check_state_round_trip, lambda d: True),
}


class DetectorCheck:
    """One check of :data:`CHECKS` bound to a detector; calling it runs the check and
    raises :class:`DetectorCheckError` (with that one failure) if the detector breaks it.
    The checks of one :func:`detector_checks` call share the simulated signals and the
    fitted detector."""

    def __init__(self, name: str, detector: Detector, context: _Context):
        self.name = name
        self.detector = detector
        self._context = context

    def failure(self) -> str | None:
        """What went wrong, or None when the detector passes this check."""
        check, _ = CHECKS[self.name]
        try:
            check(self._context)
        except DetectorCheckError as exc:
            return str(exc)
        except _NotRun as exc:
            return f"not run: {exc}"
        except _SetupError:
            raise
        except Exception as exc:               # the detector raised inside the check
            return f"raised {type(exc).__name__}: {exc}"
        return None

    def __call__(self) -> None:
        msg = self.failure()
        if msg is not None:
            raise DetectorCheckError(f"{type(self.detector).__name__} failed check "
                                     f"{self.name}: {msg}", [(self.name, msg)])

    def __repr__(self) -> str:
        return f"DetectorCheck({self.name!r}, {type(self.detector).__name__})"


def detector_checks(detector: Detector, *, surface: str = "elevator",
                    duration_s: float = 20.0) -> Iterator[tuple[str, DetectorCheck]]:
    """Yield (check name, check) for every check of :data:`CHECKS` that applies to
    *detector* (``not_fitted_error`` and ``fit_stores_state`` need ``needs_fit``,
    ``causality`` needs ``causal``). Calling a check runs it; the checks share one
    simulation and one fit, made by the first check that needs them.

    A detector whose capabilities say ``needs_aircraft`` is checked on aircraft-plant
    signals (monitored surface :data:`AIRCRAFT_SURFACE` unless *surface* names an aircraft
    surface)."""
    if not isinstance(detector, Detector):
        raise DetectorCheckError(f"{type(detector).__name__} does not subclass "
                                 "detectors.Detector", [("subclass", "not a Detector")])
    ctx = _Context(detector, surface, duration_s)
    for name, (_, applies) in CHECKS.items():
        if applies(detector):
            yield name, DetectorCheck(name, detector, ctx)


def check_detector(detector: Detector, *, surface: str = "elevator",
                   duration_s: float = 20.0) -> None:
    """Run every contract check on *detector* (:func:`detector_checks`); raise one
    :class:`DetectorCheckError` listing every check it fails."""
    failures = [(name, msg) for name, check in detector_checks(
        detector, surface=surface, duration_s=duration_s)
        if (msg := check.failure()) is not None]
    if failures:
        n = len(failures)
        raise DetectorCheckError(
            f"{type(detector).__name__} failed {n} check{'s' if n > 1 else ''}:\n"
            + "\n".join(f"  - {name}: {msg}" for name, msg in failures), failures)


def parametrize_with_checks(detectors: Sequence[Detector] | Mapping[str, Detector], *,
                            surface: str = "elevator", duration_s: float = 20.0):
    """A ``pytest.mark.parametrize`` over every check of every detector, with one test id
    per check (``"<label>-<check>"``), like scikit-learn's ``parametrize_with_checks``::

        @parametrize_with_checks({"my-detector": MyDetector()})
        def test_my_detector(check):
            check()

    *detectors* is a mapping label → detector, or a sequence (labelled by class name, with
    ``[i]`` added when a class repeats)."""
    import pytest

    if isinstance(detectors, Mapping):
        labelled = list(detectors.items())
    else:
        names = [type(d).__name__ for d in detectors]
        labelled = [(n if names.count(n) == 1 else f"{n}[{i}]", d)
                    for i, (n, d) in enumerate(zip(names, detectors))]
    params = [pytest.param(check, id=f"{label}-{name}")
              for label, det in labelled
              for name, check in detector_checks(det, surface=surface, duration_s=duration_s)]
    return pytest.mark.parametrize("check", params)
