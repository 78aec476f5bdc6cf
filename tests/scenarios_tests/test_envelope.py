"""Flight envelope: grid, uncertainty levels, flight condition, measured scheduling data and
the realistic-case rule (docs/physics.md §6, §8)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from scenarios.atmosphere import ISA_CONSTANTS, cas_to_mach
from scenarios.envelope import (
    A330,
    DRAW_COLUMNS,
    LEVELS,
    MISMATCH,
    TABLE1,
    UNCERTAINTY,
    AircraftParams,
    Mismatch,
    Uncertainty,
    flight_condition,
    grid_points,
    half_widths,
    level_draws,
    measured_schedule,
    realistic_points,
    realistic_rule,
)
from scenarios.params import parameter_table

GRID_COLUMNS = ["alt_ft", "vcas_kt", "mass_t", "cg_pct"]
CRITERIA = ("mach>MMO", "vcas>VMO", "buffet")
CONDITIONS = ("nominal", "slow_heavy", "fast_light")


# ---- parameter tables --------------------------------------------------------------------
@pytest.mark.parametrize("table", [TABLE1, A330, UNCERTAINTY, MISMATCH, ISA_CONSTANTS],
                         ids=lambda t: type(t).__name__)
def test_every_parameter_has_unit_and_source(table):
    for row in parameter_table(table):
        assert row["unit"], row["name"]
        assert row["source"], row["name"]


def test_table1_values():
    assert TABLE1.alt_ft == (8000, 18000, 28000, 38000)
    assert TABLE1.vcas_kt == (160, 220, 300)
    assert TABLE1.mass_t == (120, 180, 233)
    assert TABLE1.cg_pct == (17, 30, 41)


def test_aircraft_and_uncertainty_values():
    assert (A330.wing_area_m2, A330.mac_m, A330.mmo, A330.vmo_kt, A330.buffet_margin_g) == (
        361.6, 7.27, 0.86, 330.0, 1.3)
    assert A330.tail_arm_m == pytest.approx(28.0, abs=1.0)
    assert dataclasses.astuple(UNCERTAINTY) == (0.05, 0.10, 0.10, 0.10, 0.10) + (None,) * 6
    assert dataclasses.astuple(MISMATCH) == (True, 0.05, 0.05, 0.20, None, None, None)
    with pytest.raises(dataclasses.FrozenInstanceError):
        A330.mmo = 0.9  # type: ignore[misc]


def test_buffet_curve_interpolates_linearly_and_is_clamped():
    assert A330.buffet_cl(0.75) == pytest.approx(0.83)
    assert A330.buffet_cl(0.775) == pytest.approx((0.83 + 0.74) / 2)
    np.testing.assert_allclose(A330.buffet_cl([0.1, 0.95]), [1.50, 0.50])


# ---- grid ----------------------------------------------------------------------------------
def test_grid_has_108_unique_points():
    g = grid_points()
    assert len(g) == 108 == TABLE1.n_points
    assert list(g.columns) == ["point", *GRID_COLUMNS]
    assert g["point"].tolist() == list(range(108))
    assert not g.duplicated(GRID_COLUMNS).any()
    for col in GRID_COLUMNS:
        assert sorted(g[col].unique()) == sorted(TABLE1[col])


# ---- uncertainty levels --------------------------------------------------------------------
def test_half_widths_cover_the_draw_columns():
    w = half_widths(UNCERTAINTY, MISMATCH)
    assert tuple(w) == DRAW_COLUMNS
    assert w == {"d_cx": 0.05, "d_cy": 0.05, "d_cz": 0.05, "d_cl": 0.05, "d_cm": 0.05,
                 "d_cn": 0.05, "d_vcas": 0.10, "d_alt": 0.10, "d_mass": 0.10, "d_cg": 0.10,
                 "d_supply": 0.05, "d_kci": 0.05, "d_ch0": 0.20, "d_cha": 0.20, "d_chd": 0.20}
    off = half_widths(UNCERTAINTY, dataclasses.replace(MISMATCH, enabled=False))
    assert off["d_supply"] == off["d_kci"] == off["d_ch0"] == off["d_cha"] == off["d_chd"] == 0.0
    assert off["d_vcas"] == 0.10


def test_per_coefficient_half_widths_win_over_the_shorthands():
    """docs/physics.md §6: ``aero`` and ``hinge`` set every coefficient not given one by one."""
    w = half_widths(dataclasses.replace(UNCERTAINTY, aero=0.02, cm=0.08),
                    dataclasses.replace(MISMATCH, hinge=0.3, ch0=0.5))
    assert w["d_cm"] == 0.08
    assert w["d_cx"] == w["d_cy"] == w["d_cz"] == w["d_cl"] == w["d_cn"] == 0.02
    assert (w["d_ch0"], w["d_cha"], w["d_chd"]) == (0.5, 0.3, 0.3)


def test_level_draws():
    w = half_widths(UNCERTAINTY, MISMATCH)
    assert level_draws("min", UNCERTAINTY, MISMATCH) == {c: -v for c, v in w.items()}
    assert level_draws("max", UNCERTAINTY, MISMATCH) == w
    assert set(level_draws("nominal", UNCERTAINTY, MISMATCH).values()) == {0.0}
    custom = level_draws("min", Uncertainty(0.01, 0.02, 0.03, 0.04, 0.05),
                         Mismatch(False, 0.1, 0.1, 0.1))
    assert custom["d_mass"] == -0.04 and custom["d_ch0"] == custom["d_chd"] == 0.0
    assert custom["d_cx"] == custom["d_cn"] == -0.01


@pytest.mark.parametrize("bad", ["mean", "MAX", ""])
def test_unknown_level_is_a_clear_error(bad):
    with pytest.raises(ValueError, match=r"unknown uncertainty level.*'min', 'nominal', 'max'"):
        level_draws(bad)


# ---- flight condition ----------------------------------------------------------------------
def test_flight_condition_lift_balances_weight_and_tail_load():
    alt, vcas, mass, cg = 28_000.0, 300.0, 180.0, 30.0
    fc = flight_condition(alt, vcas, mass, cg)
    assert set(fc) == {"mach", "qbar_pa", "tas_ms", "alpha_deg", "cl"}
    assert fc["mach"] == pytest.approx(cas_to_mach(vcas, alt))
    weight = mass * 1000 * 9.80665
    tail = 1 + (A330.x_ac_pct - cg) / 100 * A330.mac_m / A330.tail_arm_m
    assert fc["cl"] * fc["qbar_pa"] * A330.wing_area_m2 == pytest.approx(weight * tail, rel=1e-12)
    # a cruise point: C_L ≈ 0.36 and a trimmed wing AoA of a few degrees
    assert fc["cl"] == pytest.approx(0.363, abs=0.005)
    assert 0.0 < fc["alpha_deg"] < 4.0


def test_forward_cg_needs_more_wing_lift():
    fc = flight_condition(18_000.0, 220.0, 180.0, np.array([17.0, 30.0, 41.0]))
    cl = fc["cl"]
    assert cl[0] > cl[1] > cl[2]
    # tail-load effect of 24 % MAC of CG travel: 0.24·7.27/28 ≈ 6 % of the wing lift
    assert cl[0] / cl[2] - 1 == pytest.approx(0.24 * 7.27 / 28 / (1 + (26 - 41) / 100 * 7.27 / 28),
                                              rel=1e-9)


def test_flight_condition_is_vectorised():
    g = grid_points()
    fc = flight_condition(g["alt_ft"], g["vcas_kt"], g["mass_t"], g["cg_pct"])
    for v in fc.values():
        assert isinstance(v, np.ndarray) and v.shape == (108,)
        assert np.all(np.isfinite(v))
    # slower and heavier → higher AoA
    slow, fast = flight_condition(8_000.0, [160.0, 300.0], 180.0, 30.0)["alpha_deg"]
    assert slow > fast


def test_lift_curve_slope_prandtl_glauert_with_cap():
    assert A330.lift_curve_slope(0.0) == pytest.approx(A330.cl_alpha_per_rad)
    assert A330.lift_curve_slope(0.6) == pytest.approx(A330.cl_alpha_per_rad / 0.8)
    assert A330.lift_curve_slope(0.95) == pytest.approx(A330.lift_curve_slope(0.75))


# ---- measured scheduling data ----------------------------------------------------------------
def test_measured_schedule_applies_the_deviations():
    true = dict(alt_ft=28_000.0, vcas_kt=220.0, mass_t=180.0, cg_pct=30.0)
    d = dict(d_alt=0.05, d_vcas=-0.10, d_mass=0.10, d_cg=-0.02)
    m = measured_schedule(**true, **d)
    assert set(m) == {"vcas_kt", "alt_ft", "mass_t", "cg_pct", "mach", "qbar_pa", "alpha_deg"}
    assert m["alt_ft"] == pytest.approx(28_000.0 * 1.05)
    assert m["vcas_kt"] == pytest.approx(220.0 * 0.90)
    assert m["mass_t"] == pytest.approx(180.0 * 1.10)
    assert m["cg_pct"] == pytest.approx(30.0 * 0.98)
    fc = flight_condition(m["alt_ft"], m["vcas_kt"], m["mass_t"], m["cg_pct"])
    for key in ("mach", "qbar_pa", "alpha_deg"):
        assert m[key] == pytest.approx(fc[key], rel=1e-12)
    truth = flight_condition(**true)
    assert m["mach"] < truth["mach"]  # the detector sees a slower aircraft
    assert m["alpha_deg"] > truth["alpha_deg"]


def test_measured_schedule_without_deviation_is_the_truth():
    g = grid_points()
    m = measured_schedule(g["alt_ft"], g["vcas_kt"], g["mass_t"], g["cg_pct"], 0.0, 0.0, 0.0, 0.0)
    fc = flight_condition(g["alt_ft"], g["vcas_kt"], g["mass_t"], g["cg_pct"])
    np.testing.assert_array_equal(m["mach"], fc["mach"])
    np.testing.assert_array_equal(m["alpha_deg"], fc["alpha_deg"])
    np.testing.assert_array_equal(m["vcas_kt"], g["vcas_kt"].to_numpy())


@pytest.mark.parametrize("level", list(LEVELS))
def test_all_324_cases_give_finite_schedules(level):
    g = grid_points()
    d = level_draws(level)
    m = measured_schedule(g["alt_ft"], g["vcas_kt"], g["mass_t"], g["cg_pct"],
                          d["d_alt"], d["d_vcas"], d["d_mass"], d["d_cg"])
    for key, v in m.items():
        assert v.shape == (108,) and np.all(np.isfinite(v)), key


# ---- realistic rule --------------------------------------------------------------------------
def test_realistic_rule_keeps_53_of_108_points():
    r = realistic_points()
    assert len(r) == 108
    assert r["realistic"].dtype == bool
    # docs/physics.md §6: exactly 53 points, i.e. 159 of the 324 cases ([CHEN]: 158)
    assert int(r["realistic"].sum()) == 53
    assert 3 * int(r["realistic"].sum()) == 159


def test_every_rejected_point_names_its_criteria():
    r = realistic_points()
    assert (r.loc[r["realistic"], "rejected_by"] == "").all()
    rejected = r.loc[~r["realistic"], "rejected_by"]
    assert (rejected != "").all()
    for reasons in rejected:
        for reason in reasons.split("; "):
            criterion, condition = reason.split("@")
            assert criterion in CRITERIA and condition in CONDITIONS, reason


def test_rule_rejects_for_the_right_reasons():
    r = realistic_points().set_index(GRID_COLUMNS)
    # 38 000 ft at 300 kt is M 0.93: beyond MMO whatever the mass and CG
    high_fast = r.xs((38_000.0, 300.0), level=("alt_ft", "vcas_kt"))
    assert not high_fast["realistic"].any()
    assert high_fast["rejected_by"].str.contains("mach>MMO@nominal").all()
    # 8 000 ft, 160 kt, 233 t: C_L ≈ 1.5 at 1 g, far beyond buffet with a 1.3 g margin
    assert "buffet@nominal" in r.loc[(8_000.0, 160.0, 233.0, 17.0), "rejected_by"]
    # a typical cruise point and a light low-altitude point are realistic
    assert r.loc[(28_000.0, 300.0, 180.0, 30.0), "realistic"]
    assert r.loc[(8_000.0, 220.0, 120.0, 30.0), "realistic"]
    # the slow/heavy corner decides borderline points (buffet ratio 1.003 there)
    assert r.loc[(28_000.0, 220.0, 180.0, 30.0), "rejected_by"] == "buffet@slow_heavy"
    # the +10 % corner of 300 kt lands exactly on VMO and is allowed (≤ VMO)
    assert not r["rejected_by"].str.contains("vcas>VMO").any()


def test_rule_depends_on_the_uncertainty_corners_and_aircraft():
    g = grid_points()
    no_corners = realistic_rule(g, Uncertainty(0.05, 0.0, 0.10, 0.0, 0.10))
    assert int(no_corners["realistic"].sum()) > 53
    # a lower VMO rejects the 300 kt points (their fast corner is 330 kt)
    low_vmo = realistic_rule(g, aircraft=dataclasses.replace(A330, vmo_kt=320.0))
    assert low_vmo.loc[g["vcas_kt"] == 300.0, "rejected_by"].str.contains(
        "vcas>VMO@fast_light").all()


def test_realistic_rule_keeps_input_and_validates_columns():
    g = grid_points()
    before = g.copy()
    out = realistic_rule(g)
    pd.testing.assert_frame_equal(g, before)  # input untouched
    pd.testing.assert_frame_equal(out[g.columns], g)
    with pytest.raises(ValueError, match="mass_t"):
        realistic_rule(g.drop(columns="mass_t"))


def test_aircraft_params_is_replaceable():
    heavy_wing = dataclasses.replace(A330, wing_area_m2=400.0)
    assert isinstance(heavy_wing, AircraftParams)
    base = flight_condition(18_000.0, 220.0, 180.0, 30.0)["cl"]
    assert flight_condition(18_000.0, 220.0, 180.0, 30.0, heavy_wing)["cl"] == pytest.approx(
        base * 361.6 / 400.0)
