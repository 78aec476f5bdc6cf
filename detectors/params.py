"""Detector parameters declared once, as data (in the manner of scikit-learn's
``_parameter_constraints``).

A detector lists its keyword parameters as :class:`Param` declarations in the class
attribute ``parameters``::

    class MyDetector(Detector):
        parameters = (
            Param("pole", "float", ge=0.0, lt=1.0, doc="pole a of the residual filter",
                  source="est."),
            Param("safety", "float", gt=1.0, doc="threshold = safety × largest fault-free "
                  "residual", source="est."),
        )

        def __init__(self, pole=0.9, safety=1.5): ...

One validator, :func:`parameter_problems`, reads these declarations. It serves

* ``Detector.validate_params`` (at ``fit`` and before a campaign starts), which raises one
  ``ValueError`` listing every problem;
* :func:`detectors.registry.parameter_errors`, which the campaign-file validation calls;
* :func:`parameter_table`, the rows (name, type, default, allowed, unit, doc) the generated
  reference docs/detectors.md lists for every built-in detector.

A detector that declares nothing still has its unknown parameter names refused (from the
``__init__`` signature); its values are then checked only by its own ``validate_params``.
"""

from __future__ import annotations

import inspect
import numbers
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from scenarios.catalog import suggest
from scenarios.declare import BOUND_SIGNS, Declared, is_real, toml_value

#: What a parameter value may be (``Param.kind``):
#:
#: ``"int"``     an integer (not a bool);
#: ``"float"``   a finite real number (an integer is accepted; a bool is not);
#: ``"bool"``    ``True`` or ``False``;
#: ``"str"``     any string;
#: ``"choice"``  one of ``choices``;
#: ``"choices"`` one of ``choices`` or a non-empty list of them;
#: ``"floats"``  a list (or tuple) of finite real numbers, each within the bounds; ``length``
#:               fixes how many, ``unique`` forbids repeats, ``scalar`` also accepts a single
#:               number.
KINDS: tuple[str, ...] = ("int", "float", "bool", "str", "choice", "choices", "floats")

_TYPE_TEXT = {"int": "int", "float": "float", "bool": "bool", "str": "str", "choice": "str",
              "choices": "str or list of str", "floats": "list of float"}


@dataclass(frozen=True, init=False)
class Param(Declared):
    """Declaration of one keyword parameter of a detector: a
    :class:`scenarios.declare.Declared` (unit, doc, source, bounds) with a name and a kind.

    Parameters
    ----------
    name : str
        The ``__init__`` keyword.
    kind : str
        One of :data:`KINDS`.
    gt, ge, lt, le : float or str, optional
        Bounds of a number (of each number of a ``"floats"`` list): > *gt*, ≥ *ge*, < *lt*,
        ≤ *le*. A string names another parameter of the same detector whose value is the
        bound (checked once that parameter is itself valid), e.g. ``gt="decay"``.
    choices : tuple of str
        The allowed values of a ``"choice"`` or ``"choices"`` parameter.
    length : int, optional
        Exact number of values of a ``"floats"`` parameter.
    unique : bool
        ``"floats"``: no value may repeat.
    scalar : bool
        ``"floats"``: a single number is accepted too.
    unit : str
        Unit of the value (``"-"`` when dimensionless).
    doc : str
        One line saying what the parameter does.
    source : str
        Where its default comes from: a citation (``"[COMB] §4"``) or ``"est."``.

    The arguments keep the order of the plugin API (a third-party detector may give the
    bounds by position).
    """

    name: str
    kind: str
    choices: tuple[str, ...] = ()
    length: int | None = None
    unique: bool = False
    scalar: bool = False
    unit: str = "-"
    source: str = "est."

    def __init__(self, name: str, kind: str, gt: float | str | None = None,
                 ge: float | str | None = None, lt: float | str | None = None,
                 le: float | str | None = None, choices: tuple[str, ...] = (),
                 length: int | None = None, unique: bool = False, scalar: bool = False,
                 unit: str = "-", doc: str = "", source: str = "est."):
        values = dict(name=name, kind=kind, gt=gt, ge=ge, lt=lt, le=le, choices=choices,
                      length=length, unique=unique, scalar=scalar, unit=unit, doc=doc,
                      source=source)
        for key, value in values.items():
            object.__setattr__(self, key, value)
        self.__post_init__()

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Param {self.name!r}: kind {self.kind!r} is not one of "
                             f"{', '.join(KINDS)}{suggest(self.kind, KINDS)}")
        if (self.kind in ("choice", "choices")) != bool(self.choices):
            raise ValueError(f"Param {self.name!r}: choices go with kind 'choice' or "
                             f"'choices' (and those kinds need them); got kind {self.kind!r}, "
                             f"choices {self.choices!r}")
        if self.bounded and self.kind not in ("int", "float", "floats"):
            raise ValueError(f"Param {self.name!r}: bounds apply to numbers, not to kind "
                             f"{self.kind!r}")
        if self.bounds_problem():
            raise ValueError(f"Param {self.name!r}: {self.bounds_problem()}")
        if (self.length is not None or self.unique or self.scalar) and self.kind != "floats":
            raise ValueError(f"Param {self.name!r}: length, unique and scalar apply to kind "
                             f"'floats' only, not {self.kind!r}")

    # ---- text ------------------------------------------------------------------------
    @property
    def type_text(self) -> str:
        """The value's type as the reference table shows it."""
        if self.kind == "floats":
            many = f"list of {self.length} floats" if self.length else "list of float"
            return f"float or {many}" if self.scalar else many
        return _TYPE_TEXT[self.kind]

    @property
    def value_name(self) -> str:
        """The name of one value in the range text: the parameter's, or ``value`` for
        each number of a ``"floats"`` list."""
        return "value" if self.kind == "floats" else self.name

    def allowed_range(self) -> str:
        """The allowed range or choices as the reference table shows them, e.g.
        ``"safety > 1"``, ``"0 ≤ pole < 1"``, ``"each value > 0"``, ``"rod_com, rod_mon"``,
        ``"true, false"`` (empty when any value of the kind is allowed; the unit has its
        own column)."""
        if self.choices:
            return ", ".join(self.choices)
        if self.kind == "bool":
            return "true, false"
        rng = self.range_text(self.value_name, unit=False)
        return f"each {rng}" if rng and self.kind == "floats" else rng

    def allowed_text(self) -> str:
        """What a valid value is, in words (used after ``allowed:`` in messages)."""
        if self.kind == "bool":
            return "true or false"
        if self.kind == "str":
            return "a string"
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "choices":
            return ("one of " + ", ".join(repr(c) for c in self.choices)
                    + ", or a non-empty list of them")
        rng = self.range_text(self.value_name, unit=False)
        unit = f" [{self.unit}]" if self.unit not in ("", "-") else ""
        if self.kind == "int":
            return f"an integer{' with ' + rng if rng else ''}{unit}"
        if self.kind == "float":
            return f"a finite number{' with ' + rng if rng else ''}{unit}"
        count = f"{self.length} " if self.length is not None else ""
        text = (f"a list of {count}finite numbers" if count else
                "a non-empty list of finite numbers")
        text += f", each {rng}" if rng else ""
        text += ", all different" if self.unique else ""
        text += unit
        return f"a single number or {text}" if self.scalar else text

    @property
    def description(self) -> str:
        """``doc`` followed by the source of the default in parentheses."""
        return f"{self.doc} ({self.source})" if self.source else self.doc

    # ---- checking --------------------------------------------------------------------
    def problem(self, value: Any, values: Mapping[str, Any] | None = None,
                valid: set[str] | None = None) -> str | None:
        """What is wrong with *value* (a short phrase), or ``None`` when it is allowed.

        *values* holds the other parameters of the detector, for bounds that name one;
        *valid* the names of those that passed their own check (a bound naming a parameter
        that is not valid is not checked)."""
        values = values or {}
        valid = set(values) if valid is None else valid
        kind = self.kind
        if kind == "bool":
            return None if isinstance(value, bool) else f"{_what(value)}, not true or false"
        if kind in ("str", "choice"):
            if not isinstance(value, str):
                return f"{_what(value)}, not a string"
            if kind == "choice" and value not in self.choices:
                return f"not one of the choices{suggest(value, self.choices)}"
            return None
        if kind == "choices":
            items = [value] if isinstance(value, str) else _as_list(value)
            if items is None:
                return f"{_what(value)}, not a string or a list of strings"
            if not items:
                return "an empty list"
            bad = [c for c in items if not (isinstance(c, str) and c in self.choices)]
            if bad:
                hint = suggest(bad[0], self.choices) if isinstance(bad[0], str) else ""
                return f"{_seq(bad)} not among the choices{hint}"
            return None
        if kind == "int":
            if not _is_int(value):
                return f"{_what(value)}, not an integer"
            return self._bound_problem(value, values, valid)
        if kind == "float":
            if is_real(value):
                return self._bound_problem(value, values, valid)
            if isinstance(value, numbers.Real) and not isinstance(value, bool):
                return "not finite"
            return f"{_what(value)}, not a number"
        # floats
        if self.scalar and is_real(value):
            items = [value]
        elif isinstance(value, (list, tuple)):
            items = list(value)
        else:
            return f"{_what(value)}, not a list of numbers"
        if self.length is not None and len(items) != self.length:
            return f"{len(items)} value{'s' if len(items) != 1 else ''}, not {self.length}"
        if not items:
            return "an empty list"
        wrong = [v for v in items if not is_real(v)]
        if wrong:
            return f"{_seq(wrong)} not finite number{'s' if len(wrong) > 1 else ''}"
        out = [v for v in items if self._bound_problem(v, values, valid) is not None]
        if out:
            return f"{_seq(out)} out of range"
        if self.unique and len({float(v) for v in items}) != len(items):
            seen, rep = set(), []
            for v in items:
                if float(v) in seen and v not in rep:
                    rep.append(v)
                seen.add(float(v))
            return f"{_seq(rep)} repeated"
        return None

    def _bound_problem(self, v, values: Mapping[str, Any], valid: set[str]) -> str | None:
        known = {k: values[k] for k in valid if k in values}
        broken = self.broken_bound(v, known)
        if broken is None:
            return None
        kw, bound = broken
        named = getattr(self, kw)
        if isinstance(named, str):
            return f"not {BOUND_SIGNS[kw]} {named} = {values[named]!r}"
        return "out of range"


# ---------------------------------------------------------------------------------------
# The validator
# ---------------------------------------------------------------------------------------
def declared_parameters(cls: type) -> tuple[Param, ...]:
    """The :class:`Param` declarations of detector class *cls* (empty when it declares
    none)."""
    return tuple(getattr(cls, "parameters", ()) or ())


def signature_defaults(cls: type) -> dict[str, Any]:
    """The keyword parameters of ``cls.__init__`` → default (``inspect.Parameter.empty``
    when there is none)."""
    sig = inspect.signature(cls.__init__)
    return {p.name: p.default for p in sig.parameters.values()
            if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}


def parameter_problems(cls: type, params: Mapping[str, Any]) -> list[str]:
    """Every problem of the keyword parameters *params* for detector class *cls*, one
    message each (empty list when they are acceptable).

    Checks, all at once: names unknown to ``cls.__init__`` (with a "did you mean"), then,
    for every declared :class:`Param`, the value given (or the default) — its type, its
    range, its choices. Each message starts with the parameter and its value and says what
    is allowed and how to fix it, so it reads on its own and after a location prefix such
    as ``detector[0].params: ``."""
    defaults = signature_defaults(cls)
    known = list(defaults)
    problems = []
    for key in params:
        if key not in known:
            problems.append(
                f"{key} = {params[key]!r}: no such parameter{suggest(key, known)}; allowed: "
                f"{', '.join(known) or '(none)'}; fix: rename or remove {key}")
    values = {k: v for k, v in defaults.items() if v is not inspect.Parameter.empty}
    values.update({k: v for k, v in params.items() if k in defaults})
    declared = declared_parameters(cls)
    # a bound naming another parameter is checked once that one is valid
    valid = {p.name for p in declared if p.name in values and p.problem(values[p.name]) is None
             and not _names_bound(p)}
    for p in declared:
        if p.name not in values:
            continue
        what = p.problem(values[p.name], values, valid)
        if what is not None:
            fix = _fix(p, defaults.get(p.name), values, valid, given=p.name in params)
            problems.append(f"{p.name} = {values[p.name]!r}: {what}; allowed: "
                            f"{p.allowed_text()}; fix: {fix}")
    return problems


def _names_bound(p: Param) -> bool:
    return any(isinstance(b, str) for b in p.bounds().values())


def _fix(p: Param, default, values: Mapping[str, Any], valid: set[str], given: bool) -> str:
    """How to fix parameter *p*: its default when that is valid next to the other values,
    else what to change."""
    if default is not inspect.Parameter.empty and p.problem(default, values, valid) is None:
        return f"e.g. {p.name} = {default!r} (the default){', or remove it' if given else ''}"
    moves = [f"raise {p.name} above {b} = {values[b]!r}, or lower {b}"
             for b in (p.gt, p.ge) if isinstance(b, str) and b in values]
    moves += [f"lower {p.name} below {b} = {values[b]!r}, or raise {b}"
              for b in (p.lt, p.le) if isinstance(b, str) and b in values]
    if moves and p.problem(values[p.name]) is None:      # only the relation is broken
        return "; ".join(moves)
    return f"give {p.name} a value that is {p.allowed_text()}"


# ---------------------------------------------------------------------------------------
# The reference table
# ---------------------------------------------------------------------------------------
def parameter_table(cls: type) -> list[dict]:
    """One row per keyword parameter of detector class *cls*, in ``__init__`` order:
    ``name``, ``type``, ``default`` (the value; ``None`` when there is none), ``allowed``
    (range or choices), ``unit`` and ``doc`` (with the source of the default). A parameter
    without a declaration has empty type, allowed, unit and doc."""
    declared = {p.name: p for p in declared_parameters(cls)}
    rows = []
    for name, default in signature_defaults(cls).items():
        p = declared.get(name)
        rows.append({
            "name": name,
            "type": p.type_text if p else "",
            "default": None if default is inspect.Parameter.empty else default,
            "allowed": p.allowed_range() if p else "",
            "unit": p.unit if p else "",
            "doc": p.description if p else "",
        })
    return rows


def parameter_markdown(detectors: Mapping[str, type]) -> str:
    """A Markdown section per detector (name → class) with its :func:`parameter_table`."""
    out = []
    for name, cls in detectors.items():
        out.append(f"## `{name}`\n")
        summary = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
        summary = re.sub(r"\s*\((see )?the module docstring\)|\s*\(module docstring\)", "",
                         summary)
        out.append(f"`{cls.__module__}.{cls.__qualname__}`: {summary}\n")
        out.append("| parameter | type | default | allowed | unit | description |")
        out.append("|---|---|---|---|---|---|")
        for r in parameter_table(cls):
            cells = [f"`{r['name']}`", r["type"],
                     f"`{toml_value(r['default'])}`" if r["default"] is not None else "",
                     r["allowed"], r["unit"], r["doc"]]
            out.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------


def _is_int(v) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _as_list(v) -> list | None:
    if isinstance(v, (bytes, Mapping)):
        return None
    try:
        return list(v)
    except TypeError:
        return None


def _what(v) -> str:
    """What *v* is, in words ("a string", "a bool", …)."""
    if isinstance(v, bool):
        return "a bool"
    names = {str: "a string", int: "an integer", float: "a number", list: "a list",
             tuple: "a list", dict: "a table", type(None): "None"}
    return names.get(type(v), f"a {type(v).__name__}")


def _seq(items: Sequence) -> str:
    return ", ".join(repr(v) for v in items)
