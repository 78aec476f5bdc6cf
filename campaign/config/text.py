"""How values, types and ranges are written in messages and in the generated documents.

Shared by the validation (:mod:`campaign.config.convert`, :mod:`campaign.config.rules`),
which quotes the offending value and how to fix it, and by the starting file and the
Markdown reference (:mod:`campaign.config.docs`), which show defaults and ranges the same
way.
"""

from __future__ import annotations

from dataclasses import MISSING
from typing import Any

from scenarios.declare import num, toml_value

from .keys import Key, thaw

__all__ = [
    "num",
    "toml_value",
    "type_word",
    "short",
    "shown_default",
    "example_value",
]

# The number format (num), the range text (Key.range_text) and the TOML literal
# (toml_value) are those of every declared parameter (scenarios.declare).

_TOML_TYPE = {str: "string", bool: "boolean", int: "integer", float: "float", list: "array",
              dict: "table"}


def type_word(value: Any) -> str:
    """The TOML name of the type of a value read from a file (``"integer"``, …)."""
    for t, word in _TOML_TYPE.items():
        if type(value) is t:
            return word
    return type(value).__name__.replace("datetime", "date-time")


def short(value: Any) -> str:
    """``repr(value)``, cut to 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def shown_default(spec: Key, value: Any) -> Any:
    """The default as a user would write it (``["all"]`` for every manoeuvre)."""
    if spec.kind == "names" and tuple(value) == spec.choices:
        return ["all"]
    return thaw(value, spec.kind)


def example_value(spec: Key, default: Any) -> Any:
    """A valid value of the key, shown in the starting file and in "fix: e.g." hints: its
    declared example, else its default, else its lower bound (else 1)."""
    if spec.example is not None:
        return spec.example
    if default is not MISSING and default is not None:
        return shown_default(spec, default)
    return spec.lower if spec.lower is not None else 1
