"""The start of a process that runs a campaign command (``fdd-campaign``): the BLAS thread
count it exports, and the garbage collector while the command starts.

* :data:`BLAS_THREAD_VARIABLES`: the environment variables that set the thread count of the
  BLAS libraries NumPy and SciPy load (:func:`campaign.execute.one_blas_thread`);
  :func:`export_one_blas_thread` sets them before NumPy loads, so that its BLAS and SciPy's
  start no thread pool that no command uses; :func:`user_environment` is the environment
  without what this process exported itself.
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
import os
import sys
from contextlib import contextmanager

#: Environment variables that set the thread count of the BLAS libraries NumPy and SciPy load
#: (OpenBLAS, MKL); one exported by the user wins over :func:`campaign.execute.one_blas_thread`.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: The variables of :data:`BLAS_THREAD_VARIABLES` this process exported itself, not the user.
_exported: set[str] = set()


def export_one_blas_thread() -> None:
    """Export one BLAS thread (:data:`BLAS_THREAD_VARIABLES` = 1) to this process and the
    processes it starts, for good, unless the user exported a thread count or NumPy is
    loaded already (its BLAS has started its threads; :func:`campaign.execute.one_blas_thread`
    limits them). The executable calls it first: every command runs BLAS at one thread, and
    the OpenBLAS builds NumPy and SciPy load each start a thread per core when they load,
    which spin for about 0.1 s before they sleep (0.2 CPU-s of a campaign's start on two
    cores, docs/execution.md, "BLAS threads that no command uses")."""
    if "numpy" in sys.modules or any(v in os.environ for v in BLAS_THREAD_VARIABLES):
        return
    _export_one()


def _export_one() -> None:
    """:data:`BLAS_THREAD_VARIABLES` set to 1, as this process's own."""
    os.environ.update({variable: "1" for variable in BLAS_THREAD_VARIABLES})
    _exported.update(BLAS_THREAD_VARIABLES)


@contextmanager
def blas_variables_at_one():
    """:data:`BLAS_THREAD_VARIABLES` set to 1 inside the block, as this process's own (not in
    :func:`user_environment`), and removed after it."""
    _export_one()
    try:
        yield
    finally:
        for variable in BLAS_THREAD_VARIABLES:
            os.environ.pop(variable, None)
            _exported.discard(variable)


def user_environment() -> dict[str, str]:
    """This process's environment without the BLAS thread counts it exported itself
    (:func:`export_one_blas_thread`, :func:`blas_variables_at_one`): the environment a
    command started beside a campaign should see, as the user's shell would give it (the
    yardstick of ``fdd-campaign bench``)."""
    return {k: v for k, v in os.environ.items() if k not in _exported}


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
