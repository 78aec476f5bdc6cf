"""Campaign files and presets: reading, loading by name or path, overriding values.

A campaign is given either as the name of a preset shipped in ``campaign/presets``
(``"smoke"``) or as a path to a TOML file; :func:`load_config` reads it and validates it
(:func:`campaign.config.schema.validate`). The shipped suites (``campaign/suites``,
loaded by :mod:`campaign.suite`) are listed here too, so that a suite given where a
campaign is expected is named as such.
"""

from __future__ import annotations

import re
import tomllib
import warnings
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from scenarios.catalog import suggest

from .convert import ConfigError, build_table, is_ok
from .keys import leaf_fields, thaw
from .rules import MagnitudeReadingNote, requirement_name_problems
from .schema import CampaignConfig, validate
from .sections import RequirementsSection
from .text import toml_value

__all__ = [
    "PRESET_PACKAGE",
    "PRESET_DIR",
    "SUITE_DIR",
    "shipped_dir",
    "shipped_names",
    "preset_path",
    "list_presets",
    "read_toml",
    "looks_like_path",
    "load_config",
    "with_overrides",
    "SCORING_REQUIREMENTS",
    "load_requirements",
    "PRESET_PLANTS",
    "preset_plant_problem",
]

#: Package holding the shipped campaign files.
PRESET_PACKAGE = "campaign"
#: Its folder of preset campaigns.
PRESET_DIR = "presets"
#: Its folder of suites of campaigns (:mod:`campaign.suite`).
SUITE_DIR = "suites"


# ----------------------------------------------------------------------------------------
# Shipped files
# ----------------------------------------------------------------------------------------
def shipped_dir(folder: str):
    """The package folder *folder* (:data:`PRESET_DIR` or :data:`SUITE_DIR`) as an
    :mod:`importlib.resources` traversable."""
    return resources.files(PRESET_PACKAGE).joinpath(folder)


def shipped_names(folder: str) -> list[str]:
    """Sorted names (file names without ``.toml``) of the TOML files in package folder
    *folder*."""
    return sorted(p.name[:-5] for p in shipped_dir(folder).iterdir()
                  if p.name.endswith(".toml"))


def preset_path(name: str) -> Path:
    """Path of the shipped preset *name* (``ConfigError`` if there is none)."""
    names = shipped_names(PRESET_DIR)
    if name not in names:
        raise ConfigError([f"{name}: unknown preset{suggest(name, names)}; allowed: "
                           f"{', '.join(names)}, or a path to a .toml file"], "<preset>")
    return Path(str(shipped_dir(PRESET_DIR).joinpath(f"{name}.toml")))


def list_presets() -> dict[str, str]:
    """Shipped presets: name → description (from their ``[campaign] description``)."""
    out = {}
    for name in shipped_names(PRESET_DIR):
        with open(preset_path(name), "rb") as fh:
            data = tomllib.load(fh)
        out[name] = str(data.get("campaign", {}).get("description", ""))
    return out


#: The plant kinds a shipped preset is valid on, and why, for the presets valid on fewer
#: than all of them: ``--plant`` naming another kind is refused before anything runs
#: (:func:`preset_plant_problem`).
PRESET_PLANTS: dict[str, tuple[tuple[str, ...], str]] = {
    name: (("actuator",),
           "its comb-interval uses the default kappa = [0.02, 0.02, 0.06], tuned on the "
           "actuator plant's learning runs (loop errors of a few mm) and not evaluated on the "
           "aircraft plant, where the control laws of model servo-4 drove the elevator servo "
           "into rate saturation (loop errors up to 40 mm) and that kappa broke [COMB] eq. 17 "
           "(|g^c| + g^r < 1; docs/aircraft.md §5). Fix: run it on the aircraft plant from a "
           "campaign file (fdd-campaign init) with [plant] kind = \"aircraft\" and "
           "params = { kappa = [0.01, 0.002, 0.012] } for comb-interval, valid there "
           "(docs/interval-detector.md), or run a preset valid there (e.g. smoke, chen-*, "
           "vanek-*)")
    for name in ("addsafe-mc", "comb-table1", "comb-table1-rod")
}


def preset_plant_problem(spec: str, kind: str) -> str | None:
    """Why the shipped preset *spec* cannot run on plant kind *kind* (None: it can, or *spec*
    is not a preset restricted in :data:`PRESET_PLANTS`), for the caller that names *kind*
    to head."""
    if str(spec) not in PRESET_PLANTS or kind in PRESET_PLANTS[str(spec)][0]:
        return None
    kinds, why = PRESET_PLANTS[str(spec)]
    return f"preset {spec!r} is valid on the {' and '.join(kinds)} plant only: {why}"


# ----------------------------------------------------------------------------------------
# Reading and loading
# ----------------------------------------------------------------------------------------
_TOML_POS = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")


def read_toml(path: Path, source: str) -> dict:
    """The content of TOML file *path*; a file that is not UTF-8 or not valid TOML raises
    :class:`ConfigError` (named *source*) giving the line and column of the problem."""
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
        names = shipped_names(PRESET_DIR)
        if text not in names:
            if text in shipped_names(SUITE_DIR):
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
                               f"{', '.join(shipped_names(PRESET_DIR))}"], source)
    data = read_toml(path, source)
    if isinstance(data, dict) and "suite" in data:
        raise ConfigError([f"{path}: a suite file ([suite] table), not a campaign file; run it "
                           "with 'fdd-campaign run' or 'plan' (docs/suites.md)"], source)
    if source.startswith("preset "):          # shipped, in the current reading
        return _validate_quietly(data, source)
    return validate(data, source, requirement_names=True)


def _validate_quietly(data, source: str) -> CampaignConfig:
    """:func:`validate` without the :class:`~campaign.config.rules.MagnitudeReadingNote`,
    for values already in the current reading (a shipped preset, a campaign re-validated)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MagnitudeReadingNote)
        return validate(data, source, requirement_names=True)


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
    return _validate_quietly(data, f"{config.source} (with overrides)")


# ----------------------------------------------------------------------------------------
# Requirements of a finished campaign
# ----------------------------------------------------------------------------------------
#: ``[requirements]`` keys that decide how each run is scored (its DTP, whether it counts as
#: detected): stored in the results, so a finished campaign cannot take other values of them
#: without being run again. The other keys are limits that only the gate and the report read.
SCORING_REQUIREMENTS: tuple[str, ...] = ("detection_time_s", "detection_window_s")


def load_requirements(path, stored: Mapping[str, Any], labels,
                      source: str | None = None) -> dict[str, Any]:
    """The ``[requirements]`` of TOML file *path* (a campaign file, or a file holding only
    that table), in place of *stored* (those of a finished campaign, in their JSON form), to
    gate and report that campaign again without recomputing it (``--requirements FILE``).

    The limits are read as in a campaign file (a limit left out takes its default); a key of
    :data:`SCORING_REQUIREMENTS` must keep the campaign's value (left out, it does); every
    detector named must be one of *labels* (the campaign's [[detector]] labels) or a variant
    of one. Returns the requirements in their JSON form; raises :class:`ConfigError` listing
    every problem, headed by *source* (how the caller names the file; default its path).
    """
    file, source = Path(path), str(path) if source is None else source
    if not file.is_file():
        what = "is a directory" if file.is_dir() else "file not found"
        raise ConfigError([f"{path}: {what}; fix: name the campaign file whose [requirements] "
                           "you corrected, or a file holding only a [requirements] table"],
                          source)
    data = read_toml(file, source)
    # a campaign file that leaves [requirements] out takes every default
    raw = data.get("requirements", {} if "campaign" in data else None)
    if not isinstance(raw, dict):
        raise ConfigError(["requirements: the file has no [requirements] table; fix: name the "
                           "campaign file whose [requirements] you corrected, or a file holding "
                           "only that table"], source)
    errors: list[str] = []
    table = build_table(RequirementsSection, raw, "requirements", errors)
    out = dict(stored)
    for f in leaf_fields(RequirementsSection):
        scoring = f.name in SCORING_REQUIREMENTS
        if not is_ok(table[f.name]) or (scoring and f.name not in table["__present__"]):
            continue
        value = thaw(table[f.name], f.metadata["key"].kind)
        if scoring and value != stored.get(f.name):
            errors.append(_scoring_change(f.name, value, stored.get(f.name)))
        elif not scoring:
            out[f.name] = value
    errors += requirement_name_problems(list(out.get("detector_max_fa_rate") or {}),
                                        list(labels))
    if errors:
        raise ConfigError(errors, source)
    return out


def _scoring_change(name: str, value: Any, was: Any) -> str:
    """The message refusing another value of the scoring requirement *name*."""
    if isinstance(value, dict) and isinstance(was, dict):
        differ = [f"{k} = {toml_value(v)} (the campaign's: {toml_value(was.get(k))})"
                  for k, v in value.items() if was.get(k) != v]
        what = f"requirements.{name}: " + ", ".join(differ)
    else:
        what = (f"requirements.{name}: {toml_value(value)} (the campaign's: "
                f"{'not set' if was is None else toml_value(was)})")
    return (f"{what}; it decides how each run was scored, so another value needs a new run; "
            "fix: keep the campaign's value (or leave the key out), or run the campaign with "
            "it into another directory")
