"""The start of a process that runs a campaign command (``fdd-campaign``): the BLAS thread
count it exports, and the garbage collector while the command starts.

* :data:`BLAS_THREAD_VARIABLES`: the environment variables that set the thread count of the
  BLAS libraries NumPy and SciPy load (:func:`campaign.execute.one_blas_thread`).
* :func:`defer_collection`, :func:`start_up_done`: the imports of the libraries and the
  loaded kernels make about 180 000 objects that live until the process ends, and each full
  pass of the collector over them takes about 80 ms with the GIL held, the worker threads
  waiting; ``fdd-campaign run`` collects nothing while it starts and then moves those
  objects out of the collector's reach (docs/execution.md, "The collector at start-up").

This module imports nothing but the standard library: the executable calls it before NumPy
loads.
"""

from __future__ import annotations

import gc

#: Environment variables that set the thread count of the BLAS libraries NumPy and SciPy load
#: (OpenBLAS, MKL); one exported by the user wins over :func:`campaign.execute.one_blas_thread`.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

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
