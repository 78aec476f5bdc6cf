"""The nominal linear models an aircraft-level detector is designed on, by the aircraft its
signals come from (:attr:`scenarios.signals.Signals.airframe`; docs/aircraft.md §8, §9.6).

A model-based detector of [CHEN] or [VANEK] is designed on linear models of the aircraft at
its flight points: on the aircraft plant, the project's own derivative model
(:func:`scenarios.aircraft.lpv.run_models`, which is also the plant, up to the drawn
[CHEN] Table 2 errors); on the JSBSim plant, JSBSim's own trimmed linearisations
(:func:`scenarios.jsbsim.fdm.nominal_models`), never ours, so that the design model differs
from the nonlinear aircraft it faces as it does in [CHEN] §6 and [VANEK] §5. Both come in
the layout of :class:`scenarios.aircraft.lpv.ContinuousModel`.
"""

from __future__ import annotations

import numpy as np

from . import envelope
from .aircraft import lpv
from .atmosphere import tas_ms
from .errors import InputError

#: The airframe of the project's linear aircraft (``[plant] kind = "aircraft"``).
OWN = "aircraft"
#: Prefix of a JSBSim aircraft's airframe name (``jsbsim:737``).
JSBSIM_PREFIX = "jsbsim:"


class AirframeError(InputError, ValueError):
    """An airframe no design model is known for."""


def _jsbsim_model(airframe: str):
    from .jsbsim import fdm

    return fdm.aircraft_model(airframe[len(JSBSIM_PREFIX):])


def check_airframe(airframe: str | None) -> str:
    """*airframe* as a known name (None: the project's aircraft, :data:`OWN`)."""
    if airframe is None or airframe == OWN:
        return OWN
    if isinstance(airframe, str) and airframe.startswith(JSBSIM_PREFIX):
        _jsbsim_model(airframe)
        return airframe
    raise AirframeError(f"airframe {airframe!r}: no design model is known for it; known: "
                        f"{OWN!r} and {JSBSIM_PREFIX!r} followed by a JSBSim aircraft")


def exactly_affine(airframe: str | None) -> bool:
    """Whether the airframe's models are affine in [CHEN] eq. 8's scheduling vector by
    construction (the project's derivative scaling, docs/chen-estimator.md); a nonlinear
    aircraft's linearisations are only approximately so."""
    return check_airframe(airframe) == OWN


def envelope_points(airframe: str | None) -> dict[str, np.ndarray]:
    """The realistic [CHEN] Table 1 points (``scenarios.envelope``) as true flight points of
    *airframe* (``alt_ft``, ``vcas_kt``, ``mass_t``, ``cg_pct``): ours as they are, a JSBSim
    aircraft's mapped onto its envelope (:func:`scenarios.jsbsim.fdm.flight_point`)."""
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]]
    true = {c: pts[c].to_numpy(float) for c in envelope.FLIGHT_COLUMNS}
    if check_airframe(airframe) == OWN:
        return true
    from .jsbsim import fdm

    return fdm.flight_point(true["alt_ft"], true["vcas_kt"], true["mass_t"], true["cg_pct"],
                            _jsbsim_model(airframe))


def nominal_models(airframe: str | None, flight: dict) -> lpv.ContinuousModel:
    """The nominal (no coefficient error) linear models of *airframe* at the flight points
    *flight*: ``mass_t``, ``cg_pct``, ``mach``, ``qbar_pa`` and ``alt_ft`` arrays (and
    ``vcas_kt`` for a JSBSim aircraft, which is trimmed at each point: about 0.15 CPU-s a
    point)."""
    if check_airframe(airframe) == OWN:
        mach = np.asarray(flight["mach"], float)
        point = {"mass_t": flight["mass_t"], "cg_pct": flight["cg_pct"], "mach": mach,
                 "qbar_pa": flight["qbar_pa"],
                 "tas_ms": tas_ms(mach, np.asarray(flight["alt_ft"], float))}
        return lpv.run_models(point, np.zeros(mach.shape))
    from .jsbsim import fdm
    from .params import TS_S

    return fdm.nominal_models(_jsbsim_model(airframe), flight, TS_S)
