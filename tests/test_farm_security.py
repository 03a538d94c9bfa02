"""Farms are not attack surfaces (issue 32): a cluster is used only when named on the command line or
in the API (never from DASK_SCHEDULER_ADDRESS), TLS schedulers with certificates, LocalClusters that
listen on loopback only, and a bound on local worker processes.

Certificates are made in the test with the ``openssl`` command; every scheduler is on 127.0.0.1.
"""

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
psutil = pytest.importorskip("psutil", reason="distributed brings psutil")

from distributed.security import Security  # noqa: E402

from realistic.cli import main  # noqa: E402
from realistic.core.image_files import read_exr  # noqa: E402
from realistic.renderer.thread_count import default_threads  # noqa: E402
from tls_helpers import certificates  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TINY = ["render", "--backend", "numpy", "--res", "12x8", "--spp", "1", "--pass-samples", "64"]


def test_dask_scheduler_address_in_the_environment_starts_no_client(tmp_path):
    """A listening socket stands in for a hostile scheduler: a plain render must never connect to it."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(4)
        server.settimeout(0)
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        code = ("import sys; from realistic.cli import main\nstatus = main(sys.argv[1:])\n"
                "print(status, sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
        out = subprocess.run([sys.executable, "-c", code, *TINY, "--out", str(tmp_path / "p.exr")], cwd=REPO,
                             capture_output=True, text=True, timeout=300,
                             env={**os.environ, "DASK_SCHEDULER_ADDRESS": address})
        assert out.stdout.strip().endswith("0 []"), out.stdout + out.stderr
        with pytest.raises(BlockingIOError):
            server.accept()  # nobody knocked


def _listening(process: psutil.Process) -> list[str]:
    return [c.laddr.ip for c in process.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]


def test_a_local_cluster_listens_on_loopback_only():
    from realistic.renderer.farm import farm_client

    me = psutil.Process()
    lines = []
    with farm_client(1, announce=lines.append) as client:
        addresses = [ip for process in (me, *me.children(recursive=True)) for ip in _listening(process)]
        workers = list(client.scheduler_info()["workers"])
    assert addresses and set(addresses) == {"127.0.0.1"}, addresses  # the dashboard was on 0.0.0.0
    assert workers and all(w.startswith("tcp://127.0.0.1:") for w in workers)
    assert "http://127.0.0.1:" in lines[0]


def test_workers_beyond_the_machine_are_refused_at_once(tmp_path, capsys):
    too_many = default_threads() + 1
    assert main([*TINY, "--workers", str(too_many), "--out", str(tmp_path / "w.exr")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"at most {default_threads()} (one per CPU" in err, err
    assert main([*TINY, "--workers", "1000", "--out", str(tmp_path / "w.exr")]) == 2
    assert "1000 workers: a LocalCluster here has at most" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.fixture(scope="module")
def tls_cluster(tmp_path_factory):
    if shutil.which("openssl") is None:
        pytest.skip("the openssl command makes the test certificates")
    folder = tmp_path_factory.mktemp("tls")
    files = certificates(folder, "farm")
    security = Security(tls_ca_file=files["ca"], tls_scheduler_cert=files["cert"], tls_scheduler_key=files["key"],
                        tls_worker_cert=files["cert"], tls_worker_key=files["key"], tls_client_cert=files["cert"],
                        tls_client_key=files["key"], require_encryption=True)
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, protocol="tls://",
                                       host="127.0.0.1", security=security, dashboard_address=None)
    yield cluster, files, certificates(folder, "stranger")
    cluster.close()


def test_a_tls_scheduler_renders_with_certificates_and_refuses_without(tls_cluster, tmp_path, capsys):
    cluster, files, stranger = tls_cluster
    address = cluster.scheduler_address
    assert address.startswith("tls://127.0.0.1:")
    tls = ["--tls-ca-file", files["ca"], "--tls-cert", files["cert"], "--tls-key", files["key"]]
    assert main([*TINY, "--scheduler", address, *tls, "--out", str(tmp_path / "tls.exr")]) == 0
    assert main([*TINY, "--out", str(tmp_path / "here.exr")]) == 0
    assert np.array_equal(read_exr(tmp_path / "tls.exr")[0], read_exr(tmp_path / "here.exr")[0])
    capsys.readouterr()
    # no certificates, or a client whose certificates another CA signed: refused in one line
    assert main([*TINY, "--scheduler", address, "--out", str(tmp_path / "x.exr")]) == 2
    assert "a tls:// scheduler needs --tls-ca-file" in capsys.readouterr().err
    strange = ["--tls-ca-file", stranger["ca"], "--tls-cert", stranger["cert"], "--tls-key", stranger["key"]]
    from realistic.renderer import farm

    farm_timeout, farm.CONNECT_TIMEOUT = farm.CONNECT_TIMEOUT, "3s"
    try:
        assert main([*TINY, "--scheduler", address, *strange, "--out", str(tmp_path / "x.exr")]) == 2
    finally:
        farm.CONNECT_TIMEOUT = farm_timeout
    assert f"cannot reach the Dask scheduler at {address}" in capsys.readouterr().err.splitlines()[-1]
    assert not (tmp_path / "x.exr").exists()


def test_the_api_takes_a_security_object(tls_cluster):
    from realistic import load_lens
    from realistic import render as render_image
    from realistic.camera.lens_camera import LensCamera
    from realistic.renderer.farm import farm_client
    from realistic.scene.staging import default_setup

    cluster, files, _ = tls_cluster
    setup = default_setup()
    camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 8, 8, 1)
    security = Security(tls_ca_file=files["ca"], tls_client_cert=files["cert"], tls_client_key=files["key"],
                        require_encryption=True)
    with farm_client(scheduler=cluster.scheduler_address, security=security) as client:
        image = render_image(setup.scene, camera, "numpy", client=client)
    assert np.array_equal(image, render_image(setup.scene, camera, "numpy"))


@pytest.mark.parametrize("args, message", [
    (["--tls-ca-file", "a.pem"], "--tls-ca-file, --tls-cert and --tls-key go together"),
    (["--scheduler", "tcp://127.0.0.1:9", "--tls-ca-file", "a", "--tls-cert", "b", "--tls-key", "c"],
     "are for a --scheduler tls://... address"),
    (["--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", "missing.pem", "--tls-cert", "b", "--tls-key", "c"],
     "--tls-ca-file missing.pem: not a readable file"),
    (["--scheduler", "tls://127.0.0.1:9"], "a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key"),
])
def test_tls_options_are_checked_before_any_work(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*TINY, "--out", str(tmp_path / "x.exr"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
