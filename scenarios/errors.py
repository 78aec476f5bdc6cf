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

__all__ = ["InputError"]


class InputError(Exception):
    """The user's mistake: its message names what is wrong and the fix (exit code 2).

    Not raised itself: each module raises its own subclass (``ConfigError``, ``FmuError``,
    ``UsageError`` …), which also derives from the builtin its callers catch."""
