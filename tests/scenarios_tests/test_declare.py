"""One way to declare a parameter (scenarios/declare.py): campaign keys, detector parameters
and plant parameters share one bound vocabulary (gt/ge/lt/le), one range text and one
bound check."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import pytest

from campaign.config.keys import Key
from detectors import Param
from scenarios.declare import Declared, field_problems, num
from scenarios.params import ELEVATOR, SENSORS, param


def test_keys_detector_and_plant_parameters_share_one_bound_vocabulary_and_range_text():
    @dataclass(frozen=True)
    class _Plant:
        gain: float = param("s", "est.", "a gain", default=0.5, gt=0.0, le=600.0)

    (plant,) = [f.metadata["declared"] for f in dataclasses.fields(_Plant)]
    key = Key(kind="float", doc="a gain", unit="s", gt=0.0, le=600.0)
    det = Param("gain", "float", unit="s", gt=0.0, le=600.0)
    for spec in (plant, key, det):
        assert isinstance(spec, Declared)
        assert spec.range_text("gain") == "0 < gain ≤ 600 s"
        # the bounds as written: 0 is excluded (gt), 600 included (le)
        assert spec.out_of_range(0.0) and not spec.out_of_range(600.0)
        assert spec.out_of_range(600.000001) and spec.out_of_range(float("nan"))
    # a bound naming another parameter is checked against that parameter's value
    named = Param("radius", "float", gt="decay")
    assert named.range_text("radius") == "radius > decay"
    assert named.broken_bound(1.0, {"decay": 2.0}) == ("gt", 2.0)
    assert named.broken_bound(3.0, {"decay": 2.0}) is None


@pytest.mark.parametrize("bounds", [{"gt": 0.0, "ge": 0.0}, {"lt": 1.0, "le": 1.0}])
def test_two_bounds_on_one_side_are_refused_for_every_declaration(bounds):
    for make in (lambda: Declared(**bounds), lambda: Key(kind="float", **bounds),
                 lambda: Param("x", "float", **bounds)):
        with pytest.raises(ValueError, match="at most one lower bound"):
            make()


def test_a_plant_parameter_outside_its_declared_bounds_is_refused_with_the_range():
    with pytest.raises(ValueError, match=r"^elevator actuator: r_mm = -1\.0: out of range; "
                                         r"allowed: r_mm > 0 mm; mach_compress_cap = 1\.0: "
                                         r"out of range; allowed: 0 < mach_compress_cap < 1$"):
        ELEVATOR.replace(r_mm=-1.0, mach_compress_cap=1.0)
    with pytest.raises(ValueError, match="rod_noise_mm = -0.1: out of range"):
        dataclasses.replace(SENSORS, rod_noise_mm=-0.1)
    # the shipped tables and the limits of a test's unloaded actuator are within the bounds
    assert field_problems(ELEVATOR) == [] and field_problems(SENSORS) == []
    assert ELEVATOR.replace(Sc_m2=0.0, Ka_N_per_mm_s2=0.0).Sc_m2 == 0.0


@pytest.mark.parametrize("x, text", [(0.5, "0.5"), (1e-6, "1e-06"), (600, "600"),
                                     (123456.0, "123456"), (1234567.0, "1234567.0"),
                                     ("decay", "decay")])
def test_one_number_format(x, text):
    # %g below 10^6; from 10^6 on %g would round (1.23457e+06), so the full repr is written
    assert num(x) == text
