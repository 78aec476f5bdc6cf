"""The campaign file: schema, validation, presets and the generated reference.

A campaign is described by one TOML file (or a preset shipped in ``campaign/presets``).
The schema is defined once, as data: every key is a field of a frozen dataclass whose
metadata (:class:`Key`) gives its type, default, allowed values or range, unit, source and
a one-line description. From that single definition this module derives

* the validation (:func:`load_config`, :meth:`CampaignConfig.from_dict`), which collects
  every problem of a file, each with its path (``group[2].fault``) and how to fix it, and
  raises them together in one :class:`ConfigError`;
* the annotated starting file written by ``fdd-campaign init`` (:func:`init_text`);
* the Markdown reference ``docs/campaign-file.md`` (:func:`schema_markdown`), regenerated
  with ``python -m campaign.config --markdown > docs/campaign-file.md``.

A validated configuration is a tree of frozen dataclasses and tuples (hashable, no mutable
containers); :meth:`CampaignConfig.to_json` is its canonical form, used for run identity
and stored in the metadata of every result file.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import re
import sys
import tomllib
import warnings
from dataclasses import MISSING, dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any, Iterator, Mapping

from detectors.compat import incompatibilities
from scenarios.aircraft.data import AIRCRAFT_SURFACES
from scenarios.plants import PLANT_KINDS, get_plant
from scenarios.catalog import (
    FAULT_TYPES,
    FAULTS,
    MANOEUVRES,
    REQUIRED_DETECTION_TIME_S,
    SURFACES,
    suggest,
)

__all__ = [
    "ConfigError",
    "CampaignConfig",
    "CampaignSection",
    "EnvelopeSection",
    "UncertaintySection",
    "MismatchSection",
    "FaultsSection",
    "GroupSpec",
    "DetectorSpec",
    "RequirementsSection",
    "LearningSection",
    "RunnerSection",
    "PlantSection",
    "Key",
    "load_config",
    "list_presets",
    "preset_path",
    "init_text",
    "schema_markdown",
    "with_overrides",
    "FAULT_MAGNITUDE_KEY",
]

PRESET_PACKAGE = "campaign"
PRESET_DIR = "presets"


# ----------------------------------------------------------------------------------------
# Errors
# ----------------------------------------------------------------------------------------
class ConfigError(ValueError):
    """A campaign file (or dict) that cannot be used.

    ``errors`` lists every problem found, each ``"path: problem; allowed …"`` or
    ``"path: problem; fix: …"``; ``str(err)`` shows them all. Survives pickling, so it can
    cross process boundaries.
    """

    def __init__(self, errors: list[str] | tuple[str, ...] | str, source: str = "<config>"):
        if isinstance(errors, str):
            errors = [errors]
        self.errors: list[str] = list(errors)
        self.source = source
        n = len(self.errors)
        head = f"{source}: {n} problem{'s' if n != 1 else ''} in the campaign file"
        super().__init__(head + "".join(f"\n  - {e}" for e in self.errors))

    def __reduce__(self):
        return (type(self), (list(self.errors), self.source))


# ----------------------------------------------------------------------------------------
# Schema description (the metadata of every key)
# ----------------------------------------------------------------------------------------
#: Kinds of values, with the words used for them in messages and in the reference.
KIND_NAMES: dict[str, str] = {
    "str": "string",
    "choice": "string",
    "bool": "boolean",
    "int": "integer",
    "float": "float",
    "floats": "list of floats",
    "pair": "[low, high]",
    "names": "list of names",
    "table": "table",
    "fault_seconds": "table fault → float",
}


@dataclass(frozen=True)
class Key:
    """Description of one key of the campaign file (stored in a dataclass field's metadata).

    kind : one of :data:`KIND_NAMES`.
    doc : one-line description.
    unit : physical unit (``"s"``, ``"ft"``, …) or ``""``.
    lo, hi : inclusive bounds of a number (``lo_open``: lower bound excluded).
    choices : allowed names (``choice`` and ``names`` kinds).
    required : the key has no default and must be given.
    optional : the key may be left out; its value is then ``None`` (meaning in ``default_doc``).
    example : value shown in the starting file and in messages.
    source : where the default comes from.
    only : ``"mc"`` when the key applies to ``design = "mc"`` only (an error with ``grid``).
    nonempty : a string that must not be empty.
    """

    kind: str
    doc: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple[str, ...] = ()
    required: bool = False
    optional: bool = False
    example: Any = None
    default_doc: str = ""
    source: str = ""
    only: str = ""
    nonempty: bool = False


def key(kind: str, doc: str, default: Any = MISSING, **options: Any):
    """Declare a key of the campaign file as a dataclass field carrying its :class:`Key`."""
    optional = options.get("optional", False)
    spec = Key(kind=kind, doc=doc, required=default is MISSING and not optional, **options)
    if optional:
        default = None
    if default is MISSING:
        return field(metadata={"key": spec})
    return field(default=default, metadata={"key": spec})


def sub_table(cls: type, doc: str):
    """Declare a nested table (``[faults.runaway]``) of a section."""
    return field(default_factory=cls, metadata={"table": cls, "doc": doc})


def section(cls: type, toml_name: str, doc: str, *, array: bool = False):
    """Declare a top-level section (``[name]``, or ``[[name]]`` when *array*)."""
    return field(metadata={"section": toml_name, "cls": cls, "doc": doc, "array": array})


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
               "their min and max", values, unit=unit, lo=lo, hi=hi, source=_CHEN_T1)


def _fixed_point_key(name: str, what: str, example: float):
    lo, hi, unit = FLIGHT_POINT_RANGES[name]
    return key("float", f"fixed {what} for every run of the group (replaces that envelope "
               "axis)", unit=unit, lo=lo, hi=hi, optional=True,
               default_doc="from [envelope]", example=example)


def _half_width(doc: str, default: float, source: str):
    return key("float", doc + " (relative half-width of a uniform draw)", default,
               unit="-", lo=0.0, hi=0.5, source=source)


# ----------------------------------------------------------------------------------------
# The schema: sections of the file, as frozen dataclasses
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class CampaignSection:
    name: str = key("str", "campaign name (reports, output metadata)", example="my-campaign",
                    nonempty=True)
    description: str = key("str", "free text describing the campaign", "")
    seed: int = key("int", "master seed: run i draws from SeedSequence(seed, spawn_key=(i,))",
                    0, lo=0)
    surface: str = key("choice", "control surface whose servo-loop is simulated", "elevator",
                       choices=SURFACES)
    duration_s: float = key("float", "duration of every evaluation run", 60.0, unit="s",
                            lo=20.0, hi=600.0)
    ts_s: float = key("float", "sampling period of the simulation and of the signals", 0.01,
                      unit="s", lo=0.001, hi=0.05)
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


@dataclass(frozen=True, kw_only=True)
class UncertaintySection:
    aero: float = _half_width("aerodynamic coefficients δCx…δCn", 0.05, _CHEN_T2)
    vcas: float = _half_width("measured VCAS error", 0.10, _CHEN_T2)
    alt: float = _half_width("measured altitude error", 0.10, _CHEN_T2)
    mass: float = _half_width("estimated mass error", 0.10, _CHEN_T2)
    cg: float = _half_width("estimated CG error", 0.10, _CHEN_T2)


@dataclass(frozen=True, kw_only=True)
class MismatchSection:
    enabled: bool = key("bool", "sample the plant/model mismatch below", True)
    supply: float = _half_width("hydraulic supply pressure", 0.05, "est. (docs/physics.md §6)")
    kci: float = _half_width("servo-valve gain Kci", 0.05, "est. (docs/physics.md §6)")
    hinge: float = _half_width("hinge-moment coefficients", 0.20, "est. (docs/physics.md §6)")


def _pair(doc: str, default: tuple[float, float], unit: str, hi: float, source: str):
    return key("pair", doc + ", drawn uniformly in [low, high]", default, unit=unit, lo=0.0,
               lo_open=True, hi=hi, source=source)


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
    onset_min_s: float = key("float", "earliest fault onset", 5.0, unit="s", lo=0.0, hi=600.0)
    onset_before_end_s: float = key("float", "latest onset is duration_s minus this", 10.0,
                                    unit="s", lo=0.0, hi=600.0)
    runaway: RunawayRanges = sub_table(RunawayRanges, "runaway magnitude (sign random)")
    liquid_jam: LiquidJamRanges = sub_table(LiquidJamRanges,
                                            "liquid-jam magnitude (sign random)")
    ofc_liquid: OfcLiquidRanges = sub_table(OfcLiquidRanges,
                                            "liquid oscillatory failure (sign random)")
    ofc_solid: OfcSolidRanges = sub_table(OfcSolidRanges,
                                          "solid oscillatory failure (sign random)")


#: Which [faults.*] range holds the magnitude of each fault type (a [[group]] ``magnitude``
#: is in the same unit). Faults not listed have no magnitude (hardover: ±i_max; solid_jam:
#: frozen where it is; disconnection: floating surface).
FAULT_MAGNITUDE_KEY: dict[str, tuple[str, str]] = {
    "runaway": ("runaway", "rate_deg_s"),
    "liquid_jam": ("liquid_jam", "bias_pct_range"),
    "ofc_liquid": ("ofc_liquid", "amplitude_mA"),
    "ofc_solid": ("ofc_solid", "amplitude_mm"),
}
#: Fault types with a sampled oscillation frequency.
OFC_FAULTS: tuple[str, ...] = ("ofc_liquid", "ofc_solid")
#: Fault types with a direction (sign of the magnitude), and the names of a fixed sign.
SIGNED_FAULTS: tuple[str, ...] = ("runaway", "hardover", "liquid_jam")
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
                            "leave out, one run per case)", lo=1, optional=True, only="mc",
                            default_doc="required with design = \"mc\"", example=10)
    onset_s: float | None = key("float", "fixed fault onset instead of the sampled one (before "
                                "the end of the run)",
                                unit="s", lo=0.0, hi=600.0, optional=True,
                                default_doc="sampled from [faults]", example=30.0)
    magnitude: float | None = key("float", "fixed magnitude in the unit of its [faults.*] "
                                  "range (runaway deg/s, liquid_jam %, ofc_liquid mA, "
                                  "ofc_solid mm); sign random unless sign is given", lo=0.0, lo_open=True,
                                  optional=True, default_doc="sampled from [faults]",
                                  example=5.0)
    freq_hz: float | None = key("float", "fixed OFC frequency (ofc_liquid, ofc_solid only)",
                                unit="Hz", lo=0.0, lo_open=True, hi=20.0, optional=True,
                                default_doc="sampled from [faults]", example=1.0)
    sign: str | None = key("choice", "fixed direction of the fault (runaway, hardover, "
                           "liquid_jam only): positive or negative deflection",
                           choices=SIGNED_FAULT_DIRECTIONS, optional=True,
                           default_doc="random", example="negative")
    manoeuvre_start_s: float | None = key(
        "float", "fixed start time of the manoeuvre instead of the sampled one (places its "
        "transients, e.g. [COMB] §4 D_V2; before the end of the run)", unit="s", lo=0.0,
        hi=600.0, optional=True, default_doc="sampled per run", example=14.3)
    alt_ft: float | None = _fixed_point_key("alt_ft", "altitude", 28000.0)
    vcas_kt: float | None = _fixed_point_key("vcas_kt", "calibrated airspeed", 220.0)
    mass_t: float | None = _fixed_point_key("mass_t", "mass", 180.0)
    cg_pct: float | None = _fixed_point_key("cg_pct", "CG position", 30.0)


@dataclass(frozen=True)
class FrozenTable:
    """An immutable, hashable table (a TOML table inside detector parameters)."""

    items: tuple[tuple[str, Any], ...]


@dataclass(frozen=True, kw_only=True)
class DetectorSpec:
    name: str = key("str", "registered detector name (built-in: position-monitor; others "
                    "through the entry-point group fdd_campaign.detectors)",
                    example="position-monitor", nonempty=True)
    label: str = key("str", "name of this detector in the results (unique)", optional=True,
                     default_doc="= name", example="pm-strict", nonempty=True)
    params: tuple[tuple[str, Any], ...] = key(
        "table", "keyword parameters of the detector (checked against its signature and "
        "ranges)", (), example={"safety": 2.0})

    def params_dict(self) -> dict:
        """The parameters as a plain dict (lists and dicts), ready for ``make_detector``."""
        return _thaw(self.params, "table")


@dataclass(frozen=True, kw_only=True)
class RequirementsSection:
    detection_time_s: tuple[tuple[str, float], ...] = key(
        "fault_seconds", "required detection time per fault type, the DTP denominator "
        "(entries given replace the defaults; ofc: 3 periods, value for 1 Hz)",
        tuple(REQUIRED_DETECTION_TIME_S.items()), unit="s", lo=0.0, lo_open=True,
        choices=FAULT_TYPES, source="est. (docs/physics.md §5)")
    max_fa_rate: float = key("float", "gate: highest accepted false-alarm rate", 0.0,
                             lo=0.0, hi=1.0)
    max_md_rate: float = key("float", "gate: highest accepted missed-detection rate", 0.0,
                             lo=0.0, hi=1.0)
    max_dtp: float = key("float", "gate: highest accepted detection time performance "
                         "(delay / required time)", 1.0, lo=0.0, lo_open=True)
    detection_window_s: float | None = key("float", "a fault counts as detected only within "
                                           "this time after onset", unit="s", lo=0.0,
                                           lo_open=True, hi=600.0, optional=True,
                                           default_doc="rest of the run", example=5.0)

    def required_time(self, fault: str) -> float:
        """Required detection time [s] of *fault*."""
        return dict(self.detection_time_s)[fault]


@dataclass(frozen=True, kw_only=True)
class LearningSection:
    runs_per_manoeuvre: int = key("int", "fault-free learning runs per manoeuvre (own seeds, "
                                  "never evaluation runs)", 10, lo=1)
    manoeuvres: tuple[str, ...] = key("names", "manoeuvres of the learning set, or [\"all\"]",
                                      MANOEUVRES, choices=MANOEUVRES)
    duration_s: float | None = key("float", "duration of a learning run", unit="s", lo=20.0,
                                   hi=600.0, optional=True,
                                   default_doc="[campaign] duration_s", example=60.0)


@dataclass(frozen=True, kw_only=True)
class RunnerSection:
    chunk_size: int = key("int", "runs simulated together by one worker task", 100, lo=1,
                          hi=10000)
    engine: str = key("choice", "implementation of the time loops: compiled (numba kernels) "
                      "or numpy (the reference they are tested against; last-bit differences "
                      "from transcendental functions)", "compiled", choices=("compiled", "numpy"))
    run_timeout_s: float | None = key("float", "time limit of one run on a worker process "
                                      "(a chunk gets this times its runs); a run exceeding it "
                                      "is recorded with status \"timeout\" and retried by a "
                                      "rerun", unit="s", lo=0.0, lo_open=True, hi=86400.0,
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
                    "docs/physics.md §7)", "actuator", choices=PLANT_KINDS)
    monitored_surface: str | None = key(
        "choice", "aircraft plant only: the surface whose servo-loop signals the detectors "
        "see (the fault acts on it)", optional=True, choices=AIRCRAFT_SURFACES,
        default_doc="the left surface of `surface`: left_elevator or left_inboard_aileron",
        example="left_inboard_aileron")
    fmu: str | None = key("str", "FMI 2.0/3.0 co-simulation FMU that replaces the built-in "
                          "servo-loop plant (path relative to the working directory; "
                          "`fdd-campaign fmu build` makes the built-in one)", optional=True,
                          default_doc="built-in plant", example="servo.fmu", nonempty=True)
    push_parameters: bool = key("bool", "set each run's true plant parameters (Kci, SdP, "
                                "SdP_ref, Ka, r_mm, x_min, x_max, hm_delta, hm_0, "
                                "stop_min_rad, stop_max_rad) into the FMU parameters of the "
                                "same names", True)
    variables: PlantVariables = sub_table(PlantVariables, "FMU variable of each engine "
                                          "signal (defaults: the built-in servo-loop FMU)")


@dataclass(frozen=True, kw_only=True)
class CampaignConfig:
    """A validated campaign (frozen, hashable). Build it with :func:`load_config` or
    :meth:`from_dict`; :meth:`to_json` is its canonical form."""

    campaign: CampaignSection = section(CampaignSection, "campaign", "What is simulated and "
                                        "how it is sampled.")
    envelope: EnvelopeSection = section(EnvelopeSection, "envelope", "Flight envelope "
                                        "([CHEN] Table 1). Lists are sorted and must not "
                                        "repeat a value.")
    uncertainty: UncertaintySection = section(
        UncertaintySection, "uncertainty", "Measurement and estimation errors ([CHEN] Table "
        "2), uniform: grid uses {−w, 0, +w}, mc samples U(−w, w).")
    mismatch: MismatchSection = section(
        MismatchSection, "mismatch", "Plant/model mismatch beyond [CHEN] Table 2 (est., "
        "docs/physics.md §6), uniform, sampled per run.")
    faults: FaultsSection = section(
        FaultsSection, "faults", "Fault sampling: onset uniform in [onset_min_s, duration_s − "
        "onset_before_end_s] (must not be empty); magnitudes uniform in the [low, high] "
        "ranges of the sub-tables; the sign (direction) is always random.")
    groups: tuple[GroupSpec, ...] = section(
        GroupSpec, "group", "Run groups (at least one). design = \"mc\": count runs per "
        "manoeuvre; design = \"grid\": one run per realistic case and manoeuvre, no count. "
        "A fixed flight-point coordinate replaces that envelope axis.", array=True)
    detectors: tuple[DetectorSpec, ...] = section(
        DetectorSpec, "detector", "Detectors evaluated (at least one; labels unique).",
        array=True)
    requirements: RequirementsSection = section(
        RequirementsSection, "requirements", "Requirements used for scoring and by "
        "`fdd-campaign gate`.")
    learning: LearningSection = section(
        LearningSection, "learning", "Fault-free learning set for detectors that fit "
        "thresholds.")
    runner: RunnerSection = section(RunnerSection, "runner", "Execution (does not change "
                                    "any result).")
    plant: PlantSection = section(
        PlantSection, "plant", "The plant the runs are simulated on: the built-in servo-loop "
        "(default), the aircraft in the loop (docs/aircraft.md), or an FMU (docs/fmu.md). "
        "With an FMU the engine keeps the FCC, the sensors and the command- and sensor-side "
        "faults; the FMU is the physical plant.")
    source: str = field(default="<dict>", compare=False, repr=False)

    # -- canonical forms ------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain JSON-able dict in schema order; optional keys left unset are omitted. It
        is itself a valid campaign file content (``from_dict(c.to_dict()) == c``)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            meta = f.metadata
            if "section" not in meta:
                continue
            value = getattr(self, f.name)
            if meta["array"]:
                out[meta["section"]] = [_table_to_dict(item) for item in value]
            else:
                out[meta["section"]] = _table_to_dict(value)
        return out

    def to_json(self) -> str:
        """Canonical JSON (sorted keys, no spaces): equal configs give equal strings."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"),
                          ensure_ascii=False, allow_nan=False)

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "<dict>") -> "CampaignConfig":
        """Validate *data* (the content of a campaign file) and freeze it; raises
        :class:`ConfigError` listing every problem."""
        return _validate(data, source)

    @property
    def detector_labels(self) -> tuple[str, ...]:
        return tuple(d.label for d in self.detectors)


# ----------------------------------------------------------------------------------------
# Schema walking
# ----------------------------------------------------------------------------------------
def _sections() -> Iterator[tuple[str, type, str, bool]]:
    """(toml path, dataclass, doc, is_array) of every table of the file, in file order."""
    for f in fields(CampaignConfig):
        meta = f.metadata
        if "section" not in meta:
            continue
        yield meta["section"], meta["cls"], meta["doc"], meta["array"]
        for sf in fields(meta["cls"]):
            if "table" in sf.metadata:
                yield (f"{meta['section']}.{sf.name}", sf.metadata["table"],
                       sf.metadata["doc"], False)


def _leaf_fields(cls: type) -> list[dataclasses.Field]:
    return [f for f in fields(cls) if "key" in f.metadata]


def _table_fields(cls: type) -> list[dataclasses.Field]:
    return [f for f in fields(cls) if "table" in f.metadata]


def _section_names() -> list[str]:
    return [f.metadata["section"] for f in fields(CampaignConfig) if "section" in f.metadata]


def _table_to_dict(obj) -> dict:
    out: dict[str, Any] = {}
    for f in fields(obj):
        value = getattr(obj, f.name)
        if "key" in f.metadata:
            if value is not None:
                out[f.name] = _thaw(value, f.metadata["key"].kind)
        elif "table" in f.metadata:
            out[f.name] = _table_to_dict(value)
    return out


# ----------------------------------------------------------------------------------------
# Formatting helpers
# ----------------------------------------------------------------------------------------
def _num(x: float) -> str:
    return f"{x:g}" if abs(x) < 1e6 else repr(x)


def _range_text(spec: Key, name: str = "value") -> str:
    lo, hi = spec.lo, spec.hi
    unit = f" {spec.unit}" if spec.unit and spec.unit != "-" else ""
    lo_op = "<" if spec.lo_open else "≤"
    if lo is not None and hi is not None:
        return f"{_num(lo)} {lo_op} {name} ≤ {_num(hi)}{unit}"
    if lo is not None:
        return f"{name} {'>' if spec.lo_open else '≥'} {_num(lo)}{unit}"
    if hi is not None:
        return f"{name} ≤ {_num(hi)}{unit}"
    return ""


def _out_of_range(spec: Key, x: float) -> bool:
    if not math.isfinite(x):
        return True
    if spec.lo is not None and (x < spec.lo or (spec.lo_open and x <= spec.lo)):
        return True
    return spec.hi is not None and x > spec.hi


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k, ensure_ascii=False)


def _toml_value(v: Any) -> str:
    """A TOML literal for a plain value (str, bool, int, float, list, dict)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        if not v:
            return "{}"
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


_TOML_TYPE = {str: "string", bool: "boolean", int: "integer", float: "float", list: "array",
              dict: "table"}


def _type_word(value: Any) -> str:
    for t, word in _TOML_TYPE.items():
        if type(value) is t:
            return word
    return type(value).__name__.replace("datetime", "date-time")


def _shown_default(spec: Key, value: Any) -> Any:
    """The default as a user would write it (``["all"]`` for every manoeuvre)."""
    if spec.kind == "names" and tuple(value) == spec.choices:
        return ["all"]
    return _thaw(value, spec.kind)


def _example(spec: Key, default: Any) -> Any:
    if spec.example is not None:
        return spec.example
    if default is not MISSING and default is not None:
        return _shown_default(spec, default)
    return spec.lo if spec.lo is not None else 1


# ----------------------------------------------------------------------------------------
# Freezing
# ----------------------------------------------------------------------------------------
def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return FrozenTable(tuple((k, _freeze(value[k])) for k in sorted(value)))
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v) for v in value)
    return value


def _thaw_value(value: Any) -> Any:
    if isinstance(value, FrozenTable):
        return {k: _thaw_value(v) for k, v in value.items}
    if isinstance(value, tuple):
        return [_thaw_value(v) for v in value]
    return value


def _thaw(value: Any, kind: str) -> Any:
    if kind in ("table", "fault_seconds"):
        return {k: _thaw_value(v) for k, v in value}
    return _thaw_value(value)


# ----------------------------------------------------------------------------------------
# Validation
# ----------------------------------------------------------------------------------------
class _Bad:
    """Marker of a value that failed validation (its error is already recorded)."""

    def __repr__(self):
        return "<invalid>"


_BAD = _Bad()


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _convert(spec: Key, name: str, value: Any, path: str, errors: list[str],
             default: Any = MISSING) -> Any:
    """Check and convert one value of the file to its frozen form (or ``_BAD``)."""
    kind = spec.kind
    got = f"got {_type_word(value)} {_short(value)}"
    fix = f"fix: e.g. {name} = {_toml_value(_example(spec, default))}"

    def bad(msg: str) -> _Bad:
        errors.append(f"{path}: {msg}")
        return _BAD

    if kind in ("str", "choice"):
        if not isinstance(value, str):
            return bad(f"expected a string in quotes, {got}; {fix}")
        if kind == "choice" and value not in spec.choices:
            return bad(f"unknown {name} {value!r}{suggest(value, spec.choices)}; "
                       f"allowed: {', '.join(spec.choices)}")
        if spec.nonempty and not value.strip():
            return bad(f"must not be empty; {fix}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            return bad(f"expected true or false (no quotes), {got}")
        return value
    if kind == "int":
        if not isinstance(value, int) or isinstance(value, bool):
            return bad(f"expected an integer, {got}; {fix}")
        if _out_of_range(spec, value):
            return bad(f"{value} is out of range; allowed: {_range_text(spec, name)}")
        return value
    if kind == "float":
        if not _is_number(value):
            return bad(f"expected a number, {got}; {fix}")
        if _out_of_range(spec, float(value)):
            return bad(f"{_num(value)} is out of range; allowed: {_range_text(spec, name)}")
        return float(value)
    if kind == "floats":
        if not isinstance(value, list) or not value:
            return bad(f"expected a non-empty list of numbers, {got}; {fix}")
        ok = True
        for i, x in enumerate(value):
            if not _is_number(x):
                errors.append(f"{path}[{i}]: expected a number, got {_type_word(x)} "
                              f"{_short(x)}; {fix}")
                ok = False
            elif _out_of_range(spec, float(x)):
                errors.append(f"{path}[{i}]: {_num(x)} is out of range; allowed: "
                              f"{_range_text(spec)}")
                ok = False
        if not ok:
            return _BAD
        vals = sorted(float(x) for x in value)
        dup = sorted({x for x in vals if vals.count(x) > 1})
        if dup:
            return bad(f"value {_num(dup[0])} is repeated; fix: list each value once")
        return tuple(vals)
    if kind == "pair":
        if not (isinstance(value, list) and len(value) == 2 and all(map(_is_number, value))):
            return bad(f"expected [low, high] (two numbers), {got}; {fix}")
        low, high = float(value[0]), float(value[1])
        ok = True
        for label, x in (("low", low), ("high", high)):
            if _out_of_range(spec, x):
                errors.append(f"{path}: {label} {_num(x)} is out of range; allowed: "
                              f"{_range_text(spec)}")
                ok = False
        if ok and low > high:
            return bad(f"low {_num(low)} > high {_num(high)}; fix: write [low, high] with "
                       f"low ≤ high, e.g. {name} = [{_num(high)}, {_num(low)}]")
        return (low, high) if ok else _BAD
    if kind == "names":
        if not (isinstance(value, list) and value and all(isinstance(x, str) for x in value)):
            return bad(f"expected a non-empty list of names or [\"all\"], {got}; {fix}")
        if "all" in value:
            if len(value) > 1:
                return bad("\"all\" cannot be combined with other names; fix: write "
                           f"{name} = [\"all\"] or list the names")
            return tuple(spec.choices)
        ok = True
        for i, x in enumerate(value):
            if x not in spec.choices:
                errors.append(f"{path}[{i}]: unknown manoeuvre {x!r}"
                              f"{suggest(x, spec.choices)}; allowed: "
                              f"{', '.join(spec.choices)}, or [\"all\"]")
                ok = False
        if ok and len(set(value)) != len(value):
            return bad("a name is repeated; fix: list each name once")
        return tuple(c for c in spec.choices if c in value) if ok else _BAD
    if kind == "table":
        if not isinstance(value, dict):
            return bad(f"expected a table, {got}; fix: e.g. {name} = "
                       f"{_toml_value(spec.example or {})}")
        ok = _check_plain(value, path, errors)
        return _freeze(value).items if ok else _BAD
    if kind == "fault_seconds":
        if not isinstance(value, dict):
            return bad(f"expected a table of fault = seconds, {got}; fix: e.g. "
                       f"{name} = {{ runaway = 0.5 }}")
        merged = dict(REQUIRED_DETECTION_TIME_S)
        ok = True
        for k, x in value.items():
            if k not in spec.choices:
                errors.append(f"{path}.{k}: unknown fault {k!r}{suggest(k, spec.choices)}; "
                              f"allowed: {', '.join(spec.choices)}")
                ok = False
            elif not _is_number(x):
                errors.append(f"{path}.{k}: expected a number of seconds, got "
                              f"{_type_word(x)} {_short(x)}; fix: e.g. {k} = 1.0")
                ok = False
            elif _out_of_range(spec, float(x)):
                errors.append(f"{path}.{k}: {_num(x)} is out of range; allowed: "
                              f"{_range_text(spec, k)}")
                ok = False
            else:
                merged[k] = float(x)
        return tuple((k, merged[k]) for k in spec.choices) if ok else _BAD
    raise AssertionError(f"unknown kind {kind!r} in the schema")  # schema bug, not input


def _check_plain(value: Any, path: str, errors: list[str]) -> bool:
    """Detector parameters must be plain JSON-able values (no dates or times)."""
    if isinstance(value, dict):
        return all([_check_plain(v, f"{path}.{k}", errors) for k, v in value.items()])
    if isinstance(value, list):
        return all([_check_plain(v, f"{path}[{i}]", errors) for i, v in enumerate(value)])
    if isinstance(value, float) and not math.isfinite(value):
        errors.append(f"{path}: {value!r} is not allowed; fix: use a finite number")
        return False
    if isinstance(value, (str, int, float, bool)):
        return True
    errors.append(f"{path}: {_type_word(value)} values are not supported; fix: use a "
                  "string, number, boolean, list or table")
    return False


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _build_table(cls: type, raw: Any, path: str, errors: list[str]) -> dict:
    """Check one table against dataclass *cls*: unknown keys, types, ranges, defaults."""
    leaves = {f.name: f for f in _leaf_fields(cls)}
    subs = {f.name: f for f in _table_fields(cls)}
    allowed = list(leaves) + list(subs)
    out: dict[str, Any] = {"__present__": set()}
    for k in raw:
        if k not in allowed:
            errors.append(f"{path}.{k}: unknown key{suggest(k, allowed)}; allowed: "
                          f"{', '.join(allowed)}")
    for name, f in leaves.items():
        spec: Key = f.metadata["key"]
        p = f"{path}.{name}"
        if name in raw and raw[name] is not None:
            out["__present__"].add(name)
            out[name] = _convert(spec, name, raw[name], p, errors, f.default)
        elif spec.required:
            errors.append(f"{p}: missing required key; fix: add {name} = "
                          f"{_toml_value(_example(spec, MISSING))} to "
                          f"[{path.split('[')[0]}]")
            out[name] = _BAD
        else:
            out[name] = f.default
    for name, f in subs.items():
        p = f"{path}.{name}"
        sub_raw = raw.get(name, {})
        if not isinstance(sub_raw, dict):
            errors.append(f"{p}: expected a table [{p}], got {_type_word(sub_raw)}; fix: "
                          f"write the keys under a [{p}] header")
            sub_raw = {}
        out[name] = _build_table(f.metadata["table"], sub_raw, p, errors)
    return out


def _ok(*values: Any) -> bool:
    return not any(v is _BAD for v in values)


def _validate(data: Any, source: str) -> CampaignConfig:
    errors: list[str] = []
    if not isinstance(data, Mapping):
        raise ConfigError([f"<top>: expected a table of sections, got {_type_word(data)}"],
                          source)
    names = _section_names()
    for k in data:
        if k not in names:
            errors.append(f"{k}: unknown section [{k}]{suggest(k, names)}; allowed sections: "
                          f"{', '.join(names)}")
    data = _migrate(data, errors)
    values: dict[str, Any] = {}
    for f in fields(CampaignConfig):
        meta = f.metadata
        if "section" not in meta:
            continue
        sec = meta["section"]
        raw = data.get(sec)
        if meta["array"]:
            if raw is None:
                raw = []
            if isinstance(raw, dict):
                errors.append(f"{sec}: expected an array of tables; fix: write [[{sec}]] "
                              f"(double brackets) before each {sec}")
                raw = [raw]
            if not isinstance(raw, list) or not all(isinstance(x, dict) for x in raw):
                errors.append(f"{sec}: expected [[{sec}]] tables, got {_type_word(raw)}")
                raw = []
            if not raw:
                example = _INIT_EXAMPLES[sec][0]
                body = "; ".join(f"{k} = {_toml_value(v)}" for k, v in example.items())
                errors.append(f"{sec}: no [[{sec}]] table; fix: add at least one, e.g. "
                              f"[[{sec}]] with {body}")
            values[f.name] = [_build_table(meta["cls"], item, f"{sec}[{i}]", errors)
                              for i, item in enumerate(raw)]
        else:
            if raw is None:
                raw = {}
            if not isinstance(raw, dict):
                errors.append(f"{sec}: expected a table [{sec}], got {_type_word(raw)}; fix: "
                              f"write [{sec}] (single brackets) once")
                raw = {}
            values[f.name] = _build_table(meta["cls"], raw, sec, errors)
    _cross_checks(values, errors)
    if errors:
        raise ConfigError(errors, source)
    return _instantiate(values, source)


#: Keys that moved: (old section, old key) → (new section, new key).
MOVED_KEYS: dict[tuple[str, str], tuple[str, str]] = {
    ("campaign", "plant"): ("plant", "kind"),
    ("campaign", "monitored_surface"): ("plant", "monitored_surface"),
}


def _migrate(data: Mapping, errors: list[str]) -> Mapping:
    """*data* with the keys of :data:`MOVED_KEYS` under their new names: a campaign file
    written with an old spelling keeps working, with a one-line FutureWarning naming the new
    one. The old and the new spelling together, with different values, is an error."""
    moves = [(old, new) for old, new in MOVED_KEYS.items()
             if isinstance(data.get(old[0]), Mapping) and old[1] in data[old[0]]]
    if not moves:
        return data
    out = {k: dict(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    for (sec, key_), (new_sec, new_key) in moves:
        value = out[sec].pop(key_)
        target = out.setdefault(new_sec, {})
        if not isinstance(target, dict):
            continue                     # reported by the section check
        if new_key in target and target[new_key] != value:
            errors.append(f"{sec}.{key_}: old spelling of {new_sec}.{new_key}, which is also "
                          f"set, to another value; fix: remove {sec}.{key_}")
            continue
        target.setdefault(new_key, value)
        warnings.warn(f"[{sec}] {key_} is now [{new_sec}] {new_key}; the old spelling still "
                      "works", FutureWarning, stacklevel=4)
    return out


def _cross_checks(v: dict, errors: list[str]) -> None:
    """Rules that involve several keys (run after every key was checked on its own)."""
    camp, faults = v["campaign"], v["faults"]
    design, duration = camp["design"], camp["duration_s"]

    # keys that only apply to Monte Carlo designs
    def only_mc(table: dict, path: str, cls: type) -> None:
        for f in _leaf_fields(cls):
            if f.metadata["key"].only == "mc" and design == "grid":
                if f.name in table["__present__"]:
                    errors.append(f"{path}.{f.name}: only used with design = \"mc\"; fix: "
                                  f"remove it (grid runs one run per case)")
                table[f.name] = None

    only_mc(camp, "campaign", CampaignSection)

    # plant level: the monitored surface belongs to the aircraft plant
    plant = v["plant"]
    if plant["kind"] == "actuator" and plant.get("monitored_surface") is not None:
        errors.append("plant.monitored_surface: only used with kind = \"aircraft\"; fix: "
                      "remove it or set [plant] kind = \"aircraft\"")

    # onset window
    if _ok(duration, faults["onset_min_s"], faults["onset_before_end_s"]):
        latest = duration - faults["onset_before_end_s"]
        if faults["onset_min_s"] > latest:
            errors.append(
                f"faults.onset_min_s: empty onset window [{_num(faults['onset_min_s'])}, "
                f"{_num(latest)}] s (duration_s {_num(duration)} − onset_before_end_s "
                f"{_num(faults['onset_before_end_s'])}); fix: lower onset_min_s or "
                f"onset_before_end_s, or lengthen campaign.duration_s")

    # groups
    explicit: dict[str, str] = {}
    for i, g in enumerate(v["groups"]):
        p = f"group[{i}]"
        only_mc(g, p, GroupSpec)
        if design == "mc" and g["count"] is None:
            errors.append(f"{p}.count: missing; required with design = \"mc\" (runs per "
                          f"manoeuvre); fix: add count = 10")
        fault = g["fault"]
        if _ok(fault):
            if fault == "none":
                for k in ("onset_s", "magnitude", "freq_hz", "sign"):
                    if g[k] is not None and _ok(g[k]):
                        errors.append(f"{p}.{k}: a fault-free group (fault = \"none\") has "
                                      f"no {k}; fix: remove it")
            else:
                if fault not in FAULT_MAGNITUDE_KEY and g["magnitude"] is not None \
                        and _ok(g["magnitude"]):
                    errors.append(f"{p}.magnitude: fault {fault!r} has no magnitude; "
                                  f"allowed only with: {', '.join(FAULT_MAGNITUDE_KEY)}; "
                                  "fix: remove it")
                elif fault in FAULT_MAGNITUDE_KEY and _ok(g["magnitude"]) \
                        and g["magnitude"] is not None:
                    sub, k = FAULT_MAGNITUDE_KEY[fault]
                    spec = _spec(FaultsSection, sub, k)
                    if _out_of_range(spec, g["magnitude"]):
                        errors.append(f"{p}.magnitude: {_num(g['magnitude'])} is out of range "
                                      f"for {fault}; allowed: "
                                      f"{_range_text(spec, 'magnitude')}")
                if fault not in SIGNED_FAULTS and g["sign"] is not None and _ok(g["sign"]):
                    errors.append(f"{p}.sign: fault {fault!r} has no direction; allowed only "
                                  f"with: {', '.join(SIGNED_FAULTS)}; fix: remove it")
                if fault not in OFC_FAULTS and g["freq_hz"] is not None and _ok(g["freq_hz"]):
                    errors.append(f"{p}.freq_hz: only for {', '.join(OFC_FAULTS)}; fix: "
                                  "remove it")
                if _ok(g["onset_s"], duration) and g["onset_s"] is not None \
                        and g["onset_s"] >= duration:
                    errors.append(f"{p}.onset_s: {_num(g['onset_s'])} s is not before the end "
                                  f"of the run; allowed: 0 ≤ onset_s < duration_s = "
                                  f"{_num(duration)} s")
        start = g["manoeuvre_start_s"]
        if _ok(start, duration) and start is not None and start >= duration:
            errors.append(f"{p}.manoeuvre_start_s: {_num(start)} s is not before the end of "
                          f"the run; allowed: 0 ≤ manoeuvre_start_s < duration_s = "
                          f"{_num(duration)} s")
        name = g["name"]
        if name is not None and _ok(name):
            if name in explicit:
                errors.append(f"{p}.name: duplicate group name {name!r} (also "
                              f"{explicit[name]}); fix: give each group a unique name")
            explicit[name] = p
    # derived names (unique, never clashing with explicit ones)
    taken = set(explicit)
    for g in v["groups"]:
        if g["name"] is None and _ok(g["fault"], g["manoeuvres"]):
            man = g["manoeuvres"]
            base = f"{g['fault']}@{'all' if man == MANOEUVRES else '+'.join(man)}"
            name, n = base, 1
            while name in taken:
                n += 1
                name = f"{base}#{n}"
            g["name"] = name
            taken.add(name)

    # detectors
    _check_detectors(v["detectors"], camp, v["plant"], errors)

    # plant: the FMU keys mean nothing without an FMU (defaults written out are harmless)
    if plant["fmu"] is None:
        given = [k for k in ("push_parameters",) if k in plant["__present__"]
                 and plant[k] != PlantSection.__dataclass_fields__[k].default]
        given += [f"variables.{f.name}" for f in _leaf_fields(PlantVariables)
                  if f.name in plant["variables"]["__present__"]
                  and plant["variables"][f.name] != f.default]
        for k in given:
            errors.append(f"plant.{k}: only used with an FMU plant; fix: set [plant] fmu = "
                          "\"servo.fmu\" or remove it")
    elif plant["kind"] == "aircraft":
        errors.append("plant.fmu: an FMU replaces the single actuator servo-loop, but "
                      "[plant] kind = \"aircraft\"; fix: set [plant] kind = "
                      "\"actuator\" or remove [plant] fmu")


def _spec(cls: type, sub: str, name: str) -> Key:
    sub_cls = next(f.metadata["table"] for f in _table_fields(cls) if f.name == sub)
    return next(f.metadata["key"] for f in _leaf_fields(sub_cls) if f.name == name)


def _check_detectors(dets: list[dict], camp: dict, plant: dict, errors: list[str]) -> None:
    from detectors.registry import (
        DetectorSpecError,
        available_detectors,
        load_detector_class,
        parameter_errors,
    )

    registered = list(available_detectors())
    labels: dict[str, str] = {}
    for i, d in enumerate(dets):
        p = f"detector[{i}]"
        name = d["name"]
        if _ok(name) and d["label"] is None:
            d["label"] = name
        label = d["label"]
        if _ok(label) and label is not None:
            if label in labels:
                errors.append(f"{p}.label: duplicate label {label!r} (also {labels[label]}); "
                              "fix: give each [[detector]] a unique label = \"…\"")
            labels[label] = p
        if not _ok(name):
            continue
        if name not in registered:
            errors.append(f"{p}.name: unknown detector {name!r}{suggest(name, registered)}; "
                          f"allowed: {', '.join(sorted(registered))} (third-party detectors "
                          "register through the entry-point group fdd_campaign.detectors)")
            continue
        if not _ok(d["params"]):
            continue
        try:
            problems = parameter_errors(name, _thaw(d["params"], "table"))
            cls = load_detector_class(name)
        except DetectorSpecError as exc:
            errors.append(f"{p}.name: {exc}")
            continue
        for msg in problems:
            hint = "" if "allowed:" in msg else f"; parameters and defaults: " \
                f"{_signature_text(cls)}"
            errors.append(f"{p}.params: {msg}{hint}")
        caps = getattr(cls, "capabilities", None)
        if caps is not None and _ok(camp["surface"], camp["pressure_sensor"], plant["kind"],
                                    plant["monitored_surface"]):
            built = get_plant(plant["kind"])
            surface = built.run_surface(camp["surface"], plant["monitored_surface"])
            for msg in incompatibilities({name: caps}, built, surface,
                                         pressure_sensor=camp["pressure_sensor"]):
                errors.append(f"{p}.name: {msg}")


def _signature_text(cls: type) -> str:
    parts = []
    for prm in inspect.signature(cls.__init__).parameters.values():
        if prm.name == "self" or prm.kind in (prm.VAR_POSITIONAL, prm.VAR_KEYWORD):
            continue
        parts.append(prm.name if prm.default is prm.empty else f"{prm.name}={prm.default!r}")
    return ", ".join(parts) or "(none)"


def _instantiate(values: dict, source: str) -> CampaignConfig:
    def build(cls: type, table: dict):
        kwargs = {}
        for f in fields(cls):
            if "key" in f.metadata:
                kwargs[f.name] = table[f.name]
            elif "table" in f.metadata:
                kwargs[f.name] = build(f.metadata["table"], table[f.name])
        return cls(**kwargs)

    kwargs: dict[str, Any] = {}
    for f in fields(CampaignConfig):
        meta = f.metadata
        if "section" not in meta:
            continue
        if meta["array"]:
            kwargs[f.name] = tuple(build(meta["cls"], t) for t in values[f.name])
        else:
            kwargs[f.name] = build(meta["cls"], values[f.name])
    return CampaignConfig(**kwargs, source=source)


# ----------------------------------------------------------------------------------------
# Files and presets
# ----------------------------------------------------------------------------------------
def _preset_dir():
    return resources.files(PRESET_PACKAGE).joinpath(PRESET_DIR)


def _preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in _preset_dir().iterdir() if p.name.endswith(".toml"))


def preset_path(name: str) -> Path:
    """Path of the shipped preset *name* (``ConfigError`` if there is none)."""
    names = _preset_names()
    if name not in names:
        raise ConfigError([f"{name}: unknown preset{suggest(name, names)}; allowed: "
                           f"{', '.join(names)}, or a path to a .toml file"], "<preset>")
    return Path(str(_preset_dir().joinpath(f"{name}.toml")))


def list_presets() -> dict[str, str]:
    """Shipped presets: name → description (from their ``[campaign] description``)."""
    out = {}
    for name in _preset_names():
        with open(preset_path(name), "rb") as fh:
            data = tomllib.load(fh)
        out[name] = str(data.get("campaign", {}).get("description", ""))
    return out


_TOML_POS = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")


def _read_toml(path: Path, source: str) -> dict:
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError([f"<file>: not UTF-8 text ({exc.reason} at byte {exc.start}); fix: "
                           "save the file as UTF-8"], source) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = _TOML_POS.search(msg)
        where = f"line {m.group(1)}, column {m.group(2)}" if m else "unknown position"
        problem = _TOML_POS.sub("", msg)
        raise ConfigError([f"<file> {where}: TOML syntax error: {problem}; fix: check the "
                           "quotes, brackets, commas and '=' on that line"], source) from None


def looks_like_path(text: str) -> bool:
    """Whether a campaign spec is written as a file path rather than a preset name."""
    return text.endswith(".toml") or "/" in text or "\\" in text


def load_config(spec: str | Path) -> CampaignConfig:
    """Load and validate a campaign: a preset name (``"smoke"``) or a path to a .toml file.

    Raises :class:`ConfigError` listing every problem of the file at once.
    """
    text = str(spec)
    if not isinstance(spec, Path) and not looks_like_path(text) and not Path(text).is_file():
        names = _preset_names()
        if text not in names:
            from .suite import list_suites

            if text in list_suites():
                raise ConfigError([f"{text}: a suite of campaigns, not one campaign; run it "
                                   "with 'fdd-campaign run' or 'plan' (docs/suites.md)"], text)
            raise ConfigError([f"{text}: unknown preset{suggest(text, names)}; allowed: "
                               f"{', '.join(names)}, or a path to a .toml file"], text)
        path = preset_path(text)
        source = f"preset {text!r}"
    else:
        path = Path(text)
        source = str(path)
        if not path.is_file():
            what = "is a directory" if path.is_dir() else "file not found"
            raise ConfigError([f"{path}: {what}; fix: check the path, or use a preset: "
                               f"{', '.join(_preset_names())}"], source)
    data = _read_toml(path, source)
    if isinstance(data, dict) and "suite" in data:
        raise ConfigError([f"{path}: a suite file ([suite] table), not a campaign file; run it "
                           "with 'fdd-campaign run' or 'plan' (docs/suites.md)"], source)
    return _validate(data, source)


def with_overrides(config: CampaignConfig, seed: int | None = None, *,
                   chunk_size: int | None = None,
                   values: Mapping[str, Any] | None = None) -> CampaignConfig:
    """A copy of *config* with some values changed and validated again.

    *values* maps dotted paths to new values, e.g. ``{"campaign.duration_s": 30.0,
    "group[0].count": 5}``; *seed* and *chunk_size* are shortcuts for the command line.
    """
    changes = dict(values or {})
    if seed is not None:
        changes["campaign.seed"] = seed
    if chunk_size is not None:
        changes["runner.chunk_size"] = chunk_size
    data = config.to_dict()
    errors = []
    for dotted, value in changes.items():
        parts = dotted.split(".")
        node: Any = data
        try:
            for part in parts[:-1]:
                m = re.fullmatch(r"(\w+)\[(\d+)\]", part)
                node = node[m.group(1)][int(m.group(2))] if m else node.setdefault(part, {})
        except (KeyError, IndexError, TypeError):
            errors.append(f"{dotted}: no such table in the campaign")
            continue
        node[parts[-1]] = value
    if errors:
        raise ConfigError(errors, f"overrides of {config.source}")
    return _validate(data, f"{config.source} (with overrides)")


# ----------------------------------------------------------------------------------------
# Generated documents: annotated starting file and Markdown reference
# ----------------------------------------------------------------------------------------
#: Entries of the array tables written into the starting file (and suggested in errors).
_INIT_EXAMPLES: dict[str, list[dict[str, Any]]] = {
    "group": [
        {"fault": "none", "count": 10},
        {"fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 10},
        {"fault": "runaway", "manoeuvres": ["cruise"], "count": 10},
    ],
    "detector": [{"name": "position-monitor"}],
}


def _key_comment(spec: Key, name: str) -> str:
    text = spec.doc
    allowed = _allowed_text(spec, name)
    if allowed:
        text += f"; allowed: {allowed}"
    elif spec.unit and spec.unit != "-":
        text += f" [{spec.unit}]"
    if spec.required:
        text += "; required"
    elif spec.optional:
        text += f"; default: {spec.default_doc}"
    if spec.source:
        text += f"; source: {spec.source}"
    return text


def _allowed_text(spec: Key, name: str = "value") -> str:
    if spec.kind == "choice":
        return ", ".join(spec.choices)
    if spec.kind == "names":
        return "any of " + ", ".join(spec.choices) + "; or [\"all\"]"
    if spec.kind == "fault_seconds":
        return "keys " + ", ".join(spec.choices) + "; each " + _range_text(spec, "value")
    if spec.kind == "table":
        return "the detector's keyword parameters"
    if spec.kind in ("int", "float"):
        return _range_text(spec, name)
    if spec.kind in ("floats", "pair"):
        return "each " + _range_text(spec, "value")
    return ""


def _wrap_comment(text: str, width: int = 90) -> list[str]:
    import textwrap

    return ["# " + line for line in textwrap.wrap(text, width - 2, break_on_hyphens=False)]


def init_text() -> str:
    """An annotated starting campaign file (every key with its doc); loads as is."""
    out = [
        "# Campaign file for fdd-campaign (reference: docs/campaign-file.md).",
        "# Check it with `fdd-campaign plan FILE --out DIR`, run it with "
        "`fdd-campaign run FILE --out DIR`.",
        "# Keys left out take the default written here; optional keys are shown commented.",
        "",
    ]
    for path, cls, doc, array in _sections():
        leaves = _leaf_fields(cls)
        if not leaves:
            continue
        if array:
            for n, example in enumerate(_INIT_EXAMPLES[path]):
                out.extend(_wrap_comment(doc) if n == 0 else [])
                out.append(f"[[{path}]]")
                for f in leaves:
                    spec = f.metadata["key"]
                    if f.name in example:
                        if n == 0:
                            out.extend(_wrap_comment(_key_comment(spec, f.name)))
                        out.append(f"{f.name} = {_toml_value(example[f.name])}")
                    elif n == 0:
                        out.extend(_wrap_comment(_key_comment(spec, f.name)))
                        out.append(f"# {f.name} = {_toml_value(_example(spec, f.default))}")
                out.append("")
            continue
        out.extend(_wrap_comment(doc))
        out.append(f"[{path}]")
        for f in leaves:
            spec = f.metadata["key"]
            out.extend(_wrap_comment(_key_comment(spec, f.name)))
            shown = _example(spec, f.default)
            prefix = "# " if spec.optional else ""
            out.append(f"{prefix}{f.name} = {_toml_value(shown)}")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _md_default(spec: Key, default: Any) -> str:
    if spec.required:
        return "required"
    if spec.optional:
        return spec.default_doc
    return f"`{_toml_value(_shown_default(spec, default))}`"


def schema_markdown() -> str:
    """The Markdown reference of the campaign file (``docs/campaign-file.md``)."""
    out = [
        "# The campaign file",
        "",
        "<!-- Generated from the schema in campaign/config.py by "
        "`python -m campaign.config --markdown > docs/campaign-file.md`; do not edit. -->",
        "",
        "A campaign is one TOML file: `fdd-campaign run FILE.toml --out DIR`, or a shipped "
        "preset by name (`fdd-campaign run smoke --out DIR`). `fdd-campaign init` writes an "
        "annotated starting file. Every section is optional except `[campaign]` (for its "
        "`name`), at least one `[[group]]` and at least one `[[detector]]`; every key left "
        "out takes its default.",
        "",
        "The whole file is checked before anything runs. Every problem is reported at once, "
        "each with its path in the file and how to fix it, for example:",
        "",
        "```text",
        "group[2].fault: unknown fault 'solid-jam' (did you mean 'solid_jam'?); allowed: "
        + ", ".join(FAULTS),
        "```",
        "",
        "Array tables are numbered from 0 in order of appearance (`group[0]` is the first "
        "`[[group]]`). Integers are accepted where a float is expected, not the reverse. "
        "A key that only applies to `design = \"mc\"` (`sampler`, `count`) is an error with "
        "`design = \"grid\"`, so nothing written in the file is silently ignored. The "
        "validated campaign is frozen; its canonical JSON (sorted keys, every default "
        "filled in, `[\"all\"]` expanded, envelope lists sorted) identifies the runs and is "
        "stored in the metadata of every result file.",
        "",
        "## Presets",
        "",
        "| preset | description |",
        "|---|---|",
    ]
    for name, desc in list_presets().items():
        out.append(f"| `{name}` | {_md_cell(desc)} |")
    out.append("")
    for path, cls, doc, array in _sections():
        leaves = _leaf_fields(cls)
        if not leaves:
            continue
        header = f"[[{path}]]" if array else f"[{path}]"
        out += [f"## `{header}`", "", doc, "",
                "| key | type | default | allowed | unit | description |",
                "|---|---|---|---|---|---|"]
        for f in leaves:
            spec = f.metadata["key"]
            desc = spec.doc + (f" (source: {spec.source})" if spec.source else "")
            unit = spec.unit if spec.unit and spec.unit != "-" else ""
            out.append("| " + " | ".join(_md_cell(c) for c in (
                f"`{f.name}`", KIND_NAMES[spec.kind], _md_default(spec, f.default),
                _allowed_text(spec, f.name), unit, desc)) + " |")
        out.append("")
    out += [
        "## Fault magnitudes",
        "",
        "A `[[group]]` `magnitude` is in the unit of the fault type's range:",
        "",
        "| fault | range key |",
        "|---|---|",
    ]
    for fault, (sub, k) in FAULT_MAGNITUDE_KEY.items():
        spec = _spec(FaultsSection, sub, k)
        out.append(f"| `{fault}` | `faults.{sub}.{k}` [{spec.unit}] |")
    others = [f for f in FAULT_TYPES if f not in FAULT_MAGNITUDE_KEY]
    out += ["", "Faults without a magnitude: " + ", ".join(f"`{f}`" for f in others) + ".", ""]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m campaign.config",
        description="Campaign-file tools. Example: python -m campaign.config --markdown > "
                    "docs/campaign-file.md")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--markdown", action="store_true", help="print the Markdown reference")
    group.add_argument("--init", action="store_true", help="print an annotated starting file")
    group.add_argument("--check", metavar="PRESET|FILE", help="validate a campaign file")
    args = parser.parse_args(argv)
    if args.markdown:
        sys.stdout.write(schema_markdown())
    elif args.init:
        sys.stdout.write(init_text())
    else:
        try:
            config = load_config(args.check)
        except ConfigError as exc:
            print(exc, file=sys.stderr)
            return 2
        print(f"{config.source}: ok ({len(config.groups)} groups, "
              f"{len(config.detectors)} detectors)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
