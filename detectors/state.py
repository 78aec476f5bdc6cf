"""A fitted detector's learned state as plain data: JSON and NumPy arrays, never pickles.

A campaign directory stores each fitted detector as its registry name, its parameters and
its learned attributes (those ending in ``_``, :meth:`detectors.base.Detector.fitted_state`),
and rebuilds it when read back: the detector is made afresh from its name and parameters
(:func:`detectors.registry.make_detector`) and the learned attributes are set on it. Loading
never runs code named by the stored files (docs/security.md).

The values a detector may keep in its parameters and learned attributes are a small,
explicit set of types (:data:`PLAIN_TYPES_DOC`):

* ``None``, ``bool``, ``int``, ``float``, ``complex``, ``str``;
* NumPy arrays of booleans, integers, floats, complex numbers or unicode strings (any shape,
  byte order kept) and NumPy scalars of those types;
* ``list`` and ``tuple`` of such values (a tuple stays a tuple);
* ``dict`` of such values, with keys that are ``str``, ``int``, ``float``, ``bool``,
  ``None`` or tuples of those;
* frozen dataclasses whose fields hold such values, when their class is registered with
  :func:`register_state_type` (by ``module:qualname``; a stored file can only name a class
  already registered by imported code, it never makes anything be imported).

:func:`encode` turns such a value into a JSON-serialisable document plus a dict of arrays
(stored as ``.npz`` and read back with ``allow_pickle=False``); :func:`decode` is its inverse,
exact to the bit (floats are written by ``repr``, which round-trips, and arrays as ``.npy``
data). Anything else (an object of another class, a function, a set, an object array) raises
:class:`StateTypeError` naming where it was found, e.g. ``design_['solver']``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from scenarios.errors import InputError

#: The supported types in one sentence, quoted by error messages.
PLAIN_TYPES_DOC = ("None, bool, int, float, complex, str, NumPy arrays and scalars of "
                   "bool/int/float/complex/str, and lists, tuples, dicts and registered "
                   "frozen dataclasses of those")

#: Array kinds stored (``numpy.dtype.kind``): bool, signed and unsigned integers, floats,
#: complex numbers and unicode strings; object arrays would need pickles.
ARRAY_KINDS = "biufcU"

_TAGS = ("$ndarray", "$scalar", "$tuple", "$dict", "$dataclass", "$complex", "$float")

#: Registered frozen dataclasses: ``"module:qualname"`` → class.
_STATE_TYPES: dict[str, type] = {}


class StateTypeError(InputError, TypeError):
    """A value that is not plain data (:data:`PLAIN_TYPES_DOC`); ``path`` says where it is."""

    def __init__(self, path: str, message: str):
        super().__init__(f"{path}: {message}")
        self.path, self.detail = path, message

    def __reduce__(self):
        return (type(self), (self.path, self.detail))


def _type_name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def register_state_type(cls: type) -> type:
    """Allow instances of the frozen dataclass *cls* in stored parameters and learned state
    (usable as a class decorator). Its fields must themselves hold plain data. Registered
    by ``module:qualname``; registering the same class twice is harmless."""
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)
            and cls.__dataclass_params__.frozen):
        raise TypeError(f"register_state_type: {cls!r} is not a frozen dataclass; only "
                        "frozen dataclasses of plain values can be stored as data")
    name = _type_name(cls)
    other = _STATE_TYPES.get(name)
    if other is not None and other is not cls:
        raise TypeError(f"register_state_type: another class is already registered as {name}")
    _STATE_TYPES[name] = cls
    return cls


# ---- encoding --------------------------------------------------------------------------------
def _float(x: float):
    """A float as JSON: a number when finite, else a tagged string (JSON has no NaN/inf)."""
    return x if math.isfinite(x) else {"$float": repr(x)}


def _key(k, path: str):
    """A dict key as JSON (keys that are not plain strings go into a ``$dict`` list)."""
    if k is None or isinstance(k, (bool, int, str)):
        return k
    if isinstance(k, float):
        return _float(k)
    if isinstance(k, tuple):
        return {"$tuple": [_key(x, f"{path}[key]") for x in k]}
    raise StateTypeError(path, f"a dict key of type {type(k).__name__} is not plain data; "
                               "use str, int, float, bool, None or tuples of those")


class _Encoder:
    def __init__(self, arrays: dict[str, np.ndarray] | None = None):
        self.arrays = {} if arrays is None else arrays

    def array(self, a: np.ndarray, path: str) -> str:
        if a.dtype.kind not in ARRAY_KINDS or a.dtype.fields is not None:
            raise StateTypeError(path, f"an array of dtype {a.dtype} is not plain data "
                                       "(object and structured arrays would need pickles); "
                                       "store numbers or strings")
        key = f"a{len(self.arrays)}"
        self.arrays[key] = a
        return key

    def value(self, v: Any, path: str):
        if v is None or type(v) in (bool, int, str):
            return v
        if isinstance(v, np.generic):
            a = np.asarray(v)
            return {"$scalar": self.array(a, path), "dtype": a.dtype.str}
        if type(v) is float:
            return _float(v)
        if type(v) is complex:
            return {"$complex": [_float(v.real), _float(v.imag)]}
        if isinstance(v, np.ndarray):
            if type(v) is not np.ndarray:
                raise StateTypeError(path, f"{type(v).__name__} (an ndarray subclass) is not "
                                           "plain data; store np.asarray(value)")
            return {"$ndarray": self.array(v, path), "dtype": v.dtype.str,
                    "shape": list(v.shape)}
        if type(v) is tuple:
            return {"$tuple": [self.value(x, f"{path}[{i}]") for i, x in enumerate(v)]}
        if type(v) is list:
            return [self.value(x, f"{path}[{i}]") for i, x in enumerate(v)]
        if type(v) is dict:
            plain = all(type(k) is str and not k.startswith("$") for k in v)
            if plain:
                return {k: self.value(x, f"{path}[{k!r}]") for k, x in v.items()}
            return {"$dict": [[_key(k, path), self.value(x, f"{path}[{k!r}]")]
                              for k, x in v.items()]}
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            name = _type_name(type(v))
            if _STATE_TYPES.get(name) is not type(v):
                raise StateTypeError(path, f"the dataclass {name} is not registered as plain "
                                           "data; decorate it with "
                                           "detectors.state.register_state_type (it must be "
                                           "frozen and hold plain values)")
            return {"$dataclass": name,
                    "fields": {f.name: self.value(getattr(v, f.name), f"{path}.{f.name}")
                               for f in dataclasses.fields(v)}}
        raise StateTypeError(path, f"a value of type {_type_name(type(v))} is not plain data "
                                   f"({PLAIN_TYPES_DOC})")


def encode(values: dict[str, Any], root: str = "",
           arrays: dict[str, np.ndarray] | None = None) -> tuple[dict, dict[str, np.ndarray]]:
    """(JSON document, arrays) of the plain-data dict *values* (attribute or parameter name →
    value). Raises :class:`StateTypeError` naming the first value that is not plain data,
    as ``<root><name>[…]``. Pass the *arrays* of an earlier call to store several documents
    with one set of arrays (keys ``a0``, ``a1``, … continue)."""
    enc = _Encoder(arrays)
    doc = {name: enc.value(v, f"{root}{name}") for name, v in values.items()}
    return doc, enc.arrays


def check_plain(values: dict[str, Any], root: str = "") -> None:
    """Raise :class:`StateTypeError` when *values* hold anything but plain data."""
    encode(values, root)


# ---- decoding --------------------------------------------------------------------------------
class StateFormatError(InputError, ValueError):
    """A stored document that is not a valid encoding (damaged or edited by hand)."""


def _decode_float(d) -> float:
    text = d.get("$float")
    if text not in ("nan", "inf", "-inf"):
        raise StateFormatError(f"invalid $float {text!r}")
    return float(text)


class _Decoder:
    def __init__(self, arrays: dict[str, np.ndarray]):
        self.arrays = arrays

    def array(self, key, dtype, path: str) -> np.ndarray:
        if not isinstance(key, str) or key not in self.arrays:
            raise StateFormatError(f"{path}: array {key!r} is not in the stored arrays")
        a = self.arrays[key]
        if a.dtype.str != dtype:
            raise StateFormatError(f"{path}: array {key!r} has dtype {a.dtype.str}, the "
                                   f"document says {dtype}")
        return a

    def key(self, k, path: str):
        if isinstance(k, dict):
            if set(k) == {"$tuple"} and isinstance(k["$tuple"], list):
                return tuple(self.key(x, path) for x in k["$tuple"])
            if set(k) == {"$float"}:
                return _decode_float(k)
            raise StateFormatError(f"{path}: invalid dict key {k!r}")
        if isinstance(k, list):
            raise StateFormatError(f"{path}: invalid dict key {k!r}")
        return k

    def value(self, v, path: str):
        if v is None or isinstance(v, (bool, int, float, str)):
            return v
        if isinstance(v, list):
            return [self.value(x, f"{path}[{i}]") for i, x in enumerate(v)]
        if not isinstance(v, dict):
            raise StateFormatError(f"{path}: unexpected JSON value {v!r}")
        tags = [k for k in v if k.startswith("$")]
        if not tags:
            return {k: self.value(x, f"{path}[{k!r}]") for k, x in v.items()}
        tag = tags[0]
        if len(tags) != 1 or tag not in _TAGS:
            raise StateFormatError(f"{path}: unknown tag(s) {tags}")
        if tag == "$ndarray":
            a = self.array(v["$ndarray"], v.get("dtype"), path)
            if list(a.shape) != v.get("shape"):
                raise StateFormatError(f"{path}: array shape {list(a.shape)}, the document "
                                       f"says {v.get('shape')}")
            return a
        if tag == "$scalar":
            a = self.array(v["$scalar"], v.get("dtype"), path)
            if a.shape != ():
                raise StateFormatError(f"{path}: a scalar stored with shape {a.shape}")
            return a[()]
        if tag == "$float":
            return _decode_float(v)
        if tag == "$complex":
            re, im = (self.value(x, path) for x in v["$complex"])
            return complex(re, im)
        if tag == "$tuple":
            return tuple(self.value(x, f"{path}[{i}]") for i, x in enumerate(v["$tuple"]))
        if tag == "$dict":
            out = {}
            for item in v["$dict"]:
                if not (isinstance(item, list) and len(item) == 2):
                    raise StateFormatError(f"{path}: invalid $dict item {item!r}")
                k = self.key(item[0], path)
                out[k] = self.value(item[1], f"{path}[{k!r}]")
            return out
        # $dataclass: only a class registered by imported code, never one named by the file
        name = v["$dataclass"]
        cls = _STATE_TYPES.get(name)
        if cls is None:
            raise StateFormatError(f"{path}: the dataclass {name!r} is not registered "
                                   "(detectors.state.register_state_type); it is not rebuilt")
        fields = v.get("fields")
        names = [f.name for f in dataclasses.fields(cls)]
        if not isinstance(fields, dict) or sorted(fields) != sorted(names):
            raise StateFormatError(
                f"{path}: the fields of {name} are {names}, the document "
                f"gives {sorted(fields) if isinstance(fields, dict) else fields}")
        obj = cls.__new__(cls)          # the stored field values exactly, as a pickle would
        for f in names:
            object.__setattr__(obj, f, self.value(fields[f], f"{path}.{f}"))
        return obj


def decode(doc: dict, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """The values encoded by :func:`encode` (*doc* as read from JSON, *arrays* as read from
    the ``.npz`` file with ``allow_pickle=False``). Raises :class:`StateFormatError` on a
    document that is not a valid encoding."""
    if not isinstance(doc, dict):
        raise StateFormatError(f"expected a JSON object of values, got {type(doc).__name__}")
    dec = _Decoder(arrays)
    return {name: dec.value(v, name) for name, v in doc.items()}
