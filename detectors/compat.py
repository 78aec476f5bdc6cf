"""Can a detector run on a plant? The one compatibility rule (docs/design.md §4, Contracts).

A detector declares what it reads as :class:`detectors.base.Capabilities`; a plant says
which signal groups it provides for a surface (:meth:`scenarios.plants.Plant.provides`,
:data:`scenarios.signals.SIGNAL_GROUPS`). A detector can run when its needs are a subset of
what the plant provides. The campaign-file validation, ``fdd-campaign plan`` and ``run``, the
runner and :func:`detectors.testing.check_detector` all ask :func:`incompatibilities`, so they
refuse the same things with the same message.
"""

from __future__ import annotations

from typing import Mapping

from scenarios.signals import SIGNAL_GROUPS

#: Capability flag → the signal group it needs.
NEED_OF_FLAG: dict[str, str] = {
    "needs_surface_sensor": "surface",
    "needs_pressure_sensor": "pressure",
    "needs_aircraft": "aircraft",
}


def needs_of(capabilities) -> frozenset[str]:
    """The signal groups a detector with *capabilities* reads (``servo`` always)."""
    return frozenset({"servo"} | {group for flag, group in NEED_OF_FLAG.items()
                                  if getattr(capabilities, flag, False)})


def _message(label: str, group: str, plant, surface: str) -> str:
    if group == "surface":
        return (f"detector {label!r} needs a surface position sensor, which the {surface} has "
                "none of; fix: choose another surface or detector")
    if group == "pressure":
        return (f"detector {label!r} needs the chamber pressure sensor; fix: set "
                "pressure_sensor = true in [campaign]")
    if group == "aircraft":
        return (f"detector {label!r} reads the aircraft sensors and every surface's rod, "
                f"which the {plant.kind} plant does not simulate; fix: set [plant] kind = "
                "\"aircraft\"")
    what = SIGNAL_GROUPS.get(group, group)
    return (f"detector {label!r} needs {what}, which the {plant.kind} plant does not provide "
            f"for the {surface}")


def incompatibilities(capabilities: Mapping[str, object], plant, surface: str, *,
                      pressure_sensor: bool) -> list[str]:
    """Every detector of *capabilities* (label → :class:`Capabilities`) that needs a signal
    group *plant* does not provide for run-row surface *surface*, one message each (naming
    the detector, what is missing and the fix); empty when all can run."""
    provided = plant.provides(surface, pressure_sensor=pressure_sensor)
    problems = []
    for label, caps in capabilities.items():
        for group in sorted(needs_of(caps) - provided, key=list(SIGNAL_GROUPS).index):
            problems.append(_message(label, group, plant, surface))
    return problems


def offline_problems(capabilities: Mapping[str, object]) -> list[str]:
    """The detectors of *capabilities* (label → :class:`Capabilities`) that declare
    ``causal=False``, one message each: a campaign refuses them (docs/write-a-detector.md,
    Capabilities).

    A campaign measures online detection: an alarm at step k may use the samples up to k
    only. A non-causal (offline) detector's alarm times use the future, so its detection
    delay and DTP are not achievable in flight, and its false alarms are not those of an
    online monitor; scoring it like the others would mix the two in one table and one gate.
    """
    return [f"detector {label!r} declares Capabilities(causal=False) (offline: its alarm at "
            "a step may use later samples), and a campaign evaluates online detection only "
            "(detection times and DTP of an offline method are not achievable in flight); "
            "fix: if it only uses past samples, declare causal=True (check_detector's "
            "causality check verifies it), else leave it out of the campaign"
            for label, caps in capabilities.items() if not getattr(caps, "causal", True)]
