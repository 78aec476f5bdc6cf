"""Documents generated from the schema: the annotated starting file and the Markdown
reference.

:func:`init_text` is what ``fdd-campaign init`` writes: every key with its description,
allowed values and default, loadable as is. :func:`schema_markdown` is
``docs/campaign-file.md``, regenerated with
``python -m campaign.config --markdown > docs/campaign-file.md`` (:func:`main`).
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from typing import Any

from scenarios.catalog import FAULT_TYPES, FAULTS

from .convert import ConfigError
from .keys import KIND_NAMES, Key, key_spec, leaf_fields
from .load import list_presets, load_config
from .rules import MOVED_KEYS
from .schema import iter_tables
from .sections import (ARRAY_EXAMPLES, FAULT_MAGNITUDE_KEY, FAULT_VARIANTS, MAGNITUDE_VARIANT,
                       FaultsSection)
from .text import example_value, shown_default, toml_value

__all__ = ["init_text", "schema_markdown", "main"]


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
    if spec.kind == "labels":
        return "distinct names"
    if spec.kind == "fault_seconds":
        return "keys " + ", ".join(spec.choices) + "; each " + spec.range_text("value")
    if spec.kind == "table":
        return "the detector's keyword parameters"
    if spec.kind == "number_table":
        return "each value " + (spec.range_text("value") or "a finite number")
    if spec.kind in ("int", "float"):
        return spec.range_text(name)
    if spec.kind in ("floats", "pair"):
        return "each " + spec.range_text("value")
    return ""


def _wrap_comment(text: str, width: int = 90) -> list[str]:
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
    for path, cls, doc, array in iter_tables():
        leaves = leaf_fields(cls)
        if not leaves:
            continue
        if array and not ARRAY_EXAMPLES.get(path):     # optional, shown commented out
            out.extend(_wrap_comment(doc))
            out.append(f"# [[{path}]]")
            for f in leaves:
                spec = f.metadata["key"]
                out.extend(_wrap_comment(_key_comment(spec, f.name)))
                out.append(f"# {f.name} = {toml_value(example_value(spec, f.default))}")
            out.append("")
            continue
        if array:
            for n, example in enumerate(ARRAY_EXAMPLES[path]):
                out.extend(_wrap_comment(doc) if n == 0 else [])
                out.append(f"[[{path}]]")
                for f in leaves:
                    spec = f.metadata["key"]
                    if f.name in example:
                        if n == 0:
                            out.extend(_wrap_comment(_key_comment(spec, f.name)))
                        out.append(f"{f.name} = {toml_value(example[f.name])}")
                    elif n == 0:
                        out.extend(_wrap_comment(_key_comment(spec, f.name)))
                        out.append(f"# {f.name} = {toml_value(example_value(spec, f.default))}")
                out.append("")
            if path == "detector":
                out += _builtin_detector_comments()
            continue
        out.extend(_wrap_comment(doc))
        out.append(f"[{path}]")
        for f in leaves:
            out += _table_key_lines(f.metadata["key"], f.name, f.default)
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _table_key_lines(spec: Key, name: str, default: Any) -> list[str]:
    """The lines of key *name* of a (non-array) table in the starting file: its comment,
    then the key. An optional key is shown commented out; so is the example of a key whose
    default is not its example (e.g. ``detector_max_fa_rate``, whose example names a detector
    the file may not have), with the default written in force below it, so that the file
    runs as written."""
    lines = _wrap_comment(_key_comment(spec, name))
    shown = example_value(spec, default)
    if spec.optional:
        return lines + [f"# {name} = {toml_value(shown)}"]
    plain = shown_default(spec, default) if not spec.required else shown
    if spec.required or shown == plain:
        return lines + [f"{name} = {toml_value(shown)}"]
    return lines + [f"# e.g. {name} = {toml_value(shown)}", f"{name} = {toml_value(plain)}"]


def _builtin_detector_comments() -> list[str]:
    """Commented lines listing every built-in detector's parameters with their defaults,
    allowed values and units (from the detectors' declarations, detectors.params)."""
    from detectors.params import parameter_table
    from detectors.registry import BUILTIN, load_detector_class

    out = ["# Parameters of the built-in detectors (params = { … }; docs/detectors.md):"]
    for name in BUILTIN:
        out.append(f"#   {name}:")
        for row in parameter_table(load_detector_class(name)):
            default = "" if row["default"] is None else f" = {toml_value(row['default'])}"
            unit = f" [{row['unit']}]" if row["unit"] and row["unit"] != "-" else ""
            allowed = f" ({row['allowed']})" if row["allowed"] else ""
            out.extend(_wrap_comment(f"    {row['name']}{default}{unit}{allowed}"))
    out.append("")
    return out


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _md_default(spec: Key, default: Any) -> str:
    if spec.required:
        return "required"
    if spec.optional:
        return spec.default_doc
    return f"`{toml_value(shown_default(spec, default))}`"


def schema_markdown() -> str:
    """The Markdown reference of the campaign file (``docs/campaign-file.md``)."""
    out = [
        "# The campaign file",
        "",
        "<!-- Generated from the schema in campaign/config/ by "
        "`python -m campaign.config --markdown > docs/campaign-file.md`; do not edit. -->",
        "",
        "A campaign is one TOML file: `fdd-campaign run FILE.toml --out DIR`, or a shipped "
        "preset by name (`fdd-campaign run smoke --out DIR`). `fdd-campaign init` writes an "
        "annotated starting file. Every section is optional except `[campaign]` (for its "
        "`name`), at least one `[[group]]` (or `[[run]]`) and at least one `[[detector]]`; "
        "every key left out takes its default.",
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
    for path, cls, doc, array in iter_tables():
        leaves = leaf_fields(cls)
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
        "A `[[group]]` `magnitude` is in the unit of the fault type's range (a jam's % of "
        "the deflection range becomes its rod bias or offset in mm, r·sin(p·Δδ), in the run "
        "table), and its direction is drawn per run unless `sign` fixes it:",
        "",
        "| fault | range key |",
        "|---|---|",
    ]
    for fault, (sub, k) in FAULT_MAGNITUDE_KEY.items():
        spec = key_spec(FaultsSection, sub, k)
        only = (f" (variant = \"{MAGNITUDE_VARIANT[fault]}\" only)"
                if fault in MAGNITUDE_VARIANT else "")
        out.append(f"| `{fault}`{only} | `faults.{sub}.{k}` [{spec.unit}] |")
    others = [f"`{f}`" for f in FAULT_TYPES if f not in FAULT_MAGNITUDE_KEY]
    others += [f"`{f}` with variant = \"{v}\"" for f, variants in FAULT_VARIANTS.items()
               for v in variants if v != MAGNITUDE_VARIANT.get(f)]
    out += ["", "Faults without a magnitude: " + ", ".join(others) + ".", ""]
    out += ["## Keys that moved", "",
            "Campaign files written with an earlier spelling keep working: the old key is "
            "read as the new one, with a one-line note naming it. Writing both, with "
            "different values, is an error.", "",
            "| old key | new key |", "|---|---|"]
    out += [f"| `[{old_sec}] {old}` | `[{new_sec}] {new}` |"
            for (old_sec, old), (new_sec, new) in MOVED_KEYS.items()]
    out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """``python -m campaign.config``: print the Markdown reference (``--markdown``) or the
    starting file (``--init``), or check a campaign (``--check``); returns the exit status
    (2: the campaign has problems, listed on standard error)."""
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

