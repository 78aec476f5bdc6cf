"""The sections of the campaign file: one frozen dataclass per table, keys as fields.

Each class is a table of the file (``[campaign]``, ``[faults.runaway]``, one ``[[group]]``,
…); each field declares one key with its type, default, allowed values or range, unit,
source and a one-line description (:mod:`campaign.config.keys`). The sections are
assembled into the whole file by :class:`campaign.config.schema.CampaignConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from detectors.registry import BUILTIN
from scenarios.aircraft.data import AIRCRAFT_SURFACES
from scenarios.catalog import JSBSIM_AIRCRAFT, PLANT_KINDS
from scenarios.turbulence import LEVELS as TURBULENCE_LEVELS
from scenarios.catalog import (
    FAULT_TYPES,
    FAULTS,
    MANOEUVRE_SETS,
    MANOEUVRES,
    REQUIRED_DETECTION_TIME_S,
    SURFACES,
)

from scenarios.faults import SOLID_JAM_VARIANTS

from ..evidence.hazard import DEFAULT_FAULT_RATES_PER_FH

from .keys import key, sub_table, thaw

__all__ = [
    "FLIGHT_POINT_RANGES",
    "CampaignSection",
    "EnvelopeSection",
    "UncertaintySection",
    "MismatchSection",
    "RunawayRanges",
    "LiquidJamRanges",
    "SolidJamRanges",
    "FAULT_VARIANTS",
    "MAGNITUDE_VARIANT",
    "OfcLiquidRanges",
    "OfcSolidRanges",
    "FaultsSection",
    "FAULT_MAGNITUDE_KEY",
    "OFC_FAULTS",
    "SIGNED_FAULTS",
    "SIGNED_FAULT_DIRECTIONS",
    "GroupSpec",
    "RunSpec",
    "RUN_STREAM_LIMIT",
    "DetectorSpec",
    "RequirementsSection",
    "LearningSection",
    "ManoeuvresSection",
    "RunnerSection",
    "PlantVariables",
    "PlantSection",
    "ARRAY_EXAMPLES",
]

#: Physical range of each flight-point coordinate: (low, high, unit). Used by the
#: [envelope] lists and by the fixed flight point of a [[group]].
FLIGHT_POINT_RANGES: dict[str, tuple[float, float, str]] = {
    "alt_ft": (0.0, 45000.0, "ft"),
    "vcas_kt": (100.0, 360.0, "kt"),
    "mass_t": (100.0, 260.0, "t"),
    "cg_pct": (10.0, 50.0, "% MAC"),
}

_CHEN_T1 = "[CHEN] Table 1"
_CHEN_T2 = "[CHEN] Table 2"


def _envelope_key(name: str, values: tuple[float, ...], what: str):
    lo, hi, unit = FLIGHT_POINT_RANGES[name]
    return key("floats", f"{what}: grid values; Monte Carlo samples uniformly between "
               "their min and max", values, unit=unit, ge=lo, le=hi, source=_CHEN_T1)


def _fixed_point_key(name: str, what: str, example: float):
    lo, hi, unit = FLIGHT_POINT_RANGES[name]
    return key("float", f"fixed {what} for every run of the group (replaces that envelope "
               "axis)", unit=unit, ge=lo, le=hi, optional=True,
               default_doc="from [envelope]", example=example)


def _half_width(doc: str, default: float, source: str):
    return key("float", doc + " (relative half-width of a uniform draw)", default,
               unit="-", ge=0.0, le=0.5, source=source)


# ----------------------------------------------------------------------------------------
# The schema: sections of the file, as frozen dataclasses
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class CampaignSection:
    name: str = key("str", "campaign name (reports, output metadata)", example="my-campaign",
                    nonempty=True)
    description: str = key("str", "free text describing the campaign", "")
    seed: int = key("int", "master seed: run i draws from SeedSequence(seed, spawn_key=(i,))",
                    0, ge=0)
    surface: str = key("choice", "control surface whose servo-loop is simulated", "elevator",
                       choices=SURFACES)
    duration_s: float = key("float", "duration of every evaluation run", 60.0, unit="s",
                            ge=20.0, le=600.0)
    ts_s: float = key("float", "sampling period of the simulation and of the signals", 0.01,
                      unit="s", ge=0.001, le=0.05)
    design: str = key("choice", "mc: Monte Carlo sampling of the envelope; grid: every "
                      "envelope point × uncertainty levels {min, 0, max}", "mc",
                      choices=("mc", "grid"))
    sampler: str | None = key("choice", "Monte Carlo sequence (design = \"mc\" only; leave "
                              "out with grid)", "sobol", choices=("sobol", "random"),
                              only="mc")
    realistic_only: bool = key("bool", "keep only flight points passing the realistic-"
                               "envelope rule (docs/physics.md §6), for grid and mc", True)
    pressure_sensor: bool = key("bool", "simulate the actuator chamber ΔP sensor",
                                False)


@dataclass(frozen=True, kw_only=True)
class EnvelopeSection:
    alt_ft: tuple[float, ...] = _envelope_key(
        "alt_ft", (8000.0, 18000.0, 28000.0, 38000.0), "pressure altitude")
    vcas_kt: tuple[float, ...] = _envelope_key(
        "vcas_kt", (160.0, 220.0, 300.0), "calibrated airspeed")
    mass_t: tuple[float, ...] = _envelope_key("mass_t", (120.0, 180.0, 233.0), "aircraft mass")
    cg_pct: tuple[float, ...] = _envelope_key("cg_pct", (17.0, 30.0, 41.0),
                                              "centre-of-gravity position")


def _coefficient_width(doc: str, shorthand: str, source: str, example: float):
    return key("float", doc + " (relative half-width of its own uniform draw; wins over "
               f"{shorthand})", unit="-", ge=0.0, le=0.5, source=source, optional=True,
               default_doc=f"the value of {shorthand}", example=example)


@dataclass(frozen=True, kw_only=True)
class UncertaintySection:
    aero: float = _half_width("every aerodynamic coefficient δCx…δCn (shorthand: sets cx, "
                              "cy, cz, cl, cm and cn not given one by one)", 0.05, _CHEN_T2)
    vcas: float = _half_width("measured VCAS error", 0.10, _CHEN_T2)
    alt: float = _half_width("measured altitude error", 0.10, _CHEN_T2)
    mass: float = _half_width("estimated mass error", 0.10, _CHEN_T2)
    cg: float = _half_width("estimated CG error", 0.10, _CHEN_T2)
    cx: float | None = _coefficient_width("drag coefficient δCx", "aero", _CHEN_T2, 0.05)
    cy: float | None = _coefficient_width("side-force coefficient δCy", "aero", _CHEN_T2, 0.05)
    cz: float | None = _coefficient_width("lift coefficient δCz", "aero", _CHEN_T2, 0.05)
    cl: float | None = _coefficient_width("rolling-moment coefficient δCl", "aero", _CHEN_T2, 0.05)
    cm: float | None = _coefficient_width("pitching-moment coefficient δCm", "aero", _CHEN_T2, 0.05)
    cn: float | None = _coefficient_width("yawing-moment coefficient δCn", "aero", _CHEN_T2, 0.05)


_EST6 = "est. (docs/physics.md §6)"


@dataclass(frozen=True, kw_only=True)
class MismatchSection:
    enabled: bool = key("bool", "sample the plant/model mismatch below", True)
    supply: float = _half_width("hydraulic supply pressure", 0.05, _EST6)
    kci: float = _half_width("servo-valve gain Kci", 0.05, _EST6)
    hinge: float = _half_width("every hinge-moment coefficient Ch0, Chα, Chδ (shorthand: sets "
                               "ch0, cha and chd not given one by one)", 0.20, _EST6)
    ch0: float | None = _coefficient_width("hinge-moment coefficient Ch0", "hinge", _EST6, 0.2)
    cha: float | None = _coefficient_width("hinge-moment derivative Chα", "hinge", _EST6, 0.2)
    chd: float | None = _coefficient_width("hinge-moment derivative Chδ", "hinge", _EST6, 0.2)


def _pair(doc: str, default: tuple[float, float], unit: str, hi: float, source: str):
    return key("pair", doc + ", drawn uniformly in [low, high]", default, unit=unit, gt=0.0,
               le=hi, source=source)


@dataclass(frozen=True, kw_only=True)
class RunawayRanges:
    rate_deg_s: tuple[float, float] = _pair("runaway ramp rate", (1.0, 10.0), "deg/s", 100.0,
                                            "docs/physics.md §5, [COMB] D_V1")


@dataclass(frozen=True, kw_only=True)
class LiquidJamRanges:
    bias_pct_range: tuple[float, float] = _pair(
        "rod-signal bias as a share of the deflection range", (1.3, 1.3), "%", 50.0,
        "[CHEN] §6.2")


@dataclass(frozen=True, kw_only=True)
class SolidJamRanges:
    offset_pct_range: tuple[float, float] = _pair(
        "offset of a solid jam with variant = \"offset\" from the rod position at onset, as a "
        "share of the deflection range", (1.8, 1.8), "%", 50.0, "[CHEN] §6.2")


@dataclass(frozen=True, kw_only=True)
class OfcLiquidRanges:
    amplitude_mA: tuple[float, float] = _pair("amplitude of the sinusoid added to the "
                                              "current", (0.5, 2.0), "mA", 10.0, "est.")
    freq_hz: tuple[float, float] = _pair("oscillation frequency", (0.5, 5.0), "Hz", 20.0,
                                         "est.")


@dataclass(frozen=True, kw_only=True)
class OfcSolidRanges:
    amplitude_mm: tuple[float, float] = _pair("amplitude of the sinusoid replacing the rod "
                                              "measurement", (0.5, 3.0), "mm", 20.0, "est.")
    freq_hz: tuple[float, float] = _pair("oscillation frequency", (0.5, 5.0), "Hz", 20.0,
                                         "est.")


@dataclass(frozen=True, kw_only=True)
class FaultsSection:
    onset_min_s: float = key("float", "earliest fault onset", 5.0, unit="s", ge=0.0, le=600.0)
    onset_before_end_s: float = key("float", "latest onset is duration_s minus this", 10.0,
                                    unit="s", ge=0.0, le=600.0)
    runaway: RunawayRanges = sub_table(RunawayRanges, "runaway magnitude (sign random)")
    liquid_jam: LiquidJamRanges = sub_table(LiquidJamRanges,
                                            "liquid-jam magnitude (sign random)")
    solid_jam: SolidJamRanges = sub_table(SolidJamRanges,
                                          "solid-jam offset of variant \"offset\" (sign random)")
    ofc_liquid: OfcLiquidRanges = sub_table(OfcLiquidRanges,
                                            "liquid oscillatory failure (sign random)")
    ofc_solid: OfcSolidRanges = sub_table(OfcSolidRanges,
                                          "solid oscillatory failure (sign random)")


#: Which [faults.*] range holds the magnitude of each fault type (a [[group]] ``magnitude``
#: is in the same unit). Faults not listed have no magnitude (hardover: ±i_max;
#: disconnection: floating surface); solid_jam has one with variant = "offset" only
#: (variant "seized": frozen where it is).
FAULT_MAGNITUDE_KEY: dict[str, tuple[str, str]] = {
    "runaway": ("runaway", "rate_deg_s"),
    "liquid_jam": ("liquid_jam", "bias_pct_range"),
    "solid_jam": ("solid_jam", "offset_pct_range"),
    "ofc_liquid": ("ofc_liquid", "amplitude_mA"),
    "ofc_solid": ("ofc_solid", "amplitude_mm"),
}
#: Fault types with a sampled oscillation frequency.
OFC_FAULTS: tuple[str, ...] = ("ofc_liquid", "ofc_solid")
#: Fault types with a direction (sign of the magnitude), and the names of a fixed sign.
SIGNED_FAULTS: tuple[str, ...] = ("runaway", "hardover", "liquid_jam", "solid_jam")
#: Fault types with variants (group key ``variant``), their choices and the default.
FAULT_VARIANTS: dict[str, tuple[str, ...]] = {"solid_jam": SOLID_JAM_VARIANTS}
#: Variant of a fault that has a magnitude and a direction; the other variants have neither.
MAGNITUDE_VARIANT: dict[str, str] = {"solid_jam": "offset"}
SIGNED_FAULT_DIRECTIONS: tuple[str, ...] = ("positive", "negative")


@dataclass(frozen=True, kw_only=True)
class GroupSpec:
    name: str = key("str", "group name in the run table (unique)", optional=True,
                    default_doc="derived: fault@manoeuvres, e.g. \"liquid_jam@cruise\"",
                    example="liquid_jam@cruise", nonempty=True)
    manoeuvres: tuple[str, ...] = key("names", "manoeuvres of the group, or [\"all\"]",
                                      MANOEUVRES, choices=MANOEUVRES)
    fault: str = key("choice", "fault type of every run of the group (\"none\": fault-free)",
                     choices=FAULTS, example="none")
    count: int | None = key("int", "runs per manoeuvre (design = \"mc\": required; grid: "
                            "leave out, one run per case)", ge=1, optional=True, only="mc",
                            default_doc="required with design = \"mc\"", example=10)
    onset_s: float | None = key("float", "fixed fault onset instead of the sampled one (before "
                                "the end of the run)",
                                unit="s", ge=0.0, le=600.0, optional=True,
                                default_doc="sampled from [faults]", example=30.0)
    variant: str | None = key("choice", "variant of the fault (solid_jam only): \"seized\" — "
                              "rod and surface seized where they stand at onset; \"offset\" — "
                              "seized at [faults.solid_jam] offset_pct_range of the deflection "
                              "range from there, the rod sensors reading the jammed rod "
                              "([CHEN] eq. 4, docs/physics.md §5)",
                              choices=SOLID_JAM_VARIANTS, optional=True,
                              default_doc="\"seized\"", example="offset")
    magnitude: float | None = key("float", "fixed magnitude in the unit of its [faults.*] "
                                  "range (runaway deg/s, liquid_jam %, solid_jam with variant "
                                  "= \"offset\" %, ofc_liquid mA, ofc_solid mm); sign random "
                                  "unless sign is given", gt=0.0,
                                  optional=True, default_doc="sampled from [faults]",
                                  example=5.0)
    freq_hz: float | None = key("float", "fixed OFC frequency (ofc_liquid, ofc_solid only)",
                                unit="Hz", gt=0.0, le=20.0, optional=True,
                                default_doc="sampled from [faults]", example=1.0)
    sign: str | None = key("choice", "fixed direction of the fault (runaway, hardover, "
                           "liquid_jam, solid_jam with variant = \"offset\" only): positive "
                           "or negative deflection",
                           choices=SIGNED_FAULT_DIRECTIONS, optional=True,
                           default_doc="random", example="negative")
    manoeuvre_start_s: float | None = key(
        "float", "fixed start time of the manoeuvre instead of the sampled one (places its "
        "transients, e.g. [COMB] §4 D_V2; before the end of the run)", unit="s", ge=0.0,
        le=600.0, optional=True, default_doc="sampled per run", example=14.3)
    alt_ft: float | None = _fixed_point_key("alt_ft", "altitude", 28000.0)
    vcas_kt: float | None = _fixed_point_key("vcas_kt", "calibrated airspeed", 220.0)
    mass_t: float | None = _fixed_point_key("mass_t", "mass", 180.0)
    cg_pct: float | None = _fixed_point_key("cg_pct", "CG position", 30.0)


#: Streams an explicit [[run]] may use: below 2³², the first stream of the learning set
#: (campaign/plan.py LEARNING_STREAM_BASE), so a run never shares the noise of a
#: learning run.
RUN_STREAM_LIMIT: int = 2 ** 32 - 1


def _run_point_key(name: str, what: str, example: float):
    lo, hi, unit = FLIGHT_POINT_RANGES[name]
    return key("float", f"true {what} of the run", unit=unit, ge=lo, le=hi, example=example)


@dataclass(frozen=True, kw_only=True)
class RunSpec:
    """One explicit run, every value of its run-table row given (a regression case, e.g. the
    worst runs ``fdd-campaign falsify`` found): replayed exactly, never sampled."""

    group: str = key("str", "group name of the run in the run table", "runs", nonempty=True)
    manoeuvre: str = key("choice", "manoeuvre of the run", choices=MANOEUVRES,
                         example="pitch_protection")
    fault: str = key("choice", "fault type (\"none\": fault-free)", "none", choices=FAULTS)
    onset_s: float | None = key("float", "fault onset (faulty runs: required; before the end "
                                "of the run)", unit="s", ge=0.0, le=600.0, optional=True,
                                default_doc="none (fault-free)", example=30.0)
    magnitude: float | None = key("float", "signed fault magnitude in the run-table unit "
                                  "(scenarios/faults.py: runaway deg/s, liquid_jam mm, "
                                  "ofc_liquid mA, ofc_solid mm); required by the faults that "
                                  "have one", optional=True, default_doc="none",
                                  example=-4.0)
    freq_hz: float | None = key("float", "OFC frequency (ofc_liquid, ofc_solid only; "
                                "required there)", unit="Hz", gt=0.0, le=20.0,
                                optional=True, default_doc="none", example=1.0)
    alt_ft: float = _run_point_key("alt_ft", "pressure altitude", 28000.0)
    vcas_kt: float = _run_point_key("vcas_kt", "calibrated airspeed", 220.0)
    mass_t: float = _run_point_key("mass_t", "mass", 180.0)
    cg_pct: float = _run_point_key("cg_pct", "centre of gravity", 30.0)
    draws: tuple[tuple[str, float], ...] = key(
        "number_table", "relative deviations of the run, one per draw column of the run "
        "table (d_… = value, docs/physics.md §6); each within ± its half-width of "
        "[uncertainty]/[mismatch]; a column left out is 0", (), ge=-0.9, le=0.9,
        source="scenarios/envelope.py DRAW_COLUMNS", example={"d_vcas": 0.05})
    stream: int = key("int", "random stream of the run: its noise, turbulence and manoeuvre "
                      "shape come from SeedSequence(seed, spawn_key=(stream,))", ge=0,
                      le=RUN_STREAM_LIMIT, example=7)
    manoeuvre_start_s: float | None = key(
        "float", "fixed start time of the manoeuvre (before the end of the run)", unit="s",
        ge=0.0, le=600.0, optional=True, default_doc="sampled from the stream",
        example=8.5)


@dataclass(frozen=True, kw_only=True)
class DetectorSpec:
    name: str = key("str", "registered detector name (built-in: "
                    + ", ".join(BUILTIN) + "; their parameters: docs/detectors.md; others "
                    "through the entry-point group fdd_campaign.detectors)",
                    example="position-monitor", nonempty=True)
    label: str = key("str", "name of this detector in the results (unique)", optional=True,
                     default_doc="= name", example="pm-strict", nonempty=True)
    params: tuple[tuple[str, Any], ...] = key(
        "table", "keyword parameters of the detector (checked against its signature and "
        "ranges)", (), example={"safety": 2.0})
    threshold_scale: float | None = key(
        "float", "every threshold of the detector multiplied by this factor: its alarm is "
        "raised where its decision statistic reaches it (below 1: earlier detection, likelier "
        "false alarms); only for a detector whose capabilities declare threshold_scale (every "
        "built-in one). The detectors fitted by another campaign are reused at any scale "
        "(run --fitted-from), and 'fdd-campaign tradeoff DIR' predicts a campaign's results "
        "at the scales it stores (docs/thresholds.md)", unit="-", gt=0.0, optional=True,
        default_doc="1 (the detector's own thresholds)", example=1.25,
        source="the user's choice of operating point")

    @property
    def scale(self) -> float:
        """The factor of every threshold (1 when ``threshold_scale`` is not set)."""
        return 1.0 if self.threshold_scale is None else float(self.threshold_scale)

    def params_dict(self) -> dict:
        """The parameters as a plain dict (lists and dicts), ready for ``make_detector``."""
        return thaw(self.params, "table")


@dataclass(frozen=True, kw_only=True)
class SystemSpec:
    name: str = key("str", "name of the detection system in the results (unique among the "
                    "[[detector]] labels and the systems)", example="fdd-system",
                    nonempty=True)
    members: tuple[str, ...] = key(
        "labels", "its detectors: [[detector]] labels (a label stands for every variant of "
        "that detector) or result names LABEL[VARIANT]; the system's alarm is the first "
        "alarm of any member, and it covers the fault types any member covers "
        "(docs/design.md §5, Detection systems)",
        example=["position-monitor", "comb-interval[a=0.9]"])


@dataclass(frozen=True, kw_only=True)
class RequirementsSection:
    detection_time_s: tuple[tuple[str, float], ...] = key(
        "fault_seconds", "required detection time per fault type, the DTP denominator "
        "(entries given replace the defaults; ofc: 3 periods, value for 1 Hz)",
        tuple(REQUIRED_DETECTION_TIME_S.items()), unit="s", gt=0.0,
        choices=FAULT_TYPES, source="est. (docs/physics.md §5)")
    max_fa_rate: float = key("float", "gate: highest accepted false-alarm rate", 0.0,
                             ge=0.0, le=1.0)
    detector_max_fa_rate: tuple[tuple[str, float], ...] = key(
        "number_table", "gate: a detector's own highest accepted false-alarm rate in place of "
        "max_fa_rate (result name, e.g. \"chen-local[solid]\", or base label = rate; each "
        "must name a [[detector]] label of the file, checked before anything runs): the "
        "documented allowance of a detector known not to reach zero; the command-line "
        "--max-fa overrides it", (), ge=0.0, le=1.0, example={"chen-local[solid]": 0.3})
    max_md_rate: float = key("float", "gate: highest accepted missed-detection rate", 0.0,
                             ge=0.0, le=1.0)
    max_dtp: float = key("float", "gate: highest accepted detection time performance "
                         "(delay / required time)", 1.0, gt=0.0)
    fault_rate_per_fh: tuple[tuple[str, float], ...] = key(
        "number_table", "occurrence rate of each actuator fault mode per flight hour, for "
        "the hazard table of `fdd-campaign certify` (rate of undetected faults per flight "
        "hour, docs/evidence.md); entries given replace the defaults, 0 for a mode that "
        "cannot occur", tuple(sorted(DEFAULT_FAULT_RATES_PER_FH.items())), unit="1/FH",
        ge=0.0, le=1.0, choices=FAULT_TYPES, example={"runaway": 1e-6},
        source="placeholder (est.), no cited source: set these from your safety assessment "
               "(campaign.evidence.hazard.DEFAULT_FAULT_RATES_PER_FH)")
    detection_window_s: float | None = key("float", "a fault counts as detected only within "
                                           "this time after onset", unit="s", gt=0.0,
                                           le=600.0, optional=True,
                                           default_doc="rest of the run", example=5.0)

    def required_time(self, fault: str) -> float:
        """Required detection time [s] of *fault*."""
        return dict(self.detection_time_s)[fault]


@dataclass(frozen=True, kw_only=True)
class LearningSection:
    runs_per_manoeuvre: int = key("int", "fault-free learning runs per manoeuvre (own seeds, "
                                  "never evaluation runs)", 10, ge=1)
    manoeuvres: tuple[str, ...] = key("names", "manoeuvres of the learning set, or [\"all\"]",
                                      MANOEUVRES, choices=MANOEUVRES)
    duration_s: float | None = key("float", "duration of a learning run", unit="s", ge=20.0,
                                   le=600.0, optional=True,
                                   default_doc="[campaign] duration_s", example=60.0)


@dataclass(frozen=True, kw_only=True)
class ManoeuvresSection:
    set: str = key("choice", "how the manoeuvres are flown: normal (normal operations: the turn "
                   "rolls in at 7.5 °/s) or stress (their aggressive end: the turn rolls in at "
                   "the normal law's full-stick 15 °/s, every amplitude range at its high end); "
                   "part of every run's id", "normal", choices=MANOEUVRE_SETS,
                   source="docs/physics.md §7")
    learning_set: str | None = key("choice", "manoeuvre set of the learning runs (e.g. "
                                   "\"normal\" to evaluate under stress detectors learned "
                                   "in normal operations)", optional=True,
                                   choices=MANOEUVRE_SETS, default_doc="= set",
                                   example="normal")


@dataclass(frozen=True, kw_only=True)
class RunnerSection:
    chunk_size: int = key("int", "runs simulated together by one worker task", 100, ge=1,
                          le=10000)
    engine: str = key("choice", "implementation of the time loops: compiled (numba kernels) "
                      "or numpy (the reference they are tested against; last-bit differences "
                      "from transcendental functions)", "compiled", choices=("compiled", "numpy"))
    run_timeout_s: float | None = key("float", "time limit of one run on a worker process "
                                      "(a chunk gets this times its runs); a run exceeding it "
                                      "is recorded with status \"timeout\" and retried by a "
                                      "rerun", unit="s", gt=0.0, le=86400.0,
                                      optional=True, default_doc="no limit", example=60.0)


def _fmu_var(doc: str, default: str):
    return key("str", doc + " (\"\" leaves it unmapped)", default,
               source="scenarios/fmu.py SIGNALS")


@dataclass(frozen=True, kw_only=True)
class PlantVariables:
    current: str = key("str", "FMU input that receives the servo-valve current held over "
                       "each period [mA]; required", "i_mA", nonempty=True,
                       source="scenarios/fmu.py SIGNALS")
    rod: str = key("str", "FMU output of the rod position [mm]; required", "x_mm",
                   nonempty=True, source="scenarios/fmu.py SIGNALS")
    surface: str = _fmu_var("FMU output of the surface deflection [deg]; unmapped: "
                            "asin(rod/r), no disconnection runs", "delta_deg")
    rod_start: str = _fmu_var("FMU parameter set to the trimmed start rod position [mm]",
                              "x0")
    jam: str = _fmu_var("FMU input set to 1 from a solid-jam onset; unmapped: the engine "
                        "holds the FMU outputs from the onset", "jam")
    disconnect: str = _fmu_var("FMU input set to 1 from a disconnection onset; required "
                               "for disconnection runs", "disconnect")


@dataclass(frozen=True, kw_only=True)
class PlantSection:
    kind: str = key("choice", "plant level: actuator (the servo-loop of `surface` alone, "
                    "orders from manoeuvre profiles) or aircraft (rigid-body aircraft, "
                    "control laws and every primary surface with its own servo-loop; "
                    "docs/physics.md §7) or jsbsim (a JSBSim aircraft flown by the same laws and "
                    "servo-loops; the [jsbsim] extra; docs/aircraft.md §9)", "actuator",
                    choices=PLANT_KINDS)
    aircraft: str = key("choice", "jsbsim plant only: the JSBSim aircraft (JSBSim's own data)",
                        "737", choices=JSBSIM_AIRCRAFT)
    monitored_surface: str | None = key(
        "choice", "aircraft plant only: the surface whose servo-loop signals the detectors "
        "see (the fault acts on it)", optional=True, choices=AIRCRAFT_SURFACES,
        default_doc="the left surface of `surface`: left_elevator or left_inboard_aileron",
        example="left_inboard_aileron")
    turbulence: str = key("choice", "aircraft and jsbsim plants only: the Dryden turbulence the "
                          "aircraft flies in (moderate, docs/physics.md §7; none: calm air, as the "
                          "ADDSAFE runs of [CHEN] footnote 1)", "moderate",
                          choices=tuple(TURBULENCE_LEVELS))
    fmu: str | None = key("str", "FMI 2.0/3.0 co-simulation FMU that replaces the built-in "
                          "servo-loop plant (path relative to the working directory; "
                          "`fdd-campaign fmu build` makes the built-in one)", optional=True,
                          default_doc="built-in plant", example="servo.fmu", nonempty=True)
    push_parameters: bool = key("bool", "set each run's true plant parameters (Kci, SdP, "
                                "SdP_ref, Ka, r_mm, x_min, x_max, hm_delta, hm_0, "
                                "stop_min_rad, stop_max_rad) into the FMU parameters of the "
                                "same names, and the FCC period into h_max_s (the internal "
                                "sub-step of the built-in servo-loop FMU)", True)
    parameters: tuple[tuple[str, float], ...] = key(
        "number_table", "FMU parameter start values to override, name = value (set after "
        "the pushed run parameters, so an override of a pushed name holds for every run; "
        "checked against the FMU's real parameters before the campaign)", (),
        source="scenarios/fmu.py FmuPlant")
    variables: PlantVariables = sub_table(PlantVariables, "FMU variable of each engine "
                                          "signal (defaults: the built-in servo-loop FMU)")




#: Entries of the array tables written into the starting file (and suggested in errors
#: when a file has none), by TOML section name.
ARRAY_EXAMPLES: dict[str, list[dict[str, Any]]] = {
    "group": [
        {"fault": "none", "count": 10},
        {"fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 10},
        {"fault": "runaway", "manoeuvres": ["cruise"], "count": 10},
    ],
    "detector": [{"name": "position-monitor"}],
}
