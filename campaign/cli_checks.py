"""Checks of the command line's input that raise :class:`UsageError` (exit code 2) before
any work starts: the error type and the writability of output paths (docs/design.md §7)."""

from __future__ import annotations

from pathlib import Path


class UsageError(ValueError):
    """Bad command-line input (exit code 2)."""


def check_writable(path, option: str, *, directory: bool = False) -> None:
    """Raise :class:`UsageError` (exit 2) naming *option*, *path* and the fix when *path*
    (a file, or a directory when *directory*) cannot be written: it exists and is not
    writable (or not of its kind), or the nearest existing folder above it is not a
    writable directory."""
    import os

    target = Path(path)
    fix = "fix: choose a writable location (e.g. under your home directory)"
    if target.exists():
        if directory and not target.is_dir():
            raise UsageError(f"{option} {path}: exists and is not a directory; {fix}")
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
        raise UsageError(f"{option} {path}: {parent} is a file, not a folder; {fix}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: cannot create it, the folder {parent} is not "
                         f"writable (permission denied); {fix}, or make that folder "
                         f"writable: chmod u+w {parent}")
