"""The campaign file: schema, validation, presets and the generated reference.

A campaign is described by one TOML file (or a preset shipped in ``campaign/presets``).
The schema is defined once, as data: every key is a field of a frozen dataclass whose
metadata (:class:`Key`) gives its type, default, allowed values or range, unit, source and
a one-line description. From that single definition this package derives

* the validation (:func:`load_config`, :meth:`CampaignConfig.from_dict`), which collects
  every problem of a file, each with its path (``group[2].fault``) and how to fix it, and
  raises them together in one :class:`ConfigError`;
* the annotated starting file written by ``fdd-campaign init`` (:func:`init_text`);
* the Markdown reference ``docs/campaign-file.md`` (:func:`schema_markdown`), regenerated
  with ``python -m campaign.config --markdown > docs/campaign-file.md``.

A validated configuration is a tree of frozen dataclasses and tuples (hashable, no mutable
containers); :meth:`CampaignConfig.to_json` is its canonical form, used for run identity
and stored in the metadata of every result file.

The modules, each importing only those listed before it:

* :mod:`~campaign.config.keys` — how a key is declared (:class:`Key`, :func:`key`) and how
  values are stored frozen;
* :mod:`~campaign.config.text` — how values and ranges are written in messages and
  documents;
* :mod:`~campaign.config.convert` — checking one value or one table against its keys;
  :class:`ConfigError`;
* :mod:`~campaign.config.sections` — the tables of the file (``[campaign]``, ``[[group]]``,
  …) as frozen dataclasses;
* :mod:`~campaign.config.rules` — rules involving several keys, and the values they derive
  (detector labels, group names);
* :mod:`~campaign.config.schema` — :class:`CampaignConfig`, its canonical forms and the
  validation of a whole file;
* :mod:`~campaign.config.load` — presets, files, :func:`load_config`,
  :func:`with_overrides`;
* :mod:`~campaign.config.docs` — :func:`init_text`, :func:`schema_markdown` and the
  ``python -m campaign.config`` entry point.
"""

from scenarios.catalog import REQUIRED_DETECTION_TIME_S  # noqa: F401  (importable from here)

from .convert import ConfigError
from .docs import init_text, main, schema_markdown
from .keys import KIND_NAMES, FrozenTable, Key
from .load import (
    PRESET_DIR,
    PRESET_PLANTS,
    PRESET_PACKAGE,
    SCORING_REQUIREMENTS,
    list_presets,
    load_config,
    load_requirements,
    looks_like_path,
    preset_path,
    preset_plant_problem,
    read_toml,
    with_overrides,
)
from .schema import CampaignConfig
from .sections import (
    FAULT_MAGNITUDE_KEY,
    FLIGHT_POINT_RANGES,
    OFC_FAULTS,
    SIGNED_FAULT_DIRECTIONS,
    SIGNED_FAULTS,
    CampaignSection,
    DetectorSpec,
    EnvelopeSection,
    FaultsSection,
    GroupSpec,
    LearningSection,
    LiquidJamRanges,
    MismatchSection,
    OfcLiquidRanges,
    OfcSolidRanges,
    PlantSection,
    PlantVariables,
    RequirementsSection,
    RunawayRanges,
    RunnerSection,
    UncertaintySection,
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
    "load_requirements",
    "SCORING_REQUIREMENTS",
    "list_presets",
    "preset_path",
    "preset_plant_problem",
    "PRESET_PLANTS",
    "init_text",
    "schema_markdown",
    "with_overrides",
    "FAULT_MAGNITUDE_KEY",
    "looks_like_path",
    "read_toml",
    "main",
    # re-exported for callers that build or inspect configurations
    "KIND_NAMES",
    "FrozenTable",
    "PRESET_DIR",
    "PRESET_PACKAGE",
    "FLIGHT_POINT_RANGES",
    "OFC_FAULTS",
    "SIGNED_FAULT_DIRECTIONS",
    "SIGNED_FAULTS",
    "LiquidJamRanges",
    "OfcLiquidRanges",
    "OfcSolidRanges",
    "PlantVariables",
    "RunawayRanges",
]
