"""Detector registry: names → lazily imported classes (like Gymnasium's registry).

Built-in detectors are listed in :data:`BUILTIN`. Third-party packages register theirs
through the entry-point group ``fdd_campaign.detectors``::

    [project.entry-points."fdd_campaign.detectors"]
    my-detector = "my_package.module:MyDetector"

An unknown name gets a "did you mean …" answer; unknown parameters are refused with the
list of allowed ones, before any run starts.
"""

from __future__ import annotations

import importlib
import inspect
from importlib.metadata import entry_points

from scenarios.catalog import suggest

from .base import Detector

ENTRY_POINT_GROUP = "fdd_campaign.detectors"

#: Built-in detectors: name → "module:Class".
BUILTIN: dict[str, str] = {
    "position-monitor": "detectors.position_monitor:PositionMonitor",
    "comb-interval": "detectors.comb_interval:IntervalDetector",
    "chen-local": "detectors.chen_local:ChenLocalEstimator",
    "chen-global": "detectors.chen_global:ChenGlobalEstimator",
    "vanek-geometric": "detectors.vanek_geometric:VanekGeometric",
}


class DetectorSpecError(ValueError):
    """A detector name or parameter that cannot be used (message says how to fix it)."""


def _entry_point_specs() -> dict[str, str]:
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_detectors() -> dict[str, str]:
    """All registered detectors: name → "module:Class" (built-ins first)."""
    specs = dict(BUILTIN)
    for name, value in _entry_point_specs().items():
        specs.setdefault(name, value)
    return specs


def load_detector_class(name: str) -> type[Detector]:
    """Import and return the class registered under *name*."""
    specs = available_detectors()
    if name not in specs:
        raise DetectorSpecError(
            f"unknown detector {name!r}{suggest(name, list(specs))}; registered: "
            f"{', '.join(sorted(specs))}. Third-party detectors register through the "
            f"entry-point group {ENTRY_POINT_GROUP!r}"
        )
    module_name, _, attr = specs[name].partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, attr)
    except (ImportError, AttributeError) as exc:
        raise DetectorSpecError(
            f"detector {name!r} is registered as {specs[name]!r}, which cannot be imported: "
            f"{exc}. Is the package that provides it installed?"
        ) from exc
    if not (inspect.isclass(cls) and issubclass(cls, Detector)):
        raise DetectorSpecError(
            f"detector {name!r} ({specs[name]}) is not a subclass of detectors.Detector"
        )
    return cls


def parameter_errors(name: str, params: dict) -> list[str]:
    """Problems with *params* for detector *name* (empty when they are acceptable)."""
    cls = load_detector_class(name)
    sig = inspect.signature(cls.__init__)
    allowed = [p for p in sig.parameters if p != "self"]
    errors = []
    for key in params:
        if key not in allowed:
            errors.append(
                f"detector {name!r} has no parameter {key!r}{suggest(key, allowed)}; "
                f"allowed: {', '.join(allowed) or '(none)'}"
            )
    if not errors:
        try:
            cls(**params).validate_params()
        except (TypeError, ValueError) as exc:
            errors.append(f"detector {name!r}: {exc}")
    return errors


def make_detector(name: str, params: dict | None = None) -> Detector:
    """Build detector *name* with keyword *params* (validated first)."""
    params = dict(params or {})
    errors = parameter_errors(name, params)
    if errors:
        raise DetectorSpecError("; ".join(errors))
    return load_detector_class(name)(**params)
