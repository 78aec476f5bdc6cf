"""How the campaign-file schema is declared, and how its values are stored frozen.

Every key of the campaign file is a field of a frozen dataclass whose metadata holds a
:class:`Key` (declared with :func:`key`); nested tables are declared with
:func:`sub_table`, top-level sections with :func:`section`. The other modules of
:mod:`campaign.config` read the schema only through these declarations
(:func:`leaf_fields`, :func:`table_fields`, :func:`key_spec`).

A validated value holds no mutable container: lists become tuples and tables become
:class:`FrozenTable` (:func:`freeze`); :func:`thaw` gives the plain value back.
"""

from __future__ import annotations

import dataclasses
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, Mapping

from scenarios.declare import Declared

__all__ = [
    "KIND_NAMES",
    "Key",
    "key",
    "sub_table",
    "section",
    "leaf_fields",
    "table_fields",
    "key_spec",
    "FrozenTable",
    "freeze",
    "thaw",
    "thaw_value",
]

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
    "labels": "list of names",
    "table": "table",
    "fault_seconds": "table fault → float",
    "number_table": "table name → float",
}


@dataclass(frozen=True)
class Key(Declared):
    """Description of one key of the campaign file (stored in a dataclass field's metadata):
    a :class:`scenarios.declare.Declared` (doc, unit, source, bounds gt/ge/lt/le) and

    kind : one of :data:`KIND_NAMES`.
    choices : allowed names (``choice`` and ``names`` kinds).
    required : the key has no default and must be given.
    optional : the key may be left out; its value is then ``None`` (meaning in ``default_doc``).
    example : value shown in the starting file and in messages.
    only : ``"mc"`` when the key applies to ``design = "mc"`` only (an error with ``grid``).
    nonempty : a string that must not be empty.
    """

    kind: str
    choices: tuple[str, ...] = ()
    required: bool = False
    optional: bool = False
    example: Any = None
    default_doc: str = ""
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


def section(cls: type, toml_name: str, doc: str, *, array: bool = False,
            required: bool = True, required_unless: str = ""):
    """Declare a top-level section (``[name]``, or ``[[name]]`` when *array*). An array
    section needs at least one table when *required*, unless the file has a table of the
    array section *required_unless*; an optional one left empty is not part of the
    canonical form."""
    return field(metadata={"section": toml_name, "cls": cls, "doc": doc, "array": array,
                           "required": required, "required_unless": required_unless})


# ----------------------------------------------------------------------------------------
# Reading the declarations
# ----------------------------------------------------------------------------------------
def leaf_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of table class *cls* that are keys (declared with :func:`key`)."""
    return [f for f in fields(cls) if "key" in f.metadata]


def table_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of table class *cls* that are nested tables (:func:`sub_table`)."""
    return [f for f in fields(cls) if "table" in f.metadata]


def key_spec(cls: type, sub: str, name: str) -> Key:
    """The :class:`Key` of key *name* in the nested table *sub* of table class *cls*."""
    sub_cls = next(f.metadata["table"] for f in table_fields(cls) if f.name == sub)
    return next(f.metadata["key"] for f in leaf_fields(sub_cls) if f.name == name)


# ----------------------------------------------------------------------------------------
# Frozen values
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FrozenTable:
    """An immutable, hashable table (a TOML table inside detector parameters)."""

    items: tuple[tuple[str, Any], ...]


def freeze(value: Any) -> Any:
    """*value* with every list made a tuple and every table a :class:`FrozenTable`
    (keys sorted)."""
    if isinstance(value, Mapping):
        return FrozenTable(tuple((k, freeze(value[k])) for k in sorted(value)))
    if isinstance(value, (list, tuple)):
        return tuple(freeze(v) for v in value)
    return value


def thaw_value(value: Any) -> Any:
    """The plain value (lists and dicts) of a frozen *value*."""
    if isinstance(value, FrozenTable):
        return {k: thaw_value(v) for k, v in value.items}
    if isinstance(value, tuple):
        return [thaw_value(v) for v in value]
    return value


def thaw(value: Any, kind: str) -> Any:
    """The plain value of a frozen key of kind *kind* (``table``, ``fault_seconds`` and
    ``number_table`` keys are stored as ``((name, value), …)`` and come back as dicts)."""
    if kind in ("table", "fault_seconds", "number_table"):
        return {k: thaw_value(v) for k, v in value}
    return thaw_value(value)
