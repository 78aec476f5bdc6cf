"""The campaign's plant, built once from its configuration (docs/design.md §4, Contracts).

:func:`plant_of` turns the campaign file's ``[plant]`` section into a
:class:`scenarios.plants.Plant`; :func:`run_surface` and :func:`run_actuator` give the run
rows' surface and its nominal actuator table; :func:`detector_problems` is the compatibility
check of the configured detectors against that plant (:func:`detectors.compat.incompatibilities`).
:func:`fmu_sha256` is the digest of an FMU plant's file, recorded with the results, and
:func:`replay_plant` the plant that the readers of a campaign directory (``report``,
``show``) re-simulate on: never an FMU the directory names, only one named on the command
line whose digest matches (docs/security.md).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from detectors.compat import incompatibilities, offline_problems
from scenarios.fmu import FmuPlant
from scenarios.fmu_files import FmuError
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
    if section.kind == "jsbsim":
        from scenarios.jsbsim.loop import JsbsimPlant

        return JsbsimPlant(aircraft=section.aircraft, turbulence=section.turbulence)
    plant = get_plant(section.kind)
    if section.kind == "aircraft" and section.turbulence != plant.turbulence:
        plant = replace(plant, turbulence=section.turbulence)
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


def fmu_sha256(plant: Plant) -> str | None:
    """SHA-256 of the FMU file of *plant* (None for a built-in plant), recorded at run time
    (``summary.parquet`` metadata ``fmu_sha256``) for :func:`replay_plant`."""
    from .store.files import sha256_of

    path = getattr(plant, "path", None)
    return None if path is None else sha256_of(Path(path))


def replay_plant(plant: Plant, recorded: str | None, fmu=None,
                 directory="DIR") -> tuple[Plant | None, str]:
    """(the plant to re-simulate runs of a campaign directory on, a note for the user).

    *plant* is the campaign's (:func:`plant_of` its ``campaign.json``), *recorded* the
    SHA-256 of its FMU recorded at run time, *fmu* the FMU file the user named on the
    command line (``--fmu``). A built-in plant is returned as it is. An FMU plant is never
    loaded from the path the directory names (native code chosen by whoever wrote it): the
    plant is *fmu*, once its SHA-256 matches *recorded*, else None (nothing is
    re-simulated; the note says how to name the FMU). :class:`FmuError` (exit 2): *fmu* on a
    campaign without an FMU, a missing file, or another FMU than the one the campaign ran on.
    """
    from .store.files import sha256_of

    path = getattr(plant, "path", None)
    if path is None:
        if fmu is not None:
            raise FmuError(f"--fmu {fmu}: {directory} ran on the built-in {plant.kind} plant, "
                           "not on an FMU; leave --fmu out")
        return plant, ""
    want = f"SHA-256 {recorded}" if recorded else "the FMU the campaign ran on"
    if fmu is None:
        return None, (f"not re-simulated: {directory} ran on the FMU plant {path}, and reading "
                      "a campaign directory never loads native code it names; to re-simulate, "
                      f"name the FMU (its {want}) on the command line: --fmu FILE")
    given = Path(fmu).expanduser().resolve()
    if not given.is_file():
        raise FmuError(f"--fmu {fmu}: file not found; give the FMU {directory} ran on ({want})")
    digest = sha256_of(given)
    if recorded and digest != recorded:
        raise FmuError(f"--fmu {fmu}: its SHA-256 {digest} is not that of the FMU {directory} "
                       f"ran on ({recorded}; campaign.json names {path}); give that FMU")
    note = "" if recorded else (f"note: {directory} holds no FMU digest (written before "
                                f"fdd-campaign recorded one): --fmu {fmu} is used unchecked")
    return replace(plant, path=str(given)), note
