"""An audit hook (sys.addaudithook) that records every file written into one campaign
directory without passing through campaign.store's directory classes (CampaignDir, SearchDir,
the lock): what the tests of "CampaignDir is the only writer" assert empty."""

from __future__ import annotations

import contextlib
import os
import sys

#: The directory whose writes are recorded (None: the hook records nothing) and what it found:
#: (path relative to it, the innermost project file on the stack) of each write outside.
_AUDITED: dict = {"root": None, "outside": []}
#: Modules through which a write into a campaign directory may pass.
WRITERS = ("campaign/store/directory.py", "campaign/store/lock.py")


def _written_path(event: str, args) -> str | None:
    """The path a file event writes (os.replace/rename: its destination; open: a file opened
    for writing, by mode or flags), else None."""
    if event == "os.rename":
        return os.fspath(args[1])
    if event == "open" and isinstance(args[0], (str, os.PathLike)):
        mode, flags = args[1], args[2]
        writes = (any(c in mode for c in "wax+") if isinstance(mode, str)
                  else bool(flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT)))
        return os.fspath(args[0]) if writes else None
    return None


def _audit(event: str, args) -> None:
    root = _AUDITED["root"]
    if root is None or event not in ("open", "os.rename"):
        return
    path = _written_path(event, args)
    if not isinstance(path, str):
        return
    path = os.path.abspath(path)
    if not path.startswith(root):
        return
    frame, names = sys._getframe(1), []
    while frame is not None:
        names.append(frame.f_code.co_filename.replace(os.sep, "/"))
        frame = frame.f_back
    if not any(name.endswith(WRITERS) for name in names):
        project = next((n for n in names if "/campaign/" in n or "/reports/" in n), names[0])
        _AUDITED["outside"].append((os.path.relpath(path, root), project))


@contextlib.contextmanager
def writes_outside_the_store(root):
    """Within the block, record every file written into directory *root* (in this process)
    not through campaign.store's directory classes; yields the list, filled at the end."""
    if not getattr(sys, "_fdd_directory_audit", False):
        sys.addaudithook(_audit)          # a hook cannot be removed: it stays idle after
        sys._fdd_directory_audit = True
    found: list = []
    _AUDITED.update(root=os.path.abspath(root) + os.sep, outside=[])
    try:
        yield found
    finally:
        found.extend(_AUDITED["outside"])
        _AUDITED["root"] = None
