"""BLAS runs single-threaded while a campaign runs, from the command line and from Python
(campaign/execute.py, ``one_blas_thread``), unless the user exported a thread count; importing
the package changes nothing."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from threadpoolctl import threadpool_info

from campaign.execute import one_blas_thread
from campaign.startup import BLAS_THREAD_VARIABLES


def blas_threads() -> set[int]:
    """The thread counts of the BLAS libraries loaded in this process."""
    return {info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"}


def clean_env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}


def probe(env: dict, code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)
    return out.stdout.strip()


@pytest.fixture
def no_exported_count(monkeypatch):
    for variable in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(variable, raising=False)


def test_importing_the_command_line_sets_nothing():
    # no import-time side effect: the variables stay unset, BLAS keeps its own count
    code = ("import campaign, campaign.cli.commands, os; "
            f"print(any(v in os.environ for v in {BLAS_THREAD_VARIABLES!r}))")
    assert probe(clean_env(), code) == "False"


def test_one_thread_inside_and_the_process_restored_after(no_exported_count):
    import numpy  # noqa: F401  (loads the BLAS threadpoolctl inspects)

    before = blas_threads()
    assert before, "no BLAS library loaded: the check below would prove nothing"
    with one_blas_thread():
        assert blas_threads() == {1}
        # worker processes started here load their BLAS with one thread
        assert [os.environ[v] for v in BLAS_THREAD_VARIABLES] == ["1"] * 2
        with one_blas_thread():                  # nested: nothing changes
            assert blas_threads() == {1}
        assert blas_threads() == {1}
    assert blas_threads() == before
    assert not any(v in os.environ for v in BLAS_THREAD_VARIABLES)


@pytest.mark.parametrize("value", ["2", "8"])
def test_a_thread_count_the_user_exported_wins(value):
    # OpenBLAS reads the variable when it loads; one_blas_thread then leaves it alone
    code = ("import numpy; from threadpoolctl import threadpool_info; "
            "from campaign.execute import one_blas_thread\n"
            "count = lambda: sorted(i['num_threads'] for i in threadpool_info() "
            "if i['user_api'] == 'blas')\n"
            "outside = count()\n"
            "with one_blas_thread():\n"
            "    import os; print(outside == count(), os.environ['OPENBLAS_NUM_THREADS'])")
    assert probe({**clean_env(), "OPENBLAS_NUM_THREADS": value}, code) == f"True {value}"


def test_a_campaign_limits_blas_although_another_live_thread_set_a_count_first():
    """A thread that set a BLAS count and lives on (a thread of the program that calls
    ``campaign.run``) would make threadpoolctl ignore the campaign's limit: the campaign
    still runs BLAS at one thread, and the count found comes back after it."""
    code = ("import threading, numpy\n"
            "from threadpoolctl import threadpool_info, threadpool_limits\n"
            "from campaign.execute import one_blas_thread\n"
            "count = lambda: sorted({i['num_threads'] for i in threadpool_info() "
            "if i['user_api'] == 'blas'})\n"
            "set_, end = threading.Event(), threading.Event()\n"
            "def other():\n"
            "    threadpool_limits(3, 'blas'); set_.set(); end.wait(10)\n"
            "t = threading.Thread(target=other); t.start(); set_.wait(10)\n"
            "with one_blas_thread():\n"
            "    inside = count()\n"
            "print(inside, count()); end.set(); t.join()")
    assert probe(clean_env(), code) == "[1] [3]"


class _Seen(Exception):
    pass


def test_campaign_run_from_python_runs_one_blas_thread(no_exported_count, monkeypatch, tmp_path):
    """campaign.run gets the limit without the command line (it once came only from
    importing campaign.cli.commands): BLAS is single-threaded while the plan is built."""
    import numpy  # noqa: F401

    import campaign
    import campaign.runner as runner
    from campaign.config import load_config

    seen = []

    def plan_blocks(config):
        seen.append(blas_threads())
        raise _Seen

    monkeypatch.setattr(runner, "PlanBlocks", plan_blocks)
    with pytest.raises(_Seen):
        campaign.run(load_config("smoke"), tmp_path / "out", jobs=1, progress=False)
    assert seen == [{1}]


#: The start of a fresh interpreter in the state of a dask worker: chunks run in the threads
#: of its pool, which live as long as the worker. Since threadpoolctl 3.8 only one thread at
#: a time may change OpenBLAS's process-wide count (the first to set it, until it clears or
#: ends; the others' calls are silently ignored), so these checks run in a fresh process
#: whose threads are known.
WORKER = """
import threading
import numpy
from threadpoolctl import threadpool_info, threadpool_limits
from campaign.execute import run_chunk_on_worker

def count(*_):
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

def start(target, *args):
    thread = threading.Thread(target=target, args=args)
    thread.start()
    return thread

def chunk(fn, seen, name, done=None, stay=None):
    seen[name] = run_chunk_on_worker(fn, None, None, None)
    if done is not None:
        done.set()
    if stay is not None:              # a pool thread outlives its chunk
        assert stay.wait(10)
"""


def test_a_chunk_on_a_dask_worker_runs_one_blas_thread_and_the_worker_is_restored():
    """The task of a chunk on a dask worker (``run_chunk_on_worker``) limits BLAS itself: a
    worker without dask's nanny has BLAS's own count (here raised to 3, so that the check
    holds on a one-core machine too), restored after the chunk."""
    code = WORKER + """
start(threadpool_limits, 3, "blas").join()
seen = {}
start(chunk, count, seen, "chunk").join()
print(seen["chunk"], count())
"""
    assert probe(clean_env(), code) == "[1] [3]"


def test_chunks_running_at_once_in_one_worker_keep_the_limit_until_the_last_ends():
    """Two chunks in two threads of one worker process (``--nthreads 2``): the first to end
    must not lift the limit under the other; the last restores the count found, although
    the thread that set the limit is still alive (as a pool thread is): threadpoolctl would
    ignore the restore from the other thread unless the limit hands control back."""
    code = WORKER + """
first_in, second_in, first_out = threading.Event(), threading.Event(), threading.Event()
printed = threading.Event()

def first(*_):
    first_in.set()
    assert second_in.wait(10)
    return count()

def second(*_):
    second_in.set()
    assert first_out.wait(10)
    return count()                       # the first chunk has ended by now

start(threadpool_limits, 3, "blas").join()
seen = {}
a = start(chunk, first, seen, "first", first_out, printed)
assert first_in.wait(10)
b = start(chunk, second, seen, "second")
b.join(10)
print(seen["first"], seen["second"], count())
printed.set()
a.join(10)
"""
    assert probe(clean_env(), code) == "[1] [1] [3]"


def test_a_chunk_limits_blas_although_another_thread_of_the_worker_set_a_count_first():
    """A thread of the worker that set a count and lives on (here the main thread, which
    never hands control back) would make threadpoolctl ignore the chunk's limit: the chunk
    must still run at one thread, and the count found must come back after it."""
    code = WORKER + """
threadpool_limits(3, "blas")
seen = {}
start(chunk, count, seen, "chunk").join()
print(seen["chunk"], count())
"""
    assert probe(clean_env(), code) == "[1] [3]"


def test_a_thread_count_set_in_the_worker_environment_wins():
    # dask's nanny sets OPENBLAS_NUM_THREADS=1 in the workers it starts; a count set there
    # by whoever starts the worker is left alone, as one_blas_thread leaves an exported one
    code = WORKER + """
seen = {}
start(chunk, count, seen, "chunk").join()
print(seen["chunk"], count())
"""
    assert probe({**clean_env(), "OPENBLAS_NUM_THREADS": "2"}, code) == "[2] [2]"


# ---- the executable exports one BLAS thread before NumPy loads (campaign/startup.py) ---------
#: A child's record at its exit of the BLAS variables, BLAS's thread counts and the
#: environment a command beside it gets (campaign.startup.user_environment).
EXECUTABLE = """
import atexit, json, os, sys
report = sys.argv[1]
def record():
    import scipy.linalg  # noqa: F401  (SciPy's BLAS too, loaded after the command)
    from threadpoolctl import threadpool_info
    from campaign.startup import user_environment
    json.dump({"env": [os.environ.get(v) for v in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")],
               "threads": sorted({i["num_threads"] for i in threadpool_info()
                                  if i["user_api"] == "blas"}),
               "user": user_environment().get("OPENBLAS_NUM_THREADS")}, open(report, "w"))
atexit.register(record)
sys.argv = ["fdd-campaign", "presets"]
"""


def run_executable(tmp_path, env: dict, entry: str) -> dict:
    subprocess.run([sys.executable, "-c", EXECUTABLE + entry, str(tmp_path / "r.json")],
                   env=env, capture_output=True, text=True, check=True, timeout=120)
    return json.loads((tmp_path / "r.json").read_text())


def test_importing_the_executable_loads_nothing_before_it_starts():
    code = "import campaign.cli, sys; print('numpy' in sys.modules)"
    assert probe(clean_env(), code) == "False"


def test_the_executable_starts_blas_at_one_thread_for_the_process(tmp_path):
    # the BLAS of NumPy and SciPy loaded with one thread (no pool started), for the whole
    # process and what it starts; a command beside it gets the user's environment
    state = run_executable(tmp_path, clean_env(),
                           "from campaign.cli import console_main\nconsole_main()")
    assert state == {"env": ["1", "1"], "threads": [1], "user": None}


def test_the_executable_keeps_a_thread_count_the_user_exported(tmp_path):
    state = run_executable(tmp_path, {**clean_env(), "OPENBLAS_NUM_THREADS": "2"},
                           "from campaign.cli import console_main\nconsole_main()")
    assert state == {"env": ["2", None], "threads": [2], "user": "2"}


def test_too_late_once_numpy_is_loaded(tmp_path):
    # the older entry (its module imports NumPy first): nothing exported, BLAS keeps the
    # threads it started, limited to one while the command runs (one_blas_thread)
    state = run_executable(tmp_path, clean_env(),
                           "from campaign.cli.commands import console_main\nconsole_main()")
    own = probe(clean_env(), "import numpy, scipy.linalg; from threadpoolctl import "
                "threadpool_info; print(sorted({i['num_threads'] for i in threadpool_info() "
                "if i['user_api'] == 'blas'}))")
    assert state == {"env": [None, None], "threads": json.loads(own), "user": None}


def test_one_blas_thread_is_not_the_users_environment(no_exported_count):
    from campaign.startup import user_environment

    with one_blas_thread():
        assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
        assert not any(v in user_environment() for v in BLAS_THREAD_VARIABLES)
    assert not any(v in os.environ for v in BLAS_THREAD_VARIABLES)
