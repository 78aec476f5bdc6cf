"""Which surface a campaign's runs name, and its actuator table, at either plant level.

``[campaign] plant = "actuator"``: the runs name ``surface`` (elevator or aileron) and its
servo-loop is simulated alone. ``plant = "aircraft"``: the runs name the monitored aircraft
surface (``monitored_surface``, by default the left surface of ``surface``), simulated with
the aircraft and every other surface in the loop (:mod:`scenarios.aircraft`).
"""

from __future__ import annotations

from scenarios.aircraft.data import DEFAULT_MONITORED
from scenarios.params import ACTUATORS, ActuatorParams


def run_surface(campaign) -> str:
    """The ``surface`` column of the campaign's run rows."""
    if getattr(campaign, "plant", "actuator") == "aircraft":
        return campaign.monitored_surface or DEFAULT_MONITORED[campaign.surface]
    return campaign.surface


def run_actuator(campaign) -> ActuatorParams:
    """Nominal actuator table of the simulated (monitored) surface."""
    if getattr(campaign, "plant", "actuator") == "aircraft":
        from scenarios.aircraft.loop import surface_actuator

        return surface_actuator(run_surface(campaign))
    return ACTUATORS[campaign.surface]
