"""One way to declare a parameter: its unit, where its value comes from, its bounds, and how
its range and its numbers are written (in the manner of scikit-learn's ``Interval``, whose
``__str__`` writes every message).

Three kinds of parameters are declared with :class:`Declared`, each adding what it needs:

* the keys of the campaign file (:class:`campaign.config.keys.Key`: kind, default, choices);
* the keyword parameters of a detector (:class:`detectors.params.Param`: name, kind,
  choices, list length);
* the parameters of the plant and of the detectors' numerics
  (:func:`scenarios.params.param`, a dataclass field carrying a :class:`Declared`).

**One bound vocabulary**: ``gt`` (>), ``ge`` (≥), ``lt`` (<), ``le`` (≤), at most one lower
and one upper bound. A bound may be a string naming another parameter of the same
declaration set (``gt="decay"``); such a bound is checked by whoever knows that
parameter's value (:meth:`Declared.broken_bound` with *values*).

**One range text** (:meth:`Declared.range_text`): the inequality the value must satisfy,
with the parameter's name and unit, e.g. ``0 < duration_s ≤ 600 s``, ``safety > 1``,
``radius > decay``; it appears in validation messages, in the generated references
(docs/campaign-file.md, docs/detectors.md) and in the starting campaign file.

**One number format** (:func:`num`) for the numbers of those texts, and one TOML literal
(:func:`toml_value`) for the values a user would write in a campaign file.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import re
from dataclasses import dataclass
from typing import Any, Mapping

__all__ = ["BOUND_SIGNS", "Declared", "field_problems", "num", "toml_value"]

#: The bound keywords and the relation each one requires of a value.
BOUND_SIGNS: dict[str, str] = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤"}


def num(x: float | str) -> str:
    """A number as written in messages and references: ``%g`` (full precision from 10⁶
    on, where ``%g`` would round); a string (a bound naming a parameter) as it is."""
    if isinstance(x, str):
        return x
    return f"{x:g}" if abs(x) < 1e6 else repr(x)


@dataclass(frozen=True, kw_only=True)
class Declared:
    """What every declared parameter has: its unit, its one-line description, where its
    value comes from, and its bounds.

    unit : physical unit of the value (``"s"``, ``"mm"``, …; ``""`` or ``"-"`` when
        dimensionless).
    doc : one line saying what the parameter is.
    source : where its value or default comes from (a citation, ``"est."``, …).
    gt, ge, lt, le : bounds of a number: > *gt*, ≥ *ge*, < *lt*, ≤ *le* (at most one lower
        bound, *gt* or *ge*, and one upper bound, *lt* or *le*). A string names another
        parameter whose value is the bound.
    """

    unit: str = ""
    doc: str = ""
    source: str = ""
    gt: float | str | None = None
    ge: float | str | None = None
    lt: float | str | None = None
    le: float | str | None = None

    def __post_init__(self):
        problem = self.bounds_problem()
        if problem:
            raise ValueError(problem)

    def bounds_problem(self) -> str | None:
        """What is wrong with the bounds as declared (``None`` when they are consistent)."""
        if (self.gt is not None and self.ge is not None) or \
                (self.lt is not None and self.le is not None):
            return ("give at most one lower bound (gt or ge) and one upper bound "
                    "(lt or le)")
        return None

    @property
    def bounded(self) -> bool:
        """Whether any bound is declared."""
        return any(b is not None for b in (self.gt, self.ge, self.lt, self.le))

    @property
    def lower(self) -> float | str | None:
        """The lower bound (open or closed), or ``None``."""
        return self.gt if self.gt is not None else self.ge

    @property
    def upper(self) -> float | str | None:
        """The upper bound (open or closed), or ``None``."""
        return self.lt if self.lt is not None else self.le

    def bounds(self) -> dict[str, float | str]:
        """The declared bounds, keyword → bound (``{"gt": 0.0, "le": 600.0}``)."""
        return {k: getattr(self, k) for k in BOUND_SIGNS if getattr(self, k) is not None}

    def range_text(self, name: str = "value", *, unit: bool = True) -> str:
        """The inequality a value named *name* must satisfy, e.g. ``0 < duration_s ≤ 600 s``,
        ``safety > 1``, ``radius > decay`` (``""`` when unbounded). The unit follows the
        upper, else the lower, bound when it is a number, *unit* is true and the unit is not
        dimensionless."""
        lo, hi = self.lower, self.upper
        if lo is None and hi is None:
            return ""
        last = hi if hi is not None else lo
        shown = (f" {self.unit}" if unit and self.unit not in ("", "-")
                 and not isinstance(last, str) else "")
        if lo is not None and hi is not None:
            lo_op = "<" if self.gt is not None else "≤"
            hi_op = "<" if self.lt is not None else "≤"
            return f"{num(lo)} {lo_op} {name} {hi_op} {num(hi)}{shown}"
        if lo is not None:
            return f"{name} {'>' if self.gt is not None else '≥'} {num(lo)}{shown}"
        return f"{name} {'<' if self.lt is not None else '≤'} {num(hi)}{shown}"

    def broken_bound(self, x: float, values: Mapping[str, Any] | None = None,
                     ) -> tuple[str, float | str] | None:
        """The first bound the number *x* breaks, as (keyword, bound), or ``None``. A
        bound naming a parameter is checked only when *values* holds a finite number for
        it."""
        for kw, bound in self.bounds().items():
            if isinstance(bound, str):
                other = (values or {}).get(bound)
                if not is_real(other):
                    continue
                bound = other
            if not _holds(kw, x, bound):
                return kw, bound
        return None

    def out_of_range(self, x: float) -> bool:
        """Whether the number *x* is not finite or breaks a numeric bound."""
        return not math.isfinite(x) or self.broken_bound(x) is not None


def field_problems(obj) -> list[str]:
    """Every field of the dataclass instance *obj* declared with bounds (a
    :class:`Declared` under the field metadata's ``"declared"``) whose number breaks them,
    one message each: ``name = value: out of range; allowed: range text``."""
    out = []
    for f in dataclasses.fields(obj):
        spec = f.metadata.get("declared")
        value = getattr(obj, f.name)
        if spec is None or not spec.bounded or not isinstance(value, numbers.Real) \
                or isinstance(value, bool):
            continue
        if spec.out_of_range(float(value)):
            out.append(f"{f.name} = {value!r}: out of range; allowed: "
                       f"{spec.range_text(f.name)}")
    return out


def _holds(kw: str, x: float, bound: float) -> bool:
    if kw == "gt":
        return x > bound
    if kw == "ge":
        return x >= bound
    if kw == "lt":
        return x < bound
    return x <= bound


def is_real(v) -> bool:
    """A finite real number that is not a bool (NumPy scalars included; NumPy bools are
    not ``numbers.Real``)."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)


# ----------------------------------------------------------------------------------------
# TOML literals
# ----------------------------------------------------------------------------------------
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k, ensure_ascii=False)


def toml_value(v: Any) -> str:
    """A TOML literal for a plain value (str, bool, int, float, list, dict), as a user
    writes it in a campaign file."""
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
