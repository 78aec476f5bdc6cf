"""The lock of a campaign directory: one run at a time writes into it (docs/security.md).

A second ``fdd-campaign run`` into a directory being written would store every run twice; it
is refused with the name of the run holding the lock (:class:`CampaignLockedError`, exit 2).
"""

from __future__ import annotations

import json
import os
import socket
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from scenarios.errors import InputError

#: The lock file, in the campaign directory.
LOCK_NAME = ".fdd-campaign.lock"
#: How long a refused run waits for a new holder to write its name: 20 × 50 ms.
HOLDER_WAIT_TRIES, HOLDER_WAIT_S = 20, 0.05


class CampaignLockedError(InputError, ValueError):
    """Another run is writing into the campaign directory (exit code 2)."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:        # alive, owned by another user
        return True
    except OSError:
        return False
    return True


def holder_text(info: dict) -> str:
    """``pid P on host H, started T`` of a lock file's content."""
    return (f"pid {info.get('pid', '?')} on host {info.get('host', '?')}, started "
            f"{info.get('started', '?')}")


class DirLock:
    """The lock of a campaign directory (``DIR/.fdd-campaign.lock``), held by the one run
    writing into it.

    The file names its holder (pid, host, start time, command) and is locked with
    ``flock``, which the operating system releases when the holder exits, however it exits:
    a second run finds it locked and is refused with the holder's name
    (:class:`CampaignLockedError`); a run finding the lock left by a killed run (file
    present, nobody holding it) takes it over with a one-line note. Released by
    :meth:`release` (the file is removed). On systems without ``fcntl`` the file is
    created exclusively and a lock whose pid no longer runs on this host is stale.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.fd: int | None = None

    @staticmethod
    def _me() -> dict:
        return {"pid": os.getpid(), "host": socket.gethostname(),
                "started": datetime.now(timezone.utc).astimezone().isoformat(timespec="seconds"),
                "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:300]}

    @staticmethod
    def _parse(data: bytes) -> dict | None:
        if not data.strip():
            return None
        try:    # the first object: a holder rewriting the file may leave an older tail
            info, _ = json.JSONDecoder().raw_decode(data.decode().lstrip())
        except (json.JSONDecodeError, UnicodeDecodeError):
            return {"pid": "?", "host": "?", "started": "? (unreadable lock file)"}
        return info if isinstance(info, dict) else {}

    def _read_holder(self, fd: int) -> dict | None:
        """The holder named in the locked file *fd*. A holder that has just taken the lock
        writes its name a moment later: an empty file is read again for up to a second."""
        for _ in range(HOLDER_WAIT_TRIES):
            holder = self._parse(os.pread(fd, 65536, 0))
            if holder is not None:
                return holder
            time.sleep(HOLDER_WAIT_S)
        return None

    def _refuse(self, holder: dict | None) -> CampaignLockedError:
        return CampaignLockedError(
            f"{self.path.parent} is being written by another run "
            f"({holder_text(holder or {})}); two runs into one directory would store every "
            "run twice: wait for it to finish (it resumes what is done) or stop it, then run "
            "this command again")

    def _stale_note(self, previous: dict | None, log) -> None:
        if previous and previous.get("pid") != os.getpid():
            log(f"note: taking over the lock of {self.path.parent} left by a run that is no "
                f"longer running ({holder_text(previous)})")

    def acquire(self, log=None) -> "DirLock":
        """Take the lock (creating the directory); :class:`CampaignLockedError` when another
        live run holds it."""
        log = log or (lambda msg: None)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            import fcntl
        except ImportError:                    # pragma: no cover - not on POSIX
            return self._acquire_exclusive(log)
        for _ in range(20):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = self._read_holder(fd)
                os.close(fd)
                raise self._refuse(holder) from None
            try:                               # the previous holder may have removed it
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            self._stale_note(self._parse(os.pread(fd, 65536, 0)), log)
            me = json.dumps(self._me()).encode()
            os.pwrite(fd, me, 0)               # never empty while held: written, then cut
            os.ftruncate(fd, len(me))
            self.fd = fd
            return self
        raise CampaignLockedError(f"cannot take the lock {self.path}: it keeps being replaced")

    def _acquire_exclusive(self, log) -> "DirLock":  # pragma: no cover - not on POSIX
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o666)
            except FileExistsError:
                holder = self._parse(self.path.read_bytes()) or {}
                if (holder.get("host") == socket.gethostname()
                        and isinstance(holder.get("pid"), int)
                        and not _pid_alive(holder["pid"])):
                    self._stale_note(holder, log)
                    self.path.unlink(missing_ok=True)
                    continue
                raise self._refuse(holder) from None
            os.write(fd, json.dumps(self._me()).encode())
            self.fd = fd
            return self
        raise self._refuse(None)

    def release(self) -> None:
        """Remove the lock file and release the lock (idempotent)."""
        if self.fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)   # still holding it: no one else has it
        finally:
            os.close(self.fd)
            self.fd = None

    @classmethod
    def holder(cls, path) -> dict | None:
        """Who the lock file at *path* names when that process still runs on this host
        (a hint for readers; never takes the lock), else None."""
        try:
            info = cls._parse(Path(path).read_bytes())
        except OSError:
            return None
        if (info and info.get("host") == socket.gethostname()
                and isinstance(info.get("pid"), int) and _pid_alive(info["pid"])):
            return info
        return None
