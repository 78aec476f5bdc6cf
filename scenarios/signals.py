"""What a simulation returns: :class:`Signals` (what a detector may read) and :class:`Truth`
(what only scoring sees). docs/design.md §4, Contracts.

Arrays are shaped ``(n_runs, n_steps)`` and sampled at ``ts`` (the FCC period); step ``k``
is time ``k·ts``. Per-run scheduling data are the *measured/estimated* values, carrying the
[CHEN] Table-2 errors; the true flight point stays in :class:`Truth`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .params import ActuatorParams

#: Units of the time-series signals, by name.
SIGNAL_UNITS: dict[str, str] = {
    "command": "mm",      # rod-position order u computed by the flight control law
    "current": "mA",      # servo-valve current order i computed by the FCC (COM)
    "rod_com": "mm",      # rod position acquired by the COM channel (the loop closes on it)
    "rod_mon": "mm",      # rod position acquired by the MON channel
    "surface": "deg",     # surface position sensor (NaN when the surface has none)
    "pressure": "Pa",     # actuator chamber differential pressure (NaN when not fitted)
}

#: Units of the optional aircraft-level signals (``Signals.aircraft``, aircraft plant only):
#: inertial rates and attitudes (θ absolute: trimmed α plus its change; φ from wings level),
#: load factors at the CG (n_z = 1 in level flight), the air-relative sideslip (β plus the
#: gust's) and the air-relative angle of attack (absolute: trimmed α plus its change plus the
#: gust's, what an α vane reads), all with sensor noise;
#: then the roll spoilers' equivalent aileron angle applied over each period (the spoilers
#: have no servo-loop here: this stands for their rod measurements, noise-free).
AIRCRAFT_SIGNAL_UNITS: dict[str, str] = {
    "p": "deg/s", "q": "deg/s", "r": "deg/s", "phi": "deg", "theta": "deg",
    "nz": "g", "ny": "g", "beta": "deg", "alpha": "deg", "spoiler": "deg",
}
#: Unit of every surface's COM rod position (``Signals.rods``, aircraft plant only).
ROD_UNIT: str = "mm"

#: Signal groups a plant provides and a detector may need (docs/design.md §4, Contracts):
#: ``servo`` (command, current, rod_com, rod_mon: every plant), ``surface`` (a surface
#: position sensor), ``pressure`` (the chamber pressure sensor), ``aircraft`` (the aircraft
#: sensors of :data:`AIRCRAFT_SIGNAL_UNITS` and every surface's rod).
SIGNAL_GROUPS: dict[str, str] = {
    "servo": "command, current and the COM/MON rod positions",
    "surface": "a surface position sensor",
    "pressure": "the actuator chamber pressure sensor",
    "aircraft": "the aircraft sensors and every surface's rod position",
}
#: The groups every servo-loop acquisition provides.
SERVO_GROUPS: frozenset[str] = frozenset({"servo"})

#: Units of the per-run scheduling data, by name.
SCHEDULE_UNITS: dict[str, str] = {
    "vcas_kt": "kt",
    "alt_ft": "ft",
    "mass_t": "t",
    "cg_pct": "% MAC",
    "mach": "-",
    "qbar_pa": "Pa",
    "alpha_deg": "deg",
}


def read_only_view(array: np.ndarray) -> np.ndarray:
    """A view of *array* whose write flag is off (no copy): how a detector receives its
    signals (:func:`detectors.base.read_only`). numba compiles a kernel once per argument
    type, read-only arrays being a type of their own, so the kernels that read signals are
    also warmed up on such views (:mod:`scenarios.compiled`)."""
    view = array.view()
    view.flags.writeable = False
    return view


@dataclass(frozen=True)
class Signals:
    """Everything a detector may read for a batch of runs.

    Parameters
    ----------
    ts : float
        Sampling period [s].
    command, current, rod_com, rod_mon, surface, pressure : ndarray (n_runs, n_steps)
        See :data:`SIGNAL_UNITS`. ``surface``/``pressure`` are all-NaN when not fitted.
    schedule : dict[str, ndarray (n_runs,)]
        Measured/estimated scheduling data (:data:`SCHEDULE_UNITS`).
    actuator : ActuatorParams
        The *nominal* actuator parameters (a model-based detector's knowledge).
    run_ids : ndarray (n_runs,) of str
        Identity of each run (for error messages and tracing only).
    aircraft : dict[str, ndarray (n_runs, n_steps)] or None
        Aircraft sensors (:data:`AIRCRAFT_SIGNAL_UNITS`); None at the actuator plant level.
    rods : dict[str, ndarray (n_runs, n_steps)] or None
        COM rod position [mm] of every primary surface, by surface name; None at the
        actuator plant level.
    airframe : str or None
        The aircraft the aircraft sensors come from, named as a source of design models
        (:data:`scenarios.design_models.AIRFRAMES`: ``"aircraft"`` the project's linear
        aircraft, ``"jsbsim:737"`` JSBSim's 737); an aircraft-level detector designs on
        that aircraft's nominal linear models. None at the actuator plant level (or from a
        plant that names none: the project's aircraft is then assumed).
    classes : ndarray (n_runs,) of str or None
        The fault-free manoeuvre of each run of a *learning set* (what ``fit`` receives), so
        that a detector may calibrate its thresholds per manoeuvre class
        (:func:`detectors.calibrate.calibrate_threshold`); None in the signals ``detect``
        receives — a detector never knows the manoeuvre of the run it monitors.
    """

    ts: float
    command: np.ndarray
    current: np.ndarray
    rod_com: np.ndarray
    rod_mon: np.ndarray
    surface: np.ndarray
    pressure: np.ndarray
    schedule: dict = field(default_factory=dict)
    actuator: ActuatorParams | None = None
    run_ids: np.ndarray | None = None
    aircraft: dict | None = None
    rods: dict | None = None
    classes: np.ndarray | None = None
    airframe: str | None = None

    @property
    def n_runs(self) -> int:
        return self.command.shape[0]

    @property
    def n_steps(self) -> int:
        return self.command.shape[1]

    @property
    def time(self) -> np.ndarray:
        """Sample times [s], shape (n_steps,)."""
        return np.arange(self.n_steps) * self.ts

    @property
    def has_surface_sensor(self) -> bool:
        return bool(np.isfinite(self.surface).any())

    @property
    def has_pressure_sensor(self) -> bool:
        return bool(np.isfinite(self.pressure).any())

    def series_names(self) -> tuple[str, ...]:
        return tuple(SIGNAL_UNITS)

    def take(self, index) -> "Signals":
        """The sub-batch of runs selected by *index* (an integer array, slice or mask)."""
        return Signals(
            ts=self.ts,
            **{name: getattr(self, name)[index] for name in SIGNAL_UNITS},
            schedule={k: np.asarray(v)[index] for k, v in self.schedule.items()},
            actuator=self.actuator,
            run_ids=None if self.run_ids is None else np.asarray(self.run_ids)[index],
            aircraft=_map(self.aircraft, lambda v: v[index]),
            rods=_map(self.rods, lambda v: v[index]),
            classes=None if self.classes is None else np.asarray(self.classes)[index],
            airframe=self.airframe,
        )

    def truncate(self, n_steps: int) -> "Signals":
        """The first *n_steps* samples of every run (used to check causality)."""
        return Signals(
            ts=self.ts,
            **{name: getattr(self, name)[:, :n_steps] for name in SIGNAL_UNITS},
            schedule=dict(self.schedule),
            actuator=self.actuator,
            run_ids=self.run_ids,
            aircraft=_map(self.aircraft, lambda v: v[:, :n_steps]),
            rods=_map(self.rods, lambda v: v[:, :n_steps]),
            classes=self.classes,
            airframe=self.airframe,
        )

    @classmethod
    def concat(cls, parts, n_runs: int | None = None) -> "Signals":
        """Stack batches of runs with the same time base.

        *parts* is a list, or an iterator of batches as they arrive with *n_runs* their total
        number of runs: each batch's series are then copied into the result as it is read,
        and nothing keeps it, so the memory peaks at the result plus one batch instead of
        twice the result (the learning set of an aircraft campaign holds about 1 MB per run).
        A signal that is one of the batch's rod series (at the aircraft level ``rod_com`` is
        ``rods[monitored]``) stays that series in the result, stored once, as long as every
        batch has it so.
        """
        if n_runs is None:
            parts = list(parts)
            n_runs = sum(p.n_runs for p in parts)
        parts = iter(parts)
        first = next(parts)

        def empty(a):
            return np.empty((n_runs,) + a.shape[1:], dtype=a.dtype)

        aircraft, rods = _map(first.aircraft, empty), _map(first.rods, empty)
        aliases = {name: k for name in SIGNAL_UNITS for k, r in (first.rods or {}).items()
                   if _same_view(getattr(first, name), r)}
        series = {name: rods[aliases[name]] if name in aliases else empty(getattr(first, name))
                  for name in SIGNAL_UNITS}
        small = []                      # per-run scalars: concatenated at the end (small)
        start = 0
        for part in itertools.chain([first], parts):
            rows = slice(start, start + part.n_runs)
            for name, out in list(series.items()):
                if name in aliases:
                    if _same_view(getattr(part, name), part.rods[aliases[name]]):
                        continue        # written with the rods below
                    own = empty(out)    # this batch holds it apart: its own array from now on
                    own[:start] = out[:start]
                    series[name], out = own, own
                    del aliases[name]
                out[rows] = getattr(part, name)
            for mine, theirs in ((aircraft, part.aircraft), (rods, part.rods)):
                for k, out in (mine or {}).items():
                    out[rows] = theirs[k]
            small.append((part.schedule, part.run_ids, part.classes))
            start += part.n_runs
        if start != n_runs:
            raise ValueError(f"Signals.concat: the batches hold {start} runs, not the "
                             f"{n_runs} announced")
        schedules, run_ids, classes = zip(*small)
        return cls(
            ts=first.ts, **series,
            schedule={k: np.concatenate([sch[k] for sch in schedules]) for k in first.schedule},
            actuator=first.actuator,
            run_ids=None if first.run_ids is None else np.concatenate(run_ids),
            aircraft=aircraft, rods=rods,
            classes=None if any(c is None for c in classes) else np.concatenate(classes),
            airframe=first.airframe,
        )

    def to_pandas(self, run: int = 0):
        """One run's time series as a DataFrame indexed by time [s] (columns carry units)."""
        import pandas as pd

        data = {f"{name} [{unit}]": getattr(self, name)[run] for name, unit in SIGNAL_UNITS.items()}
        for name, series in (self.aircraft or {}).items():
            data[f"{name} [{AIRCRAFT_SIGNAL_UNITS.get(name, '')}]"] = series[run]
        for name, series in (self.rods or {}).items():
            data[f"rod_{name} [{ROD_UNIT}]"] = series[run]
        return pd.DataFrame(data, index=pd.Index(self.time, name="time [s]"))


@dataclass(frozen=True)
class Truth:
    """What only scoring (and plots) may see.

    rod_mm, surface_deg : ndarray (n_runs, n_steps)
        True rod position [mm] and surface deflection [deg].
    current_mA : ndarray (n_runs, n_steps)
        Current actually flowing in the servo-valve [mA] (differs from the FCC's order
        under a hardover or an oscillatory current fault).
    fault : ndarray (n_runs,) of str
        Fault type (``"none"`` for a fault-free run).
    onset_s : ndarray (n_runs,)
        Fault onset [s] (NaN for a fault-free run).
    magnitude : ndarray (n_runs,)
        Fault magnitude in the unit of its type (runaway: deg/s; liquid_jam: mm; hardover:
        ±1 direction; OFC: amplitude). NaN where it does not apply.
    aircraft : dict[str, ndarray (n_runs, n_steps)] or None
        True aircraft perturbation states (alpha, q, theta, beta, p, r, phi in deg, deg/s)
        at the aircraft plant level.
    surfaces_deg : dict[str, ndarray (n_runs, n_steps)] or None
        True deflection [deg] of every primary surface at the aircraft plant level.
    rod_fault_mm : ndarray (n_runs, n_steps) or None
        The additive fault f [mm] of [CHEN] eq. 4 on the COM rod measurement of the jam runs
        from their onset on (:func:`scenarios.simulate.rod_measurement_fault`); NaN before
        onset and for other runs; None when the batch holds no jam. It may be given as a
        function of no argument that returns it: it is then computed on its first read and
        kept. Only a detector's fault estimate is scored against it, and computing it takes
        a healthy servo model of every jam run (0.2 CPU-s of addsafe-mc's runs, whose
        detectors estimate nothing).
    """

    rod_mm: np.ndarray
    surface_deg: np.ndarray
    current_mA: np.ndarray
    fault: np.ndarray
    onset_s: np.ndarray
    magnitude: np.ndarray
    flight: dict = field(default_factory=dict)
    aircraft: dict | None = None
    surfaces_deg: dict | None = None
    rod_fault_mm: np.ndarray | None = None

    def __getattribute__(self, name):
        value = object.__getattribute__(self, name)
        if name == "rod_fault_mm" and callable(value):     # deferred: computed once, kept
            value = value()
            object.__setattr__(self, name, value)
        return value

    def take(self, index) -> "Truth":
        return Truth(
            rod_mm=self.rod_mm[index],
            surface_deg=self.surface_deg[index],
            current_mA=self.current_mA[index],
            fault=np.asarray(self.fault)[index],
            onset_s=np.asarray(self.onset_s)[index],
            magnitude=np.asarray(self.magnitude)[index],
            flight={k: np.asarray(v)[index] for k, v in self.flight.items()},
            aircraft=_map(self.aircraft, lambda v: v[index]),
            surfaces_deg=_map(self.surfaces_deg, lambda v: v[index]),
            rod_fault_mm=self._rod_fault_of(index),
        )

    def stored_rod_fault(self):
        """``rod_fault_mm`` as stored, without computing it: the array, None or the function
        that computes it (to pass on, e.g. to ``dataclasses.replace``, which would read it)."""
        return object.__getattribute__(self, "rod_fault_mm")

    def _rod_fault_of(self, index):
        """``rod_fault_mm[index]``, still deferred when ``rod_fault_mm`` is."""
        if callable(self.stored_rod_fault()):
            return lambda: None if self.rod_fault_mm is None else self.rod_fault_mm[index]
        return None if self.rod_fault_mm is None else self.rod_fault_mm[index]


def _same_view(a, b) -> bool:
    """Whether arrays *a* and *b* are the same view of the same memory."""
    return (a.shape == b.shape and a.strides == b.strides and a.dtype == b.dtype
            and a.__array_interface__["data"][0] == b.__array_interface__["data"][0])


def _map(series: dict | None, fn) -> dict | None:
    """Apply *fn* to every array of an optional dict of series (None stays None)."""
    return None if series is None else {k: fn(v) for k, v in series.items()}
