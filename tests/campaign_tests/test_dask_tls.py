"""The campaign on a dask.distributed cluster over mutual TLS: a certificate authority made
for the test (openssl), a scheduler and a worker started as processes on 127.0.0.1 with their
certificates, and ``fdd-campaign run --scheduler tls://…`` with the certificate options or
dask's configuration; the results equal local workers' bit for bit (docs/security.md)."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pandas as pd
import pytest

import distributed  # noqa: F401  (the [dask] extra, part of the [test] extra)

from campaign.cli.commands import main
from campaign.execute import ClusterError, TlsFiles, connect
from campaign import load

from test_dask_cluster import _free_port, _stop

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None,
                                reason="the openssl command makes the test certificates")


def _openssl(*args, cwd) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def _authority(directory, name: str) -> dict:
    """A CA and a certificate it signed for 127.0.0.1 (scheduler, worker and client alike):
    {"ca": …, "cert": …, "key": …} file paths in *directory*."""
    directory.mkdir(parents=True, exist_ok=True)
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key",
             "-out", "ca.pem", "-days", "2", "-subj", f"/CN={name} test CA", cwd=directory)
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "node.key", "-out",
             "node.csr", "-subj", "/CN=127.0.0.1", cwd=directory)
    (directory / "san.cnf").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    _openssl("x509", "-req", "-in", "node.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
             "-CAcreateserial", "-out", "node.pem", "-days", "2", "-extfile", "san.cnf",
             cwd=directory)
    return {"ca": str(directory / "ca.pem"), "cert": str(directory / "node.pem"),
            "key": str(directory / "node.key")}


@pytest.fixture(scope="module")
def tls_cluster(tmp_path_factory):
    """(address, certificate files) of a TLS scheduler and one single-threaded worker."""
    from distributed import Client, Security

    work = tmp_path_factory.mktemp("dask-tls")
    files = _authority(work / "pki", "cluster")
    tls = ["--tls-ca-file", files["ca"], "--tls-cert", files["cert"], "--tls-key", files["key"]]
    port = _free_port()
    address = f"tls://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    procs = []
    try:
        procs.append(subprocess.Popen(
            dask + ["scheduler", "--protocol", "tls", "--host", "127.0.0.1", "--port",
                    str(port), "--no-dashboard", *tls],
            cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs.append(subprocess.Popen(
            dask + ["worker", address, "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny",
                    "--no-dashboard", "--local-directory", str(work / "w0"), *tls],
            cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        security = Security(tls_ca_file=files["ca"], tls_client_cert=files["cert"],
                            tls_client_key=files["key"], require_encryption=True)
        with Client(address, security=security, timeout=60) as client:
            client.wait_for_workers(1, timeout=120)
        yield address, files
    finally:
        _stop(procs)


@pytest.fixture(scope="module")
def local_rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "smoke"
    assert main(["run", "smoke", "--out", str(out), "--jobs", "2", "--quiet"]) == 0
    rows = load(out).results
    return rows.sort_values(["run_id", "detector"]).reset_index(drop=True)


def _rows(out) -> pd.DataFrame:
    rows = load(out).results
    return rows.sort_values(["run_id", "detector"]).reset_index(drop=True)


def test_smoke_over_tls_with_the_certificate_options_equals_local_workers(
        tls_cluster, local_rows, tmp_path, capsys):
    address, files = tls_cluster
    out = tmp_path / "tls"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--scheduler", address,
                 "--tls-ca-file", files["ca"], "--tls-cert", files["cert"],
                 "--tls-key", files["key"]]) == 0
    assert "warning" not in capsys.readouterr().err
    pd.testing.assert_frame_equal(_rows(out), local_rows, check_exact=True)
    assert main(["verify", str(out)]) == 0


def test_smoke_over_tls_with_dask_configuration_equals_local_workers(
        tls_cluster, local_rows, tmp_path):
    import dask

    address, files = tls_cluster
    out = tmp_path / "tls-config"
    with dask.config.set({"distributed.comm.tls.ca-file": files["ca"],
                          "distributed.comm.tls.client.cert": files["cert"],
                          "distributed.comm.tls.client.key": files["key"]}):
        assert main(["run", "smoke", "--out", str(out), "--quiet", "--scheduler",
                     address]) == 0
    pd.testing.assert_frame_equal(_rows(out), local_rows, check_exact=True)


def test_a_client_certificate_of_another_authority_is_refused(tls_cluster, tmp_path):
    address, _ = tls_cluster
    other = _authority(tmp_path / "other", "stranger")
    with pytest.raises(ClusterError, match="cannot reach the dask scheduler at tls://"):
        connect(address, timeout_s=2.0, tls=TlsFiles(ca_file=other["ca"], cert=other["cert"],
                                                     key=other["key"]))


def test_plain_tcp_to_the_tls_scheduler_does_not_connect(tls_cluster):
    address, _ = tls_cluster
    with pytest.raises(ClusterError):
        connect(address.replace("tls://", "tcp://"), timeout_s=2.0, log=lambda m: None)

