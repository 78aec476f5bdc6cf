"""What every ``fdd-campaign`` command shares (docs/design.md §7, Command line): the exit
codes, :class:`UsageError`, the options the library's argument errors are named by
(:func:`input_message`), the registration of a sub-command (:func:`add_command`) and of a
group of them (:func:`add_group`), and the check that an output path can be written. Kept
apart from :mod:`campaign.cli.commands` so that
commands defined in their own modules (:mod:`campaign.cli.falsify`) use them without
importing the command line itself."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from scenarios.errors import ArgumentError, InputError

EXIT_OK, EXIT_GATE, EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class UsageError(InputError, ValueError):
    """Bad command-line input (exit code 2)."""


#: Options whose name is not the library argument's with dashes (``chunk_size`` →
#: ``--chunk-size``): argument → option (``fdd-campaign bench``).
ARGUMENT_FLAGS = {"n_runs": "--runs", "duration_s": "--duration"}


def input_message(exc: InputError, flags: dict | None = None) -> str:
    """The message of the user's mistake *exc* as the command line says it: a library
    function's :class:`scenarios.errors.ArgumentError` names its command-line options
    (``--chunk-size 0`` for ``chunk_size=0``; *flags*, the command's own argument →
    option, before :data:`ARGUMENT_FLAGS`), any other as it is."""
    if isinstance(exc, ArgumentError):
        return exc.for_command_line({**ARGUMENT_FLAGS, **(flags or {})})
    return str(exc)


def argument_flags(parser, flags: dict) -> None:
    """Declare the options of *parser*'s command whose name is not that of the library
    argument they give (``{"label": "--detector"}``; added to those declared before):
    :func:`input_message` names the command's argument errors by them."""
    parser.set_defaults(argument_flags={**(parser.get_default("argument_flags") or {}),
                                        **flags})


def add_command(subs, name: str, help_: str, example: str, func):
    """Register the sub-command *name* of *subs* (an ``add_subparsers`` action): *help_* is
    its line in the command list and its description, *example* the command its ``--help``
    ends with, *func* (``args -> exit code``) what it runs. The one way every module of the
    command line adds its commands; returns the sub-parser, for the command's arguments."""
    import argparse

    p = subs.add_parser(name, help=help_, description=help_, epilog="example:\n  " + example,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.set_defaults(func=func)
    return p


def add_group(subs, name: str, help_: str, description: str, dest: str, metavar: str):
    """Register the command group *name* of *subs* (``fdd-campaign NAME COMMAND``): *help_*
    is its line in the command list, *description* heads its ``--help``, and the chosen
    command is stored as *dest*, listed as *metavar*. Returns the group's ``add_subparsers``
    action, to which :func:`add_command` adds its commands."""
    group = subs.add_parser(name, help=help_, description=description)
    return group.add_subparsers(dest=dest, metavar=metavar, required=True)


def print_error(msg: str) -> None:
    """*msg* on stderr as the command line's error line (``fdd-campaign: error: …``)."""
    print(f"fdd-campaign: error: {msg}", file=sys.stderr)


def report_internal_error(exc: BaseException, argv: list[str]) -> Path | None:
    """Tell the user that *exc*, raised by the command *argv*, is a fault of the engine or
    of a library it uses, not of their input (exit code 3): a line on stderr naming the
    error, and one naming the file its traceback was written to (a new file in the system's
    temporary folder, headed by the command) with the request to report it. Returns that
    file (None when it could not be written: the traceback then goes to stderr)."""
    import tempfile
    import traceback

    text = "".join(traceback.format_exception(exc))
    try:
        handle, name = tempfile.mkstemp(prefix="fdd-campaign-error-", suffix=".txt", text=True)
        with os.fdopen(handle, "w", encoding="utf-8") as file:
            file.write(f"fdd-campaign {' '.join(argv)}\n\n{text}")
        where = Path(name)
    except OSError:
        print(text, file=sys.stderr, end="")
        where = None
    print(f"fdd-campaign: internal error: {type(exc).__name__}: {exc}", file=sys.stderr)
    print("  a fault of fdd-campaign or of a library it uses, not of your input; its traceback "
          f"is {f'in {where}' if where else 'above'}: please report it with that traceback and "
          "the command you ran", file=sys.stderr)
    return where


def check_writable(path, option: str, *, directory: bool = False) -> None:
    """Raise :class:`UsageError` (exit 2) naming *option*, *path* and the fix when *path*
    (a file, or a directory when *directory*) cannot be written: it exists and is not of its
    kind (a file where a directory is wanted, or the reverse) or is not writable, or a folder
    above it is a file, or the nearest existing folder above it is not writable.

    A file's folders that do not exist yet are created here, before any work (as ``mkdir
    -p``; as a directory option's directory is created by the command that writes it), so
    that ``gate DIR --junit reports/gate.xml`` writes its report where it is asked to."""
    import os

    target = Path(path)
    fix = "fix: choose a writable location (e.g. under your home directory)"
    if target.exists():
        if directory and not target.is_dir():
            raise UsageError(f"{option} {path}: is a file, not a directory; fix: pass a "
                             f"directory (a new or empty one), e.g. {option} "
                             f"{target.with_suffix('')}-out/")
        if not directory and target.is_dir():
            raise UsageError(f"{option} {path}: is a directory, a file name is needed; fix: "
                             f"e.g. {option} {target / 'out'}")
        if not os.access(target, os.W_OK | (os.X_OK if directory else 0)):
            raise UsageError(f"{option} {path}: not writable (permission denied); {fix}, or "
                             f"make it writable: chmod u+w {target}")
        return
    parent = target.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: {parent} is a file, not a folder; fix: name a "
                         f"path in a folder (or a new one), not under the file {parent}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: cannot create it, the folder {parent} is not "
                         f"writable (permission denied); {fix}, or make that folder "
                         f"writable: chmod u+w {parent}")
    if not directory:
        try:
            target.absolute().parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"{option} {path}: cannot create its folder "
                             f"{target.absolute().parent}: {exc.strerror or exc}; {fix}") from None
