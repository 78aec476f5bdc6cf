"""``fdd-campaign``: the command line (docs/design.md §7, Command line). Exit codes: 0 ok, 1 gate
failed, 2 bad input, 3 internal error, 130 interrupted."""

from __future__ import annotations

import argparse
import sys
import textwrap
import warnings

from scenarios.errors import InputError

from .common import (  # noqa: F401  (part of this module's interface)
    EXIT_GATE,
    EXIT_INPUT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    UsageError,
    add_command,
    check_writable,
    input_message,
    print_error,
    report_internal_error,
)
from ..startup import start_up_done
from .evidence import add_evidence_parsers
from .falsify import add_falsify_parser
from .result_commands import add_result_parsers
from .run_commands import add_run_parsers, cmd_run
from .study_commands import add_study_parsers
from .tool_commands import add_simulate_parser, add_tool_parsers
from .tradeoff import add_tradeoff_parser

#: The command table: one entry per command group, in the order ``--help`` lists them; each
#: registers its commands with :func:`campaign.cli.common.add_command` (and a group of
#: commands, ``fmu`` and ``study``, with :func:`campaign.cli.common.add_group`).
COMMAND_GROUPS = (add_run_parsers, add_result_parsers, add_simulate_parser, add_tool_parsers,
                  add_study_parsers, add_falsify_parser, add_evidence_parsers,
                  add_tradeoff_parser)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fdd-campaign",
        description="Monte Carlo evaluation campaigns for control-surface fault detectors: "
                    "false alarms, missed detections and detection time performance (DTP).",
        epilog=textwrap.dedent("""\
            examples:
              fdd-campaign run addsafe-mc --jobs 2 --out results/
              fdd-campaign gate results/ --junit gate.xml
              fdd-campaign simulate --surface elevator --manoeuvre turn_coordination \\
                  --fault solid_jam --plot run.png --out run.parquet"""),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    from ..store.files import UNKNOWN_VERSION, engine_version

    v = engine_version()
    v += " (not installed)" if v == UNKNOWN_VERSION else ""
    parser.add_argument("--version", action="version", version=f"fdd-campaign {v}")
    subs = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMAND_GROUPS:
        add(subs)
    return parser


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line on stderr (an old campaign-file spelling, a solver's remark)."""
    prefix = "note" if issubclass(category, FutureWarning) else category.__name__
    print(f"{prefix}: {message}", file=sys.stderr, flush=True)


class _ReaderMayLeave:
    """Standard output that a reader may stop reading (``fdd-campaign run … | head -1``):
    once a write finds the pipe closed, the rest of the output goes to the null device, so
    the command finishes its work and exits with its own status (a gate's verdict
    included) instead of stopping half-way with an error about a path."""

    def __init__(self, stream):
        self._stream = stream

    def _left(self):
        import os

        self._stream = open(os.devnull, "w")

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._left()
            return len(text)

    def flush(self):
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._left()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def main(argv=None) -> int:
    """Run the command of *argv* (default the process's arguments); returns its exit code."""
    if isinstance(sys.stdout, _ReaderMayLeave):
        return _main(argv)
    stdout = sys.stdout
    sys.stdout = _ReaderMayLeave(stdout)
    try:
        return _main(argv)
    finally:
        if isinstance(sys.stdout, _ReaderMayLeave):
            sys.stdout = stdout


def _main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_INPUT
    if args.func is not cmd_run:
        # the collector deferred by console_main waits for a campaign's kernels only
        # (campaign.runner turns it on again); every other command has it from here on
        start_up_done()
    from ..execute import one_blas_thread

    try:
        with warnings.catch_warnings(), one_blas_thread():
            warnings.showwarning = _note
            return args.func(args)
    # bad input: the user's mistake (scenarios.errors.InputError: a campaign file, an option,
    # a directory, an FMU, a detector's name or parameters, a plugin that fails at the
    # start), or a file that is missing; the message names the field and the fix
    except (InputError, FileNotFoundError) as exc:
        print_error(input_message(exc, getattr(args, "argument_flags", None))
                    if isinstance(exc, InputError) else str(exc))
        return EXIT_INPUT
    except OSError as exc:    # a path the checks above could not foresee (disk full, …)
        where = f" {exc.filename}" if exc.filename else ""
        print_error(f"cannot access{where}: {exc.strerror or exc}; fix: check that the path "
                    "exists, that you may write there and that the disk has room")
        return EXIT_INPUT
    except KeyboardInterrupt:
        print_error("interrupted")
        return EXIT_INTERRUPTED
    except Exception as exc:  # noqa: BLE001 - anything else is a fault of the engine or a library
        report_internal_error(exc, sys.argv[1:] if argv is None else list(argv))
        return EXIT_INTERNAL


def console_main() -> None:
    """Deprecated: the executable of an installation made before it moved to
    :func:`campaign.cli.console_main` (reinstall to use that), once this module is imported."""
    from ..startup import defer_collection

    defer_collection()
    leave(main())


def leave(code: int) -> None:
    """Exit the process with *code*, skipping the interpreter's teardown when that is safe.

    The teardown frees every module and object one by one (numba's compiled libraries,
    pandas, scipy.stats, the campaign's arrays): 0.35–0.4 s after a campaign of a few seconds
    (docs/execution.md, "Leaving the process"), none of it output. The exit handlers still run
    (temporary directories, logging, what a library registered), the standard streams are
    flushed, and then the process ends with ``os._exit``. With another thread or a child
    process still alive (a library's worker that the normal exit would join) it is the
    normal exit, ``sys.exit(code)``."""
    import atexit
    import os
    import threading

    busy = any(t is not threading.main_thread() and t.is_alive() and not t.daemon
               for t in threading.enumerate())
    children = sys.modules.get("multiprocessing") is not None and bool(
        sys.modules["multiprocessing"].active_children())
    run_handlers = getattr(atexit, "_run_exitfuncs", None)
    if busy or children or run_handlers is None:
        sys.exit(code)
    run_handlers()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):   # a reader that left (``| head``), a closed stream
        pass
    os._exit(code or 0)


if __name__ == "__main__":
    console_main()
