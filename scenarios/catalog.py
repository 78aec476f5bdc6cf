"""The names the simulator knows: surfaces, manoeuvres, faults.

Kept in one small module with no heavy imports so that the campaign-file validator, the
CLI and the detectors can list the allowed values without importing the simulator.
"""

from __future__ import annotations

import difflib

#: Control surfaces with a built-in servo-loop parameter set (docs/physics.md §3).
SURFACES: tuple[str, ...] = ("elevator", "aileron")

#: The plant kinds a campaign names in ``[plant] kind`` (:mod:`scenarios.plants`; an FMU
#: plant is the actuator kind with ``[plant] fmu`` set: the FMU replaces the servo-loop).
PLANT_KINDS: tuple[str, ...] = ("actuator", "aircraft", "jsbsim")
#: The plant kinds that fly an aircraft (its laws and every surface; the run rows name the
#: monitored aircraft surface).
AIRCRAFT_KINDS: tuple[str, ...] = ("aircraft", "jsbsim")
#: The JSBSim aircraft ``[plant] aircraft`` may name (:data:`scenarios.jsbsim.fdm.AIRCRAFT`).
JSBSIM_AIRCRAFT: tuple[str, ...] = ("737",)

#: The six ADDSAFE fault-free manoeuvres ([CHEN] §6.1, docs/physics.md §7).
MANOEUVRES: tuple[str, ...] = (
    "cruise",
    "nose_up",
    "aoa_protection",
    "pitch_protection",
    "yaw_angle_mode",
    "turn_coordination",
)

#: Manoeuvre sets (docs/physics.md §7): ``normal`` flies every manoeuvre as in normal
#: operations (the turn rolls in at 7.5 °/s, the ranges of the shape tables); ``stress``
#: flies them at their aggressive end (the turn rolls in at the normal law's full-stick
#: 15 °/s, every amplitude range at its high end). A run's set is the run-table column
#: ``manoeuvre_set``; ``normal`` is the default and leaves run ids unchanged.
MANOEUVRE_SETS: tuple[str, ...] = ("normal", "stress")

#: Fault types (docs/physics.md §5). ``none`` marks a fault-free run.
FAULTS: tuple[str, ...] = (
    "none",
    "runaway",
    "hardover",
    "liquid_jam",
    "solid_jam",
    "disconnection",
    "ofc_liquid",
    "ofc_solid",
)

#: Faults that really are faults (everything but ``none``).
FAULT_TYPES: tuple[str, ...] = FAULTS[1:]

#: Required detection times [s], the DTP denominators (docs/physics.md §5: est. defaults, the
#: ADDSAFE values are not published; [CHEN]'s printed DTPs imply a 120 s denominator,
#: inferred in :mod:`reports.render.paper`, twice a 60 s run, so it is not used here and its
#: tables are compared in seconds). OFC: 3 oscillation periods of the default 1 Hz
#: oscillation, a fixed 3 s for every OFC run (not resolved from each run's frequency).
REQUIRED_DETECTION_TIME_S: dict[str, float] = {
    "runaway": 0.5,
    "hardover": 0.2,
    "liquid_jam": 2.0,
    "solid_jam": 2.0,
    "disconnection": 1.0,
    "ofc_liquid": 3.0,
    "ofc_solid": 3.0,
}


#: Detection budget of a fault [s]: the time a drawn onset leaves before the end of the run
#: (docs/physics.md §5, "Onsets that leave time to detect"; applied by
#: campaign.plan where onsets are drawn). The latest drawn onset is
#: duration_s − max(``[faults] onset_before_end_s``, budget): a fault that starts too late
#: to be detected is a miss of the campaign design, not of the detector. disconnection:
#: twice the slowest delay [CHEN] prints for it, 7.01 s (Table 3: DTP 0.0584167 =
#: 701/12000 steps of 10 ms of a 120 s run), rounded up to 15 s. The other faults keep the
#: 10 s of onset_before_end_s, at least 5 times each of their required times
#: (docs/physics.md §5).
DETECTION_BUDGET_S: dict[str, float] = {"disconnection": 15.0}


def latest_onset_s(fault: str, duration_s: float, onset_before_end_s: float) -> float:
    """Latest onset [s] a group of *fault* may draw in a run of *duration_s*: the run leaves
    at least ``onset_before_end_s`` and the fault's :data:`DETECTION_BUDGET_S` after it."""
    return float(duration_s) - max(float(onset_before_end_s),
                                   DETECTION_BUDGET_S.get(fault, 0.0))


def suggest(value: str, allowed: tuple[str, ...] | list[str]) -> str:
    """Return a `` (did you mean 'x'?)`` hint for a misspelt name, or an empty string."""
    close = difflib.get_close_matches(str(value), list(allowed), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def check_name(kind: str, value: str, allowed: tuple[str, ...] | list[str]) -> str:
    """Return *value* if it is one of *allowed*, else raise a ``ValueError`` naming both."""
    if value not in allowed:
        raise ValueError(
            f"unknown {kind} {value!r}{suggest(value, allowed)}; "
            f"allowed: {', '.join(allowed)}"
        )
    return value
