"""Run the chunks of a campaign on workers and survive faults in the machinery.

Three ways to run the chunks, one contract: every chunk ends as result rows handed to
``on_result`` as soon as it finishes (the runner writes each as a Parquet shard), and every
run of the plan ends either done or recorded with a status and its message:

* in-process (``jobs == 1``), one chunk after the other;
* a pool of local workers: ``"loky"`` processes (joblib's process executor) or
  ``"threading"`` threads (the compiled kernels release the GIL);
* a dask.distributed cluster (:func:`run_on_cluster`, ``--scheduler tcp://HOST:PORT``, or
  ``tls://HOST:PORT`` with certificates, :func:`connect`).

Faults in the machinery (TimeEval-style per-run status)
-------------------------------------------------------
* **A worker process dies** (killed, out of memory, a crash in native code): loky fails
  every task in flight on the broken pool. The finished chunks are already stored; the
  chunks that were in flight are retried once, each *alone* in a fresh pool so that a
  second death points at its chunk. A chunk that kills its worker again is split into
  single runs, each tried alone; a run that still kills its worker is recorded with
  ``status="error"`` and the reason. On dask the scheduler reschedules the tasks of a lost
  worker itself and gives up with ``KilledWorker`` after its ``allowed-failures``; such a
  chunk is recorded as ``error``.
* **A detector raises** on some runs: :func:`campaign.evaluate.evaluate` records those runs
  with ``status="error"`` (never fatal).
* **A run exceeds** ``[runner] run_timeout_s``: a chunk gets that limit times its number
  of runs, counted from the moment it is handed to an idle worker (one chunk per worker at
  a time, in pools whose workers have already started). A chunk over its limit has its
  pool stopped; it is split into single runs, each tried alone with the per-run limit; a
  run over it is recorded with ``status="timeout"``. Chunks that were merely in flight next
  to it are resubmitted unchanged. Only a worker process can be stopped: with a limit the
  runner runs the chunks on loky processes (one with ``--jobs 1``) and refuses thread
  workers and a dask cluster before any work (:func:`time_limit_refusal`);
  :func:`run_local` refuses a limit on threads. :func:`call_bounded` runs one call (the
  start-up check of a third-party detector) in a worker process under a limit.

A rerun into the same directory retries exactly the runs whose rows are not all ``ok``.
Splitting never changes a result: a run simulated alone equals the same run in any chunk.

BLAS runs one thread per process while a campaign runs (:func:`one_blas_thread`).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from scenarios.errors import ArgumentError, InputError

from .startup import BLAS_THREAD_VARIABLES, blas_variables_at_one

BACKENDS = ("loky", "threading")

#: Seconds a fresh pool may take to start its workers (imports, kernels from the cache).
POOL_START_TIMEOUT_S = 300.0


@dataclass
class Task:
    """A chunk of runs and what happened to it so far."""

    rows: pd.DataFrame
    alone: bool = False     # must run with nothing else in flight (retry after a failure)
    single: bool = False    # one run split out of a chunk that failed twice

    @property
    def n(self) -> int:
        return len(self.rows)

    def split(self) -> list["Task"]:
        return [Task(self.rows.iloc[[j]], alone=True, single=True) for j in range(self.n)]


@contextmanager
def one_blas_thread():
    """Run BLAS with one thread per process inside the ``with`` block (or the decorated
    function), unless the user exported a thread count (:data:`BLAS_THREAD_VARIABLES`).

    The campaign's parallelism is its workers (``jobs``: processes, or threads for the
    aircraft plant); a multi-threaded BLAS inside each of them oversubscribes the cores (on
    two cores a batch of 100 matrix exponentials took 40–130 ms with OpenBLAS's default
    threads, 3–10 ms with one, and chen-mc 82 → 55 CPU-s), and a result computed with one
    thread does not depend on the machine's core count. This process's BLAS is limited with
    threadpoolctl (restored on leaving; from any thread, :func:`_blas_control`), and the
    variables are set to 1 meanwhile, so that
    the worker processes started inside (loky) load their BLAS with one thread. Nested use
    changes nothing. Used by :func:`campaign.runner.run` (hence ``campaign.run``), the
    falsification search, the certificate and every ``fdd-campaign`` command; on the workers
    of a dask cluster each chunk runs under :func:`one_blas_thread_on_worker`.
    """
    if any(variable in os.environ for variable in BLAS_THREAD_VARIABLES):
        yield           # the user's choice, the executable's (startup) or an enclosing one's
        return
    from threadpoolctl import threadpool_limits

    with blas_variables_at_one():
        with _blas_control():               # also when another thread set a count first
            limiter = threadpool_limits(limits=1, user_api="blas")
        try:
            yield
        finally:
            with _blas_control():
                limiter.restore_original_limits()


@contextmanager
def _blas_control():
    """Control of OpenBLAS's process-wide thread count for this thread, handed back after.

    Since threadpoolctl 3.8, only one thread at a time may change that count: the first to
    set it, until it clears its claim or ends; the calls of every other thread are silently
    ignored (``OpenBLASController`` in threadpoolctl). A dask worker's pool threads live as
    long as the worker, so the thread that limited BLAS for one chunk would keep the claim,
    and the restore by the thread whose chunk ends last, or the next limit after a count
    set by the worker's main thread, would do nothing. :class:`_SharedBlasLimit` orders its
    holders itself (its lock and count), so each change takes the claim for its duration
    and gives it back. Older threadpoolctl versions have no claim and need nothing."""
    from threadpoolctl import OpenBLASController

    clear = getattr(OpenBLASController, "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)
    try:
        yield
    finally:
        if clear is not None:
            clear(force=True)


class _SharedBlasLimit:
    """BLAS limited to one thread while at least one holder is inside :meth:`held`: the
    first holder applies the limit (threadpoolctl, for the whole process), the last one to
    leave restores the limits found, whichever threads they are (:func:`_blas_control`).
    For the threads of one process that run chunks at the same time (a dask worker with
    ``--nthreads`` above 1), where each applying and restoring its own limit would lift it
    under the others."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._holders = 0
        self._limiter = None

    @contextmanager
    def held(self):
        with self._lock:
            if self._holders == 0:
                from threadpoolctl import threadpool_limits

                with _blas_control():
                    self._limiter = threadpool_limits(limits=1, user_api="blas")
            self._holders += 1
        try:
            yield
        finally:
            with self._lock:
                self._holders -= 1
                if self._holders == 0:
                    with _blas_control():
                        self._limiter.restore_original_limits()
                    self._limiter = None


_WORKER_BLAS = _SharedBlasLimit()


@contextmanager
def one_blas_thread_on_worker():
    """BLAS at one thread while a chunk runs on a dask worker, for the reason of
    :func:`one_blas_thread`, unless the worker's environment sets a thread count
    (:data:`BLAS_THREAD_VARIABLES`; dask's nanny sets them to 1 in the worker processes it
    starts, ``distributed.nanny.pre-spawn-environ``). A worker started without a nanny
    (``dask worker --no-nanny``, or a worker inside another program) has BLAS's default, a
    thread per core, and spent twice the CPU time on the aircraft plant's matrix
    exponentials (docs/execution.md). The environment is left alone (its variables are the
    process's, shared by the worker's threads and whatever else it runs), and the limits
    found are restored when the last chunk running in the process ends."""
    if any(variable in os.environ for variable in BLAS_THREAD_VARIABLES):
        yield
        return
    with _WORKER_BLAS.held():
        yield


def run_chunk_on_worker(chunk_fn, rows, detectors, settings):
    """The task of a chunk on a dask worker: ``chunk_fn(rows, detectors, settings)`` with
    BLAS at one thread (:func:`one_blas_thread_on_worker`)."""
    with one_blas_thread_on_worker():
        return chunk_fn(rows, detectors, settings)


def _worker_init() -> None:
    """Start-up of every worker process: import the engine, load the compiled kernels."""
    from scenarios import compiled as kernels

    from . import evaluate  # noqa: F401  (the imports of a chunk, done before any chunk)

    kernels.warm_up()


def _worker_pid(pause_s: float) -> int:
    """A warm-up task: the id of the worker process that ran it (after *pause_s* [s], so
    that the tasks of one round spread over the workers)."""
    import os

    time.sleep(pause_s)
    return os.getpid()


class LocalPool:
    """A loky process pool or a thread pool, restartable after a failure."""

    def __init__(self, backend: str, jobs: int):
        if backend not in BACKENDS:
            raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
        self.backend, self.jobs = backend, jobs
        self.executor = None
        self._warm = []
        self.restarts = -1

    @property
    def can_stop_a_task(self) -> bool:
        return self.backend == "loky"

    def start(self) -> None:
        """Start the workers (returns at once; :meth:`ready` waits for them)."""
        if self.backend == "loky":
            from joblib.externals.loky import ProcessPoolExecutor

            self.executor = ProcessPoolExecutor(max_workers=self.jobs, initializer=_worker_init)
            self._warm = [self.executor.submit(_worker_pid, 0.05) for _ in range(self.jobs)]
        else:
            self.executor = ThreadPoolExecutor(max_workers=self.jobs,
                                               thread_name_prefix="fdd-chunk")
            self._warm = []
        self.restarts += 1

    def ready(self) -> None:
        """Wait until every worker has started (so that time limits count chunk work only)."""
        if self.executor is None:
            self.start()
        t_end = time.perf_counter() + POOL_START_TIMEOUT_S
        pids: set[int] = set()
        for _ in range(20):
            if not self._warm:
                break
            done, pending = wait(self._warm, timeout=max(0.0, t_end - time.perf_counter()))
            if pending:
                raise RuntimeError(f"worker processes did not start within "
                                   f"{POOL_START_TIMEOUT_S:g} s")
            pids.update(f.result() for f in done)  # a worker that cannot start: raise it
            missing = self.jobs - len(pids)
            self._warm = [self.executor.submit(_worker_pid, 0.05) for _ in range(missing)]
        self._warm = []

    def submit(self, fn, *args):
        return self.executor.submit(fn, *args)

    def stop(self, kill: bool = False) -> None:
        if self.executor is None:
            return
        if self.backend == "loky":
            self.executor.shutdown(wait=True, kill_workers=kill)
        else:
            self.executor.shutdown(wait=True, cancel_futures=True)
        self.executor = None


def _is_pool_failure(exc: BaseException) -> bool:
    from concurrent.futures import BrokenExecutor

    return isinstance(exc, BrokenExecutor)


def run_local(chunks, call, fail, on_result, *, jobs: int, backend: str,
              run_timeout_s: float | None, pool: LocalPool | None = None, log=print) -> dict:
    """Run *chunks* (DataFrames of runs, or an iterable making them as they are taken) with
    ``call(rows) -> result rows`` on *jobs* workers; ``fail(rows, status, message)`` makes
    the rows of runs that could not be run.

    Returns counts of what happened: ``{"pool_failures", "timeouts", "retried_chunks"}``.
    """
    stats = {"pool_failures": 0, "timeouts": 0, "retried_chunks": 0}
    source = iter(chunks)       # taken one at a time: a chunk exists once it is next
    queue: deque[Task] = deque()
    isolated: deque[Task] = deque()

    def more() -> bool:
        """Whether a normal chunk waits (the next one is taken from *chunks* if need be)."""
        if not queue:
            rows = next(source, None)
            if rows is not None:
                queue.append(Task(rows))
        return bool(queue)

    if pool is None:
        pool = LocalPool(backend, jobs)
    if run_timeout_s is not None and not pool.can_stop_a_task:
        raise ValueError(f"run_timeout_s = {run_timeout_s:g} s needs worker processes: backend "
                         f"{pool.backend!r} cannot stop a running chunk (use 'loky')")
    limit = run_timeout_s
    inflight: dict = {}  # future -> (task, deadline)
    # Threads: a chunk waits queued behind each running one, so that a worker that finishes
    # takes the next at once instead of idling while this thread stores the result and
    # submits another (8–10 ms per chunk, 0.1 s when the manifest is written: about 5 % of
    # addsafe-mc's runs). Processes: none, as a chunk's time limit and the retries after a
    # dead worker count from a worker taking it.
    depth = jobs if pool.can_stop_a_task else 2 * jobs

    def submit(task: Task) -> None:
        deadline = None if limit is None else time.perf_counter() + limit * task.n
        inflight[pool.submit(call, task.rows)] = (task, deadline)

    def after_pool_failure(task: Task, exc: BaseException) -> None:
        if not task.alone:
            stats["retried_chunks"] += 1
            isolated.append(Task(task.rows, alone=True))
        elif task.n > 1:
            isolated.extend(task.split())
        else:
            what = "this run" if task.single else "the chunk of this run"
            on_result(fail(task.rows, "error", f"worker process died running {what} twice "
                                               f"(retried alone in a fresh pool): {_short(exc)}"))

    def after_timeout(task: Task) -> None:
        stats["timeouts"] += 1
        if task.n > 1:
            isolated.extend(task.split())
        else:
            on_result(fail(task.rows, "timeout", f"run exceeded the time limit of "
                                                 f"{limit:g} s ([runner] run_timeout_s)"))

    try:
        while more() or isolated or inflight:
            if not more() and not inflight and isolated and pool.jobs > 1:
                pool.stop()          # retries run one at a time: one worker is enough
                pool = LocalPool(backend, 1)
            if pool.executor is None:
                pool.start()
            if pool._warm:
                pool.ready()
            # fill the free workers: normal chunks first, then isolated retries one by one
            alone_inflight = any(t.alone for t, _ in inflight.values())
            while len(inflight) < depth and not alone_inflight and more():
                submit(queue.popleft())
            if not more() and not inflight and isolated:
                submit(isolated.popleft())
            deadlines = [d for _, d in inflight.values() if d is not None]
            wait_s = None if not deadlines else max(0.0, min(deadlines) - time.perf_counter())
            done, _ = wait(list(inflight), timeout=wait_s, return_when=FIRST_COMPLETED)
            broken = None
            for fut in done:
                task, _ = inflight.pop(fut)
                try:
                    frame = fut.result()
                except Exception as exc:  # noqa: BLE001 - sorted below, never lost
                    if _is_pool_failure(exc):
                        broken = exc
                        after_pool_failure(task, exc)
                        continue
                    frame = fail(task.rows, "error", f"chunk failed: {_short(exc)}")
                on_result(frame)
            if broken is not None:
                stats["pool_failures"] += 1
                for task, _ in inflight.values():   # every task in flight died with the pool
                    after_pool_failure(task, broken)
                inflight.clear()
                pool.stop(kill=True)
                log(f"a worker process died ({_short(broken)}); finished chunks are kept, "
                    "the chunks in flight are retried alone in a fresh pool")
                continue
            now = time.perf_counter()
            late = [f for f, (_, d) in inflight.items() if d is not None and now > d]
            if late:
                for fut in late:
                    task, _ = inflight.pop(fut)
                    after_timeout(task)
                for task, _ in inflight.values():   # innocent neighbours: resubmit unchanged
                    (isolated if task.alone else queue).appendleft(task)
                inflight.clear()
                pool.stop(kill=True)
    finally:
        pool.stop(kill=bool(inflight))
    return stats


def time_limit_refusal(limit_s: float | None, *, backend: str | None,
                       scheduler: str | None) -> tuple[str, dict] | None:
    """Why ``[runner] run_timeout_s`` = *limit_s* cannot be enforced on *backend* or the dask
    *scheduler* (None: it can, or no limit is set), as the sentence and the values that
    :meth:`scenarios.errors.ArgumentError.said` takes (the arguments *backend* and
    *scheduler* written ``{backend}``, ``{scheduler}``). A running chunk can be stopped only
    in a worker process of the local pool (loky), never in a thread nor in a task on a dask
    worker; the runner refuses such a combination before any work (exit 2) rather than run
    without the limit."""
    if limit_s is None or (scheduler is None and backend != "threading"):
        return None
    if scheduler is None:
        where, fix = ("{backend} threading: a thread cannot be stopped",
                      "{backend} loky (worker processes, the default when run_timeout_s is "
                      "set)")
    else:
        where, fix = ("{scheduler} {address}: a task running on a dask worker cannot be "
                      "stopped", "leave out {scheduler} (local worker processes enforce it)")
    return (f"[runner] run_timeout_s = {{limit}} s cannot be enforced with {where}; nothing "
            f"was run. Fix: {fix}, or remove run_timeout_s from the campaign file "
            "(docs/execution.md)", {"limit": f"{limit_s:g}", "address": scheduler})


class TimeLimitExceeded(RuntimeError):
    """A call of :func:`call_bounded` did not finish within its limit (its worker process
    was stopped)."""


def call_bounded(fn, *args, limit_s: float | None):
    """``fn(*args)`` in a worker process of its own, stopped once it has run *limit_s*
    seconds (counted from when the worker has started): returns what *fn* returns, raises
    what it raises, or :class:`TimeLimitExceeded`. *fn* and *args* must pickle. Without a
    limit (None) it is called here, in this process."""
    if limit_s is None:
        return fn(*args)
    pool = LocalPool("loky", 1)
    finished = False
    try:
        pool.ready()
        future = pool.submit(fn, *args)
        done, _ = wait([future], timeout=limit_s)
        if not done:
            raise TimeLimitExceeded(f"did not finish within {limit_s:g} s")
        finished = True
        return future.result()
    finally:
        pool.stop(kill=not finished)


def _short(exc: BaseException, limit: int = 300) -> str:
    text = f"{type(exc).__name__}: {exc}".replace("\n", " ")
    return text if len(text) <= limit else text[:limit - 1] + "…"


# ---- dask.distributed ------------------------------------------------------------------------
#: Seconds to wait for the dask scheduler before giving up (a clear error, exit code 2).
CONNECT_TIMEOUT_S = 5.0


class ClusterError(InputError, ValueError):
    """The dask cluster cannot be used (not installed, unreachable, bad address)."""


class ClusterOptionError(ClusterError, ArgumentError):
    """The files of a TLS connection (*tls*, :class:`TlsFiles`) that cannot serve, named as
    ``tls_ca_file``, ``tls_cert`` and ``tls_key`` (the fields of *tls*), or the *scheduler*
    that cannot be reached without them; ``fdd-campaign`` names its options
    (:class:`scenarios.errors.ArgumentError`)."""


@dataclass(frozen=True)
class TlsFiles:
    """Files of a TLS connection to a dask scheduler (``fdd-campaign run --tls-ca-file
    --tls-cert --tls-key``, dask's own option names). A field left None is taken from dask's
    configuration (``distributed.comm.tls.ca-file``, ``distributed.comm.tls.client.cert``,
    ``distributed.comm.tls.client.key``)."""

    ca_file: str | None = None
    cert: str | None = None
    key: str | None = None

    def given(self) -> list[str]:
        """The fields given, each named ``tls_`` + its name (``tls_ca_file``), as messages name
        them (:class:`ClusterOptionError`)."""
        return [name for name, v in (("tls_ca_file", self.ca_file), ("tls_cert", self.cert),
                                     ("tls_key", self.key)) if v]


def _split_address(address) -> tuple[str, str]:
    """(scheme, host) of ``SCHEME://HOST:PORT``; :class:`ClusterError` otherwise."""
    scheme, sep, rest = address.partition("://") if isinstance(address, str) else ("", "", "")
    host, colon, port = rest.rpartition(":")
    if not sep or not colon or not host or not port.isdigit() or scheme not in ("tcp", "tls"):
        raise ClusterError(f"scheduler address {address!r} is not of the form tcp://HOST:PORT "
                           "or tls://HOST:PORT (e.g. tcp://127.0.0.1:8786)")
    return scheme, host.strip("[]")


def _is_loopback(host: str) -> bool:
    """Whether *host* (a name or an address) names this machine's loopback interface only."""
    import ipaddress
    import socket

    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(i[4][0].split("%")[0]).is_loopback
                               for i in infos)


def _security(tls: TlsFiles | None):
    """The ``distributed.Security`` of a ``tls://`` connection: the given files, the rest
    from dask's configuration; :class:`ClusterError` naming what is missing."""
    from distributed import Security

    tls = tls or TlsFiles()
    given = {k: v for k, v in (("tls_ca_file", tls.ca_file), ("tls_client_cert", tls.cert),
                               ("tls_client_key", tls.key)) if v}
    for name, path in zip(tls.given(), given.values()):
        if not Path(path).is_file():
            raise ClusterOptionError.of(name, path, "no such file")
    security = Security(require_encryption=True, **given)
    missing = [f"{{{name}}} (or dask's {key})" for name, key, value in (
        ("tls_ca_file", "distributed.comm.tls.ca-file", security.tls_ca_file),
        ("tls_cert", "distributed.comm.tls.client.cert", security.tls_client_cert))
        if not value]
    if missing:
        raise ClusterOptionError.said(
            "a tls:// scheduler needs the CA certificate that signed the cluster's "
            "certificates and a client certificate (with its key, {tls_key}, unless the "
            "certificate file holds it): give " + " and ".join(missing)
            + " (docs/security.md)")
    return security


def connect(address: str, timeout_s: float = CONNECT_TIMEOUT_S, *, tls: TlsFiles | None = None,
            log=None):
    """A ``distributed.Client`` connected to the scheduler at *address*.

    ``tcp://HOST:PORT``: plain TCP, neither encrypted nor authenticated; a one-line warning
    on *log* when HOST is not a loopback address. ``tls://HOST:PORT``: mutual TLS with the
    files of *tls* (:class:`TlsFiles`), the fields left None taken from dask's
    configuration ``distributed.comm.tls.*``.
    """
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    scheme, host = _split_address(address)
    if tls is not None and tls.given() and scheme != "tls":
        raise ClusterOptionError.said(
            ", ".join("{" + name + "}" for name in tls.given()) + " apply to a tls:// "
            "scheduler; the address {address} is {scheme}://: write tls://HOST:PORT",
            address=address, scheme=scheme)
    try:
        from distributed import Client
    except ImportError as exc:
        raise ClusterOptionError.said("{scheduler} needs dask.distributed, which is not "
                                      "installed: pip install 'fdd-campaign[dask]'") from exc
    security = None
    if scheme == "tls":
        security = _security(tls)
    elif not _is_loopback(host):
        log(f"warning: {address} is plain TCP, neither encrypted nor authenticated: whoever "
            "can reach the scheduler can run code on its workers; use tls:// "
            "(docs/security.md)")
    try:
        return Client(address, timeout=timeout_s, security=security)
    except (OSError, TimeoutError) as exc:
        hint = ("; check that the scheduler and workers use certificates signed by the CA "
                "given and that the scheduler listens on tls://" if scheme == "tls" else
                "; start one with 'dask scheduler --host 127.0.0.1' and workers with "
                "'dask worker tcp://127.0.0.1:8786' (docs/execution.md)")
        raise ClusterError(f"cannot reach the dask scheduler at {address} within "
                           f"{timeout_s:g} s ({type(exc).__name__}: {exc}){hint}") from exc
    except ValueError as exc:     # e.g. an unreadable certificate (ssl.SSLError is OSError)
        raise ClusterError(f"cannot connect to the dask scheduler at {address}: {exc}") from exc


#: Chunks a dask client keeps submitted per worker thread of the cluster: enough that no
#: worker waits for its next chunk, few enough that the client never holds the plan's
#: chunks all at once (nor the scheduler their tasks).
CLUSTER_CHUNKS_PER_THREAD = 2


def run_on_cluster(client, chunks, chunk_fn, detectors, settings, fail, on_result,
                   log=print) -> dict:
    """Run *chunks* as dask futures, ``chunk_fn(rows, detectors, settings)`` each (with BLAS
    at one thread on the worker, :func:`run_chunk_on_worker`), handing
    results to *on_result* as they complete (``as_completed``). At most
    :data:`CLUSTER_CHUNKS_PER_THREAD` chunks per worker thread (at least 4) are submitted
    at a time; each finished chunk lets the next one in."""
    from distributed import as_completed

    try:
        from distributed.scheduler import KilledWorker
    except ImportError:  # pragma: no cover - older layout
        from distributed import KilledWorker

    stats = {"killed_chunks": 0}
    det_future = client.scatter([detectors], broadcast=True, hash=False)[0]
    window = max(4, CLUSTER_CHUNKS_PER_THREAD * sum(client.nthreads().values()))
    pending = iter(chunks)
    futures = {}

    def submit_next() -> object | None:
        rows = next(pending, None)
        if rows is None:
            return None
        fut = client.submit(run_chunk_on_worker, chunk_fn, rows, det_future, settings,
                            pure=False)
        futures[fut] = rows
        return fut

    for _ in range(window):
        if submit_next() is None:
            break
    try:
        running = as_completed(list(futures))
        for fut in running:
            rows = futures.pop(fut)
            try:
                frame = fut.result()
            except KilledWorker as exc:
                stats["killed_chunks"] += 1
                frame = fail(rows, "error", f"dask workers died running this chunk: "
                                            f"{_short(exc)}")
            except Exception as exc:  # noqa: BLE001
                frame = fail(rows, "error", f"chunk failed on the cluster: {_short(exc)}")
            on_result(frame)
            fut.release()
            nxt = submit_next()
            if nxt is not None:
                running.add(nxt)
    finally:
        for fut in futures:
            fut.cancel()
    return stats
