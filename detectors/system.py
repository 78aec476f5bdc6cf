"""Detection systems: a set of detectors whose alarm is the first alarm of any member.

ADDSAFE's requirements (zero false alarms, zero missed detections, a good detection time
performance) are on the detection *system* of a surface, which may combine monitors that
each see some faults ([CHEN] §5; docs/design.md §5, Detection systems). A campaign file
names one with ``[[system]]`` (its ``members``: detector labels, a label standing for every
variant of that detector, or result names ``LABEL[VARIANT]``); the engine scores it like a
detector, under its own name.

The system's detection of a run is made of its members' (:meth:`DetectionSystem.combine`):

* alarm: the members' alarms or-ed, step by step, so its first alarm is the earliest of
  theirs, before onset (a false alarm of any member is the system's) and after;
* residual: the largest member residual at each step (NaN where every member's is);
* decision: the largest member decision at each step, when every member gives one. Then the
  system's first alarm is the first step where it reaches 1, and at every threshold × s of
  every member the first step where it reaches s: the system has a threshold scale
  (:attr:`detectors.base.Capabilities.threshold_scale`), and its margin — the decision's
  largest value before onset — is the largest member margin;
* no fault estimate.

A system covers the fault types any member covers (:meth:`detectors.base.Coverage.union`).
It learns nothing: its members are fitted on their own.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from .base import (Capabilities, Coverage, Detection, Detector, as_variants,
                   at_threshold_scale, threshold_scale_of)

__all__ = ["DetectionSystem", "with_systems"]


class DetectionSystem(Detector):
    """The first alarm of any of *members* (detector labels or result names
    ``LABEL[VARIANT]``) of the fitted *detectors* (label → Detector) it is bound to."""

    def __init__(self, members: tuple[str, ...] = (), detectors: Mapping | None = None):
        self.members = tuple(members)
        self.detectors = dict(detectors or {})
        missing = [m for m in self.member_labels if m not in self.detectors]
        if missing:
            raise ValueError(f"detection system members {', '.join(map(repr, missing))} "
                             "name no detector given")
        caps = [d.capabilities for d in self.member_detectors.values()]
        self.capabilities = Capabilities(
            needs_fit=False,
            needs_surface_sensor=any(c.needs_surface_sensor for c in caps),
            needs_pressure_sensor=any(c.needs_pressure_sensor for c in caps),
            needs_aircraft=any(c.needs_aircraft for c in caps),
            causal=all(c.causal for c in caps),
            threshold_scale=bool(caps) and all(getattr(c, "threshold_scale", False)
                                               for c in caps))

    def get_params(self) -> dict:
        return {"members": self.members}

    @property
    def member_labels(self) -> tuple[str, ...]:
        """The detector labels the members name, in their order, once each."""
        return tuple(dict.fromkeys(m.split("[", 1)[0] for m in self.members))

    @property
    def member_detectors(self) -> dict:
        """label → fitted detector of each member label."""
        return {label: self.detectors[label] for label in self.member_labels}

    def has_members_in(self, names: Iterable[str]) -> bool:
        """Whether *names* (result names) hold a detection of every member detector, so that
        :meth:`combine` can be made from them without running the members again."""
        names = list(names)
        return all(any(_of_label(n, label) for n in names) for label in self.member_labels)

    def member_names(self, names: Iterable[str]) -> list[str]:
        """The result names of *names* (the variants the member detectors gave) that are
        members: a bare label stands for the label itself and every ``label[…]``. Raises
        ``ValueError`` naming a member ``LABEL[VARIANT]`` that is not among them."""
        names = list(names)
        out = []
        for member in self.members:
            if "[" in member:
                if member not in names:
                    base = member.split("[", 1)[0]
                    given = [n for n in names if n == base or n.startswith(base + "[")]
                    raise ValueError(
                        f"member {member!r} is no result of detector {base!r}, whose results "
                        f"are {', '.join(given) or '(none)'}; fix: name one of those in "
                        "[[system]] members, or the bare label for all of them")
                out.append(member)
            else:
                out += [n for n in names if _of_label(n, member)]
        return list(dict.fromkeys(out))

    def coverage(self, variant: str | None = None) -> Coverage:
        """The fault types any member covers."""
        total = None
        for member in self.members:
            label, _, rest = member.partition("[")
            cov = self.detectors[label].coverage(rest[:-1] if rest else None)
            total = cov if total is None else total.union(cov)
        return total if total is not None else Coverage()

    def combine(self, detections: Mapping[str, Detection]) -> Detection:
        """The system's detection from its members' (*detections*: result name →
        Detection, holding at least every member's; see the module docstring)."""
        parts = [detections[n] for n in self.member_names(detections)]
        if not parts:
            raise ValueError("no member gave a detection")
        alarm = np.logical_or.reduce([np.asarray(p.alarm) for p in parts])
        residual = _fmax([p.residual for p in parts])
        decisions = [p.decision for p in parts]
        decision = None if any(d is None for d in decisions) else _fmax(decisions)
        return Detection(alarm=alarm, residual=residual, decision=decision)

    def _detect(self, signals):
        """The members run here, on *signals*, each at its threshold scale (a caller that
        already has their detections uses :meth:`combine`)."""
        detections = {}
        for label, det in self.member_detectors.items():
            try:
                # each member at its own [[detector]] threshold_scale, as the engine runs it
                detections.update({name: at_threshold_scale(d, threshold_scale_of(det))
                                   for name, d in as_variants(label, det.detect(signals)).items()})
            except Exception as exc:
                raise RuntimeError(f"member {label!r} failed: {type(exc).__name__}: "
                                   f"{exc}") from exc
        return self.combine(detections)


def _of_label(name: str, label: str) -> bool:
    """Whether result name *name* is detector *label*'s (the label itself or a variant)."""
    return name == label or name.startswith(label + "[")


def _fmax(arrays) -> np.ndarray:
    """Element-wise maximum of *arrays* ignoring NaN (NaN where every one is)."""
    out = np.array(arrays[0], dtype=float, copy=True)
    for a in arrays[1:]:
        np.fmax(out, a, out=out)
    return out


def with_systems(detectors: Mapping, systems: Iterable) -> dict:
    """*detectors* (label → fitted Detector) followed by a :class:`DetectionSystem` of them
    for each of *systems* (``[[system]]`` specs: ``name`` and ``members``), under its name."""
    out = dict(detectors)
    for spec in systems:
        out[spec.name] = DetectionSystem(spec.members, detectors)
    return out
