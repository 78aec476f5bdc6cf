"""BLAS runs single-threaded while a campaign runs, from the command line and from Python
(campaign/execute.py, ``one_blas_thread``), unless the user exported a thread count; importing
the package changes nothing."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from threadpoolctl import threadpool_info

from campaign.execute import BLAS_THREAD_VARIABLES, one_blas_thread


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

    def build_plan(config):
        seen.append(blas_threads())
        raise _Seen

    monkeypatch.setattr(runner, "build_plan", build_plan)
    with pytest.raises(_Seen):
        campaign.run(load_config("smoke"), tmp_path / "out", jobs=1, progress=False)
    assert seen == [{1}]
