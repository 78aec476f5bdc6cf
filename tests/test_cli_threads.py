"""The command line runs BLAS single-threaded unless the user says otherwise
(campaign/cli_common.py, ``BLAS_THREAD_VARIABLES``): set before NumPy loads OpenBLAS."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from campaign.cli_common import BLAS_THREAD_VARIABLES

PROBE = ("import campaign.cli, os, numpy; "
         "print(','.join(os.environ[v] for v in %r))" % (BLAS_THREAD_VARIABLES,))


def probe(env: dict) -> list[str]:
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True,
                         text=True, check=True)
    return out.stdout.strip().split(",")


def clean_env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}


def test_blas_runs_one_thread_under_the_command_line():
    assert "OPENBLAS_NUM_THREADS" in BLAS_THREAD_VARIABLES
    assert probe(clean_env()) == ["1"] * len(BLAS_THREAD_VARIABLES)


@pytest.mark.parametrize("value", ["2", "8"])
def test_a_thread_count_the_user_exported_wins(value):
    env = {**clean_env(), "OPENBLAS_NUM_THREADS": value}
    assert probe(env)[0] == value
