"""Clear errors (exit code 2) when the dask cluster cannot be used."""

from __future__ import annotations

import socket
import sys

import pytest

from campaign.cli.commands import main
from campaign.execute import ClusterError, connect


def test_a_malformed_scheduler_address_exits_2_with_the_expected_form(tmp_path, capsys):
    assert main(["run", "smoke", "--out", str(tmp_path / "o"), "--scheduler",
                 "127.0.0.1:8786"]) == 2
    err = capsys.readouterr().err
    assert "'127.0.0.1:8786' is not of the form tcp://HOST:PORT" in err
    assert not (tmp_path / "o").exists()          # refused before any work


def test_dask_not_installed_is_named_with_the_extra_to_install(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)   # import distributed → ImportError
    assert main(["run", "smoke", "--out", str(tmp_path / "o"), "--scheduler",
                 "tcp://127.0.0.1:8786"]) == 2
    assert "pip install 'fdd-campaign[dask]'" in capsys.readouterr().err


def test_an_unreachable_scheduler_fails_within_the_connect_timeout():
    with socket.socket() as s:                    # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ClusterError, match=f"cannot reach the dask scheduler at "
                                           f"tcp://127.0.0.1:{port} within 0.5 s"):
        connect(f"tcp://127.0.0.1:{port}", timeout_s=0.5)
