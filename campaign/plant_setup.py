"""The campaign resolved once: its configuration with its plant and what follows from them
(docs/design.md §4, Contracts).

:func:`resolve` turns a configuration into a :class:`ResolvedCampaign` — the plant its
``[plant]`` section names (:func:`plant_of`, built here and nowhere else), the run rows'
surface and its nominal actuator table, the detector classes and the isolation map — built
once when a campaign is set up and handed down to the run table, the learning set, the
workers and the gate, each stage given the resolved campaign alone; :func:`as_resolved` lets
an entry from Python that takes either (:func:`campaign.plan.build_plan`) resolve a raw
configuration once. :func:`run_surface` and :func:`run_actuator` give the surface and
actuator of a built plant (the runner checks the built detectors against the resolved plant
and surface, :func:`campaign.runner.fit_detectors`). :func:`fmu_sha256` is the digest of an
FMU plant's file, recorded with the results, and :func:`replay_plant` the plant that the
readers of a campaign directory (``report``, ``show``) re-simulate on: never an FMU the
directory names, only one named on the command line whose digest matches
(docs/security.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from scenarios.fmu import FmuPlant
from scenarios.errors import ArgumentError
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


def run_surface(config, plant: Plant) -> str:
    """The ``surface`` column of the campaign's run rows, on its built *plant*."""
    return plant.run_surface(config.campaign.surface, config.plant.monitored_surface)


def run_actuator(config, plant: Plant) -> ActuatorParams:
    """Nominal actuator table of the simulated (monitored) surface of the built *plant*."""
    return plant.actuator(run_surface(config, plant))


def detector_classes(config) -> dict[str, type]:
    """Label → the class of each ``[[detector]]`` entry of *config*; a label whose class
    cannot be imported here (a plugin no longer installed when a finished campaign is gated)
    is left out."""
    from detectors.registry import DetectorSpecError, load_detector_class

    out = {}
    for d in config.detectors:
        try:
            out[d.label] = load_detector_class(d.name)
        except DetectorSpecError:
            continue
    return out


def isolation_map(surface: str, classes: dict[str, type]) -> dict[str, str]:
    """Detector label → the surface whose faults it must not alarm on, for each class of
    *classes* (label → class) whose declared fault surfaces
    (:attr:`detectors.base.Capabilities.fault_surfaces`) do not include *surface*, the
    campaign's faulty surface (empty: every detector is scored for detection;
    :mod:`campaign.isolation`)."""
    out = {}
    for label, cls in classes.items():
        declared = tuple(getattr(cls.capabilities, "fault_surfaces", ()) or ())
        if declared and surface not in declared:
            out[label] = surface
    return out


class ReplayFmuError(FmuError, ArgumentError):
    """The FMU named to re-simulate a campaign directory's runs (*fmu* of
    :func:`replay_plant`) that cannot be used, named as Python names the argument;
    ``fdd-campaign report`` and ``show`` name their option (``--fmu``)."""


@dataclass(frozen=True)
class ResolvedCampaign:
    """A campaign's configuration and what follows from it, built once (:func:`resolve`)
    and handed down: nothing downstream builds the plant or re-derives these again.

    config : the :class:`campaign.config.CampaignConfig` (its seed the one the runs use)
    plant : the built :class:`scenarios.plants.Plant` (:func:`plant_of`)
    surface : the run rows' ``surface`` (:func:`run_surface`)
    actuator : the nominal actuator table of that surface (:func:`run_actuator`)
    detector_classes : label → detector class (:func:`detector_classes`)
    isolation : label → the surface it must stay silent on (:func:`isolation_map`)
    chunk_size : runs per chunk [runs] (the run's argument or ``[runner] chunk_size``)
    """

    config: object
    plant: Plant
    surface: str
    actuator: ActuatorParams
    detector_classes: dict = field(default_factory=dict)
    isolation: dict = field(default_factory=dict)
    chunk_size: int | None = None

    @property
    def seed(self) -> int:
        """The campaign seed (``[campaign] seed``, or the one :func:`resolve` was given)."""
        return int(self.config.campaign.seed)


def resolve(config, *, seed: int | None = None, chunk_size: int | None = None,
            plant: Plant | None = None) -> ResolvedCampaign:
    """The :class:`ResolvedCampaign` of *config*: its plant built once (:func:`plant_of`,
    unless the built *plant* is given) and everything that follows from it. *seed* replaces
    ``[campaign] seed`` (:func:`campaign.config.with_overrides`: part of the campaign, so of
    its run ids); *chunk_size* (default ``[runner] chunk_size``; checked by the runner,
    :func:`campaign.runner.check_run_options`) is how the runs are cut, never part of
    them."""
    if seed is not None and int(seed) != int(config.campaign.seed):
        from .config import with_overrides

        config = with_overrides(config, seed=seed)
    plant = plant or plant_of(config)
    surface = run_surface(config, plant)
    classes = detector_classes(config)
    return ResolvedCampaign(
        config=config, plant=plant, surface=surface, actuator=plant.actuator(surface),
        detector_classes=classes, isolation=isolation_map(surface, classes),
        chunk_size=config.runner.chunk_size if chunk_size is None else chunk_size)


def as_resolved(campaign) -> ResolvedCampaign:
    """*campaign* itself when it is a :class:`ResolvedCampaign`, else the configuration
    *campaign* resolved (:func:`resolve`): what a function that takes either does once at
    its entry."""
    return campaign if isinstance(campaign, ResolvedCampaign) else resolve(campaign)


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
    re-simulated; the note says how to name the FMU). :class:`ReplayFmuError` (exit 2): *fmu*
    on a campaign without an FMU, a missing file, or another FMU than the one the campaign
    ran on.
    """
    from .store.files import sha256_of

    path = getattr(plant, "path", None)
    if path is None:
        if fmu is not None:
            raise ReplayFmuError.of("fmu", str(fmu), f"{directory} ran on the built-in "
                                    f"{plant.kind} plant, not on an FMU; leave {{fmu}} out")
        return plant, ""
    want = f"SHA-256 {recorded}" if recorded else "the FMU the campaign ran on"
    if fmu is None:
        return None, (f"not re-simulated: {directory} ran on the FMU plant {path}, and reading "
                      "a campaign directory never loads native code it names; to re-simulate, "
                      f"name the FMU (its {want}) on the command line: --fmu FILE")
    given = Path(fmu).expanduser().resolve()
    if not given.is_file():
        raise ReplayFmuError.of("fmu", str(fmu), f"file not found; give the FMU {directory} "
                                f"ran on ({want})")
    digest = sha256_of(given)
    if recorded and digest != recorded:
        raise ReplayFmuError.of("fmu", str(fmu), f"its SHA-256 {digest} is not that of the FMU "
                                f"{directory} ran on ({recorded}; campaign.json names {path}); "
                                "give that FMU")
    note = "" if recorded else (f"note: {directory} holds no FMU digest (written before "
                                f"fdd-campaign recorded one): --fmu {fmu} is used unchecked")
    return replace(plant, path=str(given)), note
