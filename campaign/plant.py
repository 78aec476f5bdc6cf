"""The campaign's plant, built once from its configuration (docs/design.md §4, Contracts).

:func:`plant_of` turns the campaign file's ``[plant]`` section into a
:class:`scenarios.plants.Plant`; :func:`run_surface` and :func:`run_actuator` give the run
rows' surface and its nominal actuator table; :func:`detector_problems` is the compatibility
check of the configured detectors against that plant (:func:`detectors.compat.incompatibilities`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from detectors.compat import incompatibilities, offline_problems
from scenarios.fmu import FmuPlant
from scenarios.params import ActuatorParams
from scenarios.plants import Plant, get_plant


def plant_of(config) -> Plant:
    """The plant of *config*: its ``[plant]`` kind, or the FMU its ``fmu`` names (the path
    made absolute against the working directory, so workers find it wherever they run)."""
    section = config.plant
    if section.fmu is not None:
        variables = {name: getattr(section.variables, name)
                     for name in section.variables.__dataclass_fields__}
        return FmuPlant.of(Path(section.fmu).expanduser().resolve(), variables,
                           push_parameters=section.push_parameters,
                           parameters=dict(section.parameters))
    plant = get_plant(section.kind)
    if section.kind == "aircraft" and section.turbulence != plant.turbulence:
        plant = dataclasses.replace(plant, turbulence=section.turbulence)
    return plant


def run_surface(config, plant: Plant | None = None) -> str:
    """The ``surface`` column of the campaign's run rows."""
    plant = plant or plant_of(config)
    return plant.run_surface(config.campaign.surface, config.plant.monitored_surface)


def run_actuator(config, plant: Plant | None = None) -> ActuatorParams:
    """Nominal actuator table of the simulated (monitored) surface."""
    plant = plant or plant_of(config)
    return plant.actuator(run_surface(config, plant))


def detector_problems(config, capabilities: dict, plant: Plant | None = None) -> list[str]:
    """What keeps the detectors of *capabilities* (label → Capabilities) from running on the
    campaign's plant, one message each (empty: all can run); a non-causal detector is
    refused too (:func:`detectors.compat.offline_problems`)."""
    plant = plant or plant_of(config)
    return (incompatibilities(capabilities, plant, run_surface(config, plant),
                              pressure_sensor=config.campaign.pressure_sensor)
            + offline_problems(capabilities))
