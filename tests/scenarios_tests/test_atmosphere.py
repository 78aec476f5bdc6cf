"""ISA and airspeed conversions against standard-atmosphere tables (ICAO Doc 7488/3)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenarios.atmosphere import (
    ISA_CONSTANTS,
    Atmosphere,
    cas_to_mach,
    dynamic_pressure_pa,
    isa,
    mach_to_cas,
    tas_ms,
)

KT_TO_MS, FT_TO_M = ISA_CONSTANTS.kt_ms, ISA_CONSTANTS.ft_m

M_PER_FT = 0.3048
FT_11KM = 11_000.0 / M_PER_FT  # 36 089.24 ft


# ICAO Doc 7488/3 tabulated values (geopotential altitude): (alt_ft, T [K], p [Pa],
# rho [kg/m³], a [m/s]). The tables give 5–6 significant digits, so compare with rtol 1e-4.
ISA_TABLE = [
    (0.0, 288.15, 101_325.0, 1.2250, 340.294),
    (10_000.0 / M_PER_FT, 223.15, 26_436.3, 0.41271, 299.463),   # 10 km
    (FT_11KM, 216.65, 22_632.1, 0.36392, 295.070),               # 11 km, tropopause
    (36_089.0, 216.65, 22_632.1, 0.36392, 295.070),               # 36 089 ft (0.24 ft below)
]


@pytest.mark.parametrize("alt_ft, T, p, rho, a", ISA_TABLE)
def test_isa_matches_standard_table(alt_ft, T, p, rho, a):
    atm = isa(alt_ft)
    assert isinstance(atm, Atmosphere)
    np.testing.assert_allclose(atm.temperature_K, T, rtol=1e-4)
    np.testing.assert_allclose(atm.pressure_Pa, p, rtol=1e-4)
    np.testing.assert_allclose(atm.density_kgm3, rho, rtol=1e-4)
    np.testing.assert_allclose(atm.sound_speed_ms, a, rtol=1e-4)


def test_isa_constants_are_consistent():
    c = ISA_CONSTANTS
    # tabulated ρ0 = p0/(R·T0) to the 5 digits the table gives
    assert c.p0_Pa / (c.R_J_per_kgK * c.T0_K) == pytest.approx(c.rho0_kgm3, rel=1e-5)
    assert KT_TO_MS == pytest.approx(0.514444, rel=1e-6)
    assert FT_TO_M == 0.3048
    assert c.T_tropopause_K == pytest.approx(216.65, abs=1e-9)


def test_isa_is_continuous_and_isothermal_above_tropopause():
    below, above = isa([FT_11KM - 1e-6, FT_11KM + 1e-6]).pressure_Pa
    assert above == pytest.approx(below, rel=1e-9)  # no jump at the layer boundary
    atm = isa([40_000.0, 60_000.0])
    np.testing.assert_allclose(atm.temperature_K, 216.65, rtol=1e-12)
    # isothermal layer: p falls by exp(−Δh/H) with the scale height H = R·T11/g0 = 6341.6 m
    ratio = atm.pressure_Pa[1] / atm.pressure_Pa[0]
    assert ratio == pytest.approx(np.exp(-20_000 * M_PER_FT / 6341.62), rel=1e-5)


def test_isa_vectorised_shapes():
    alts = np.linspace(0, 60_000, 12).reshape(3, 4)
    atm = isa(alts)
    for f in dataclasses.fields(atm):
        assert getattr(atm, f.name).shape == (3, 4)
    assert np.all(np.diff(isa(np.linspace(0, 65_000, 50)).pressure_Pa) < 0)


@pytest.mark.parametrize("bad", [-100.0, 65_001.0, np.nan, [1000.0, 70_000.0]])
def test_isa_rejects_altitude_outside_range(bad):
    with pytest.raises(ValueError, match=r"alt_ft=.*outside.*\[0, 65000\] ft"):
        isa(bad)


def test_out_of_range_error_names_the_value():
    with pytest.raises(ValueError, match="70000"):
        cas_to_mach(250.0, [1000.0, 70_000.0])


def test_cas_equals_tas_at_sea_level():
    vcas = np.array([100.0, 160.0, 250.0, 330.0, 500.0])
    mach = cas_to_mach(vcas, 0.0)
    # at sea level CAS = TAS by definition of CAS; only rounding error is allowed
    np.testing.assert_allclose(tas_ms(mach, 0.0), vcas * KT_TO_MS, rtol=1e-12)
    # Mach 1 at sea level is the sea-level speed of sound: 661.48 kt
    assert mach_to_cas(1.0, 0.0) == pytest.approx(661.4786, rel=1e-6)


def test_known_cas_to_mach_value():
    # Airspeed tables / flight computers: 300 KCAS at FL300 (ISA) is M 0.79, TAS 466 kt.
    # Tolerance 0.005 covers the rounding of such tables.
    mach = cas_to_mach(300.0, 30_000.0)
    assert mach == pytest.approx(0.79, abs=0.005)
    assert tas_ms(mach, 30_000.0) / KT_TO_MS == pytest.approx(466.0, abs=2.0)
    # TAS exceeds CAS at altitude, and compressibility makes M grow faster than 1/sqrt(σ)
    assert cas_to_mach(300.0, 38_000.0) > cas_to_mach(300.0, 28_000.0) > 0.7


def test_cas_to_mach_against_independent_impact_pressure_formula():
    # Independent evaluation at the tropopause with the tabulated p = 22 632.1 Pa:
    # q_c = p·((1 + 0.2 M²)^3.5 − 1), then V_c = a0·sqrt(5·((q_c/p0 + 1)^(2/7) − 1)).
    mach = 0.8
    qc = 22_632.1 * ((1 + 0.2 * mach**2) ** 3.5 - 1)
    vc_kt = 340.294 * np.sqrt(5 * ((qc / 101_325.0 + 1) ** (2 / 7) - 1)) / KT_TO_MS
    assert mach_to_cas(mach, FT_11KM) == pytest.approx(vc_kt, rel=1e-4)  # table digits


@settings(max_examples=200, deadline=None, database=None)
@given(vcas=st.floats(60.0, 450.0), alt=st.floats(0.0, 65_000.0))
def test_cas_mach_round_trip(vcas, alt):
    mach = cas_to_mach(vcas, alt)
    # both directions are closed-form: only floating-point rounding remains
    assert mach_to_cas(mach, alt) == pytest.approx(vcas, rel=1e-9)


def test_round_trip_vectorised():
    alt = np.array([[0.0], [20_000.0], [40_000.0]])
    mach = np.array([0.2, 0.5, 0.85])
    cas = mach_to_cas(mach, alt)
    assert cas.shape == (3, 3)
    np.testing.assert_allclose(cas_to_mach(cas, alt), np.broadcast_to(mach, (3, 3)), rtol=1e-9)


def test_dynamic_pressure():
    # q̄ = 0.7·p·M² at the tropopause, M 0.8: 0.7 × 22 632.1 × 0.64 = 10 139.2 Pa (table p)
    assert dynamic_pressure_pa(0.8, FT_11KM) == pytest.approx(10_139.2, rel=1e-4)
    # equals ½ρV² with V the true airspeed (identity, rounding only)
    alts = np.array([0.0, 8_000.0, 28_000.0, 45_000.0])
    mach = np.array([0.3, 0.45, 0.78, 0.85])
    atm = isa(alts)
    half_rho_v2 = 0.5 * atm.density_kgm3 * tas_ms(mach, alts) ** 2
    np.testing.assert_allclose(dynamic_pressure_pa(mach, alts), half_rho_v2, rtol=1e-12)
