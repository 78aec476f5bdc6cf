"""Flight envelope, uncertainty tables and the "realistic case" rule (docs/physics.md §6).

- :data:`TABLE1` — the parametric grid of [CHEN] Table 1 (4 × 3 × 3 × 3 = 108 points);
- :data:`A330` — the aircraft data the envelope rule and the trimmed flight condition need;
- :data:`UNCERTAINTY` ([CHEN] Table 2) and :data:`MISMATCH` (plant/model mismatch beyond
  Table 2, est.), with the run-table columns :data:`DRAW_COLUMNS` that hold one run's
  relative deviations and the three grid levels ``min`` / ``nominal`` / ``max``;
- :func:`flight_condition` — Mach, q̄, TAS, wing lift coefficient and trimmed angle of attack
  of a flight point; :func:`measured_schedule` — what a detector sees of it;
- :func:`realistic_rule` — which grid points are realistic, and why the others are not.

Conventions (docs/physics.md §1): VCAS in kt, altitude in ft (ISA pressure altitude), mass in t,
CG in % of the mean aerodynamic chord (MAC), angles in deg, pressures in Pa.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .atmosphere import ISA_CONSTANTS, cas_to_mach, dynamic_pressure_pa, tas_ms
from .params import param

#: Kilograms per tonne (unit conversion of ``mass_t``).
KG_PER_T: float = 1000.0
#: Percent per unit (``cg_pct`` and chord positions are given in % MAC).
PERCENT: float = 100.0
#: Relative tolerance of the ≤ limit comparisons of the realistic rule. A corner that lands
#: exactly on a limit (300 kt + 10 % = VMO = 330 kt) counts as within it, as the rule's "≤"
#: says; without it, rounding of 300·1.1 (= 330.00000000000006) would reject it.
LIMIT_RTOL: float = 1e-9
#: The flight point of a run: its run-table columns, in the order of the grid's nested
#: loops (:func:`grid_points`). The realistic rule (:func:`realistic_rule`) reads them; a
#: Monte Carlo design samples them in the campaign's ``[envelope]`` box.
FLIGHT_COLUMNS: tuple[str, ...] = ("alt_ft", "vcas_kt", "mass_t", "cg_pct")


# ---------------------------------------------------------------------------------------
# [CHEN] Table 1: the parametric grid
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GridTable:
    """Values of the parametric flight-point grid (one tuple per flight parameter)."""

    alt_ft: tuple[float, ...] = param("ft", "[CHEN] Table 1", "pressure altitudes")
    vcas_kt: tuple[float, ...] = param("kt", "[CHEN] Table 1", "calibrated airspeeds")
    mass_t: tuple[float, ...] = param("t", "[CHEN] Table 1", "aircraft masses")
    cg_pct: tuple[float, ...] = param("% MAC", "[CHEN] Table 1", "centre-of-gravity positions")

    #: Grid columns, in the order of the nested loops of :func:`grid_points`.
    columns = FLIGHT_COLUMNS

    def __getitem__(self, name: str) -> tuple[float, ...]:
        if name not in self.columns:
            raise KeyError(f"unknown grid column {name!r}; allowed: {list(self.columns)}")
        return getattr(self, name)

    @property
    def n_points(self) -> int:
        """Number of grid points (product of the value counts)."""
        return int(np.prod([len(self[c]) for c in self.columns]))


TABLE1 = GridTable(
    alt_ft=(8000.0, 18000.0, 28000.0, 38000.0),
    vcas_kt=(160.0, 220.0, 300.0),
    mass_t=(120.0, 180.0, 233.0),
    cg_pct=(17.0, 30.0, 41.0),
)


# ---------------------------------------------------------------------------------------
# Aircraft data
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AircraftParams:
    """Aircraft data for the envelope rule and the trimmed flight condition (docs/physics.md §6).

    The wing lift balances the weight plus the tail load that trims the aircraft: with the
    wing-body lift acting at the aerodynamic centre x_ac and the tail lift at ``tail_arm_m``
    behind it, moments about x_ac give (Etkin & Reid §2.3, first-order trim, wing Cm0
    folded into x_ac)

        L_wing = W·(1 + (x_ac − x_cg)·MAC/l_t)

    so a forward CG (x_cg < x_ac) needs a tail download and more wing lift.
    """

    name: str = param("-", "-", "aircraft name")
    wing_area_m2: float = param("m²", "docs/physics.md §6 (A330 reference wing area)",
                                "wing area S")
    mac_m: float = param("m", "docs/physics.md §6 (A330)", "mean aerodynamic chord")
    tail_arm_m: float = param("m", "docs/physics.md §6 (≈ 28 m, est.)",
                              "distance from the wing-body aerodynamic centre to the tail's")
    x_ac_pct: float = param("% MAC", "est. (53-of-108 rule holds for 25–27 % MAC)",
                            "wing-body aerodynamic centre, slightly aft of the quarter chord")
    mmo: float = param("-", "docs/physics.md §6 (A330 MMO)", "maximum operating Mach number")
    vmo_kt: float = param("kt", "docs/physics.md §6 (A330 VMO)", "maximum operating speed (CAS)")
    buffet_margin_g: float = param("g", "docs/physics.md §6 (1.3 g buffet margin)",
                                   "load factor the wing must sustain below buffet onset")
    clb_mach: tuple[float, ...] = param("-", "docs/physics.md §6 (est.)",
                                        "Mach breakpoints of C_Lb(M)")
    clb: tuple[float, ...] = param("-", "docs/physics.md §6 (est.)",
                                   "clean CLmax / buffet-onset lift coefficient C_Lb at clb_mach")
    cl_alpha_per_rad: float = param("1/rad", "est. (swept wing, aspect ratio ≈ 10)",
                                    "incompressible wing lift-curve slope CLα")
    cl_alpha_mach_cap: float = param("-", "est. (as the hinge moments, docs/physics.md §3)",
                                     "Prandtl–Glauert scaling of CLα held above this Mach")
    cl0: float = param("-", "est.", "wing lift coefficient at zero angle of attack")

    def buffet_cl(self, mach) -> np.ndarray:
        """C_Lb(M): linear interpolation of the table, held constant outside it
        (docs/physics.md §6)."""
        return np.interp(np.asarray(mach, dtype=float), self.clb_mach, self.clb)

    def lift_curve_slope(self, mach) -> np.ndarray:
        """CLα(M) = CLα0/sqrt(1 − M²) (Prandtl–Glauert), M held at the cap above it [1/rad]."""
        m = np.minimum(np.asarray(mach, dtype=float), self.cl_alpha_mach_cap)
        return self.cl_alpha_per_rad / np.sqrt(1.0 - m ** 2)

    def wing_lift_factor(self, cg_pct) -> np.ndarray:
        """L_wing/W = 1 + (x_ac − x_cg)·MAC/l_t (class docstring) [-]."""
        d_x = (self.x_ac_pct - np.asarray(cg_pct, dtype=float)) / PERCENT
        return 1.0 + d_x * self.mac_m / self.tail_arm_m


A330 = AircraftParams(
    name="A330-class",
    wing_area_m2=361.6,
    mac_m=7.27,
    tail_arm_m=28.0,
    x_ac_pct=26.0,
    mmo=0.86,
    vmo_kt=330.0,
    buffet_margin_g=1.3,
    clb_mach=(0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.75, 0.80, 0.84, 0.88),
    clb=(1.50, 1.45, 1.30, 1.15, 1.02, 0.90, 0.83, 0.74, 0.64, 0.50),
    cl_alpha_per_rad=5.0,
    cl_alpha_mach_cap=0.75,
    cl0=0.20,
)


# ---------------------------------------------------------------------------------------
# Uncertainties
# ---------------------------------------------------------------------------------------
def _optional(unit: str, source: str, doc: str):
    """A parameter field whose default ``None`` means "take the shorthand"."""
    return param(unit, source, doc, default=None)


#: The six aerodynamic coefficients of [CHEN] Table 2 (δCx, δCy, δCz, δCl, δCm, δCn): the
#: keys of their half-widths and, prefixed ``d_``, their run-table columns.
AERO_COEFFICIENTS: tuple[str, ...] = ("cx", "cy", "cz", "cl", "cm", "cn")
#: The hinge-moment coefficients Ch0, Chα, Chδ (docs/physics.md §3): the keys of their
#: mismatch half-widths and, prefixed ``d_``, their run-table columns.
HINGE_COEFFICIENTS: tuple[str, ...] = ("ch0", "cha", "chd")


@dataclass(frozen=True)
class Uncertainty:
    """Relative half-widths of the uniform uncertainties of [CHEN] Table 2 (docs/physics.md §6).

    ``aero`` is the shorthand of the six aerodynamic coefficients: each of ``cx`` … ``cn``
    left at ``None`` takes it; one given explicitly wins over it (:meth:`coefficient`).
    """

    aero: float = param("-", "[CHEN] Table 2", "every aerodynamic coefficient δCx…δCn (shorthand)")
    vcas: float = param("-", "[CHEN] Table 2", "measured calibrated airspeed δVCAS")
    alt: float = param("-", "[CHEN] Table 2", "measured altitude δh")
    mass: float = param("-", "[CHEN] Table 2", "estimated mass δm")
    cg: float = param("-", "[CHEN] Table 2", "estimated centre of gravity δXcg")
    cx: float | None = _optional("-", "[CHEN] Table 2 (None: aero)", "drag coefficient δCx")
    cy: float | None = _optional("-", "[CHEN] Table 2 (None: aero)", "side-force coefficient δCy")
    cz: float | None = _optional("-", "[CHEN] Table 2 (None: aero)", "lift coefficient δCz")
    cl: float | None = _optional("-", "[CHEN] Table 2 (None: aero)",
                                 "rolling-moment coefficient δCl")
    cm: float | None = _optional("-", "[CHEN] Table 2 (None: aero)",
                                 "pitching-moment coefficient δCm")
    cn: float | None = _optional("-", "[CHEN] Table 2 (None: aero)",
                                 "yawing-moment coefficient δCn")


@dataclass(frozen=True)
class Mismatch:
    """Plant/model mismatch beyond [CHEN] Table 2 (docs/physics.md §6, est.), relative half-widths.

    The plant runs with the perturbed values while model-based detectors keep the nominal
    ones. ``enabled=False`` switches all of it off (half-widths 0). ``hinge`` is the
    shorthand of the three hinge-moment coefficients: each of ``ch0``, ``cha``, ``chd`` left
    at ``None`` takes it; one given explicitly wins over it.
    """

    enabled: bool = param("-", "docs/physics.md §6", "whether the mismatch is sampled")
    supply: float = param("-", "est. (docs/physics.md §6)", "hydraulic supply pressure ΔP")
    kci: float = param("-", "est. (docs/physics.md §6)", "servo-valve gain Kci")
    hinge: float = param("-", "est. (docs/physics.md §6)",
                         "every hinge-moment coefficient Ch0, Chα, Chδ (shorthand)")
    ch0: float | None = _optional("-", "est. (None: hinge)", "hinge-moment coefficient Ch0")
    cha: float | None = _optional("-", "est. (None: hinge)", "hinge-moment derivative Chα")
    chd: float | None = _optional("-", "est. (None: hinge)", "hinge-moment derivative Chδ")


UNCERTAINTY = Uncertainty(aero=0.05, vcas=0.10, alt=0.10, mass=0.10, cg=0.10)
MISMATCH = Mismatch(enabled=True, supply=0.05, kci=0.05, hinge=0.20)

#: Run-table columns holding one run's relative deviations (true → measured/perturbed).
DRAW_COLUMNS: tuple[str, ...] = (
    *(f"d_{c}" for c in AERO_COEFFICIENTS), "d_vcas", "d_alt", "d_mass", "d_cg", "d_supply",
    "d_kci", *(f"d_{c}" for c in HINGE_COEFFICIENTS),
)

#: Grid uncertainty levels and the multiple of the half-width each one takes.
LEVELS: dict[str, float] = {"min": -1.0, "nominal": 0.0, "max": 1.0}


def coefficient_width(table, name: str, shorthand: str) -> float:
    """The half-width of coefficient *name* in *table* (an :class:`Uncertainty`, a
    :class:`Mismatch` or a campaign-file section of the same keys): its own value when it is
    given (not ``None``), else the value of the shorthand key *shorthand*."""
    own = getattr(table, name, None)
    return float(getattr(table, shorthand) if own is None else own)


def half_widths(uncertainty: Uncertainty = UNCERTAINTY,
                mismatch: Mismatch = MISMATCH) -> dict[str, float]:
    """Relative half-width of each draw column (mismatch columns 0 when it is disabled).

    The six aerodynamic coefficients take ``uncertainty.aero`` unless given one by one, the
    three hinge-moment coefficients ``mismatch.hinge`` likewise (:func:`coefficient_width`).
    """
    on = 1.0 if mismatch.enabled else 0.0
    return {
        **{f"d_{c}": coefficient_width(uncertainty, c, "aero") for c in AERO_COEFFICIENTS},
        "d_vcas": float(uncertainty.vcas),
        "d_alt": float(uncertainty.alt),
        "d_mass": float(uncertainty.mass),
        "d_cg": float(uncertainty.cg),
        "d_supply": on * float(mismatch.supply),
        "d_kci": on * float(mismatch.kci),
        **{f"d_{c}": on * coefficient_width(mismatch, c, "hinge") for c in HINGE_COEFFICIENTS},
    }


def level_draws(level: str, uncertainty: Uncertainty = UNCERTAINTY,
                mismatch: Mismatch = MISMATCH) -> dict[str, float]:
    """Deviations of a grid level: ``min`` all at −w, ``nominal`` all 0, ``max`` all at +w."""
    if level not in LEVELS:
        raise ValueError(f"unknown uncertainty level {level!r}; allowed: {list(LEVELS)}")
    sign = LEVELS[level]
    return {col: sign * w + 0.0 for col, w in half_widths(uncertainty, mismatch).items()}


# ---------------------------------------------------------------------------------------
# Grid and flight condition
# ---------------------------------------------------------------------------------------
def grid_points(table: GridTable = TABLE1) -> pd.DataFrame:
    """All combinations of the grid values, one row per point (altitude varies slowest).

    Columns ``point`` (0 … n−1), ``alt_ft``, ``vcas_kt``, ``mass_t``, ``cg_pct``.
    """
    rows = list(itertools.product(*(table[c] for c in table.columns)))
    frame = pd.DataFrame(rows, columns=list(table.columns), dtype=float)
    frame.insert(0, "point", np.arange(len(frame), dtype=np.int64))
    return frame


def flight_condition(alt_ft, vcas_kt, mass_t, cg_pct,
                     aircraft: AircraftParams = A330) -> dict[str, np.ndarray]:
    """Steady 1-g flight at a point: Mach, q̄, TAS, wing lift coefficient, trimmed AoA.

    - mach: compressible CAS → Mach (:func:`scenarios.atmosphere.cas_to_mach`);
    - qbar_pa: q̄ = 0.7·p·M²; tas_ms: M·a;
    - cl: C_L = W·(1 + (x_ac − x_cg)·MAC/l_t)/(q̄·S), the wing lift that carries the weight
      and the trimming tail load (:class:`AircraftParams`);
    - alpha_deg: α = (C_L − C_L0)/CLα(M) (linear lift curve, Prandtl–Glauert CLα).

    Inputs broadcast together; outputs are float arrays of the broadcast shape.
    """
    alt, vcas, mass, cg = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                                for v in (alt_ft, vcas_kt, mass_t, cg_pct)))
    mach = cas_to_mach(vcas, alt)
    qbar = dynamic_pressure_pa(mach, alt)
    weight_N = mass * KG_PER_T * ISA_CONSTANTS.g0_ms2
    cl = weight_N * aircraft.wing_lift_factor(cg) / (qbar * aircraft.wing_area_m2)
    alpha_rad = (cl - aircraft.cl0) / aircraft.lift_curve_slope(mach)
    return {
        "mach": mach,
        "qbar_pa": qbar,
        "tas_ms": tas_ms(mach, alt),
        "alpha_deg": np.degrees(alpha_rad),
        "cl": cl,
    }


def measured_schedule(alt_ft, vcas_kt, mass_t, cg_pct, d_alt, d_vcas, d_mass, d_cg,
                      aircraft: AircraftParams = A330) -> dict[str, np.ndarray]:
    """Scheduling data a detector sees: measured/estimated values carrying the deviations.

    measured = true·(1 + d) for VCAS, altitude, mass and CG ([CHEN] Table 2, docs/physics.md §4);
    mach, qbar_pa and alpha_deg are recomputed from the measured values through
    :func:`flight_condition`, as an on-board estimate would be.
    """
    meas = {
        "vcas_kt": np.asarray(vcas_kt, dtype=float) * (1.0 + np.asarray(d_vcas, dtype=float)),
        "alt_ft": np.asarray(alt_ft, dtype=float) * (1.0 + np.asarray(d_alt, dtype=float)),
        "mass_t": np.asarray(mass_t, dtype=float) * (1.0 + np.asarray(d_mass, dtype=float)),
        "cg_pct": np.asarray(cg_pct, dtype=float) * (1.0 + np.asarray(d_cg, dtype=float)),
    }
    shaped = dict(zip(meas, np.broadcast_arrays(*meas.values())))
    fc = flight_condition(shaped["alt_ft"], shaped["vcas_kt"], shaped["mass_t"],
                          shaped["cg_pct"], aircraft)
    return {**shaped, "mach": fc["mach"], "qbar_pa": fc["qbar_pa"], "alpha_deg": fc["alpha_deg"]}


# ---------------------------------------------------------------------------------------
# The realistic-case rule
# ---------------------------------------------------------------------------------------
def rule_conditions(uncertainty: Uncertainty = UNCERTAINTY) -> dict[str, tuple[float, float]]:
    """The conditions the realistic rule checks: name → (d_vcas, d_mass) (docs/physics.md §6)."""
    return {
        "nominal": (0.0, 0.0),
        "slow_heavy": (-uncertainty.vcas, +uncertainty.mass),
        "fast_light": (+uncertainty.vcas, -uncertainty.mass),
    }


def realistic_rule(points: pd.DataFrame, uncertainty: Uncertainty = UNCERTAINTY,
                   aircraft: AircraftParams = A330) -> pd.DataFrame:
    """Flag the realistic flight points (docs/physics.md §6, after [CHEN] §5.1's 158 of 324 cases).

    A point is realistic if, at each of three conditions — ``nominal``, ``slow_heavy``
    (VCAS −10 %, mass +10 %) and ``fast_light`` (VCAS +10 %, mass −10 %); altitude and CG
    at their nominal values; the widths come from ``uncertainty`` — all three criteria hold:

    - ``mach>MMO``: M ≤ MMO (0.86), M from ISA + compressible CAS → Mach;
    - ``vcas>VMO``: VCAS ≤ VMO (330 kt);
    - ``buffet``: n_b·C_L < C_Lb(M), with n_b = 1.3 g, C_L the 1-g wing lift coefficient of
      :func:`flight_condition` (weight plus trimming tail load,
      W·(1 + (x_ac − x_cg)·MAC/l_t)/(q̄·S), x_ac = 26 % MAC, MAC 7.27 m, l_t = 28 m,
      S = 361.6 m²) and C_Lb interpolated linearly in the table, held outside it.

    Limits are compared with :data:`LIMIT_RTOL`. A realistic point keeps its three
    uncertainty levels (``min``/``nominal``/``max``).

    With :data:`TABLE1`, :data:`A330` and :data:`UNCERTAINTY` this keeps 53 of 108 points
    (159 of 324 cases; [CHEN]: 158). The 55 rejected points:

    - 46 fail ``buffet`` only, always at the slow/heavy corner (16 there alone, 13 also at
      nominal, 17 at all three conditions);
    - the 9 points at 38 000 ft and 300 kt fail ``mach>MMO`` at nominal (M 0.928) and at the
      fast/light corner (330 kt, M 1.007); their slow/heavy corner (270 kt, M 0.846) passes
      it; 6 of them also fail ``buffet``.

    Failures by criterion@condition: buffet@slow_heavy 52, buffet@nominal 35,
    buffet@fast_light 18, mach>MMO@nominal 9, mach>MMO@fast_light 9, vcas>VMO 0 (the fast
    corner of 300 kt lands exactly on VMO = 330 kt and passes). Applying the Mach and VMO
    checks at the corners or at nominal only gives the same 53 points. Borderline points
    (worst buffet ratio n_b·C_L/C_Lb within 1 % of 1, all at the slow/heavy corner):
    28 000 ft/220 kt/180 t/30 % (1.0027, rejected), 8 000 ft/220 kt/233 t/41 % (0.9970,
    kept), 18 000 ft/160 kt/120 t/17 % (0.9950, kept). The count is 53 for x_ac from 25 to
    27 % MAC (24.75 → 54, 27.25 → 52; at 25 % the first point sits on the limit) and for
    tail arms 26–30 m; x_ac = 26 % is the middle of that band. Without the CG term the
    count is 51; the opposite sign (aft CG loading the wing, which contradicts the moment
    balance) gives 51 for x_ac between 25 and 30 % MAC.

    Returns a copy of ``points`` with ``realistic`` (bool) and ``rejected_by`` (str: "" when
    realistic, otherwise every failing ``criterion@condition`` joined by "; ", in the order
    conditions nominal, slow_heavy, fast_light and criteria mach>MMO, vcas>VMO, buffet).
    """
    required = FLIGHT_COLUMNS
    missing = [c for c in required if c not in points.columns]
    if missing:
        raise ValueError(f"points lack the column(s) {missing}; required: {list(required)}")
    alt = points["alt_ft"].to_numpy(dtype=float)
    vcas = points["vcas_kt"].to_numpy(dtype=float)
    mass = points["mass_t"].to_numpy(dtype=float)
    cg = points["cg_pct"].to_numpy(dtype=float)

    failures: list[tuple[str, np.ndarray]] = []
    for cond, (d_vcas, d_mass) in rule_conditions(uncertainty).items():
        v = vcas * (1.0 + d_vcas)
        fc = flight_condition(alt, v, mass * (1.0 + d_mass), cg, aircraft)
        failures.append((f"mach>MMO@{cond}", fc["mach"] > aircraft.mmo * (1.0 + LIMIT_RTOL)))
        failures.append((f"vcas>VMO@{cond}", v > aircraft.vmo_kt * (1.0 + LIMIT_RTOL)))
        failures.append((f"buffet@{cond}",
                         aircraft.buffet_margin_g * fc["cl"] >= aircraft.buffet_cl(fc["mach"])))

    reasons = ["; ".join(name for name, failed in failures if failed[i])
               for i in range(len(points))]
    out = points.copy()
    out["realistic"] = np.array([r == "" for r in reasons], dtype=bool)
    out["rejected_by"] = pd.Series(reasons, index=points.index, dtype=object)
    return out


def realistic_points(table: GridTable = TABLE1) -> pd.DataFrame:
    """The grid of ``table`` with the realistic-rule flags (all points, see ``realistic``)."""
    return realistic_rule(grid_points(table))
