"""How values, types and ranges are written in messages and in the generated documents.

Shared by the validation (:mod:`campaign.config.convert`, :mod:`campaign.config.rules`),
which quotes the offending value and how to fix it, and by the starting file and the
Markdown reference (:mod:`campaign.config.docs`), which show defaults and ranges the same
way.
"""

from __future__ import annotations

import json
import re
from dataclasses import MISSING
from typing import Any, Mapping

from .keys import Key, thaw

__all__ = [
    "num",
    "range_text",
    "toml_value",
    "type_word",
    "short",
    "shown_default",
    "example_value",
]


def num(x: float) -> str:
    """A number as written in messages (``%g``, full precision beyond 10⁶)."""
    return f"{x:g}" if abs(x) < 1e6 else repr(x)


def range_text(spec: Key, name: str = "value") -> str:
    """The allowed range of *spec* as ``lo ≤ name ≤ hi unit`` (``""`` when unbounded)."""
    lo, hi = spec.lo, spec.hi
    unit = f" {spec.unit}" if spec.unit and spec.unit != "-" else ""
    lo_op = "<" if spec.lo_open else "≤"
    if lo is not None and hi is not None:
        return f"{num(lo)} {lo_op} {name} ≤ {num(hi)}{unit}"
    if lo is not None:
        return f"{name} {'>' if spec.lo_open else '≥'} {num(lo)}{unit}"
    if hi is not None:
        return f"{name} ≤ {num(hi)}{unit}"
    return ""


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k, ensure_ascii=False)


def toml_value(v: Any) -> str:
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
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        if not v:
            return "{}"
        return "{ " + ", ".join(f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


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
    return spec.lo if spec.lo is not None else 1
