"""Parameter tables of the servo-loop and its sensors (docs/physics.md §3–4).

Every number used by the plant lives here, with its unit and its provenance, so a user can
replace it with their own actuator data (``dataclasses.replace(ELEVATOR, S_m2=...)``).
"(est.)" marks engineering estimates: the Airbus benchmark data is proprietary.

Conventions: rod position and order in mm, current in mA, surface deflection in deg
(positive trailing edge down), force in N, pressure in Pa, time in s. Rod and surface are
linked by x = r·sin(δ) (lever arm r).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import MISSING, dataclass, field

from .declare import Declared, field_problems


def param(unit: str, source: str, doc: str = "", *, default=MISSING, **bounds):
    """Declare a parameter field (with *default*, if given): its
    :class:`scenarios.declare.Declared` (unit, provenance, description and, given as
    *bounds*, gt/ge/lt/le) in the field metadata."""
    return field(default=default,
                 metadata={"declared": Declared(unit=unit, source=source, doc=doc, **bounds)})


def _check_declared(params, what: str) -> None:
    """:class:`ValueError` naming every field of the dataclass instance *params* whose value
    is outside the bounds its declaration gives, and the allowed range."""
    problems = field_problems(params)
    if problems:
        raise ValueError(f"{what}: " + "; ".join(problems))


@dataclass(frozen=True)
class ActuatorParams:
    """One active hydraulic servo-actuator and its control surface (docs/physics.md §3).

    The adjacent actuator of the same surface is in damping mode: it resists the motion with
    a force Ka·ẋ|ẋ| ([COMB] eq. 2, [CHEN] eq. 11). A value outside the bounds its field
    declares is refused when the parameters are made (:func:`_check_declared`).
    """

    def __post_init__(self):
        _check_declared(self, f"{self.surface} actuator")

    surface: str = param("-", "docs/physics.md §3", "surface name")
    delta_min_deg: float = param("deg", "A330-class (docs/physics.md §3)",
                                 "electrical deflection limit, lower")
    delta_max_deg: float = param("deg", "A330-class (docs/physics.md §3)",
                                 "electrical deflection limit, upper")
    stop_margin_deg: float = param("deg",
                                   "est. (docs/physics.md §3: 1–2° beyond the electrical limits)",
                                   "mechanical stops lie this far beyond the electrical limits",
                                   ge=0.0)
    r_mm: float = param("mm", "est.", "lever arm r between rod and hinge line", gt=0.0)
    dP_Pa: float = param("Pa", "3000 psi hydraulic system", "supply differential pressure ΔP",
                         gt=0.0)
    dP_ref_Pa: float = param("Pa", "docs/physics.md §3 (ΔP_ref = ΔP)",
                             "pressure drop of the maximum rod speed",
                            gt=0.0)
    S_m2: float = param("m²", "est. (A320 aileron jack 22.7 cm²)", "piston area S", gt=0.0)
    K_mA_per_mm: float = param("mA/mm", "est.", "servo-loop gain K", gt=0.0)
    Kci_mm_s_per_mA: float = param("(mm/s)/mA", "est.", "servo-valve gain Kci", gt=0.0)
    i_max_mA: float = param("mA", "est.", "current saturation ±i_max", gt=0.0)
    Ka_N_per_mm_s2: float = param("N/(mm/s)²", "est.", "damping-mode neighbour coefficient Ka",
                                   ge=0.0)
    Sc_m2: float = param("m²", "est.", "control surface area S_c", ge=0.0)
    cc_m: float = param("m", "est.", "control surface chord c_c", gt=0.0)
    Ch_delta: float = param("1/rad", "est. (see the instance)", "hinge-moment derivative Chδ")
    Ch_alpha: float = param("1/rad", "est. (see the instance)", "hinge-moment derivative Chα")
    Ch0: float = param("-", "est. (see the instance)",
                       "hinge-moment coefficient at zero α and δ (negative: trailing edge up)")
    downwash: float = param("-", "est. (elevator: dε/dα; 0 for the aileron)",
                         "local AoA of the surface α_s = α·(1 − dε/dα)", ge=0.0, lt=1.0)
    mach_compress_cap: float = param("-", "docs/physics.md §3",
                                     "Prandtl–Glauert scaling held above this Mach",
                                      gt=0.0, lt=1.0)
    has_surface_sensor: bool = param("-",
                                     "docs/physics.md §4 ([CHEN]: none on the inboard aileron)",
                                  "whether a surface position sensor is fitted")
    order_load_limit: float = param("-", "est. (docs/physics.md §3: no stall in normal flight)",
                                    "the flight control laws keep manoeuvre orders where the "
                                    "hinge load stays below this share of the stall force S·ΔP",
                                    gt=0.0, le=1.0)

    # ---- derived quantities (never stored twice) -------------------------------------
    @property
    def stop_min_deg(self) -> float:
        """Lower mechanical stop [deg]."""
        return self.delta_min_deg - self.stop_margin_deg

    @property
    def stop_max_deg(self) -> float:
        """Upper mechanical stop [deg]."""
        return self.delta_max_deg + self.stop_margin_deg

    @property
    def x_min_mm(self) -> float:
        """Rod position at the lower mechanical stop [mm]."""
        return self.r_mm * math.sin(math.radians(self.stop_min_deg))

    @property
    def x_max_mm(self) -> float:
        """Rod position at the upper mechanical stop [mm]."""
        return self.r_mm * math.sin(math.radians(self.stop_max_deg))

    @property
    def u_min_mm(self) -> float:
        """Rod order at the lower electrical limit [mm]."""
        return self.r_mm * math.sin(math.radians(self.delta_min_deg))

    @property
    def u_max_mm(self) -> float:
        """Rod order at the upper electrical limit [mm]."""
        return self.r_mm * math.sin(math.radians(self.delta_max_deg))

    @property
    def bandwidth_per_s(self) -> float:
        """Small-signal loop bandwidth Kci·K [1/s]; time constant τ = 1/(Kci·K)."""
        return self.Kci_mm_s_per_mA * self.K_mA_per_mm

    @property
    def tau_s(self) -> float:
        """Small-signal time constant 1/(Kci·K) [s]."""
        return 1.0 / self.bandwidth_per_s

    @property
    def rate_max_mm_s(self) -> float:
        """Saturated no-load rod speed Kci·i_max [mm/s] (no aero load, no damping neighbour)."""
        return self.Kci_mm_s_per_mA * self.i_max_mA

    @property
    def stall_force_N(self) -> float:
        """Force S·ΔP above which the rod cannot move against the load [N]."""
        return self.S_m2 * self.dP_Pa

    @property
    def deflection_range_deg(self) -> float:
        """Operational deflection range between the electrical limits [deg]."""
        return self.delta_max_deg - self.delta_min_deg

    def deg_to_mm(self, delta_deg):
        """Rod position for a surface deflection, x = r·sin δ [mm]. An array is converted
        in one new array (no temporaries of its size: a chunk's orders or surface signals
        are 5 MB each); the values are those of ``r_mm * np.sin(np.radians(delta_deg))``."""
        import numpy as np

        x = np.radians(delta_deg)
        if not isinstance(x, np.ndarray):
            return self.r_mm * np.sin(x)
        np.sin(x, out=x)
        x *= self.r_mm
        return x

    def mm_to_deg(self, x_mm):
        """Surface deflection for a rod position, δ = asin(x/r) [deg]."""
        import numpy as np

        return np.degrees(np.arcsin(np.clip(np.asarray(x_mm) / self.r_mm, -1.0, 1.0)))

    def replace(self, **changes) -> "ActuatorParams":
        """A copy with some parameters changed (unknown names raise a clear error)."""
        names = {f.name for f in dataclasses.fields(self)}
        bad = sorted(set(changes) - names)
        if bad:
            raise ValueError(f"unknown actuator parameter(s) {bad}; allowed: {sorted(names)}")
        return dataclasses.replace(self, **changes)


ELEVATOR = ActuatorParams(
    surface="elevator",
    delta_min_deg=-30.0,
    delta_max_deg=15.0,
    stop_margin_deg=1.5,
    r_mm=120.0,
    dP_Pa=20.68e6,
    dP_ref_Pa=20.68e6,
    S_m2=50e-4,
    K_mA_per_mm=1.5,
    Kci_mm_s_per_mA=10.0,
    i_max_mA=10.0,
    Ka_N_per_mm_s2=1.55,
    Sc_m2=10.0,
    cc_m=1.3,
    Ch_delta=-0.30,
    Ch_alpha=-0.15,
    # Ch0 = 0 (est.): a symmetric tailplane section carries no zero-lift hinge moment, so a
    # freed elevator floats with the tail's own angle of attack only, δ_f = −Chα·α_s/Chδ
    # (0.1–2.2° trailing edge up over the realistic envelope, docs/physics.md §3).
    Ch0=0.0,
    downwash=0.35,
    mach_compress_cap=0.75,
    has_surface_sensor=True,
    order_load_limit=0.6,
)

AILERON = ActuatorParams(
    surface="aileron",
    delta_min_deg=-25.0,
    delta_max_deg=25.0,
    stop_margin_deg=1.5,
    r_mm=70.0,
    dP_Pa=20.68e6,
    dP_ref_Pa=20.68e6,
    S_m2=30e-4,
    K_mA_per_mm=2.5,
    Kci_mm_s_per_mA=7.0,
    i_max_mA=10.0,
    Ka_N_per_mm_s2=1.5,
    Sc_m2=4.0,
    cc_m=0.8,
    # Chδ, Chα (est.): an aerodynamically balanced aileron (nose or internal balance, as on
    # transport ailerons) has about half the hinge-moment slopes of a plain flap (−0.4, −0.2
    # per rad); the ratio Chα/Chδ = 0.5 is kept.
    Ch_delta=-0.20,
    Ch_alpha=-0.10,
    # Ch0 (est.): a supercritical wing is aft-loaded, so its aileron has a strong
    # trailing-edge-up hinge moment at zero deflection. −0.04 makes a freed aileron float
    # 10.5° trailing edge up at the median realistic flight point (7.7–14.3° over the 53
    # realistic points): 21 % of its 50° range, as [CHEN] §6.2 reports (21.4 %). Holding it
    # at neutral takes 15–48 % of the stall force S·ΔP (docs/physics.md §3); with the
    # unbalanced slopes above it would take up to 95 %.
    Ch0=-0.04,
    downwash=0.0,
    mach_compress_cap=0.75,
    has_surface_sensor=False,
    order_load_limit=0.6,
)

ACTUATORS: dict[str, ActuatorParams] = {"elevator": ELEVATOR, "aileron": AILERON}

#: Rudder servo-loop of the aircraft-level plant (scenarios.aircraft; not an actuator-level
#: surface). All est. for an A330-class fin: deflection ±30° (A330 rudder travel at low
#: speed, limited further by the hinge-moment authority at high q̄), rudder ≈ 30 % of the
#: 47.6 m² fin; sign positive trailing edge left (Etkin & Reid). The fin sees the sideslip,
#: not the trimmed angle of attack, so Chα is 0 in level flight.
RUDDER = ActuatorParams(
    surface="rudder",
    delta_min_deg=-30.0,
    delta_max_deg=30.0,
    stop_margin_deg=1.5,
    r_mm=110.0,
    dP_Pa=20.68e6,
    dP_ref_Pa=20.68e6,
    S_m2=50e-4,
    K_mA_per_mm=1.6,
    Kci_mm_s_per_mA=10.0,
    i_max_mA=10.0,
    Ka_N_per_mm_s2=1.55,
    Sc_m2=14.0,
    cc_m=1.8,
    Ch_delta=-0.30,
    Ch_alpha=0.0,
    Ch0=0.0,
    downwash=0.0,
    mach_compress_cap=0.75,
    has_surface_sensor=True,
    order_load_limit=0.6,
)


@dataclass(frozen=True)
class SensorParams:
    """Sensors acquired by the FCC (docs/physics.md §4). All values (est.)."""

    def __post_init__(self):
        _check_declared(self, "sensor parameters")

    rod_noise_mm: float = param("mm", "est. (docs/physics.md §4)",
                                "white-noise σ of each LVDT acquisition", ge=0.0)
    rod_quant_mm: float = param("mm", "est. (docs/physics.md §4)",
                                "quantisation step of the rod acquisitions", ge=0.0)
    rod_bias_mm: float = param("mm", "est. (docs/physics.md §4)", "per-run bias ~ U(−b, b)", ge=0.0)
    rod_scale: float = param("-", "est. (docs/physics.md §4)",
                             "per-run scale error ~ U(−s, s), relative", ge=0.0)
    surface_noise_deg: float = param("deg", "est. (docs/physics.md §4)",
                                     "white-noise σ of the surface sensor", ge=0.0)
    surface_quant_deg: float = param("deg", "est. (docs/physics.md §4)",
                                     "quantisation of the surface sensor", ge=0.0)
    surface_bias_deg: float = param("deg", "est. (docs/physics.md §4)", "per-run bias ~ U(−b, b)",
                                    ge=0.0)
    pressure_noise_frac: float = param("-", "est. (docs/physics.md §4)",
                                    "σ of the chamber ΔP sensor as a fraction of supply", ge=0.0)


SENSORS = SensorParams(
    rod_noise_mm=0.03,
    rod_quant_mm=0.01,
    rod_bias_mm=0.1,
    rod_scale=0.005,
    surface_noise_deg=0.02,
    surface_quant_deg=0.01,
    surface_bias_deg=0.05,
    pressure_noise_frac=0.01,
)

#: FCC period [s] ([COMB] §4: T = 10 ms).
TS_S: float = 0.01


def parameter_table(params) -> list[dict]:
    """Rows (name, value, unit, source, doc) describing a parameter dataclass instance."""
    rows = []
    for f in dataclasses.fields(params):
        declared = f.metadata.get("declared", Declared())
        rows.append({
            "name": f.name,
            "value": getattr(params, f.name),
            "unit": declared.unit,
            "source": declared.source,
            "doc": declared.doc,
        })
    return rows
