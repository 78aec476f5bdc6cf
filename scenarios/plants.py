"""Plants: what a campaign's runs are simulated on (docs/design.md §4, Contracts).

A plant is an object with one interface (:class:`Plant`), whatever is inside it:

``actuator``
    one surface's nonlinear servo-loop alone (:class:`scenarios.simulate.ActuatorPlant`)
``aircraft``
    the aircraft, its laws and every surface (:class:`scenarios.aircraft.loop.AircraftPlant`)
``fmu``
    the servo-loop's physics in an FMI FMU (:class:`scenarios.fmu.FmuPlant`)
``jsbsim``
    a JSBSim aircraft, our laws and servo-loops (:class:`scenarios.jsbsim.loop.JsbsimPlant`)

The plant says which surfaces it has, the actuator table of a surface, and which signal
groups (:data:`scenarios.signals.SIGNAL_GROUPS`) it provides for a surface; a detector's
declared needs are checked against that in one place
(:func:`detectors.compat.incompatibilities`). The implementations live beside the code they
run and never import this module; this module only names them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import pandas as pd

from .catalog import PLANT_KINDS, suggest
from .fmu import FmuPlant
from .params import SENSORS, TS_S, ActuatorParams, SensorParams
from .signals import Signals, Truth
from .simulate import ActuatorPlant

if TYPE_CHECKING:      # imported when first asked for (module __getattr__ below)
    from .aircraft.loop import AircraftPlant

__all__ = ["PLANT_KINDS", "ActuatorPlant", "AircraftPlant", "FmuPlant", "Plant", "get_plant",
           "simulate"]


@runtime_checkable
class Plant(Protocol):
    """The interface every plant implements (picklable and hashable: plants are sent to
    worker processes and are part of a chunk's settings)."""

    #: ``"actuator"``, ``"aircraft"`` or ``"fmu"``
    kind: str
    #: True when the plant holds per-process state (an FMU instance) and must run on worker
    #: processes rather than threads
    needs_processes: bool

    @property
    def surfaces(self) -> tuple[str, ...]:
        """The values the run rows' ``surface`` column may take."""

    def run_surface(self, surface: str, monitored: str | None = None) -> str:
        """The run rows' ``surface`` for a campaign on *surface* (``elevator``/``aileron``)
        and its optional *monitored* aircraft surface."""

    def actuator(self, surface: str) -> ActuatorParams:
        """The nominal actuator table of run-row surface *surface*."""

    def provides(self, surface: str, *, pressure_sensor: bool) -> frozenset[str]:
        """The signal groups (:data:`scenarios.signals.SIGNAL_GROUPS`) the runs of
        *surface* carry."""

    def check(self, faults=()) -> None:
        """Raise a clear error before any work if the plant cannot run (*faults*: the fault
        types the campaign injects)."""

    def simulate(self, runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                 pressure_sensor: bool = False) -> tuple[Signals, Truth]:
        """Simulate a batch of run rows (one surface and duration): what detectors may read
        and what only scoring sees."""


#: The built-in plants that need no options, by kind: (module, class) (an FMU plant needs
#: its file: :meth:`scenarios.fmu.FmuPlant.of`); their names, :data:`PLANT_KINDS`, are
#: listed in :mod:`scenarios.catalog`, which costs no import. The aircraft's modules (its
#: laws, LPV models and compiled loop) are imported when an aircraft plant is asked for,
#: not by a campaign of the actuator alone.
_BUILT_IN: dict[str, tuple[str, str]] = {"actuator": ("scenarios.simulate", "ActuatorPlant"),
                                         "aircraft": ("scenarios.aircraft.loop", "AircraftPlant"),
                                         "jsbsim": ("scenarios.jsbsim.loop", "JsbsimPlant")}


def _built_in(kind: str) -> type:
    module, name = _BUILT_IN[kind]
    return getattr(importlib.import_module(module), name)


def __getattr__(name: str):
    """``AircraftPlant``, imported from :mod:`scenarios.aircraft.loop` when first asked for."""
    if name == "AircraftPlant":
        return _built_in("aircraft")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")



def get_plant(plant: str | Plant = "actuator") -> Plant:
    """The plant *plant* names (``"actuator"``, ``"aircraft"`` or ``"jsbsim"``), or *plant* itself
    when it already is one. An unknown name is answered with the allowed ones (and a close match);
    an FMU plant is built with :meth:`scenarios.fmu.FmuPlant.of`."""
    if isinstance(plant, str):
        if plant not in _BUILT_IN:
            hint = (" (an FMU plant is built from its file: scenarios.fmu.FmuPlant.of(path))"
                    if plant == "fmu" else suggest(plant, list(_BUILT_IN)))
            raise ValueError(f"unknown plant {plant!r}{hint}; allowed: "
                             f"{', '.join(_BUILT_IN)}")
        return _built_in(plant)()
    if not isinstance(plant, Plant):
        raise TypeError(f"{plant!r} is not a plant: a plant has kind, needs_processes, "
                        "surfaces, run_surface, actuator, provides, check and simulate "
                        "(scenarios.plants.Plant)")
    return plant


def simulate(runs: pd.DataFrame, *, plant: str | Plant = "actuator", ts: float = TS_S,
             sensors: SensorParams = SENSORS, pressure_sensor: bool = False
             ) -> tuple[Signals, Truth]:
    """Simulate the run rows *runs* on *plant* (a kind name or a :class:`Plant`)."""
    return get_plant(plant).simulate(runs, ts=ts, sensors=sensors,
                                     pressure_sensor=pressure_sensor)
