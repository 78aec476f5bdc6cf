"""What each detector of a campaign is checked for besides false alarms: *isolation* rather
than detection, the fault types it covers, the detection system it belongs to (:class:`Roles`).

A detector that declares the plant surfaces whose faults it detects
(:attr:`detectors.base.Capabilities.fault_surfaces`, e.g. ``vanek-geometric``: the left inboard
aileron) must raise no alarm on a fault of any other surface: in a campaign whose runs fault
another surface (the run rows' ``surface``,
:attr:`campaign.plant_setup.ResolvedCampaign.surface`), its alarms after onset are isolation
failures, which the gate reports as such (:func:`reports.scoring.gate.evaluate_gate`,
``isolation``), and its missed-detection and DTP limits do not apply there. Fault-free runs
and alarms before onset are scored as for any detector.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

from detectors.base import Coverage

__all__ = ["Roles", "roles_of"]


def _stored_config(config_dict: Mapping | None):
    """The configuration stored with a campaign's results, validated again without its
    one-line notes (old spellings); None when there is none or this version cannot read
    it."""
    if not config_dict:
        return None
    from .config import CampaignConfig, ConfigError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            return CampaignConfig.from_dict(dict(config_dict), "stored campaign")
    except ConfigError:
        return None


@dataclass(frozen=True)
class Roles:
    """What each detector of a campaign is held to, beyond false alarms: the surface it must
    stay silent on (:attr:`isolation`, :func:`campaign.plant_setup.isolation_map`), the
    fault types it is designed to detect (:meth:`coverage`) and the detection system whose
    member it is (:meth:`system_of`), by result name (``label`` or ``label[variant]``, a
    system's name). Built by :func:`roles_of`."""

    isolation: dict = field(default_factory=dict)
    #: label → the detector built from the campaign file (unfitted: coverage reads its
    #: parameters only); a label whose class cannot be imported is left out
    detectors: dict = field(default_factory=dict)
    #: system name → its members (``[[system]]``)
    systems: dict = field(default_factory=dict)

    def coverage(self, name: str) -> Coverage:
        """The fault types result name *name* is designed to detect (every fault type for a
        detector that declares none, or whose class is not installed here)."""
        if name in self.systems:
            from detectors.system import DetectionSystem
            try:
                return DetectionSystem(self.systems[name], self.detectors).coverage()
            except ValueError:      # a member whose class is not installed here
                return Coverage()
        label, _, rest = name.partition("[")
        det = self.detectors.get(label)
        return Coverage() if det is None else det.coverage(rest[:-1] if rest else None)

    def system_of(self, name: str) -> str | None:
        """The first detection system that has result name *name* among its members (named,
        or by its label), or None."""
        label = name.split("[", 1)[0]
        for system, members in self.systems.items():
            if name in members or label in members:
                return system
        return None


def roles_of(source) -> Roles:
    """The :class:`Roles` of the detectors and systems of a campaign, the one way to them:
    *source* is its :class:`campaign.plant_setup.ResolvedCampaign` (its isolation map as
    resolved), its configuration (resolved here), or the configuration stored with its
    results in JSON form (``campaign.json``, ``meta["config"]``; none, or one this version
    cannot read — an older directory —, gives no roles; the one-line notes a reload may give,
    old spellings, are not repeated: the stored file was validated when it ran). A detector
    whose class cannot be imported here (a plugin no longer installed when a finished
    campaign is gated) declares nothing: scored for detection, every fault type."""
    from detectors.registry import DetectorSpecError, make_detector

    from .plant_setup import ResolvedCampaign, as_resolved

    if source is None or (isinstance(source, Mapping)
                          and not isinstance(source, ResolvedCampaign)):
        source = _stored_config(source)
        if source is None:
            return Roles()
    campaign = as_resolved(source)
    config = campaign.config
    built = {}
    for d in config.detectors:
        try:
            built[d.label] = make_detector(d.name, d.params_dict())
        except (DetectorSpecError, ValueError, TypeError):
            continue
    return Roles(isolation=dict(campaign.isolation), detectors=built,
                 systems={s.name: tuple(s.members) for s in config.systems})
