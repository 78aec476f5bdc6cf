"""The one progress reporter of the commands that simulate runs: runs done of a total,
share, rate and ETA, on a terminal line or as log lines."""

from __future__ import annotations

import sys
import time


class Progress:
    """The one progress reporter of the commands that simulate runs (``run``, ``falsify``,
    ``certify --sampling``), driven by the runs as they finish: runs done of *total*, share,
    rate and ETA. The rate counts only the runs computed since the reporter started (not
    those done before, *done*, nor those read back, ``update(n, computed=False)``).

    With *log* (a callable taking one line), every update is one line, after *label* and
    before the update's *note*. Otherwise the line goes to *stream* (default stderr), after
    *label*: on a terminal one line with a bar, rewritten in place; elsewhere a line every
    5 s and at the end. *unit* names what is counted (``report`` counts figures too)."""

    def __init__(self, total: int, done: int = 0, enabled: bool = True, stream=None, *,
                 log=None, label: str = "", unit: str = "runs"):
        self.total, self.done, self.enabled = total, done, enabled
        self.stream = stream or sys.stderr
        self.log, self.label, self.unit = log, label, unit
        self.start = time.perf_counter()
        self.start_done = done
        self.last_print = -1.0
        self.tty = log is None and hasattr(self.stream, "isatty") and self.stream.isatty()

    def update(self, n: int, *, computed: bool = True, note: str = "") -> None:
        """*n* more runs done (*computed*: simulated now, else read back)."""
        self.done += n
        if not computed:
            self.start_done += n
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        new = self.done - self.start_done
        rate = new / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        frac = self.done / self.total if self.total else 1.0
        line = (f"{self.done}/{self.total} {self.unit} {100 * frac:5.1f} %  "
                f"{rate:7.1f} {self.unit}/s  ETA {eta:5.1f} s")
        if self.log is not None:
            self.log(f"{self.label}{line}{note}")
            return
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        line = f"{self.label}[{bar}] {line}"
        if self.tty:
            print("\r" + line, end="", file=self.stream, flush=True)
        elif elapsed - self.last_print >= 5.0 or self.done >= self.total:
            print(line, file=self.stream, flush=True)
            self.last_print = elapsed

    def close(self) -> None:
        if self.enabled and self.tty:
            print(file=self.stream, flush=True)
