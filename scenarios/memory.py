"""Returning freed memory to the system between batches of runs.

Series of a block of runs (about 1 MB each for 25 runs of 60 s at 100 Hz) come from the C
allocator's heaps once glibc has raised its mmap threshold, and a heap keeps what is freed:
a process that simulates a learning set in parts, or a batch in blocks, holds the memory
of the parts after it copied them into the result. :func:`release_freed_memory` hands it
back (glibc's ``malloc_trim``; nothing on other C libraries). Measured on the learning set
of ``chen-mc`` (300 runs on two threads): 790 MB held after it without the trim, 594 MB
with it (docs/aircraft.md).
"""

from __future__ import annotations

import ctypes
import functools


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim``, or None; looked up on first use among the symbols the process
    has already loaded (the C library's), without ``ctypes.util.find_library``: that runs
    ``ldconfig`` in a child process, and a child forked from a campaign's process shows that
    process's resident memory a second time to whoever sums the process tree (``fdd-campaign
    bench``'s peak)."""
    try:
        libc = ctypes.CDLL(None)
    except OSError:  # pragma: no cover - a platform without dlopen(NULL)
        return None
    return getattr(libc, "malloc_trim", None)


def release_freed_memory() -> None:
    """Give the memory freed so far back to the system: glibc's ``malloc_trim`` (a no-op
    where the C library has none) and, once pyarrow is imported, the unused memory of its
    allocator (the string columns of pandas' tables live there)."""
    import sys

    trim = _malloc_trim()
    if trim is not None:
        trim(0)
    if "pyarrow" in sys.modules:
        sys.modules["pyarrow"].default_memory_pool().release_unused()
