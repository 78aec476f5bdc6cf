"""Whose fault an error is (docs/design.md §7, Exit codes): :class:`InputError`, the base of
every error that reports the user's mistake — a campaign file, a command-line option, a path,
an FMU, a detector's name or parameters, a campaign directory — with a message naming what is
wrong and how to fix it. ``fdd-campaign`` exits 2 on these; anything else that escapes a
command is an internal error (a fault of the engine or of a library it uses): exit 3, its
traceback kept in a file the message names.

The one module every package may import (it imports nothing of the project), so that the
errors of :mod:`scenarios`, :mod:`detectors`, :mod:`reports` and :mod:`campaign` share one
base. Each error class also keeps the builtin it derives from (``ValueError`` for most), so a
caller's ``except ValueError`` still catches it.
"""

from __future__ import annotations

import shlex

__all__ = ["ArgumentError", "InputError"]


class InputError(Exception):
    """The user's mistake: its message names what is wrong and the fix (exit code 2).

    Not raised itself: each module raises its own subclass (``ConfigError``, ``FmuError``,
    ``UsageError`` …), which also derives from the builtin its callers catch."""


class _Names(dict):
    """The names ``{name}`` fields of an :class:`ArgumentError`'s texts stand for: the
    Python argument (``chunk_size``) or, for the command line, its option (``--chunk-size``,
    or the one *flags* gives)."""

    def __init__(self, flags: dict | None):
        super().__init__()
        self.flags = flags

    def __missing__(self, name: str) -> str:
        if self.flags is None:
            return name
        return self.flags.get(name) or "--" + name.replace("_", "-")


class _Kept(dict):
    """Values that fill some ``{name}`` fields of a text, every other field kept for the
    argument names (:meth:`ArgumentError.said`)."""

    def __missing__(self, name: str) -> str:
        return "{" + name + "}"


def _filled(text: str, values: dict) -> str:
    """*text* with the fields of *values* filled as they are (their braces doubled, so that
    the argument names can still be filled in later)."""
    if not values:
        return text
    return text.format_map(_Kept({k: str(v).replace("{", "{{").replace("}", "}}")
                                  for k, v in values.items()}))


def _word(value) -> str:
    """*value* as the command line writes it (a float without a trailing .0, quoted as a
    shell would need)."""
    if isinstance(value, float):
        return f"{value:g}"
    return shlex.quote(str(value))


def _named(text: str, names: _Names) -> str:
    """*text* with its ``{name}`` fields written as *names* says (as it is when it holds
    other braces, e.g. a path's)."""
    try:
        return text.format_map(names)
    except (KeyError, ValueError, IndexError, AttributeError):
        return text


class ArgumentError(InputError, ValueError):
    """Arguments of a library function that it cannot take, named as Python names them.

    *problems*: one ``(argument, value, problem, example)`` each: *argument* the parameter's
    name (None: *problem* is a whole sentence, :meth:`said`), *value* what was given (None:
    the problem is that it is given), *problem* what is wrong (other arguments written
    ``{name}``), *example* a value that works, or None; *fix* (same ``{name}`` fields) ends
    the message. ``str()`` is the Python caller's message (``chunk_size=0: out of range
    …; fix: e.g. chunk_size=100``); :meth:`for_command_line` the same with each argument
    written as its command-line option (``--chunk-size 0: …; fix: e.g. --chunk-size 100``),
    which ``fdd-campaign`` prints (exit 2)."""

    def __init__(self, problems, fix: str = ""):
        self.problems = [tuple(p) for p in problems]
        self.fix = fix
        super().__init__(self.render(None))

    @classmethod
    def of(cls, argument: str, value, problem: str, example=None, fix: str = "", **values):
        """The error of one argument; *values* fill their own fields of *problem* as they
        are (:meth:`said`)."""
        return cls([(argument, value, _filled(problem, values), example)], fix)

    @classmethod
    def said(cls, text: str, **values):
        """The error of a whole sentence *text* that writes each argument it names as a
        ``{name}`` field (``"{sampling}: the design is {design}; leave {sampling} out"``),
        for a problem that is no value out of range (a combination, a missing file);
        *values* fill their own fields as they are (``design="'grid'"``), braces and all."""
        return cls([(None, None, _filled(text, values), None)])

    def render(self, flags: dict | None) -> str:
        """The message, arguments as Python names them (*flags* None) or as the options of
        *flags* (argument → option; any other ``--`` + its name with dashes)."""
        names = _Names(flags)
        parts = []
        for argument, value, problem, example in self.problems:
            if argument is None:            # a whole sentence (said)
                parts.append(_named(problem, names))
                continue
            name = names[argument]
            if flags is None:
                given, fix = f"{name}={value!r}", f"{name}={example!r}"
            else:
                given, fix = f"{name} {_word(value)}", f"{name} {_word(example)}"
            # no value: the problem is about the argument being given at all
            text = (f"{name} {_named(problem, names)}" if value is None
                    else f"{given}: {_named(problem, names)}")
            if example is not None:
                text += f"; fix: e.g. {fix}"
            parts.append(text)
        message = "; ".join(parts)
        if self.fix:
            message += (", " if self.problems[-1][3] is not None else "; fix: ") + \
                _named(self.fix, names)
        return message

    def for_command_line(self, flags: dict | None = None) -> str:
        """The message with every argument written as its option (:meth:`render`)."""
        return self.render(flags or {})

    def __reduce__(self):
        return (type(self), (self.problems, self.fix))
