"""The campaign file as a whole: :class:`CampaignConfig`, its canonical forms and its
validation.

:class:`CampaignConfig` assembles the sections of :mod:`campaign.config.sections` into the
file (``[campaign]``, ``[envelope]``, …, ``[[group]]``, ``[[detector]]``, ``[plant]``).
:func:`validate` checks a whole file content — unknown sections, every table
(:func:`campaign.config.convert.build_table`), then the rules that involve several keys
(:mod:`campaign.config.rules`) — and raises one :class:`ConfigError` listing every
problem, or returns the frozen configuration. :meth:`CampaignConfig.to_json` is its
canonical form, used for run identity and stored in the metadata of every result file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from typing import Any, Iterator, Mapping

from scenarios.catalog import suggest

from .convert import ConfigError, build_table
from .keys import section, thaw
from .rules import check_rules, derive_group_names, migrate, normalise
from .sections import (
    ARRAY_EXAMPLES,
    CampaignSection,
    DetectorSpec,
    SystemSpec,
    EnvelopeSection,
    FaultsSection,
    GroupSpec,
    LearningSection,
    ManoeuvresSection,
    MismatchSection,
    PlantSection,
    RequirementsSection,
    RunnerSection,
    RunSpec,
    UncertaintySection,
)
from .text import toml_value, type_word

__all__ = ["CampaignConfig", "iter_tables", "section_names", "table_to_dict", "validate",
           "check_tables"]


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
        "2), uniform: grid uses {−w, 0, +w} (every deviation at once), mc samples each "
        "U(−w, w) on its own. The six aerodynamic coefficients are drawn independently; "
        "`aero` is the shorthand that sets all six, and a coefficient given by its own key "
        "(`cx`, `cy`, `cz`, `cl`, `cm`, `cn`) wins over it (docs/physics.md §6).")
    mismatch: MismatchSection = section(
        MismatchSection, "mismatch", "Plant/model mismatch beyond [CHEN] Table 2 (est., "
        "docs/physics.md §6), uniform, sampled per run. Ch0, Chα and Chδ are drawn "
        "independently; `hinge` is the shorthand that sets all three, and a coefficient given "
        "by its own key (`ch0`, `cha`, `chd`) wins over it.")
    faults: FaultsSection = section(
        FaultsSection, "faults", "Fault sampling: onset uniform in [onset_min_s, duration_s − "
        "max(onset_before_end_s, the fault's detection budget)] (must not be empty; the "
        "budget is 15 s for a disconnection, docs/physics.md §5); magnitudes uniform in the [low, "
        "high] ranges of the sub-tables; the sign (direction) is always random.")
    groups: tuple[GroupSpec, ...] = section(
        GroupSpec, "group", "Run groups (at least one). design = \"mc\": count runs per "
        "manoeuvre; design = \"grid\": one run per realistic case and manoeuvre, no count. "
        "A fixed flight-point coordinate replaces that envelope axis. A file of [[run]] "
        "entries only needs none.", array=True, required_unless="run")
    runs: tuple[RunSpec, ...] = section(
        RunSpec, "run", "Explicit runs (optional): every value of one run's row given, "
        "replayed exactly after the runs of the groups, e.g. the regression corpus "
        "`worst.toml` that `fdd-campaign falsify` writes (docs/evidence.md). A run keeps its "
        "stream; with realistic_only its flight point must pass the realistic-envelope rule.",
        array=True, required=False)
    detectors: tuple[DetectorSpec, ...] = section(
        DetectorSpec, "detector", "Detectors evaluated (at least one; labels unique).",
        array=True)
    systems: tuple[SystemSpec, ...] = section(
        SystemSpec, "system", "Detection systems (optional): a set of the campaign's "
        "detectors whose alarm is the first alarm of any member, scored, gated, certified and "
        "reported like a detector. With a system, the missed-detection and detection-time "
        "requirements apply to the systems and to the detectors that belong to none; a "
        "member's are reported for information (docs/design.md §5, Detection systems).",
        array=True, required=False)
    requirements: RequirementsSection = section(
        RequirementsSection, "requirements", "Requirements used for scoring and by "
        "`fdd-campaign gate`.")
    learning: LearningSection = section(
        LearningSection, "learning", "Fault-free learning set for detectors that fit "
        "thresholds.")
    manoeuvres: ManoeuvresSection = section(
        ManoeuvresSection, "manoeuvres", "How the six manoeuvres are flown, at both plant "
        "levels (docs/physics.md §7): the normal-operations set or the stress set.")
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
                if not value and not meta["required"]:
                    continue       # an optional array left empty: not in the canonical form
                out[meta["section"]] = [table_to_dict(item) for item in value]
            else:
                out[meta["section"]] = table_to_dict(value)
        return out

    def to_json(self) -> str:
        """Canonical JSON (sorted keys, no spaces): equal configs give equal strings."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"),
                          ensure_ascii=False, allow_nan=False)

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "<dict>") -> "CampaignConfig":
        """Validate *data* (the content of a campaign file) and freeze it; raises
        :class:`ConfigError` listing every problem."""
        return validate(data, source)

    @property
    def detector_labels(self) -> tuple[str, ...]:
        return tuple(d.label for d in self.detectors)

    @property
    def system_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.systems)


# ----------------------------------------------------------------------------------------
# Walking the schema
# ----------------------------------------------------------------------------------------
def iter_tables() -> Iterator[tuple[str, type, str, bool]]:
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


def section_names() -> list[str]:
    """The TOML names of the top-level sections, in file order."""
    return [f.metadata["section"] for f in fields(CampaignConfig) if "section" in f.metadata]


def table_to_dict(obj) -> dict:
    """One validated table as plain values; optional keys left unset are omitted."""
    out: dict[str, Any] = {}
    for f in fields(obj):
        value = getattr(obj, f.name)
        if "key" in f.metadata:
            if value is not None:
                out[f.name] = thaw(value, f.metadata["key"].kind)
        elif "table" in f.metadata:
            out[f.name] = table_to_dict(value)
    return out


# ----------------------------------------------------------------------------------------
# Validation of a whole file
# ----------------------------------------------------------------------------------------
def validate(data: Any, source: str, *, requirement_names: bool = False) -> CampaignConfig:
    """Validate *data* (the content of a campaign file) and freeze it.

    *source* names the file in the error. Raises :class:`ConfigError` listing every
    problem: unknown sections, then each table's keys in file order, then the rules that
    involve several keys. With *requirement_names* the detectors ``[requirements]`` names
    must be the file's too (:func:`campaign.config.load.load_config` checks it before a
    campaign runs; a campaign read back from its directory is not refused for it, its
    requirements are corrected with ``--requirements FILE``).
    """
    if not isinstance(data, Mapping):
        raise ConfigError([f"<top>: expected a table of sections, got {type_word(data)}"],
                          source)
    errors: list[str] = []
    data = migrate(data, errors)
    values = normalise(check_tables(data, errors))
    check_rules(values, errors, requirement_names=requirement_names)
    if errors:
        raise ConfigError(errors, source)
    return _instantiate(derive_group_names(values), source)


def check_tables(data: Mapping, errors: list[str]) -> dict[str, Any]:
    """Check every section of *data* on its own (unknown sections, then each table's keys,
    in file order), appending the problems to *errors*.

    Returns the checked values by :class:`CampaignConfig` field name (``"groups"`` and
    ``"detectors"`` hold lists), each table as :func:`campaign.config.convert.build_table`
    gives it; the input of :mod:`campaign.config.rules`.
    """
    names = section_names()
    for k in data:
        if k not in names:
            errors.append(f"{k}: unknown section [{k}]{suggest(k, names)}; allowed sections: "
                          f"{', '.join(names)}")
    values: dict[str, Any] = {}
    for f in fields(CampaignConfig):
        meta = f.metadata
        if "section" not in meta:
            continue
        raw = data.get(meta["section"])
        if meta["array"]:
            other = meta["required_unless"]
            required = meta["required"] and not (other and data.get(other))
            values[f.name] = _check_array(meta["cls"], meta["section"], raw, errors,
                                          required)
        else:
            values[f.name] = _check_table(meta["cls"], meta["section"], raw, errors)
    return values


def _check_array(cls: type, sec: str, raw: Any, errors: list[str],
                 required: bool = True) -> list[dict]:
    """The checked tables of the array section ``[[sec]]`` (at least one when
    *required*)."""
    if raw is None:
        raw = []
    if isinstance(raw, dict):
        errors.append(f"{sec}: expected an array of tables; fix: write [[{sec}]] "
                      f"(double brackets) before each {sec}")
        raw = [raw]
    if not isinstance(raw, list) or not all(isinstance(x, dict) for x in raw):
        errors.append(f"{sec}: expected [[{sec}]] tables, got {type_word(raw)}")
        raw = []
    if not raw and required:
        example = ARRAY_EXAMPLES[sec][0]
        body = "; ".join(f"{k} = {toml_value(v)}" for k, v in example.items())
        errors.append(f"{sec}: no [[{sec}]] table; fix: add at least one, e.g. "
                      f"[[{sec}]] with {body}")
    return [build_table(cls, item, f"{sec}[{i}]", errors) for i, item in enumerate(raw)]


def _check_table(cls: type, sec: str, raw: Any, errors: list[str]) -> dict:
    """The checked table of the section ``[sec]`` (left out: every key takes its default)."""
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        errors.append(f"{sec}: expected a table [{sec}], got {type_word(raw)}; fix: "
                      f"write [{sec}] (single brackets) once")
        raw = {}
    return build_table(cls, raw, sec, errors)


def _instantiate(values: Mapping[str, Any], source: str) -> CampaignConfig:
    def build(cls: type, table: Mapping):
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
