"""Fault detectors: the contract, the registry and the built-in detectors."""

from .base import (
    Capabilities,
    Coverage,
    Detection,
    Detector,
    NotFittedError,
    as_variants,
    confirm,
    decide,
    detection_problems,
    read_only,
    windowed_min,
    writes_input,
)
from .params import Param, parameter_problems, parameter_table
from .registry import (
    DetectorSpecError,
    available_detectors,
    load_detector_class,
    make_detector,
    parameter_errors,
)

__all__ = [
    "Capabilities", "Coverage", "Detection", "Detector", "NotFittedError", "as_variants", "confirm",
    "decide", "detection_problems", "read_only", "windowed_min", "writes_input",
    "DetectorSpecError", "available_detectors", "load_detector_class", "make_detector",
    "parameter_errors", "Param", "parameter_problems", "parameter_table",
]
