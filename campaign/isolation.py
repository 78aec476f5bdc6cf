"""Which detectors of a campaign are checked for *isolation* rather than detection.

A detector that declares the plant surfaces whose faults it detects
(:attr:`detectors.base.Capabilities.fault_surfaces`, e.g. ``vanek-geometric``: the left inboard
aileron) must raise no alarm on a fault of any other surface: in a campaign whose runs fault
another surface (the run rows' ``surface``, :func:`campaign.plant_setup.run_surface`), its alarms
after onset are isolation failures, which the gate reports as such
(:func:`reports.gate.evaluate_gate`, ``isolation``), and its missed-detection and DTP limits
do not apply there. Fault-free runs and alarms before onset are scored as for any detector.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping

__all__ = ["isolation_of", "isolation_of_stored"]


def isolation_of(config) -> dict[str, str]:
    """Detector label → the surface whose faults it must not alarm on, for each detector of
    *config* whose declared fault surfaces do not include the campaign's faulty surface
    (empty: every detector is scored for detection). A detector whose class cannot be
    imported here (a plugin no longer installed when a finished campaign is gated) declares
    nothing and is scored for detection."""
    from detectors.registry import DetectorSpecError, load_detector_class

    from .plant_setup import run_surface

    surface = run_surface(config)
    out = {}
    for d in config.detectors:
        try:
            capabilities = load_detector_class(d.name).capabilities
        except DetectorSpecError:
            continue
        declared = tuple(getattr(capabilities, "fault_surfaces", ()) or ())
        if declared and surface not in declared:
            out[d.label] = surface
    return out


def isolation_of_stored(config_dict: Mapping | None) -> dict[str, str]:
    """:func:`isolation_of` for the configuration stored with a campaign's results (its
    JSON form); empty when there is none. The stored file was validated when it ran; the
    one-line notes a reload may give (old spellings) are not repeated here. A stored
    configuration this version cannot read (an older directory) gives none either."""
    if not config_dict:
        return {}
    from .config import CampaignConfig, ConfigError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            config = CampaignConfig.from_dict(dict(config_dict), "stored campaign")
    except ConfigError:
        return {}
    return isolation_of(config)
