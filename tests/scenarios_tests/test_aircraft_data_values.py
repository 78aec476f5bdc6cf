"""scenarios.aircraft.data by value: the tables are those the specification gives
(docs/aircraft.md §4 for the laws, docs/physics.md §4 and §7 for the sensors, the surfaces
and the laws' summary), the declared bounds of the laws are where they are declared, and the
surface look-up names what it refuses. The derivative set and the airframes are checked
through the models they build (test_aircraft_model.py: the published 747 modes;
test_aircraft_lpv_values.py: the scaling), the pilot table through the inputs it shapes
(test_aircraft_pilot_values.py)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from scenarios.aircraft import data, lpv
from scenarios.aircraft.data import (AIRCRAFT_SENSORS, B747_CONDITION, B747_DERIVATIVES, LAWS,
                                     LAYOUT)
from scenarios.params import AILERON, ELEVATOR, RUDDER

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_the_laws_are_the_table_of_aircraft_md():
    """docs/aircraft.md §4's parameter table (`name` | value | unit | source), every row."""
    text = (DOCS / "aircraft.md").read_text()
    rows = re.findall(r"^\| `(\w+)`[^|]*\| ([-0-9.]+) \|", text, flags=re.M)
    fields = {f.name for f in dataclasses.fields(data.LawParams)}
    found = {name: float(v) for name, v in rows if name in fields}
    assert len(found) == 13, sorted(found)
    for name, value in found.items():
        assert getattr(LAWS, name) == value, name


def test_the_rest_of_the_laws_are_those_of_physics_md():
    """docs/physics.md §7's laws table: yaw damper 1 s⁻¹, sideslip feedback 1 s⁻² and its
    integral 0.5 s⁻³, turn compensation up to 33° of bank, orders kept where the hinge load
    stays below 0.9 of the stall force."""
    assert (LAWS.yaw_damping, LAWS.sideslip_gain, LAWS.sideslip_integral) == (1.0, 1.0, 0.5)
    assert LAWS.bank_max_deg == 33.0
    assert LAWS.hinge_load_limit == 0.9


def test_the_aircraft_sensors_are_those_of_physics_md():
    """docs/physics.md §4, aircraft level: p, q, r σ 0.02 °/s; φ, θ σ 0.02°; n_z, n_y σ
    0.003 g; β and α σ 0.1°."""
    s = AIRCRAFT_SENSORS
    assert (s.rate_noise_deg_s, s.attitude_noise_deg, s.load_noise_g) == (0.02, 0.02, 0.003)
    assert (s.sideslip_noise_deg, s.aoa_noise_deg) == (0.1, 0.1)


#: docs/physics.md §7 "Each surface on every axis", at M 0.8 and 25 % MAC: (column, Cz, Cm,
#: Cl, Cn) as printed; a value is checked to half a unit of its last printed digit.
SURFACE_TABLE = [
    ("left_elevator", "-0.182", "-0.722", "0.0124", "0"),
    ("right_elevator", "-0.182", "-0.722", "-0.0124", "0"),
    ("left_inboard_aileron", "-0.0295", "-0.022", "0.0103", "1.5e-4"),
    ("right_inboard_aileron", "-0.0295", "-0.022", "-0.0103", "-1.5e-4"),
    ("left_outboard_aileron", "-0.0238", "-0.027", "0.0103", "1.5e-4"),
    ("right_outboard_aileron", "-0.0238", "-0.027", "-0.0103", "-1.5e-4"),
    ("spoiler", "0", "0", "-0.041", "-0.0041"),
]


def _half_unit(printed: str) -> float:
    """Half a unit of the last printed digit ("-0.0295" → 5e-5, "1.5e-4" → 5e-6); exact 0
    for a printed 0 (the term is absent)."""
    if float(printed) == 0.0:
        return 0.0
    mantissa, _, exp = printed.lstrip("-").partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (-decimals + (int(exp) if exp else 0))


@pytest.mark.parametrize("column, cz, cm, cl, cn", SURFACE_TABLE)
def test_the_control_derivatives_are_the_table_of_physics_md(column, cz, cm, cl, cn):
    c = lpv.control_derivatives(B747_CONDITION.mach, data.B747.cg_ref_pct)
    j = lpv.I_SPOILER if column == "spoiler" else LAYOUT.names.index(column)
    for key, printed in (("Cz", cz), ("Cm", cm), ("Cl", cl), ("Cn", cn)):
        got = float(c[key][j])
        assert abs(got - float(printed)) <= _half_unit(printed), (key, got, printed)


def test_the_rudder_carries_the_whole_747_rudder_set():
    """docs/physics.md §7: the rudder's column is Cyδr, Clδr, Cnδr of the 747 set (Etkin &
    Reid, Boeing 747 at 40 000 ft, M 0.8: Cyδr 0.1146, Clδr 6.976e-3, Cnδr −0.1257), with no
    lift or pitch."""
    c = lpv.control_derivatives(0.8, 25.0)
    j = LAYOUT.names.index("rudder")
    assert (B747_DERIVATIVES.Cy_dr, B747_DERIVATIVES.Cl_dr, B747_DERIVATIVES.Cn_dr) == (
        0.1146, 6.976e-3, -0.1257)
    assert [float(c[k][j]) for k in ("Cy", "Cl", "Cn", "Cz", "Cm")] == pytest.approx(
        [0.1146, 6.976e-3, -0.1257, 0.0, 0.0], rel=1e-12, abs=0.0)


def test_the_reference_condition_is_40000_ft_at_mach_0_8():
    """docs/aircraft.md: the derivative set is Etkin & Reid's 747 at 40 000 ft, M 0.8."""
    assert (B747_CONDITION.alt_ft, B747_CONDITION.mach) == (40000.0, 0.8)


_POSITIVE = ("pitch_cap", "pitch_zeta", "pitch_integral", "pitch_filter_s", "roll_bandwidth",
             "roll_filter_s", "yaw_filter_s", "elevator_rate_deg_s", "aileron_rate_deg_s",
             "rudder_rate_deg_s")


@pytest.mark.parametrize("name", _POSITIVE + ("pitch_omega_min", "pitch_omega_max"))
def test_each_declared_positive_law_parameter_is_refused_at_zero_only(name):
    """Declared gt=0: a small positive value is accepted, 0 refused with the name and the
    allowed range."""
    small = {name: 0.01}
    if name == "pitch_omega_max":
        small["pitch_omega_min"] = 0.01
    dataclasses.replace(LAWS, **small)
    message = rf"control laws \(LawParams\): {name} = 0.0: out of range"
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(LAWS, **dict(small, **{name: 0.0}))


def test_the_lowest_short_period_may_equal_the_highest_but_not_exceed_it():
    dataclasses.replace(LAWS, pitch_omega_min=1.5, pitch_omega_max=1.5)
    with pytest.raises(ValueError, match=r"pitch_omega_min 1.6 rad/s is above pitch_omega_max "
                                         r"1.5 rad/s"):
        dataclasses.replace(LAWS, pitch_omega_min=1.6, pitch_omega_max=1.5)


def test_each_surface_gets_its_kind_of_actuator_under_its_own_name():
    for surface, kind in zip(LAYOUT.names, (ELEVATOR, ELEVATOR, AILERON, AILERON, AILERON,
                                            AILERON, RUDDER)):
        act = data.surface_actuator(surface)
        assert act == kind.replace(surface=surface), surface
    with pytest.raises(ValueError, match="unknown aircraft surface 'flap'; allowed: left_elevator"):
        data.surface_actuator("flap")


def test_the_derivative_set_is_the_published_one():
    """Etkin & Reid, Boeing 747 at 40 000 ft, M 0.8 (after Heffley & Jewell, NASA CR-2144),
    stability axes, per rad. A change of 1 in Czq, Czα̇, Cmq or Cmα̇ (or Cyr from 0 to 1)
    moves the published modes that test_aircraft_model.py reproduces by under its 1 % of
    |λ|, so the set is checked entry by entry."""
    published = dict(
        Cz_alpha=-4.920, Cz_q=-5.921, Cz_alphadot=5.896, Cm_alpha=-1.023, Cm_q=-23.92,
        Cm_alphadot=-6.314, Cz_de=-0.3648, Cm_de=-1.444, Cy_beta=-0.8771, Cl_beta=-0.2797,
        Cn_beta=0.1946, Cy_p=0.0, Cl_p=-0.3295, Cn_p=-0.04073, Cy_r=0.0, Cl_r=0.3040,
        Cn_r=-0.2737, Cl_da=-1.368e-2, Cn_da=-1.973e-4, Cy_dr=0.1146, Cl_dr=6.976e-3,
        Cn_dr=-0.1257)
    assert dataclasses.asdict(B747_DERIVATIVES) == published


@pytest.mark.parametrize("table", [B747_DERIVATIVES, data.B747, B747_CONDITION,
                                   data.A330_SCALING, LAYOUT, LAWS, data.PILOT,
                                   AIRCRAFT_SENSORS], ids=lambda t: type(t).__name__)
def test_every_table_is_frozen(table):
    """A table is shared by every run of every campaign: it cannot be changed in place."""
    name = dataclasses.fields(table)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(table, name, getattr(table, name))
