"""Check and convert the values of a campaign file, one key or one table at a time.

:func:`convert_value` checks one value read from TOML against its :class:`Key` (type,
allowed names, range) and returns its frozen form; :func:`build_table` does so for every
key of one table, reports unknown keys and fills in the defaults. A problem is appended to
the caller's error list as ``"path: problem; allowed …"`` or ``"path: problem; fix: …"``
and the value is replaced by :data:`BAD`, so that validation goes on and every problem of
a file is reported at once (:class:`ConfigError`). Rules that involve several keys are in
:mod:`campaign.config.rules`.
"""

from __future__ import annotations

import math
from dataclasses import MISSING
from typing import Any, Callable

from scenarios.catalog import REQUIRED_DETECTION_TIME_S, suggest
from scenarios.errors import InputError

from .keys import Key, freeze, leaf_fields, table_fields
from .text import example_value, num, short, toml_value, type_word

__all__ = [
    "ConfigError",
    "BAD",
    "is_ok",
    "is_number",
    "convert_value",
    "check_plain",
    "build_table",
]


class ConfigError(InputError, ValueError):
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


class _Bad:
    """Marker of a value that failed validation (its error is already recorded)."""

    def __repr__(self):
        return "<invalid>"


#: Stands in for a value that failed validation (its error is already recorded).
BAD = _Bad()


def is_ok(*values: Any) -> bool:
    """Whether none of *values* failed validation."""
    return not any(v is BAD for v in values)


def is_number(v: Any) -> bool:
    """An int or a float, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


# ----------------------------------------------------------------------------------------
# One value
# ----------------------------------------------------------------------------------------
class _Check:
    """What a converter needs besides the value: its key, name, path and error list."""

    def __init__(self, spec: Key, name: str, value: Any, path: str, errors: list[str],
                 default: Any):
        self.spec, self.name, self.path, self.errors = spec, name, path, errors
        self.default = default
        self.got = f"got {type_word(value)} {short(value)}"
        self.fix = f"fix: e.g. {name} = {toml_value(example_value(spec, default))}"

    def bad(self, msg: str) -> _Bad:
        """Record ``path: msg`` and return :data:`BAD`."""
        self.errors.append(f"{self.path}: {msg}")
        return BAD


def _to_str(c: _Check, value: Any) -> Any:
    spec = c.spec
    if not isinstance(value, str):
        return c.bad(f"expected a string in quotes, {c.got}; {c.fix}")
    if spec.kind == "choice" and value not in spec.choices:
        return c.bad(f"unknown {c.name} {value!r}{suggest(value, spec.choices)}; "
                     f"allowed: {', '.join(spec.choices)}")
    if spec.nonempty and not value.strip():
        return c.bad(f"must not be empty; {c.fix}")
    return value


def _to_bool(c: _Check, value: Any) -> Any:
    if not isinstance(value, bool):
        return c.bad(f"expected true or false (no quotes), {c.got}")
    return value


def _to_int(c: _Check, value: Any) -> Any:
    if not isinstance(value, int) or isinstance(value, bool):
        return c.bad(f"expected an integer, {c.got}; {c.fix}")
    if c.spec.out_of_range(value):
        return c.bad(f"{value} is out of range; allowed: {c.spec.range_text(c.name)}")
    return value


def _to_float(c: _Check, value: Any) -> Any:
    if not is_number(value):
        return c.bad(f"expected a number, {c.got}; {c.fix}")
    if c.spec.out_of_range(float(value)):
        return c.bad(f"{num(value)} is out of range; allowed: {c.spec.range_text(c.name)}")
    return float(value)


def _to_floats(c: _Check, value: Any) -> Any:
    if not isinstance(value, list) or not value:
        return c.bad(f"expected a non-empty list of numbers, {c.got}; {c.fix}")
    ok = True
    for i, x in enumerate(value):
        if not is_number(x):
            c.errors.append(f"{c.path}[{i}]: expected a number, got {type_word(x)} "
                            f"{short(x)}; {c.fix}")
            ok = False
        elif c.spec.out_of_range(float(x)):
            c.errors.append(f"{c.path}[{i}]: {num(x)} is out of range; allowed: "
                            f"{c.spec.range_text()}")
            ok = False
    if not ok:
        return BAD
    vals = sorted(float(x) for x in value)
    dup = sorted({x for x in vals if vals.count(x) > 1})
    if dup:
        return c.bad(f"value {num(dup[0])} is repeated; fix: list each value once")
    return tuple(vals)


def _to_pair(c: _Check, value: Any) -> Any:
    if not (isinstance(value, list) and len(value) == 2 and all(map(is_number, value))):
        return c.bad(f"expected [low, high] (two numbers), {c.got}; {c.fix}")
    low, high = float(value[0]), float(value[1])
    ok = True
    for label, x in (("low", low), ("high", high)):
        if c.spec.out_of_range(x):
            c.errors.append(f"{c.path}: {label} {num(x)} is out of range; allowed: "
                            f"{c.spec.range_text()}")
            ok = False
    if ok and low > high:
        return c.bad(f"low {num(low)} > high {num(high)}; fix: write [low, high] with "
                     f"low ≤ high, e.g. {c.name} = [{num(high)}, {num(low)}]")
    return (low, high) if ok else BAD


def _to_names(c: _Check, value: Any) -> Any:
    choices = c.spec.choices
    if not (isinstance(value, list) and value and all(isinstance(x, str) for x in value)):
        return c.bad(f"expected a non-empty list of names or [\"all\"], {c.got}; {c.fix}")
    if "all" in value:
        if len(value) > 1:
            return c.bad("\"all\" cannot be combined with other names; fix: write "
                         f"{c.name} = [\"all\"] or list the names")
        return tuple(choices)
    ok = True
    for i, x in enumerate(value):
        if x not in choices:
            c.errors.append(f"{c.path}[{i}]: unknown manoeuvre {x!r}"
                            f"{suggest(x, choices)}; allowed: "
                            f"{', '.join(choices)}, or [\"all\"]")
            ok = False
    if ok and len(set(value)) != len(value):
        return c.bad("a name is repeated; fix: list each name once")
    return tuple(n for n in choices if n in value) if ok else BAD


def _to_labels(c: _Check, value: Any) -> Any:
    """A non-empty list of distinct free names (detector result names)."""
    if not (isinstance(value, list) and value and all(isinstance(x, str) and x.strip()
                                                      for x in value)):
        return c.bad(f"expected a non-empty list of names, {c.got}; {c.fix}")
    if len(set(value)) != len(value):
        return c.bad("a name is repeated; fix: list each name once")
    return tuple(value)


def _to_table(c: _Check, value: Any) -> Any:
    if not isinstance(value, dict):
        return c.bad(f"expected a table, {c.got}; fix: e.g. {c.name} = "
                     f"{toml_value(c.spec.example or {})}")
    ok = check_plain(value, c.path, c.errors)
    return freeze(value).items if ok else BAD


def _to_fault_seconds(c: _Check, value: Any) -> Any:
    spec = c.spec
    if not isinstance(value, dict):
        return c.bad(f"expected a table of fault = seconds, {c.got}; fix: e.g. "
                     f"{c.name} = {{ runaway = 0.5 }}")
    merged = dict(REQUIRED_DETECTION_TIME_S)
    ok = True
    for k, x in value.items():
        if k not in spec.choices:
            c.errors.append(f"{c.path}.{k}: unknown fault {k!r}{suggest(k, spec.choices)}; "
                            f"allowed: {', '.join(spec.choices)}")
            ok = False
        elif not is_number(x):
            c.errors.append(f"{c.path}.{k}: expected a number of seconds, got "
                            f"{type_word(x)} {short(x)}; fix: e.g. {k} = 1.0")
            ok = False
        elif spec.out_of_range(float(x)):
            c.errors.append(f"{c.path}.{k}: {num(x)} is out of range; allowed: "
                            f"{spec.range_text(k)}")
            ok = False
        else:
            merged[k] = float(x)
    return tuple((k, merged[k]) for k in spec.choices) if ok else BAD


def _to_number_table(c: _Check, value: Any) -> Any:
    if not isinstance(value, dict):
        return c.bad(f"expected a table of name = number, {c.got}; fix: e.g. {c.name} = "
                     f"{toml_value(c.spec.example or {'h_max_s': 0.005})}")
    ok = True
    for k, x in value.items():
        if c.spec.choices and k not in c.spec.choices:
            c.errors.append(f"{c.path}.{k}: unknown name {k!r}{suggest(k, c.spec.choices)}; "
                            f"allowed: {', '.join(c.spec.choices)}")
            ok = False
        elif not is_number(x):
            c.errors.append(f"{c.path}.{k}: expected a number, got {type_word(x)} "
                            f"{short(x)}; fix: e.g. {k} = 1.0")
            ok = False
        elif c.spec.out_of_range(float(x)):
            c.errors.append(f"{c.path}.{k}: {num(x)} is out of range; allowed: "
                            f"{c.spec.range_text(k) or 'a finite number'}")
            ok = False
    if not ok:
        return BAD
    # a table of fixed names (choices): the entries given replace the default's
    merged = dict(c.default or ()) if c.spec.choices else {}
    merged.update((k, float(x)) for k, x in value.items())
    return tuple(sorted(merged.items()))


_CONVERTERS: dict[str, Callable[[_Check, Any], Any]] = {
    "str": _to_str,
    "choice": _to_str,
    "bool": _to_bool,
    "int": _to_int,
    "float": _to_float,
    "floats": _to_floats,
    "pair": _to_pair,
    "names": _to_names,
    "labels": _to_labels,
    "table": _to_table,
    "fault_seconds": _to_fault_seconds,
    "number_table": _to_number_table,
}


def convert_value(spec: Key, name: str, value: Any, path: str, errors: list[str],
                  default: Any = MISSING) -> Any:
    """Check one value of the file against its key *spec* and return its frozen form, or
    :data:`BAD` after appending the problem(s) to *errors*.

    *name* is the key's name and *path* its place in the file (``group[2].fault``), both
    used in the messages; *default* is the key's default, shown in "fix: e.g." hints when
    the key has no example.
    """
    converter = _CONVERTERS.get(spec.kind)
    if converter is None:  # a bug of the schema, not of the input
        raise AssertionError(f"unknown kind {spec.kind!r} in the schema")
    return converter(_Check(spec, name, value, path, errors, default), value)


def check_plain(value: Any, path: str, errors: list[str]) -> bool:
    """Detector parameters must be plain JSON-able values (no dates or times)."""
    if isinstance(value, dict):
        return all([check_plain(v, f"{path}.{k}", errors) for k, v in value.items()])
    if isinstance(value, list):
        return all([check_plain(v, f"{path}[{i}]", errors) for i, v in enumerate(value)])
    if isinstance(value, float) and not math.isfinite(value):
        errors.append(f"{path}: {value!r} is not allowed; fix: use a finite number")
        return False
    if isinstance(value, (str, int, float, bool)):
        return True
    errors.append(f"{path}: {type_word(value)} values are not supported; fix: use a "
                  "string, number, boolean, list or table")
    return False


# ----------------------------------------------------------------------------------------
# One table
# ----------------------------------------------------------------------------------------
def build_table(cls: type, raw: Any, path: str, errors: list[str]) -> dict:
    """Check one table against dataclass *cls*: unknown keys, types, ranges, defaults.

    Returns ``{key: frozen value or BAD or default}``, nested tables as dicts of the same
    form, and under ``"__present__"`` the set of keys written in the file.
    """
    leaves = {f.name: f for f in leaf_fields(cls)}
    subs = {f.name: f for f in table_fields(cls)}
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
            out[name] = convert_value(spec, name, raw[name], p, errors, f.default)
        elif spec.required:
            errors.append(f"{p}: missing required key; fix: add {name} = "
                          f"{toml_value(example_value(spec, MISSING))} to "
                          f"[{path.split('[')[0]}]")
            out[name] = BAD
        else:
            out[name] = f.default
    for name, f in subs.items():
        p = f"{path}.{name}"
        sub_raw = raw.get(name, {})
        if not isinstance(sub_raw, dict):
            errors.append(f"{p}: expected a table [{p}], got {type_word(sub_raw)}; fix: "
                          f"write the keys under a [{p}] header")
            sub_raw = {}
        out[name] = build_table(f.metadata["table"], sub_raw, p, errors)
    return out
