"""Returning freed memory to the system between batches of runs.

Series of a block of runs (about 1 MB each for 25 runs of 60 s at 100 Hz) come from the C
allocator's heaps once glibc has raised its mmap threshold, and a heap keeps what is freed:
a process that simulates a learning set in parts, or a batch in blocks, holds the memory
of the parts after it copied them into the result. :func:`release_freed_memory` hands it
back (glibc's ``malloc_trim``; nothing on other C libraries). Measured on the learning set
of ``chen-mc`` (300 runs on two threads): 790 MB held after it without the trim, 594 MB
with it (docs/aircraft.md).

The garbage collector at the start of a command-line process
(:func:`defer_collection`, :func:`start_up_done`): the imports of the libraries and the loaded
kernels make about 180 000 objects that live until the process ends, and each full pass of
the collector over them takes about 80 ms with the GIL held, the worker threads waiting;
``fdd-campaign run`` collects nothing while it starts and then moves those objects out of the
collector's reach (docs/execution.md, "The collector at start-up").
"""

from __future__ import annotations

import ctypes
import functools
import gc


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


#: Whether :func:`defer_collection` turned the collector off and :func:`start_up_done` has
#: not yet turned it on again.
_deferred = False


def defer_collection() -> None:
    """Turn the garbage collector off for the start-up of a process that runs one command
    (``fdd-campaign run``), until :func:`start_up_done`: the imported modules and the loaded
    kernels live until the exit, and the collector's passes over them while they are made
    find nothing to free. A no-op when the collector is off already (the caller's choice,
    kept)."""
    global _deferred
    if gc.isenabled():
        gc.disable()
        _deferred = True


def start_up_done() -> None:
    """End of the start-up deferred by :func:`defer_collection`: every object there is now is
    moved out of the collector's reach for good (``gc.freeze``; the process keeps them until
    it ends) and the collector is on again for what the command makes from here on, so a
    campaign of any size frees its garbage as before. A no-op without
    :func:`defer_collection`: a program that calls :func:`campaign.run` keeps its collector
    as it is."""
    global _deferred
    if _deferred:
        _deferred = False
        gc.freeze()
        gc.enable()
