"""International Standard Atmosphere and airspeed conversions (docs/physics.md §6).

ISA troposphere (constant lapse rate) and isothermal lower stratosphere, valid from sea level
to 65 000 ft (19 812 m, below the 20 km top of the isothermal layer). Altitudes are
geopotential pressure altitudes in ft, as in [CHEN] Table 1. Airspeed conversions are the
subsonic isentropic (compressible) relations between calibrated airspeed, impact pressure
and Mach number.

Every function is vectorised with numpy: it accepts scalars or arrays (broadcast together)
and returns numpy arrays (0-d for scalar input).

References: ICAO Doc 7488/3 (Manual of the ICAO Standard Atmosphere, 1993), ISO 2533:1975;
the impact-pressure relations are the standard subsonic pitot-static formulas (e.g.
Anderson, *Introduction to Flight*, §3.12; Gracey, NASA RP-1046, ch. 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import param


@dataclass(frozen=True)
class IsaConstants:
    """Constants of the standard atmosphere and unit conversions (ICAO Doc 7488/3)."""

    p0_Pa: float = param("Pa", "ICAO Doc 7488/3", "sea-level standard pressure")
    T0_K: float = param("K", "ICAO Doc 7488/3", "sea-level standard temperature")
    rho0_kgm3: float = param("kg/m³", "ICAO Doc 7488/3", "sea-level standard density (= p0/(R·T0))")
    lapse_K_per_m: float = param("K/m", "ICAO Doc 7488/3",
                                 "temperature lapse rate of the troposphere")
    tropopause_m: float = param("m", "ICAO Doc 7488/3", "geopotential altitude of the tropopause")
    R_J_per_kgK: float = param("J/(kg·K)", "ICAO Doc 7488/3", "specific gas constant of dry air")
    gamma: float = param("-", "ICAO Doc 7488/3", "ratio of specific heats of air")
    g0_ms2: float = param("m/s²", "ICAO Doc 7488/3", "standard acceleration of gravity")
    kt_ms: float = param("(m/s)/kt", "international knot (1852 m/h)", "knots to m/s")
    ft_m: float = param("m/ft", "international foot", "feet to metres")
    alt_min_ft: float = param("ft", "validity of this module", "lowest altitude accepted")
    alt_max_ft: float = param("ft", "validity of this module (isothermal layer up to 20 km)",
                              "highest altitude accepted")

    @property
    def T_tropopause_K(self) -> float:
        """Temperature of the isothermal layer T0 − L·h_trop [K] (216.65 K)."""
        return self.T0_K - self.lapse_K_per_m * self.tropopause_m

    @property
    def a0_ms(self) -> float:
        """Sea-level speed of sound sqrt(γ·R·T0) [m/s] (340.294 m/s)."""
        return float(np.sqrt(self.gamma * self.R_J_per_kgK * self.T0_K))

    @property
    def p_tropopause_Pa(self) -> float:
        """Pressure at the tropopause p0·(T11/T0)^(g0/(R·L)) [Pa] (22 632 Pa)."""
        return self.p0_Pa * (self.T_tropopause_K / self.T0_K) ** (
            self.g0_ms2 / (self.R_J_per_kgK * self.lapse_K_per_m))


ISA_CONSTANTS = IsaConstants(
    p0_Pa=101_325.0,
    T0_K=288.15,
    rho0_kgm3=1.225,
    lapse_K_per_m=0.0065,
    tropopause_m=11_000.0,
    R_J_per_kgK=287.05287,
    gamma=1.4,
    g0_ms2=9.80665,
    kt_ms=1852.0 / 3600.0,
    ft_m=0.3048,
    alt_min_ft=0.0,
    alt_max_ft=65_000.0,
)

#: Standard acceleration of gravity [m/s²] (:data:`ISA_CONSTANTS`, not stored twice).
G0_MS2: float = ISA_CONSTANTS.g0_ms2


@dataclass(frozen=True)
class Atmosphere:
    """Static air state at one or more altitudes (arrays broadcast like the input)."""

    temperature_K: np.ndarray
    pressure_Pa: np.ndarray
    density_kgm3: np.ndarray
    sound_speed_ms: np.ndarray


def _check_altitude(alt_ft, c: IsaConstants) -> np.ndarray:
    """Altitudes as a float array; ValueError naming the values outside the valid range."""
    h = np.asarray(alt_ft, dtype=float)
    bad = ~((h >= c.alt_min_ft) & (h <= c.alt_max_ft))  # also catches NaN
    if np.any(bad):
        shown = ", ".join(f"{v:g}" for v in np.unique(h[bad])[:5])
        more = "" if np.count_nonzero(bad) <= 5 else f" (and {np.count_nonzero(bad) - 5} more)"
        raise ValueError(
            f"alt_ft={shown}{more} is outside the ISA model's validity range "
            f"[{c.alt_min_ft:g}, {c.alt_max_ft:g}] ft; give a pressure altitude inside it")
    return h


def isa(alt_ft, constants: IsaConstants = ISA_CONSTANTS) -> Atmosphere:
    """ISA temperature, pressure, density and speed of sound at pressure altitude ``alt_ft``.

    Troposphere (h ≤ 11 km): T = T0 − L·h, p = p0·(T/T0)^(g0/(R·L)).
    Isothermal layer (11–20 km): T = T11, p = p11·exp(−g0·(h − 11 km)/(R·T11)).
    ρ = p/(R·T), a = sqrt(γ·R·T). (ICAO Doc 7488/3, Table D.)

    Raises ValueError if any altitude lies outside [0, 65 000] ft (or is NaN).
    """
    c = constants
    h_m = _check_altitude(alt_ft, c) * c.ft_m
    in_troposphere = h_m <= c.tropopause_m
    T_trop = c.T0_K - c.lapse_K_per_m * np.minimum(h_m, c.tropopause_m)
    p_trop = c.p0_Pa * (T_trop / c.T0_K) ** (c.g0_ms2 / (c.R_J_per_kgK * c.lapse_K_per_m))
    p_strat = c.p_tropopause_Pa * np.exp(
        -c.g0_ms2 * (np.maximum(h_m, c.tropopause_m) - c.tropopause_m)
        / (c.R_J_per_kgK * c.T_tropopause_K))
    T = np.where(in_troposphere, T_trop, c.T_tropopause_K)
    p = np.where(in_troposphere, p_trop, p_strat)
    rho = p / (c.R_J_per_kgK * T)
    a = np.sqrt(c.gamma * c.R_J_per_kgK * T)
    return Atmosphere(temperature_K=T, pressure_Pa=p, density_kgm3=rho, sound_speed_ms=a)


def _impact_pressure_from_cas(vcas_kt, c: IsaConstants) -> np.ndarray:
    """Impact pressure q_c = p0·((1 + (γ−1)/2·(Vc/a0)²)^(γ/(γ−1)) − 1) [Pa] (subsonic)."""
    v_ms = np.asarray(vcas_kt, dtype=float) * c.kt_ms
    k = (c.gamma - 1.0) / 2.0
    return c.p0_Pa * ((1.0 + k * (v_ms / c.a0_ms) ** 2) ** (c.gamma / (c.gamma - 1.0)) - 1.0)


def cas_to_mach(vcas_kt, alt_ft, constants: IsaConstants = ISA_CONSTANTS) -> np.ndarray:
    """Mach number from calibrated airspeed [kt] and pressure altitude [ft].

    Isentropic subsonic relations (Anderson §3.12): the impact pressure q_c of the CAS at
    sea level is the same at altitude, M = sqrt(2/(γ−1)·((q_c/p + 1)^((γ−1)/γ) − 1)).
    Valid for M ≤ 1; above, the value returned is that of the subsonic formula (the Rayleigh
    pitot relation is not modelled), which only concerns points far beyond MMO.
    """
    c = constants
    p = isa(alt_ft, c).pressure_Pa
    qc = _impact_pressure_from_cas(vcas_kt, c)
    k = (c.gamma - 1.0) / c.gamma
    return np.sqrt(2.0 / (c.gamma - 1.0) * ((qc / p + 1.0) ** k - 1.0))


def mach_to_cas(mach, alt_ft, constants: IsaConstants = ISA_CONSTANTS) -> np.ndarray:
    """Calibrated airspeed [kt] from Mach number and pressure altitude [ft].

    Inverse of :func:`cas_to_mach`: q_c = p·((1 + (γ−1)/2·M²)^(γ/(γ−1)) − 1), then
    Vc = a0·sqrt(2/(γ−1)·((q_c/p0 + 1)^((γ−1)/γ) − 1)) (Anderson §3.12, subsonic).
    """
    c = constants
    p = isa(alt_ft, c).pressure_Pa
    m = np.asarray(mach, dtype=float)
    g = c.gamma
    qc = p * ((1.0 + (g - 1.0) / 2.0 * m ** 2) ** (g / (g - 1.0)) - 1.0)
    v_ms = c.a0_ms * np.sqrt(2.0 / (g - 1.0) * ((qc / c.p0_Pa + 1.0) ** ((g - 1.0) / g) - 1.0))
    return v_ms / c.kt_ms


def tas_ms(mach, alt_ft, constants: IsaConstants = ISA_CONSTANTS) -> np.ndarray:
    """True airspeed V = M·a(h) [m/s]."""
    return np.asarray(mach, dtype=float) * isa(alt_ft, constants).sound_speed_ms


def dynamic_pressure_pa(mach, alt_ft, constants: IsaConstants = ISA_CONSTANTS) -> np.ndarray:
    """Dynamic pressure q̄ = ½·ρ·V² = (γ/2)·p·M² (= 0.7·p·M² for air) [Pa]."""
    c = constants
    m = np.asarray(mach, dtype=float)
    return c.gamma / 2.0 * isa(alt_ft, c).pressure_Pa * m ** 2
