"""Detector parameters declared once (detectors.params): the built-in declarations, the
one validator behind Detector.validate_params, registry.parameter_errors and the campaign
file, and the generated reference docs/detectors.md."""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

from detectors import (
    Detector,
    Param,
    parameter_errors,
    parameter_problems,
    parameter_table,
)
from detectors.base import Capabilities
from detectors.params import declared_parameters, signature_defaults
from detectors.registry import BUILTIN, load_detector_class, main, reference_markdown

REPO = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------------------------------
# the built-in declarations
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_every_builtin_declares_each_parameter_once_with_unit_doc_and_source(name):
    cls = load_detector_class(name)
    declared = [p.name for p in declared_parameters(cls)]
    assert declared == list(signature_defaults(cls))           # all of them, in order, once
    assert all(p.unit and p.doc and p.source for p in declared_parameters(cls))
    assert parameter_problems(cls, {}) == []                    # the defaults are allowed


def test_no_builtin_keeps_a_hand_written_parameter_check():
    # the declarations are the only source of the ranges: no built-in overrides
    # validate_params except for what a declaration cannot say (vanek's optional libraries)
    overriding = sorted(name for name in BUILTIN
                        if "validate_params" in vars(load_detector_class(name)))
    assert overriding == ["vanek-geometric"]
    src = inspect.getsource(load_detector_class("vanek-geometric").validate_params)
    assert "super().validate_params()" in src


@pytest.mark.parametrize("name, params", [
    # values valid before the declarations existed stay valid
    ("position-monitor", {"checks": "loop"}),
    ("position-monitor", {"checks": ["com_mon", "surface"], "safety": 2, "confirm_s": 0}),
    ("comb-interval", {"poles": 0.9}),
    ("comb-interval", {"poles": [0.6], "kappa": (0.1, 0.01, 0.05), "q_max": 50}),
    ("comb-interval", {"sensor": "surface", "use_power_law": True, "h_radius": 0}),
    ("chen-local", {"post_filter_zero_rad_s": 2, "post_filter_pole_rad_s": 10.0}),
    ("chen-local", {"sensor": "rod_mon", "h_perturbation": 0, "solid_confirm_s": 0.0}),
    ("chen-global", {"h_output": "r", "gust_channel": False, "filter_s": 0}),
    ("vanek-geometric", {"variants": "lpv", "decay": 1.0, "radius": 1.5, "smoothing_s": 0}),
    ("vanek-geometric", {"variants": ["lti", "lpv-affine"], "decouple_gusts": False}),
    # NumPy scalars are numbers too
    ("comb-interval", {"q_max": np.int64(40), "safety": np.float64(1.3)}),
])
def test_valid_values_are_accepted(name, params):
    assert parameter_errors(name, params) == []


# ---------------------------------------------------------------------------------------
# the validator
# ---------------------------------------------------------------------------------------
def test_every_problem_is_reported_at_once_naming_value_allowed_and_fix():
    errors = parameter_errors("comb-interval", {
        "poles": [0.9, 0.9], "kappa": [0.1, 0.1], "q_max": 2.5, "sensor": "rod",
        "use_power_law": 1, "floor_mm": 0.0, "safty": 1.5})
    assert errors == [
        "safty = 1.5: no such parameter (did you mean 'safety'?); allowed: poles, safety, "
        "kappa, h_radius, q_max, x0_radius_mm, sensor, use_power_law, floor_mm, "
        "threshold_method, target_fa_per_run, threshold_confidence, threshold_tail; fix: "
        "rename or remove "
        "safty",
        "poles = [0.9, 0.9]: 0.9 repeated; allowed: a single number or a non-empty list of "
        "finite numbers, each 0 < value < 1, all different; fix: e.g. poles = "
        "(0.6, 0.8, 0.9, 0.95, 0.99) (the default), or remove it",
        "kappa = [0.1, 0.1]: 2 values, not 3; allowed: a list of 3 finite numbers, each value > 0 "
        "[-, 1/mm, -]; fix: e.g. kappa = (0.02, 0.02, 0.06) (the default), or remove it",
        "q_max = 2.5: a number, not an integer; allowed: an integer with q_max ≥ 2 [steps]; "
        "fix: e.g. q_max = 300 (the default), or remove it",
        "sensor = 'rod': not one of the choices (did you mean 'rod_mon'?); allowed: one of "
        "'rod_com', 'rod_mon', 'surface'; fix: e.g. sensor = 'rod_com' (the default), or "
        "remove it",
        "use_power_law = 1: an integer, not true or false; allowed: true or false; fix: e.g. "
        "use_power_law = False (the default), or remove it",
        "floor_mm = 0.0: out of range; allowed: a finite number with floor_mm > 0 [mm]; "
        "fix: e.g. floor_mm = 0.0001 (the default), or remove it",
    ]


@pytest.mark.parametrize("params, expected", [
    ({"safety": float("inf")}, "safety = inf: not finite; allowed: a finite number with "
                               "safety > 1"),
    ({"safety": True}, "safety = True: a bool, not a number; allowed: a finite number with "
                       "safety > 1"),
    ({"confirm_s": "long"}, "confirm_s = 'long': a string, not a number; allowed: a finite "
                            "number with confirm_s ≥ 0 [s]"),
    ({"checks": []}, "checks = []: an empty list; allowed: one of 'loop', 'com_mon', "
                     "'surface', or a non-empty list of them"),
    ({"checks": ["loop", "surfce"]}, "checks = ['loop', 'surfce']: 'surfce' not among the "
                                     "choices (did you mean 'surface'?)"),
    ({"checks": 5}, "checks = 5: an integer, not a string or a list of strings"),
])
def test_each_kind_of_problem_reads_naturally(params, expected):
    (msg,) = parameter_errors("position-monitor", params)
    assert msg.startswith(expected)
    assert "; fix: " in msg


def test_a_bound_can_name_another_parameter():
    assert parameter_errors("vanek-geometric", {"decay": 2.0, "radius": 1.0}) == [
        "radius = 1.0: not > decay = 2.0; allowed: a finite number with radius > decay "
        "[rad/s]; fix: e.g. radius = 20.0 (the default), or remove it"]
    # the default radius no longer fits: say what to move instead
    assert parameter_errors("vanek-geometric", {"decay": 30.0}) == [
        "radius = 20.0: not > decay = 30.0; allowed: a finite number with radius > decay "
        "[rad/s]; fix: raise radius above decay = 30.0, or lower decay"]
    # an invalid decay is reported alone: radius cannot be compared with it
    (msg,) = parameter_errors("vanek-geometric", {"decay": -1.0, "radius": -2.0})
    assert msg.startswith("decay = -1.0: out of range")
    (msg,) = parameter_errors("chen-local", {"post_filter_zero_rad_s": 5.0,
                                             "post_filter_pole_rad_s": 1.0})
    assert msg.startswith("post_filter_pole_rad_s = 1.0: not > post_filter_zero_rad_s = 5.0")


def test_validate_params_lists_every_problem_and_fit_calls_it_first():
    from detectors.builtin.chen_global import ChenGlobalEstimator

    det = ChenGlobalEstimator(h_perturbation=0.0, h_output="beta", gust_channel=1)
    with pytest.raises(ValueError) as info:
        det.validate_params()
    text = str(info.value)
    assert text.startswith("ChenGlobalEstimator has 3 invalid parameters:\n")
    for needle in ("h_perturbation = 0.0: out of range", "h_output = 'beta': not one of",
                   "gust_channel = 1: an integer, not true or false"):
        assert needle in text
    with pytest.raises(ValueError, match="3 invalid parameters"):
        det.fit(None)                  # refused before the signals are even looked at
    assert not det.is_fitted


def test_the_campaign_file_reports_every_parameter_problem(tmp_path):
    from campaign.config import ConfigError, load_config

    path = tmp_path / "c.toml"
    path.write_text('[campaign]\nname = "t"\n\n[[group]]\nfault = "none"\ncount = 2\n\n'
                    '[[detector]]\nname = "position-monitor"\n'
                    'params = { safety = 0.5, checks = ["loop", "surfce"] }\n')
    with pytest.raises(ConfigError) as info:
        load_config(path)
    errors = info.value.errors
    assert errors == [
        "detector[0].params: safety = 0.5: out of range; allowed: a finite number with "
        "safety > 1; fix: e.g. safety = 1.5 (the default), or remove it",
        "detector[0].params: checks = ['loop', 'surfce']: 'surfce' not among the choices "
        "(did you mean 'surface'?); allowed: one of 'loop', 'com_mon', 'surface', or a "
        "non-empty list of them; fix: e.g. checks = ('loop', 'com_mon', 'surface') (the "
        "default), or remove it"]


# ---------------------------------------------------------------------------------------
# third-party detectors
# ---------------------------------------------------------------------------------------
class _Undeclared(Detector):
    """A third-party detector that declares nothing."""

    capabilities = Capabilities(needs_fit=False)

    def __init__(self, threshold=1.0):
        self.threshold = threshold


class _Declared(Detector):
    """A third-party detector declaring its parameters."""

    capabilities = Capabilities(needs_fit=False)
    parameters = (
        Param("pole", "float", ge=0.0, lt=1.0, doc="pole a of the residual filter"),
        Param("mode", "choice", choices=("abs", "rel"), doc="residual form",
              source="[X] §2"),
    )

    def __init__(self, pole=0.9, mode="abs", label=None):
        self.pole = pole
        self.mode = mode
        self.label = label


def test_a_detector_without_declarations_refuses_unknown_names_only():
    assert parameter_problems(_Undeclared, {"threshold": "anything"}) == []
    _Undeclared(threshold="anything").validate_params()
    (msg,) = parameter_problems(_Undeclared, {"treshold": 2.0})
    assert msg == ("treshold = 2.0: no such parameter (did you mean 'threshold'?); allowed: "
                   "threshold; fix: rename or remove treshold")


def test_parameter_table_lists_declared_and_undeclared_parameters():
    assert parameter_table(_Declared) == [
        {"name": "pole", "type": "float", "default": 0.9, "allowed": "0 ≤ pole < 1", "unit": "-",
         "doc": "pole a of the residual filter (est.)"},
        {"name": "mode", "type": "str", "default": "abs", "allowed": "abs, rel", "unit": "-",
         "doc": "residual form ([X] §2)"},
        {"name": "label", "type": "", "default": None, "allowed": "", "unit": "", "doc": ""},
    ]
    with pytest.raises(ValueError, match=r"pole = 1\.0: out of range; allowed: a finite "
                                         r"number with 0 ≤ pole < 1"):
        _Declared(pole=1.0).validate_params()


@pytest.mark.parametrize("kwargs, needle", [
    ({"kind": "floatt"}, "kind 'floatt' is not one of .* \\(did you mean 'float'\\?\\)"),
    ({"kind": "choice"}, "choices go with kind 'choice' or 'choices'"),
    ({"kind": "float", "choices": ("a",)}, "choices go with kind"),
    ({"kind": "bool", "gt": 0.0}, "bounds apply to numbers"),
    ({"kind": "float", "gt": 0.0, "ge": 1.0}, "at most one lower bound"),
    ({"kind": "float", "length": 3}, "apply to kind 'floats' only"),
])
def test_a_malformed_declaration_is_refused(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        Param("x", **kwargs)


# ---------------------------------------------------------------------------------------
# the generated reference
# ---------------------------------------------------------------------------------------
def test_docs_detectors_reference_is_up_to_date():
    doc = (REPO / "docs" / "detectors.md").read_text(encoding="utf-8")
    assert doc == reference_markdown(), (
        "docs/detectors.md is out of date; regenerate it with "
        "`python -m detectors --markdown > docs/detectors.md`")


def test_reference_lists_every_builtin_parameter(capsys):
    md = reference_markdown()
    for name in BUILTIN:
        assert f"## `{name}`" in md
        for row in parameter_table(load_detector_class(name)):
            assert f"| `{row['name']}` | {row['type']} |" in md
    assert main(["--markdown"]) == 0
    assert capsys.readouterr().out == md



def test_param_takes_its_bounds_by_position_as_the_plugin_api_always_did():
    # third-party detectors written against the plugin API may give gt, ge, lt, le by
    # position after name and kind: the same declaration, the same check
    assert Param("pole", "float", None, 0.0, 1.0) == Param("pole", "float", ge=0.0, lt=1.0)
    assert Param("pole", "float", None, 0.0, 1.0).range_text("pole") == "0 ≤ pole < 1"
    with pytest.raises(ValueError, match="at most one lower bound"):
        Param("pole", "float", 0.0, 0.0)
