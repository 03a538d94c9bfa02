"""Renders on Dask (renderer/farm): bit-identical to in-process renders for 1, 2 and 3 workers, a
killed worker, sweeps as one job, worker-side caching, and the CLI's farm options.

One LocalCluster serves the module (scaled between tests); renders are 32x32 at a few spp.
"""

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")

from realistic import load_lens  # noqa: E402
from realistic import render as render_image  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402
from realistic.cli import main  # noqa: E402
from realistic.core.image_files import read_exr  # noqa: E402
from realistic.renderer.farm import DaskPasses, close_local_cluster  # noqa: E402
from realistic.renderer.job import RenderJob, RenderObserver  # noqa: E402
from realistic.renderer.passes import render  # noqa: E402
from realistic.renderer.sweep import parse_sweep, sweep_cameras  # noqa: E402
from realistic.scene.staging import default_setup  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PASS = 256  # 16 passes of a 32x32, 4 spp render
TASK = 512  # two passes a task


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
    with distributed.Client(cluster) as client:
        yield client
    close_local_cluster(cluster)  # a worker a test killed and its nanny restarted can trip dask's watcher


def _scale(client, workers: int) -> None:
    client.cluster.scale(workers)
    client.wait_for_workers(workers, timeout=60)
    deadline = time.monotonic() + 60
    while len(client.scheduler_info()["workers"]) != workers and time.monotonic() < deadline:
        time.sleep(0.05)


@pytest.fixture(scope="module")
def tiny():
    setup = default_setup()
    camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 32, 32, 4)
    return setup.scene, camera


@pytest.fixture(scope="module")
def reference(tiny):
    scene, camera = tiny
    return {backend: render(RenderJob(scene, (camera,), backend, seed=5, pass_samples=PASS))[0].image
            for backend in ("numpy", "opencl")}


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_farm_image_is_bit_identical_to_the_in_process_render(client, tiny, reference, workers):
    scene, camera = tiny
    _scale(client, workers)
    result = render(RenderJob(scene, (camera,), "numpy", seed=5, pass_samples=PASS), DaskPasses(client, TASK))[0]
    assert not result.interrupted and result.samples_done == result.samples_total
    assert reference["numpy"].max() > 0 and np.array_equal(result.image, reference["numpy"])


def test_the_opencl_kernel_on_workers_is_bit_identical_too(client, tiny, reference):
    scene, camera = tiny
    _scale(client, 2)
    image = render_image(scene, camera, "opencl", seed=5, pass_samples=PASS, client=client, task_samples=TASK)
    assert np.array_equal(image, reference["opencl"])


def test_a_spectral_render_with_several_wavelengths_per_sample_is_bit_identical_too(client, tiny):
    scene, camera = tiny  # dgauss has Abbe numbers: dispersive, 3 rays per sample
    spectral = dataclasses.replace(camera, spectral=True, wavelengths_per_sample=3)
    _scale(client, 2)
    local = render(RenderJob(scene, (spectral,), "opencl", seed=5, pass_samples=PASS))[0]
    farmed = render(RenderJob(scene, (spectral,), "opencl", seed=5, pass_samples=PASS), DaskPasses(client, TASK))[0]
    assert local.image.max() > 0 and np.array_equal(farmed.image, local.image)
    assert farmed.samples_done == local.samples_done == spectral.sample_count
    assert farmed.primary_rays == local.primary_rays > spectral.sample_count  # up to 3 rays a sample


def test_each_worker_builds_the_scene_and_camera_once(client, tiny):
    from realistic.renderer import farm

    scene, camera = tiny
    _scale(client, 2)
    client.run(lambda: (farm._runners.clear(), farm._scenes.clear()))
    render(RenderJob(scene, (camera,), "numpy", seed=5, pass_samples=PASS), DaskPasses(client, PASS))  # 16 tasks
    counts = client.run(lambda: (len(farm._runners), len(farm._scenes)))
    assert all(count in ((0, 0), (1, 1)) for count in counts.values()) and (1, 1) in counts.values()


def test_a_worker_killed_mid_render_costs_only_its_tasks(client, tiny, reference):
    scene, camera = tiny
    _scale(client, 2)
    pids = client.run(os.getpid)
    killed = []

    def kill_a_busy_worker(result):
        if killed:
            return
        busy = [address for address, keys in client.processing().items() if keys and address in pids]
        if busy:
            os.kill(pids[busy[0]], signal.SIGKILL)
            killed.append(busy[0])

    result = render(RenderJob(scene, (camera,), "numpy", seed=5, pass_samples=PASS), DaskPasses(client, PASS),
                    RenderObserver(on_pass=kill_a_busy_worker))[0]
    assert killed and not result.interrupted
    assert np.array_equal(result.image, reference["numpy"])
    _scale(client, 2)  # the nanny restarts it
    assert set(client.run(os.getpid).values()) != set(pids.values())


def test_a_sweep_is_one_job_whose_frames_match_single_renders(client, tiny):
    scene, camera = tiny
    _scale(client, 2)
    cameras = sweep_cameras(camera, parse_sweep("focus=1.5:6:2"))
    frames = render(RenderJob(scene, cameras, "numpy", seed=5, pass_samples=PASS), DaskPasses(client, TASK))
    for frame, each in zip(frames, cameras):
        alone = render(RenderJob(scene, (each,), "numpy", seed=5, pass_samples=PASS))[0].image
        assert np.array_equal(frame.image, alone)
    assert not np.array_equal(frames[0].image, frames[-1].image)


def test_cli_workers_render_matches_the_threaded_render(tmp_path, capsys):
    args = ["render", "--backend", "numpy", "--res", "24x16", "--spp", "2", "--pass-samples", "128"]
    assert main([*args, "--out", str(tmp_path / "t.exr")]) == 0
    assert main([*args, "--workers", "2", "--out", str(tmp_path / "w.exr")]) == 0
    err = capsys.readouterr().err
    assert "LocalCluster of 2 worker processes; dashboard" in err and "http://" in err
    assert np.array_equal(read_exr(tmp_path / "t.exr")[0], read_exr(tmp_path / "w.exr")[0])


def test_cli_sweep_writes_numbered_frames(tmp_path, capsys):
    out = tmp_path / "f.exr"
    assert main(["render", "--backend", "numpy", "--res", "16x12", "--spp", "1", "--sweep", "aperture=8:16:2",
                 "--out", str(out)]) == 0
    frames = sorted(p.name for p in tmp_path.iterdir())
    assert frames == ["f_0001.exr", "f_0001.png", "f_0002.exr", "f_0002.png"]
    assert [read_exr(tmp_path / f"f_000{i}.exr")[1]["frame"] for i in (1, 2)] == [1, 2]


def test_an_unreachable_scheduler_is_one_line_after_the_plain_tcp_warning(capsys, monkeypatch):
    from realistic.renderer import farm

    monkeypatch.setattr(farm, "CONNECT_TIMEOUT", "1s")
    assert main(["render", "--backend", "numpy", "--res", "8x8", "--scheduler", "tcp://127.0.0.1:9"]) == 2
    warning, error = capsys.readouterr().err.splitlines()
    assert "tcp://127.0.0.1:9 is neither encrypted nor authenticated: whoever runs that scheduler" in warning
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in error


def test_help_and_plain_renders_do_not_import_dask(tmp_path):
    code = ("import sys; from realistic.cli import main\ntry: main(sys.argv[1:])\nexcept SystemExit: pass\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    for args in (["render", "--help"],
                 ["render", "--backend", "numpy", "--res", "8x8", "--spp", "1", "--out", str(tmp_path / "p.exr")]):
        out = subprocess.run([sys.executable, "-c", code, *args], cwd=REPO, capture_output=True, text=True,
                             timeout=120, env={k: v for k, v in os.environ.items() if k != "DASK_SCHEDULER_ADDRESS"})
        assert out.stdout.strip().endswith("[]"), out.stdout + out.stderr


@pytest.mark.parametrize("args, message", [
    (["--workers", "0"], "workers must be between 1 and"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "not allowed with argument"),
    (["--pass-samples", "0"], "pass size (samples) must be between 1 and"),
    (["--sweep", "focus=1:2"], "--sweep 'focus=1:2'"),
    (["--sweep", "focus=1:2:2", "--resume"], "--resume continues one image"),
])
def test_farm_options_are_checked_in_one_line(args, message, tmp_path, capsys):
    assert main(["render", "--backend", "numpy", "--res", "8x8", "--out", str(tmp_path / "x.exr"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err


def _ignored_signals() -> int:
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("SigIgn:")).split()[1], 16)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the signal mask from Linux's /proc")
def test_local_workers_ignore_the_terminals_ctrl_c_after_building_the_kernel(tiny):
    """Ctrl-C reaches the whole process group; PoCL's LLVM installs its own SIGINT handler when it
    compiles the kernel, so the workers re-ignore SIGINT and SIGHUP and only this process handles them."""
    from realistic.renderer.farm import farm_client

    scene, camera = tiny
    with farm_client(1, announce=lambda line: None) as client:
        render_image(scene, camera, "opencl", pass_samples=4096, client=client)
        masks = client.run(_ignored_signals)
    assert masks and all(mask & (1 << (signal.SIGINT - 1)) and mask & (1 << (signal.SIGHUP - 1))
                         for mask in masks.values())
