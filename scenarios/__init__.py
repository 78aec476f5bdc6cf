"""What is simulated: envelope and atmosphere, uncertainties, the servo-loop plant, sensors,
faults and manoeuvres. ``simulate(runs)`` returns :class:`Signals` and :class:`Truth`."""

from .catalog import FAULT_TYPES, FAULTS, MANOEUVRES, REQUIRED_DETECTION_TIME_S, SURFACES
from .params import ACTUATORS, AILERON, ELEVATOR, SENSORS, TS_S, ActuatorParams, SensorParams
from .signals import SIGNAL_UNITS, Signals, Truth

__all__ = [
    "FAULT_TYPES", "FAULTS", "MANOEUVRES", "REQUIRED_DETECTION_TIME_S", "SURFACES",
    "ACTUATORS", "AILERON", "ELEVATOR", "SENSORS", "TS_S", "ActuatorParams", "SensorParams",
    "SIGNAL_UNITS", "Signals", "Truth",
]
