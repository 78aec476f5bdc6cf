"""Detector registry: names → lazily imported classes (like Gymnasium's registry).

Built-in detectors are listed in :data:`BUILTIN`. Third-party packages register theirs
through the entry-point group ``fdd_campaign.detectors``::

    [project.entry-points."fdd_campaign.detectors"]
    my-detector = "my_package.module:MyDetector"

An unknown name gets a "did you mean …" answer; unknown parameters are refused with the
list of allowed ones, before any run starts.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import sys
from importlib.metadata import entry_points

from scenarios.catalog import suggest
from scenarios.errors import InputError

from .base import Detector
from .params import parameter_markdown, parameter_problems

ENTRY_POINT_GROUP = "fdd_campaign.detectors"

#: Built-in detectors: name → "module:Class".
BUILTIN: dict[str, str] = {
    "position-monitor": "detectors.builtin.position_monitor:PositionMonitor",
    "comb-interval": "detectors.builtin.comb_interval:IntervalDetector",
    "chen-local": "detectors.builtin.chen_local:ChenLocalEstimator",
    "chen-global": "detectors.builtin.chen_global:ChenGlobalEstimator",
    "chen-global-paper": "detectors.builtin.chen_global_paper:ChenGlobalPaper",
    "vanek-geometric": "detectors.builtin.vanek_geometric:VanekGeometric",
}


class DetectorSpecError(InputError, ValueError):
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
    except Exception as exc:  # noqa: BLE001 - a plugin's module that fails: named (exit 2)
        if name in BUILTIN:
            raise                   # a built-in detector that cannot load is a bug
        raise DetectorSpecError(
            f"detector {name!r} ({specs[name]}, a third-party detector) fails when its module "
            f"is imported: {type(exc).__name__}: {exc}; fix it in that package (e.g. its "
            "parameter declarations, docs/write-a-detector.md)"
        ) from exc
    if not (inspect.isclass(cls) and issubclass(cls, Detector)):
        raise DetectorSpecError(
            f"detector {name!r} ({specs[name]}) is not a subclass of detectors.Detector"
        )
    return cls


def parameter_errors(name: str, params: dict) -> list[str]:
    """Every problem with the keyword *params* of detector *name*, one message each (empty
    when they are acceptable).

    Unknown names (from the ``__init__`` signature) and the values of the parameters the
    detector declares (:attr:`Detector.parameters`, :func:`detectors.params.parameter_problems`)
    are checked all at once. When those pass, the detector is built and its own
    ``validate_params`` runs (checks a declaration cannot express, and the checks of a
    detector that declares nothing). Each message starts with the parameter, so it reads
    after a location prefix such as ``detector[0].params: ``."""
    cls = load_detector_class(name)
    problems = parameter_problems(cls, params)
    if problems:
        return problems
    try:
        cls(**params).validate_params()
    except (TypeError, ValueError) as exc:
        return [str(exc)]
    return []


def make_detector(name: str, params: dict | None = None) -> Detector:
    """Build detector *name* with keyword *params* (validated first)."""
    params = dict(params or {})
    errors = parameter_errors(name, params)
    if errors:
        raise DetectorSpecError(f"detector {name!r}: " + "; ".join(errors))
    return load_detector_class(name)(**params)


REFERENCE_INTRO = """\
# Built-in detectors and their parameters

Generated from the parameter declarations of each detector class (`parameters`, see
[write-a-detector.md](write-a-detector.md)); regenerate with
`python -m detectors --markdown > docs/detectors.md`.

Give parameters in a campaign file as `params = { … }` of a `[[detector]]` table; every
parameter has a default. Values are shown as they are written in TOML. *allowed*: the
inequality a value must satisfy, written as in [campaign-file.md](campaign-file.md)
(`0 < pole < 1`; `each` for every number of a list); a bound may name another parameter. The
description ends with the source of the default value (`est.`: estimated for this
simulator). Parameters are checked before any run starts: every problem is reported at
once with the allowed values.
"""


def reference_markdown() -> str:
    """docs/detectors.md: the parameter table of every built-in detector
    (:func:`detectors.params.parameter_markdown`)."""
    body = parameter_markdown({name: load_detector_class(name) for name in BUILTIN})
    return REFERENCE_INTRO + "\n" + body


def main(argv: list[str] | None = None) -> int:
    """``python -m detectors``: list the registered detectors, or print the parameter
    reference docs/detectors.md (``--markdown``)."""
    parser = argparse.ArgumentParser(prog="python -m detectors",
                                     description=main.__doc__)
    parser.add_argument("--markdown", action="store_true",
                        help="print docs/detectors.md (the built-in detectors' parameters)")
    args = parser.parse_args(argv)
    if args.markdown:
        sys.stdout.write(reference_markdown())
    else:
        for name, spec in available_detectors().items():
            print(f"{name}\t{spec}")
    return 0
