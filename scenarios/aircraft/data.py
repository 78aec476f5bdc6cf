"""Parameter tables of the aircraft level (docs/physics.md §7 phase 2). Every number used by the
rigid-body model, the surface layout, the control laws, the pilot inputs and the aircraft
sensors lives here with its unit and provenance ("(est.)" marks engineering estimates).

Aerodynamic data: the Boeing 747 non-dimensional stability derivatives of Etkin & Reid,
*Dynamics of Flight: Stability and Control* (3rd ed., 1996), Boeing 747 flight condition at
40 000 ft and M 0.8 (data after Heffley & Jewell, NASA CR-2144, 1972), stability axes.
Longitudinal set: Cz, Cm of α, q, α̇ and the elevator's CLδe, Cmδe; lateral set: the β, p,
r derivatives and the control derivatives Clδa, Cnδa, Cyδr, Clδr, Cnδr, all of that one
flight condition (Etkin & Reid, chapters 6–7, Boeing 747 tables and worked examples). The
published eigenvalues of that condition (same worked examples) are kept in
:data:`B747_REFERENCE_MODES` and the tests reproduce them.

Rescaling to the A330 class (:class:`ScalingParams`): the non-dimensional derivatives are
kept (similar transport configuration), the dimensional ones are rebuilt with the A330
wing area and MAC of :data:`scenarios.envelope.A330`, the span and inertias below, the
run's mass, CG, dynamic pressure, true airspeed and Mach.

Sign conventions (Etkin & Reid): elevator and ailerons positive trailing edge down, rudder
positive trailing edge left; β positive nose left of the wind (wind from the right), p
right wing down, r nose right, φ right wing down.
"""

from __future__ import annotations

import types
from dataclasses import dataclass

from ..declare import field_problems
from ..params import AILERON, ELEVATOR, RUDDER, ActuatorParams, param


@dataclass(frozen=True)
class StabilityDerivatives:
    """Non-dimensional stability and control derivatives (per rad), stability axes.

    Dimensionalisation (Etkin & Reid Tables 4.4 and 4.5): forces with q̄·S, pitching
    moment with q̄·S·c̄, rolling/yawing moments with q̄·S·b; rate derivatives with
    the non-dimensional rates q·c̄/(2V), p·b/(2V), r·b/(2V), α̇·c̄/(2V).
    """

    Cz_alpha: float = param("1/rad", "Etkin & Reid B747 longitudinal table (40 kft, M 0.8)", "Czα")
    Cz_q: float = param("1/rad", "Etkin & Reid B747 longitudinal table", "Czq")
    Cz_alphadot: float = param("1/rad", "Etkin & Reid B747 longitudinal table", "Czα̇")
    Cm_alpha: float = param("1/rad", "Etkin & Reid B747 longitudinal table (CG at cg_ref_pct)",
                            "Cmα")
    Cm_q: float = param("1/rad", "Etkin & Reid B747 longitudinal table", "Cmq")
    Cm_alphadot: float = param("1/rad", "Etkin & Reid B747 longitudinal table", "Cmα̇")
    Cz_de: float = param("1/rad", "Etkin & Reid B747 control derivatives (CLδe = 0.3648)",
                         "Czδe = −CLδe")
    Cm_de: float = param("1/rad", "Etkin & Reid B747 control derivatives", "Cmδe")
    Cy_beta: float = param("1/rad", "Etkin & Reid B747 lateral table (40 kft, M 0.8)", "Cyβ")
    Cl_beta: float = param("1/rad", "Etkin & Reid B747 lateral table", "Clβ")
    Cn_beta: float = param("1/rad", "Etkin & Reid B747 lateral table", "Cnβ")
    Cy_p: float = param("1/rad", "Etkin & Reid B747 lateral table", "Cyp")
    Cl_p: float = param("1/rad", "Etkin & Reid B747 lateral table", "Clp")
    Cn_p: float = param("1/rad", "Etkin & Reid B747 lateral table", "Cnp")
    Cy_r: float = param("1/rad", "Etkin & Reid B747 lateral table", "Cyr")
    Cl_r: float = param("1/rad", "Etkin & Reid B747 lateral table", "Clr")
    Cn_r: float = param("1/rad", "Etkin & Reid B747 lateral table", "Cnr")
    Cl_da: float = param("1/rad", "Etkin & Reid B747 control derivatives (δa = antisymmetric "
                                  "aileron angle)", "Clδa")
    Cn_da: float = param("1/rad", "Etkin & Reid B747 control derivatives", "Cnδa")
    Cy_dr: float = param("1/rad", "Etkin & Reid B747 control derivatives", "Cyδr")
    Cl_dr: float = param("1/rad", "Etkin & Reid B747 control derivatives", "Clδr")
    Cn_dr: float = param("1/rad", "Etkin & Reid B747 control derivatives", "Cnδr")


B747_DERIVATIVES = StabilityDerivatives(
    Cz_alpha=-4.920, Cz_q=-5.921, Cz_alphadot=5.896,
    Cm_alpha=-1.023, Cm_q=-23.92, Cm_alphadot=-6.314,
    Cz_de=-0.3648, Cm_de=-1.444,
    Cy_beta=-0.8771, Cl_beta=-0.2797, Cn_beta=0.1946,
    Cy_p=0.0, Cl_p=-0.3295, Cn_p=-0.04073,
    Cy_r=0.0, Cl_r=0.3040, Cn_r=-0.2737,
    Cl_da=-1.368e-2, Cn_da=-1.973e-4,
    Cy_dr=0.1146, Cl_dr=6.976e-3, Cn_dr=-0.1257,
)


@dataclass(frozen=True)
class AirframeData:
    """Geometry, mass and inertia of an airframe at a flight condition (SI units)."""

    name: str = param("-", "-", "airframe")
    wing_area_m2: float = param("m²", "see instance", "reference wing area S")
    mac_m: float = param("m", "see instance", "mean aerodynamic chord c̄")
    span_m: float = param("m", "see instance", "wing span b")
    length_m: float = param("m", "see instance", "fuselage length (inertia scaling only)")
    mass_kg: float = param("kg", "see instance", "mass")
    Ix_kgm2: float = param("kg·m²", "see instance", "rolling moment of inertia")
    Iy_kgm2: float = param("kg·m²", "see instance", "pitching moment of inertia")
    Iz_kgm2: float = param("kg·m²", "see instance", "yawing moment of inertia")
    Izx_kgm2: float = param("kg·m²", "see instance", "product of inertia")
    cg_ref_pct: float = param("% MAC", "see instance", "CG of the derivative set")


#: The Boeing 747 of the reference flight condition (Etkin & Reid, B747 data table:
#: W = 2.83176e6 N, S = 511 m², c̄ = 8.324 m, b = 59.64 m, inertias in body axes; length
#: 70.6 m (Boeing 747-100 published length).
B747 = AirframeData(
    name="Boeing 747 (Etkin & Reid, 40 kft, M 0.8)",
    wing_area_m2=511.0, mac_m=8.324, span_m=59.64, length_m=70.6,
    mass_kg=2.83176e6 / 9.80665,
    Ix_kgm2=0.247e8, Iy_kgm2=0.449e8, Iz_kgm2=0.673e8, Izx_kgm2=-0.212e7,
    cg_ref_pct=25.0,
)


@dataclass(frozen=True)
class ReferenceCondition:
    """The flight condition of the derivative set (Etkin & Reid, B747 case)."""

    alt_ft: float = param("ft", "Etkin & Reid (B747 case)", "altitude")
    mach: float = param("-", "Etkin & Reid (B747 case)", "Mach number")
    tas_ms: float = param("m/s", "Etkin & Reid (B747 case: u0 = 235.9 m/s)", "true airspeed u0")
    rho_kgm3: float = param("kg/m³", "Etkin & Reid (B747 case)", "air density")


B747_CONDITION = ReferenceCondition(alt_ft=40000.0, mach=0.8, tas_ms=235.9, rho_kgm3=0.3045)

#: Published eigenvalues [1/s] of the reference condition (Etkin & Reid, B747 examples):
#: the short period of the longitudinal model and the three lateral modes.
B747_REFERENCE_MODES = types.MappingProxyType({
    "short_period": complex(-0.3719, 0.8875),
    "dutch_roll": complex(-0.03313, 0.9470),
    "roll": -0.5630,
    "spiral": -0.007297,
})


@dataclass(frozen=True)
class ScalingParams:
    """How the reference derivative set is carried to an A330-class flight point (est.).

    - inertias: I = I_747·(m/m_747)·(d/d_747)² with d the span (Ix, Izx), the length (Iy)
      or sqrt(b² + l²) (Iz) — mass distributed like the reference airframe's (est.);
    - Mach: every derivative scales with the Prandtl–Glauert factor 1/sqrt(1 − M²) relative
      to the reference Mach, M held at ``mach_cap`` (as CLα in :mod:`scenarios.envelope`);
    - CG: Cmα and Cmδe move with the CG, Cm_cg = Cm_ref + CLx·(h − h_ref) (Etkin & Reid
      §2.3), CLx = −Czx;
    - aerodynamic uncertainty: every derivative times (1 + d) with d the draw of its own
      coefficient (Cz, Cm, Cy, Cl, Cn; [CHEN] Table 2, docs/physics.md §6).
    """

    span_m: float = param("m", "A330-300 published span", "wing span b")
    length_m: float = param("m", "A330-300 published length", "fuselage length")
    mach_cap: float = param("-", "as scenarios.envelope.A330.cl_alpha_mach_cap (est.)",
                            "Prandtl–Glauert scaling held above this Mach")


A330_SCALING = ScalingParams(span_m=60.3, length_m=63.7, mach_cap=0.75)


@dataclass(frozen=True)
class SurfaceLayout:
    """The primary surfaces, their share of the control derivatives and the geometry that
    makes each act on every axis it physically should (docs/physics.md §7; est.).

    Elevators: each moves half of the elevator derivatives (lift Czδe, pitch Cmδe) and,
    its lift increment acting ``elevator_arm_m`` off the plane of symmetry, rolls the
    aircraft: Clδ = side·(y_e/b)·Czδe·share (side −1 left, +1 right; a left elevator
    trailing edge down lifts the left tail and rolls right wing down). Ailerons: δa =
    (δ_right − δ_left)/2 (Etkin & Reid), shared between the inboard and outboard pairs; the
    747 set at M 0.8 has its outboard ailerons locked out, so the A330 roll power (four
    active ailerons) is ``aileron_factor`` times it (rolling moment Clδa and the published
    747 yawing moment Cnδa). Each aileron's rolling moment is its lift increment times its
    lateral arm, so that lift, CLδ = −side·Clδ·b/y_a, and its pitching moment about the
    derivative set's reference point, Cmδ = −CLδ·x_a/c̄ (x_a the aft distance of the lift
    increment), act too. Spoilers: a fixed coupling to the roll order that adds
    ``spoiler_factor`` times the aileron rolling moment of that order and a yawing moment
    ``spoiler_yaw_ratio`` times their own rolling moment (spoilers are not monitored and
    have no servo-loop here). Rudder: the whole δr set.
    """

    names: tuple[str, ...] = param("-", "docs/physics.md §7", "surfaces, in array order")
    actuator: tuple[str, ...] = param("-", "scenarios.params", "actuator table of each surface")
    elevator_share: float = param("-", "est. (two equal elevators)",
                                  "share of the elevator derivatives per elevator")
    inboard_share: float = param("-", "est.", "share of the aileron derivatives per inboard pair")
    outboard_share: float = param("-", "est.", "share of the aileron derivatives per outboard pair")
    aileron_factor: float = param("-", "est. (747 cruise: outboard ailerons locked out)",
                                  "A330 aileron roll power relative to the 747 Clδa, Cnδa")
    spoiler_factor: float = param("-", "est. (roll spoilers 2–6)",
                                  "spoiler rolling moment per unit aileron roll order, "
                                  "relative to the ailerons'")
    elevator_arm_m: float = param(
        "m", "est. (A330 horizontal tail span 19.4 m; the centroid of an elliptic load over "
        "a 9.7 m semi-span lies at 4·s/(3π) = 4.1 m)",
        "lateral arm of each elevator's lift increment from the plane of symmetry")
    inboard_arm_m: float = param(
        "m", "est. (A330 semi-span 30.15 m; inboard aileron at about 63–76 % of it)",
        "lateral arm of an inboard aileron's lift increment")
    outboard_arm_m: float = param(
        "m", "est. (outboard aileron at about 78–94 % of the semi-span)",
        "lateral arm of an outboard aileron's lift increment")
    inboard_aft_m: float = param(
        "m", "est. (quarter-chord sweep 30°: (21.0 − 12.6 m)·tan 30° from the MAC station "
        "at 12.6 m, plus 0.7 m from the local quarter chord to the flap-induced load)",
        "distance of an inboard aileron's lift increment behind 25 % MAC")
    outboard_aft_m: float = param(
        "m", "est. ((26.0 − 12.6 m)·tan 30° + 0.6 m, as inboard_aft_m)",
        "distance of an outboard aileron's lift increment behind 25 % MAC")
    spoiler_yaw_ratio: float = param(
        "-", "est. (a roll spoiler adds drag on the down-going wing: proverse yaw, drag "
        "increment about 0.1 of the lift it spoils, at the same arm)",
        "spoiler yawing moment per unit of its rolling moment, Cn_sp/Cl_sp")
    elevator_yaw: float = param(
        "-", "est. 0: the first-order drag change of a deflected elevator is the tail's "
        "induced-drag slope 2·C_Lt·C_Lδt/(π·e·A_t), under 4 % of its lift slope at the "
        "small trimmed tail loads of §6 (|C_Lt| ≤ 0.2, A_t ≈ 5, e ≈ 0.85); acting at the "
        "same arm, its yawing moment is under 4 % of its rolling moment",
        "elevator yawing moment per unit of its rolling moment")


LAYOUT = SurfaceLayout(
    names=("left_elevator", "right_elevator", "left_inboard_aileron", "right_inboard_aileron",
           "left_outboard_aileron", "right_outboard_aileron", "rudder"),
    actuator=("elevator", "elevator", "aileron", "aileron", "aileron", "aileron", "rudder"),
    elevator_share=0.5, inboard_share=0.5, outboard_share=0.5,
    aileron_factor=3.0, spoiler_factor=1.0,
    elevator_arm_m=4.1, inboard_arm_m=21.0, outboard_arm_m=26.0,
    inboard_aft_m=5.5, outboard_aft_m=8.3, spoiler_yaw_ratio=0.1, elevator_yaw=0.0,
)

#: Surfaces of the aircraft plant, in array order.
AIRCRAFT_SURFACES: tuple[str, ...] = LAYOUT.names

#: Actuator table of each kind of surface (:data:`LAYOUT` ``actuator``).
AIRCRAFT_ACTUATORS: dict[str, ActuatorParams] = {
    "elevator": ELEVATOR, "aileron": AILERON, "rudder": RUDDER}


def surface_actuator(surface: str) -> ActuatorParams:
    """The nominal actuator table of an aircraft surface (named after that surface)."""
    if surface not in AIRCRAFT_SURFACES:
        raise ValueError(f"unknown aircraft surface {surface!r}; allowed: "
                         f"{', '.join(AIRCRAFT_SURFACES)}")
    kind = LAYOUT.actuator[AIRCRAFT_SURFACES.index(surface)]
    return AIRCRAFT_ACTUATORS[kind].replace(surface=surface)


@dataclass(frozen=True)
class LawParams:
    """Normal-law-like control laws (structure after Goupil 2011; equations in
    docs/aircraft.md §4).

    Pitch: load-factor command with pitch-rate feedback and integral action; the gains are
    placed on the short-period model of the *measured* flight point for a closed-loop short
    period (ω_sp, ζ) and an integral pole a, with ω_sp scheduled on the control anticipation
    parameter: ω_sp = sqrt(CAP·n_α) bounded to [ω_min, ω_max] (docs/aircraft.md §4.1).
    Roll: roll-rate command with bank hold through a nominal-model inversion of the roll
    subsidence (docs/aircraft.md §4.2). Yaw: yaw damper on r − r_turn and sideslip feedback;
    turn coordination r_turn = g·sin φ/V (docs/aircraft.md §4.3). Every fed-back measurement
    passes a first-order filter and every surface order a rate limiter (docs/aircraft.md §4.4).
    A value outside its declared bounds, or ω_min above ω_max, is refused.
    """

    def __post_init__(self):
        problems = field_problems(self)
        if problems:
            raise ValueError("control laws (LawParams): " + "; ".join(problems))
        if self.pitch_omega_min > self.pitch_omega_max:
            raise ValueError(f"control laws (LawParams): pitch_omega_min "
                             f"{self.pitch_omega_min} rad/s is above pitch_omega_max "
                             f"{self.pitch_omega_max} rad/s; give min <= max")

    pitch_cap: float = param(
        "1/(g·s²)", "est. 0.3, inside the Level 1 band of the control anticipation parameter "
        "CAP = ω_sp²/(n/α) of MIL-F-8785C §3.2.2.1.1 for the flight phases of the realistic "
        "envelope (Category B 0.085–3.6, Category C 0.16–3.6); near its low end, as the "
        "unaugmented A330-class airframe (0.05–0.21 over the realistic points), to keep the "
        "surface activity low", "CAP the closed-loop short period is scheduled on", gt=0.0)
    pitch_omega_min: float = param(
        "rad/s", "est. 1.0, above the Level 1 floor ω_sp ≥ 0.7 rad/s of MIL-F-8785C "
        "§3.2.2.1.1 for Category C, Class III", "lowest closed-loop short-period ω_sp", gt=0.0)
    pitch_omega_max: float = param(
        "rad/s", "est. 2.0 (the fixed ω_sp of the laws of model servo-4); CAP ≤ 3.6 for every "
        "n/α above 1.1 g/rad", "highest closed-loop short-period ω_sp", gt=0.0)
    pitch_zeta: float = param(
        "-", "est. 0.7, inside the Level 1 short-period damping of MIL-F-8785C §3.2.2.1.2 "
        "Table IV (Categories A and C 0.35–1.30, B 0.30–2.00)", "closed-loop short-period "
        "damping ζ_sp", gt=0.0)
    pitch_integral: float = param("rad/s", "est.", "integral pole a", gt=0.0)
    pitch_filter_s: float = param(
        "s", "est. 0.1: corner at 10 rad/s, five times the highest ω_sp (phase lag at ω_sp "
        "≤ 11°); takes the sensors' white noise on n_z and q down by sqrt(Ts/(2τ)) = 0.22",
        "time constant of the first-order filter on the fed-back Δn_z and q", gt=0.0)
    roll_bandwidth: float = param(
        "rad/s", "est. 3.0: closed-loop roll-mode time constant 1/ω_p = 0.33 s, inside the "
        "Level 1 limit of MIL-F-8785C §3.3.1.2 Table IX for Class III airplanes (1.4 s "
        "in Categories A, B and C); with the bank hold it sets the steady bank offset a "
        "steady rolling moment leaves (no integral action on the bank)",
        "roll-rate loop bandwidth ω_p", gt=0.0)
    bank_gain: float = param("1/s", "est. (ζ = 1 with ω_p: k_φ = ω_p/4)", "bank hold gain k_φ")
    bank_max_deg: float = param("deg", "A330 normal law (bank protection 33° stick free)",
                                "bank angle used by the turn compensation at most")
    roll_filter_s: float = param(
        "s", "est. 0.05: corner at 20 rad/s, 6.7 times ω_p", "time constant of the first-order "
        "filter on the fed-back p", gt=0.0)
    yaw_damping: float = param("1/s", "est.", "yaw damper: added −∂ṙ/∂r")
    sideslip_gain: float = param("1/s²", "est.", "sideslip feedback: added ∂ṙ/∂β")
    sideslip_integral: float = param("1/s³", "est.", "sideslip integral (turn coordination)")
    yaw_filter_s: float = param(
        "s", "est. 0.2: corner at 5 rad/s, five times the Dutch roll frequency of the "
        "reference condition (0.95 rad/s, docs/physics.md §8); the sideslip vane's noise "
        "(σ 0.1°) is ten times the gyros'",
        "time constant of the first-order filter on the fed-back r and β", gt=0.0)
    elevator_rate_deg_s: float = param(
        "deg/s", "est. 24: half the elevator servo's saturated no-load rate Kci·i_max/r = "
        "47.7 °/s (scenarios.params.ELEVATOR), so that an order moving at the limit is followed "
        "with the current below its saturation up to a hinge load of about 70 % of the stall "
        "force (docs/aircraft.md §4.4)",
        "rate limit of each elevator order", gt=0.0)
    aileron_rate_deg_s: float = param(
        "deg/s", "est. 28: half the aileron servo's saturated no-load rate 57.3 °/s "
        "(scenarios.params.AILERON), as elevator_rate_deg_s; the spoilers' order too",
        "rate limit of each aileron order and of the spoilers' roll order", gt=0.0)
    rudder_rate_deg_s: float = param(
        "deg/s", "est. 26: half the rudder servo's saturated no-load rate 52.1 °/s "
        "(scenarios.params.RUDDER), as elevator_rate_deg_s", "rate limit of the rudder order",
        gt=0.0)
    hinge_load_limit: float = param(
        "-", "est. (docs/physics.md §3: no stall in normal flight; like a rudder travel limiter)",
        "orders stay where the hinge load is below this share of the stall force S·ΔP")


LAWS = LawParams(
    pitch_cap=0.3, pitch_omega_min=1.0, pitch_omega_max=2.0, pitch_zeta=0.7,
    pitch_integral=1.0, pitch_filter_s=0.1,
    roll_bandwidth=3.0, bank_gain=0.75, bank_max_deg=33.0, roll_filter_s=0.05,
    yaw_damping=1.0, sideslip_gain=1.0, sideslip_integral=0.5, yaw_filter_s=0.2,
    elevator_rate_deg_s=24.0, aileron_rate_deg_s=28.0, rudder_rate_deg_s=26.0,
    hinge_load_limit=0.9,
)


@dataclass(frozen=True)
class PilotParams:
    """Pilot inputs of the six manoeuvres (docs/physics.md §7 shapes flown through the laws; est.).

    Ranges (lo, hi) are sampled per run from the manoeuvre stream.
    """

    start_s: tuple[float, float] = param("s", "est.", "time of the first input")
    nose_up_g: tuple[float, float] = param("g", "est. (docs/physics.md §7 nose_up)",
                                           "load-factor step")
    nose_up_hold_s: tuple[float, float] = param("s", "docs/physics.md §7", "time held")
    aoa_g: tuple[float, float] = param("g", "est. (docs/physics.md §7 aoa_protection: slow)",
                                       "pull")
    aoa_ramp_s: tuple[float, float] = param("s", "est.", "ramp in and out")
    aoa_hold_s: tuple[float, float] = param("s", "est.", "time held")
    pitch_g: tuple[float, float] = param("g", "est. (docs/physics.md §7 pitch_protection)",
                                         "pull/push")
    pitch_hold_s: tuple[float, float] = param("s", "est.", "time held at each peak")
    pitch_gap_s: float = param("s", "est.", "pause between the pull and the push")
    yaw_beta_deg: tuple[float, float] = param("deg", "est. (docs/physics.md §7 yaw_angle_mode)",
                                              "pedal sideslip order")
    yaw_hold_s: tuple[float, float] = param("s", "docs/physics.md §7", "time held")
    turn_rate_deg_s: float = param(
        "deg/s", "docs/physics.md §7: normal operations, est. as half the 15 °/s full-stick "
        "roll-rate demand of the Airbus normal law (Airbus FCOM DSC-27-20-10-30); passenger-"
        "comfort turn entries are gentler than full stick (flight-guidance roll-rate limits "
        "3.5–5 °/s); the stress set (scenarios.aircraft.pilot.PILOT_STRESS) uses 15 °/s",
        "roll-rate order of the turn's roll-in and roll-out")
    turn_bank_deg: tuple[float, float] = param("deg", "est.", "bank of the turn")
    turn_hold_s: tuple[float, float] = param("s", "est.", "time in the turn")
    smooth_s: float = param("s", "est.", "rise time of every stick/pedal input but the turn's")
    turn_smooth_s: float = param("s", "est. (a gradual stick input in normal operations; "
                                 "the stress set uses smooth_s)",
                                 "rise and fall time of the turn's roll-rate order")


PILOT = PilotParams(
    start_s=(3.0, 8.0),
    nose_up_g=(0.15, 0.3), nose_up_hold_s=(5.0, 10.0),
    aoa_g=(0.2, 0.35), aoa_ramp_s=(2.0, 4.0), aoa_hold_s=(2.0, 5.0),
    pitch_g=(0.3, 0.45), pitch_hold_s=(1.0, 2.0), pitch_gap_s=2.0,
    yaw_beta_deg=(2.0, 4.0), yaw_hold_s=(5.0, 10.0),
    turn_rate_deg_s=7.5, turn_bank_deg=(25.0, 33.0), turn_hold_s=(4.0, 7.0),
    smooth_s=0.5, turn_smooth_s=1.5,
)


@dataclass(frozen=True)
class AircraftSensorParams:
    """Aircraft-level sensors (inertial reference and air data; est. white-noise σ)."""

    rate_noise_deg_s: float = param("deg/s", "est. (ADIRU gyro)", "σ of p, q, r")
    attitude_noise_deg: float = param("deg", "est. (ADIRU)", "σ of φ, θ")
    load_noise_g: float = param("g", "est. (ADIRU accelerometer)", "σ of nz, ny")
    sideslip_noise_deg: float = param("deg", "est. (air data)", "σ of β")
    aoa_noise_deg: float = param("deg", "est. (air data vane, as the sideslip's)", "σ of α")


AIRCRAFT_SENSORS = AircraftSensorParams(
    rate_noise_deg_s=0.02, attitude_noise_deg=0.02, load_noise_g=0.003, sideslip_noise_deg=0.1,
    aoa_noise_deg=0.1,
)

#: Monitored aircraft surface when a campaign names only the actuator-level surface.
DEFAULT_MONITORED: dict[str, str] = {"elevator": "left_elevator",
                                     "aileron": "left_inboard_aileron"}
