"""Plants as FMUs: run an FMI 2.0 / 3.0 co-simulation FMU through fmpy instead of the
built-in servo-loop plant.

What lives where
----------------
The FMU is the *physical plant* only: it receives the servo-valve current [mA] held over
each FCC period and returns the rod position [mm] and the surface deflection [deg]. The
engine keeps everything else, exactly as with the built-in plant (:mod:`scenarios.simulate`):
the orders, the FCC (current law, one period of delay), the sensors and their noise, and the
injection of command-side and sensor-side faults (runaway, hardover, liquid jam, both OFCs)
around the FMU. Plant-internal faults need the FMU's cooperation:

* ``solid_jam``: set through the FMU's jam input when one is mapped; otherwise the engine
  emulates it by holding the FMU's outputs from the onset on (a seized rod is, for the rest
  of the loop, a rod whose outputs stop moving). Its ``"offset"`` variant (a finite
  magnitude, docs/physics.md §5) is always emulated: the outputs jump by the offset at the
  onset and stop there.
* ``disconnection``: needs a mapped disconnection input (and the surface output), because
  the engine cannot unload a rod from outside; a campaign with disconnection runs is
  refused before it starts when the FMU has none.

The campaign file maps the FMU's variables to the engine's signals (``[plant.variables]``,
:data:`SIGNALS`). When ``push_parameters`` is on, each run's true plant parameters
(:class:`scenarios.servo.PlantArrays`: ``Kci``, ``SdP``, ``SdP_ref``, ``Ka``, ``r_mm``,
``x_min``, ``x_max``, ``hm_delta``, ``hm_0``, plus ``stop_min_rad``/``stop_max_rad``) are
set into the FMU parameters of the same names before initialisation, so the built-in
servo-loop FMU (``fdd-campaign fmu build``) and the Python plant share one parameter table.

Execution
---------
FMUs are scalar: the loop runs one run at a time (fixed-step co-simulation at Ts, one
``doStep`` per FCC period). Each worker process extracts and instantiates an FMU once
(module-level cache keyed by its path) and calls ``reset()`` between runs: fmpy objects do
not pickle and leak when re-instantiated thousands of times. An output that is NaN, infinite
or beyond all physical range (:data:`ROD_LIMIT_R`, :data:`SURFACE_LIMIT_DEG`: the plant
diverged), or an FMI call that fails, stops that run with :class:`FmuRunError` naming the
FMU, the variable and the time, before the value reaches the engine's arithmetic; the
campaign records the run with ``status="error"`` and goes on.

Checks
------
Before any work :func:`inspect_fmu` (the archive) and :func:`probe` (load, instantiate, one
step) refuse with an :class:`FmuError` naming the file and the fix (docs/fmu.md, Bad FMUs):
files that are no FMU, FMI 1.0, FMUs without co-simulation, without a binary for this
platform, binaries that do not load or refuse the GUID, mismatched variables or parameters.
"""

from __future__ import annotations

import atexit
import ctypes
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .acquisition import Trajectory
from .catalog import suggest
from .faults import NEVER
from .errors import InputError
from .fmu_files import FmuError, container, load_failure
from .params import SENSORS, TS_S, SensorParams
from .simulate import ServoLoopPlant, simulate

#: Engine signals an FMU variable can be mapped to:
#: name → (causality, FMI types accepted, required, meaning).
SIGNALS: dict[str, tuple[str, tuple[str, ...], bool, str]] = {
    "current": ("input", ("Real", "Float64"), True,
                "servo-valve current held over the step [mA] (engine → FMU)"),
    "rod": ("output", ("Real", "Float64"), True, "rod position [mm] (FMU → engine)"),
    "surface": ("output", ("Real", "Float64"), False,
                "surface deflection [deg] (FMU → engine); unmapped: asin(rod/r)"),
    "rod_start": ("parameter", ("Real", "Float64"), False,
                  "initial (trimmed) rod position [mm], set to the first rod order"),
    "jam": ("input", ("Boolean", "Integer", "Int32", "Real", "Float64"), False,
            "solid-jam input, set to 1 from the onset; unmapped: emulated by the engine"),
    "disconnect": ("input", ("Boolean", "Integer", "Int32", "Real", "Float64"), False,
                   "disconnection input, set to 1 from the onset; required for "
                   "disconnection runs"),
}

#: Variable names of the built-in servo-loop FMU (the defaults of ``[plant.variables]``).
SERVO_VARIABLES: dict[str, str] = {
    "current": "i_mA", "rod": "x_mm", "surface": "delta_deg", "rod_start": "x0",
    "jam": "jam", "disconnect": "disconnect",
}

#: Per-run plant parameters pushed into FMU parameters of the same name.
PUSHED_PARAMETERS: tuple[str, ...] = ("Kci", "SdP", "SdP_ref", "Ka", "r_mm", "x_min", "x_max",
                                      "hm_delta", "hm_0", "stop_min_rad", "stop_max_rad")

#: FMU parameter that receives the engine's period Ts [s] when parameters are pushed: the
#: longest internal integration sub-step of the built-in servo-loop FMU (start value 0.01 s,
#: :data:`scenarios.fmu_build.H_MAX_S`). Set to Ts, each ``doStep(Ts)`` is one RK4 step,
#: the built-in plant's, at whatever period the campaign runs.
STEP_PARAMETER = "h_max_s"

#: Largest |rod position| an FMU may return, in lever arms r [-]. δ = asin(x/r)
#: (docs/physics.md §3) has no value beyond |x| = r and the mechanical stops hold a real rod
#: well inside; a rod twice as far out has diverged. Checked before the engine's arithmetic
#: (the COM acquisition) sees the value.
ROD_LIMIT_R = 2.0
#: Largest |surface deflection| an FMU may return [deg]: beyond a half turn it has diverged.
SURFACE_LIMIT_DEG = 180.0


def plant_parameters(pl, act, j: int) -> dict[str, float]:
    """The pushed parameters of run *j* of a batch: :data:`PUSHED_PARAMETERS` from the
    PlantArrays *pl* (true per-run values) and the stops [rad] of ActuatorParams *act*."""
    out = {name: float(np.asarray(getattr(pl, name))[j]) for name in PUSHED_PARAMETERS
           if hasattr(pl, name)}
    out["stop_min_rad"] = float(np.radians(act.stop_min_deg))
    out["stop_max_rad"] = float(np.radians(act.stop_max_deg))
    return out


class FmuRunError(InputError, RuntimeError):
    """A run of an FMU that failed (NaN, infinite or diverged output, failing FMI call): the
    user's plant, recorded per run in a campaign, exit 2 naming the FMU elsewhere."""


@dataclass(frozen=True)
class FmuPlant(ServoLoopPlant):
    """A plant back end: which FMU to run and how its variables map to the engine
    (picklable, hashable; a :class:`scenarios.plants.Plant`:
    ``FmuPlant.of("servo.fmu").simulate(runs)``).

    path : the .fmu file.
    variables : (engine signal, FMU variable) pairs; an empty name leaves a signal unmapped.
    push_parameters : set each run's true plant parameters into same-named FMU parameters.
    parameters : (FMU parameter, value) pairs set after the pushed ones (start-value
        overrides, e.g. for a third-party FMU's own parameters).
    """

    path: str
    variables: tuple[tuple[str, str], ...] = tuple(SERVO_VARIABLES.items())
    push_parameters: bool = True
    parameters: tuple[tuple[str, float], ...] = ()

    kind = "fmu"
    #: one FMU instance per worker process (fmpy changes the working directory; an
    #: instance is not safe to share between threads)
    needs_processes = True

    @property
    def mapping(self) -> dict[str, str]:
        """engine signal → FMU variable, mapped signals only."""
        return {k: v for k, v in self.variables if v}

    # -- the scenarios.plants.Plant protocol (surfaces, actuator, provides: ServoLoopPlant)
    def check(self, faults=()) -> None:
        """:func:`probe` the FMU (load, instantiate, one step) before any work."""
        probe(self, faults)

    def simulate(self, runs, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                 pressure_sensor: bool = False):
        """The engine's FCC, sensors and faults around this FMU (:func:`integrate_fmu`)."""
        return simulate(runs, ts=ts, sensors=sensors, pressure_sensor=pressure_sensor,
                        integrator=lambda p, s: integrate_fmu(p, s, self))

    @classmethod
    def of(cls, path, variables: dict | None = None, push_parameters: bool = True,
           parameters: dict | None = None) -> "FmuPlant":
        """Build a spec; *variables* entries replace the servo-FMU defaults."""
        merged = dict(SERVO_VARIABLES)
        merged.update(variables or {})
        unknown = sorted(set(merged) - set(SIGNALS))
        if unknown:
            raise FmuError(f"[plant.variables]: unknown engine signal(s) {unknown}; allowed: "
                           f"{', '.join(SIGNALS)}")
        return cls(path=str(path), variables=tuple((k, str(merged[k])) for k in SIGNALS),
                   push_parameters=bool(push_parameters),
                   parameters=tuple(sorted((str(k), float(v))
                                           for k, v in (parameters or {}).items())))


# ---------------------------------------------------------------------------------------
# Inspection (before the campaign)
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FmuInfo:
    """What the engine needs to know of a checked FMU."""

    path: str
    version: str                 # "2.0" or "3.0"
    model_identifier: str
    guid: str
    vr: dict                     # engine signal → value reference
    vtype: dict                  # engine signal → FMI type name
    parameters: dict             # FMU parameter name → (value reference, type) (Real only)
    sources: bool = False        # ships C/C++ sources (it can be recompiled: fmpy compile)


def inspect_fmu(spec: FmuPlant, faults=()) -> FmuInfo:
    """Check *spec* against its FMU without running it; raises :class:`FmuError` listing
    every problem (each naming the FMU and the variable). *faults* are the fault types the
    campaign will run (disconnection needs a mapped input)."""
    path = Path(spec.path)
    md, name, version, ident, sources = container(path)
    problems, vr, vtype = _variable_problems(spec, md, name, faults)
    params, more = _parameter_problems(spec, md, name)
    problems += more
    if problems:
        raise FmuError("; ".join(problems) if len(problems) == 1 else
                       f"{name}: {len(problems)} problems:\n  - " + "\n  - ".join(problems))
    return FmuInfo(path=str(path), version=version, model_identifier=ident, guid=md.guid,
                   vr=vr, vtype=vtype, parameters=params, sources=sources)


def _variable_problems(spec: FmuPlant, md, name: str, faults):
    """Every problem of the variable map of *spec* against the model description *md*, and
    the value reference and type of each mapped engine signal."""
    by_name = {v.name: v for v in md.modelVariables}
    problems = []
    mapping = spec.mapping
    vr, vtype = {}, {}
    for signal, (causality, types, required, meaning) in SIGNALS.items():
        var = mapping.get(signal)
        if not var:
            if required:
                cands = [v.name for v in md.modelVariables if v.causality == causality
                         and v.type in types]
                problems.append(f"[plant.variables] {signal} is not mapped ({meaning}); fix: "
                                f"{signal} = one of the FMU's {causality}s: "
                                f"{', '.join(cands) or 'none'}")
            continue
        v = by_name.get(var)
        if v is None:
            cands = [x.name for x in md.modelVariables if x.causality == causality]
            problems.append(f"[plant.variables] {signal} = {var!r}: {name} has no variable "
                            f"{var!r}{suggest(var, list(by_name))}; its {causality}s: "
                            f"{', '.join(cands) or 'none'}")
            continue
        if v.causality != causality:
            problems.append(f"[plant.variables] {signal} = {var!r}: in {name} this variable "
                            f"is a(n) {v.causality}, the engine's {signal} needs a(n) "
                            f"{causality} ({meaning})")
            continue
        if v.type not in types:
            problems.append(f"[plant.variables] {signal} = {var!r}: in {name} this variable "
                            f"is {v.type}; allowed: {', '.join(types)}")
            continue
        if v.shape and int(np.prod(v.shape)) != 1:
            problems.append(f"[plant.variables] {signal} = {var!r}: array variables are not "
                            "supported; map a scalar")
            continue
        vr[signal], vtype[signal] = v.valueReference, v.type
    faults = set(faults)
    if "disconnection" in faults:
        for signal in ("disconnect", "surface"):
            if signal not in mapping:
                problems.append(
                    f"[plant.variables] {signal} is not mapped, but the campaign has "
                    f"disconnection runs: the engine cannot disconnect a plant from outside; "
                    f"fix: map the {name}'s {SIGNALS[signal][0]} for it, or remove the "
                    "disconnection groups")
    return problems, vr, vtype


def _parameter_problems(spec: FmuPlant, md, name: str):
    """The FMU's settable real parameters (name → (value reference, type)) and every
    parameter override of *spec* that is not one of them."""
    by_name = {v.name: v for v in md.modelVariables}
    problems = []
    params = {v.name: (v.valueReference, v.type) for v in md.modelVariables
              if v.causality == "parameter" and v.type in ("Real", "Float64")
              and v.variability in ("fixed", "tunable")}
    for pname, _value in spec.parameters:
        if pname in params:
            continue
        v = by_name.get(pname)
        if v is None:
            why = f"{name} has no variable {pname!r}{suggest(pname, list(params))}"
        else:
            why = (f"in {name} this variable is a(n) {v.causality} ({v.type}, "
                   f"{v.variability}); only real parameters (fixed or tunable) can be set")
        problems.append(f"parameter override {pname!r} ([plant] parameters): {why}; fix: "
                        f"name one of its real parameters: {', '.join(params) or 'none'}")
    return params, problems


def probe(spec: FmuPlant, faults=()) -> FmuInfo:
    """:func:`inspect_fmu`, then load, instantiate, initialise (with the parameter
    overrides of *spec*) and step the FMU once in this process; raises :class:`FmuError`
    naming the FMU and what failed (its binary does not load, the binary refuses the
    model description's GUID/instantiationToken, initialisation fails, an output is not a
    number)."""
    info = inspect_fmu(spec, faults)
    inst = _Instance(info, spec)   # FmuError when the binary does not load or instantiate
    stage = "initialise"
    try:
        inst.start(x0=0.0, params={})
        for t in (0.0, TS_S):
            if t:
                stage = "step"
                inst.step(0.0, TS_S)
            for signal, value in zip(("rod", "surface"), inst.outputs(t)):
                if signal in info.vr and not math.isfinite(value):
                    raise FmuError(f"FMU {info.path}: output {spec.mapping[signal]!r} "
                                   f"({signal}) is {value!r} at t = {t:.2f} s of a trial run "
                                   "(rod at 0, the FMU's own parameters and the overrides); "
                                   "fix: check the FMU and its parameters with "
                                   f"'python -m fmpy simulate {info.path}'")
    except FmuError:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure of a foreign binary
        raise FmuError(f"FMU {info.path}: fails to {stage} ({type(exc).__name__}: {exc}); "
                       f"fix: check the FMU with 'python -m fmpy simulate {info.path}' or "
                       "rebuild it") from None
    finally:
        inst.close()
    return info


# ---------------------------------------------------------------------------------------
# One loaded FMU instance
# ---------------------------------------------------------------------------------------
class _Instance:
    """An extracted, instantiated FMU: start / step / outputs, reset between runs."""

    def __init__(self, info: FmuInfo, spec: FmuPlant):
        from fmpy import extract

        self.info, self.spec = info, spec
        self.tmp = tempfile.mkdtemp(prefix="fdd-fmu-")
        self.slave = None
        self.used = False
        cwd = os.getcwd()  # fmpy changes directory to load the library (and may not return)
        stage = "extract"
        try:
            unzip = extract(info.path, unzipdir=self.tmp)
            stage = "load"
            if info.version == "2.0":
                from fmpy.fmi2 import FMU2Slave

                self.slave = FMU2Slave(guid=info.guid, unzipDirectory=unzip,
                                       modelIdentifier=info.model_identifier,
                                       instanceName="fdd_plant")
            else:
                from fmpy.fmi3 import FMU3Slave

                self.slave = FMU3Slave(guid=info.guid, unzipDirectory=unzip,
                                       modelIdentifier=info.model_identifier,
                                       instanceName="fdd_plant")
            stage = "instantiate"
            self.slave.instantiate()
        except Exception as exc:  # noqa: BLE001 - any failure of a foreign archive or binary
            self.close()
            raise FmuError(load_failure(info, stage, exc)) from None
        finally:
            os.chdir(cwd)
        self.v2 = info.version == "2.0"
        vr = info.vr
        # preallocated ctypes buffers for the per-step calls
        self._out_sig = [s for s in ("rod", "surface") if s in vr]
        if self.v2:
            from fmpy.fmi2 import fmi2Real, fmi2ValueReference

            self._vr_in = (fmi2ValueReference * 1)(vr["current"])
            self._val_in = (fmi2Real * 1)()
            self._vr_out = (fmi2ValueReference * len(self._out_sig))(
                *[vr[s] for s in self._out_sig])
            self._val_out = (fmi2Real * len(self._out_sig))()
        else:
            from fmpy.fmi3 import fmi3Boolean, fmi3Float64, fmi3ValueReference

            self._event, self._terminate = fmi3Boolean(), fmi3Boolean()
            self._early, self._last_time = fmi3Boolean(), fmi3Float64()
            self._step_out = [ctypes.byref(v) for v in (self._event, self._terminate,
                                                        self._early, self._last_time)]

            self._vr_in = (fmi3ValueReference * 1)(vr["current"])
            self._val_in = (fmi3Float64 * 1)()
            self._vr_out = (fmi3ValueReference * len(self._out_sig))(
                *[vr[s] for s in self._out_sig])
            self._val_out = (fmi3Float64 * len(self._out_sig))()

    # -- per-run life cycle ---------------------------------------------------------------
    def start(self, x0: float, params: dict) -> None:
        """Reset (after the first run), set the parameters and initialise at t = 0."""
        s, info = self.slave, self.info
        if self.used:
            s.reset()
        self.used = True
        values = {}
        if self.spec.push_parameters:
            values.update({k: v for k, v in params.items() if k in info.parameters})
        values.update(dict(self.spec.parameters))
        for name, value in values.items():
            self._set_real(info.parameters[name][0], value)
        if "rod_start" in info.vr:
            self._set_real(info.vr["rod_start"], x0)
        if self.v2:
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
        else:
            s.enterInitializationMode(startTime=0.0)
        self.flags = {}
        for signal in ("jam", "disconnect"):
            if signal in info.vr:
                self.set_flag(signal, False)
        s.exitInitializationMode()

    def _set_real(self, vr: int, value: float) -> None:
        if self.v2:
            self.slave.setReal([vr], [float(value)])
        else:
            self.slave.setFloat64([vr], [float(value)])

    def set_flag(self, signal: str, on: bool) -> None:
        """Set a fault input (only when it changes)."""
        if self.flags.get(signal) is on:
            return
        vr, t = self.info.vr[signal], self.info.vtype[signal]
        s = self.slave
        if t == "Boolean":
            s.setBoolean([vr], [bool(on)])
        elif t in ("Integer", "Int32"):
            (s.setInteger if self.v2 else s.setInt32)([vr], [int(on)])
        else:
            self._set_real(vr, 1.0 if on else 0.0)
        self.flags[signal] = on

    def step(self, t: float, h: float, current: float | None = None) -> None:
        """Hold *current* [mA] over [t, t + h] and advance the FMU."""
        s = self.slave
        if self.v2:
            if current is not None:
                self._val_in[0] = current
                s.fmi2SetReal(s.component, self._vr_in, 1, self._val_in)
            s.fmi2DoStep(s.component, t, h, 1)
        else:
            if current is not None:
                self._val_in[0] = current
                s.fmi3SetFloat64(s.component, self._vr_in, 1, self._val_in, 1)
            s.fmi3DoStep(s.component, t, h, True, *self._step_out)
            if self._terminate.value or self._early.value:
                raise FmuRunError(f"FMU {self.info.path}: fmi3DoStep at t = {t:.2f} s "
                                  "asked to terminate or returned early")

    def outputs(self, t: float) -> tuple[float, float]:
        """(rod [mm], surface [deg] or NaN when unmapped) at time *t*."""
        s = self.slave
        n = len(self._out_sig)
        if self.v2:
            s.fmi2GetReal(s.component, self._vr_out, n, self._val_out)
        else:
            s.fmi3GetFloat64(s.component, self._vr_out, n, self._val_out, n)
        vals = dict(zip(self._out_sig, self._val_out))
        return vals["rod"], vals.get("surface", np.nan)

    def close(self) -> None:
        if self.slave is not None:
            try:
                if self.slave.component is not None:
                    self.slave.terminate()
            except Exception:  # noqa: BLE001 - best effort on the way out
                pass
            try:
                self.slave.freeInstance()
            except Exception:  # noqa: BLE001
                pass
            self.slave = None
        shutil.rmtree(self.tmp, ignore_errors=True)


#: Loaded FMUs of this process: key → (FmuInfo, _Instance). One per FMU file and mapping.
_CACHE: dict = {}


def _key(spec: FmuPlant):
    p = Path(spec.path).resolve()
    st = p.stat()
    return (str(p), st.st_mtime_ns, st.st_size, spec)


def instance(spec: FmuPlant, faults=()) -> tuple[FmuInfo, _Instance]:
    """The process's loaded instance of *spec* (loaded and checked on first use)."""
    try:
        key = _key(spec)
    except OSError:
        inspect_fmu(spec)  # raises the clear "file not found" message
        raise
    if key not in _CACHE:
        info = inspect_fmu(spec, faults)
        for old in [k for k in _CACHE if k[0] == key[0] and k[1:3] != key[1:3]]:  # rebuilt
            _CACHE.pop(old)[1].close()
        cwd = os.getcwd()
        try:
            _CACHE[key] = (info, _Instance(info, spec))
        except FmuError as exc:   # checked by probe() before a campaign; here: a worker
            raise FmuRunError(str(exc)) from None
        finally:
            os.chdir(cwd)
    return _CACHE[key]


def _evict(spec: FmuPlant) -> None:
    """Close and forget the loaded instance of *spec* (after a failed run)."""
    try:
        key = _key(spec)
    except OSError:
        return
    entry = _CACHE.pop(key, None)
    if entry is not None:
        entry[1].close()


@atexit.register
def _close_all() -> None:
    while _CACHE:
        _CACHE.popitem()[1][1].close()


# ---------------------------------------------------------------------------------------
# The closed loop with an FMU plant
# ---------------------------------------------------------------------------------------
def integrate_fmu(p, sensors: SensorParams = SENSORS, spec: FmuPlant | None = None):
    """Same closed loop as :func:`scenarios.simulate.integrate`, with the plant advanced by
    the FMU of *spec* (one run at a time, one ``doStep`` of Ts per FCC period).

    *p* is a :class:`scenarios.simulate.Prepared` batch; returns its
    :class:`scenarios.simulate.Trajectory`. Raises :class:`FmuRunError` (naming the FMU, the
    variable and the time) on an output that is NaN, infinite or beyond |rod| ≤
    :data:`ROD_LIMIT_R`·r, |surface| ≤ :data:`SURFACE_LIMIT_DEG` (checked before the value
    enters the COM acquisition), or on a failing FMI call. With ``push_parameters`` the FMU
    parameter :data:`STEP_PARAMETER` is set to Ts.

    The FCC side of the loop is the one of :func:`scenarios.simulate.acquire_com` and
    :func:`scenarios.simulate.applied_current`, written on Python floats for one run (the
    numpy versions cost ~60 µs per step on length-1 arrays); the operations and their order
    are the same, so both back ends round alike (checked in tests/scenarios_tests/test_fmu.py).
    """
    if spec is None:
        raise ValueError("integrate_fmu needs an FmuPlant (which FMU to run)")
    faults = {"disconnection"} if (p.faults.k_disc < NEVER).any() else set()
    info, inst = instance(spec, faults)
    n, T = p.u.shape
    ts, pl, fa = p.ts, p.plant, p.faults
    out = {k: np.empty((n, T)) for k in ("x", "delta", "i_cmd", "i_app", "y_com")}
    has_jam, has_disc = "jam" in info.vr, "disconnect" in info.vr
    has_surface = "surface" in info.vr
    quant = sensors.rod_quant_mm
    for j in range(n):
        rod_limit = ROD_LIMIT_R * float(pl.r_mm[j])
        k_jam, k_disc, k_osc = int(fa.k_jam[j]), int(fa.k_disc[j]), int(fa.k_osc[j])
        jam_offset = float(fa.jam_offset[j])
        # an "offset" solid jam (docs/physics.md §5) is always emulated: an FMU's jam input
        # seizes the rod where it stands
        emulate_jam = k_jam < NEVER and (not has_jam or jam_offset != 0.0)
        x_lo, x_hi = float(pl.x_min[j]), float(pl.x_max[j])
        K, i_max, r_mm = float(pl.K[j]), float(pl.i_max[j]), float(pl.r_mm[j])
        scale1 = 1.0 + float(p.com_scale[j])
        bias = float(p.com_bias[j])
        noise = p.com_noise[j].tolist()
        u_loop = fa.u_loop[j].tolist()
        com_add = None if fa.com_add is None else fa.com_add[j].tolist()
        com_osc = None if fa.com_osc is None else np.nan_to_num(fa.com_osc[j]).tolist()
        cur_add = None if fa.cur_add is None else fa.cur_add[j].tolist()
        cur_force = None if fa.cur_force is None else fa.cur_force[j].tolist()
        xs, ds, icmd, iapp, ycom = ([0.0] * T for _ in range(5))
        i_prev = 0.0
        y_hold = 0.0
        t = 0.0
        try:
            inst.start(x0=float(p.u[j, 0]),
                       params={**plant_parameters(pl, p.act, j), STEP_PARAMETER: ts})
            for k in range(T):
                t = k * ts
                if emulate_jam and k > k_jam:
                    x, d = xs[k - 1], ds[k - 1]      # seized: the outputs stop moving
                else:
                    x, surf = inst.outputs(t)
                    # diverged outputs end the run here, before the acquisition arithmetic
                    if not abs(x) <= rod_limit:             # also NaN
                        _bad(inst, "rod", x, t, f"±{rod_limit:g} mm = {ROD_LIMIT_R:g} r")
                    if has_surface:
                        if not abs(surf) <= SURFACE_LIMIT_DEG:
                            _bad(inst, "surface", surf, t, f"±{SURFACE_LIMIT_DEG:g} deg")
                        d = math.radians(surf)
                    else:
                        d = math.asin(min(max(x / r_mm, -1.0), 1.0))
                    if emulate_jam and k == k_jam and jam_offset != 0.0:
                        x = min(max(x + jam_offset, x_lo), x_hi)    # the jump at onset
                        d = math.asin(min(max(x / r_mm, -1.0), 1.0))
                # COM acquisition (scenarios.simulate.acquire_com)
                v = x * scale1 + bias + noise[k]
                y = quant * round(v / quant)
                if com_add is not None:
                    y = y + com_add[k]
                if com_osc is not None:
                    if k == k_osc:
                        y_hold = y
                    if k >= k_osc:
                        y = y_hold + com_osc[k]
                # FCC current law, and the current flowing over the period
                i_new = min(max(K * (u_loop[k] - y), -i_max), i_max)
                i_app = i_prev
                if cur_add is not None:
                    i_app = i_app + cur_add[k]
                if cur_force is not None and math.isfinite(cur_force[k]):
                    i_app = cur_force[k]
                xs[k], ds[k], icmd[k], iapp[k], ycom[k] = x, d, i_new, i_app, y
                if has_jam and k == k_jam and not emulate_jam:
                    inst.set_flag("jam", True)
                if has_disc and k == k_disc:
                    inst.set_flag("disconnect", True)
                inst.step(t, ts, i_app)
                i_prev = i_new
        except FmuRunError:
            _evict(spec)  # a fresh instance for the next run, whatever state this one is in
            raise
        except Exception as exc:  # noqa: BLE001 - a failing FMI call (FMICallException, …)
            _evict(spec)
            raise FmuRunError(f"FMU {info.path}: an FMI call failed at t = {t:.2f} s "
                              f"({type(exc).__name__}: {exc})") from None
        for name, vals in (("x", xs), ("delta", ds), ("i_cmd", icmd), ("i_app", iapp),
                           ("y_com", ycom)):
            out[name][j] = vals
    return Trajectory(**out)


def _bad(inst: _Instance, signal: str, value: float, t: float, limit: str):
    """Stop the run: output *signal* is NaN, infinite or beyond *limit* (diverged)."""
    what = "not a number" if math.isnan(value) else (
        "infinite" if math.isinf(value) else f"beyond {limit}")
    raise FmuRunError(f"FMU {inst.info.path}: output {inst.spec.mapping[signal]!r} "
                      f"({signal}) is {value!r} at t = {t:.2f} s ({what}: the plant "
                      "diverged or failed); the run is stopped")
