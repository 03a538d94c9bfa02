"""Memory estimates that hold (issue 32): the estimate counts geometry, lights and textures, per-thread
buffers are bounded by the work there is, a limit beyond the machine is not believed, the refusal
says what the memory goes to, and a render's measured peak stays within its estimate."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import realistic.renderer.memory as memory
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.cli import main
from realistic.errors import UserError
from realistic.renderer.memory import check_memory, estimate_peak_bytes, memory_parts
from realistic.scene.lights import EmissiveInstance, PointLight
from realistic.scene.model import ImageTexture, Instance, Material, Scene
from realistic.scene.shapes import sphere

REPO = Path(__file__).resolve().parents[1]


def _camera(width: int = 64, height: int = 48, spp: int = 16) -> LensCamera:
    return LensCamera.looking_at(load_lens("dgauss"), np.array([0.0, 0.5, -3.0]), np.zeros(3), 3.0, 43.27,
                                 width, height, spp)


def _spheres(count: int, emitting: bool, shared: bool = True) -> Scene:
    """``count`` spheres in a row, instances of one mesh when ``shared`` (else each its own), each an
    area light when ``emitting``."""
    scene = Scene(meshes=[sphere(0.02) for _ in range(1 if shared else count)])
    for i in range(count):
        transform = np.eye(4)
        transform[0, 3] = 0.05 * i
        scene.instances.append(Instance(0 if shared else i, transform))
        if emitting:
            scene.lights.append(EmissiveInstance(i, (2.0, 2.0, 2.0)))
    if not emitting:
        scene.lights.append(PointLight((1.0, 1.0, 1.0), np.array([0.0, 2.0, 0.0])))
    return scene


def test_per_thread_buffers_are_bounded_by_the_work_there_is(tmp_path, capsys):
    """--threads 1024 on a 64x48 render was refused as needing 28.6 GiB: one pass holds all its samples."""
    scene, camera = _spheres(1, False), _camera()
    assert estimate_peak_bytes(scene, camera, 262144, 1024) == estimate_peak_bytes(scene, camera, 262144, 1)
    assert main(["render", "--backend", "numpy", "--res", "64x48", "--spp", "4", "--threads", "1024",
                 "--max-memory", "2G", "--out", str(tmp_path / "t.exr")]) == 0


def test_emitting_shapes_are_counted_as_light_tables_and_geometry():
    camera = _camera()
    faces = len(sphere(0.02).faces)
    plain = memory_parts(_spheres(2000, False), camera, 262144, 2)
    lit = memory_parts(_spheres(2000, True), camera, 262144, 2)
    assert lit["light tables"] - plain["light tables"] == memory.EMITTER_BYTES_PER_TRIANGLE * faces * 2000
    # embree builds a large mesh placed several times once; meshes placed once are copied each
    one = memory_parts(_spheres(1, False), camera, 262144, 2)["geometry"]
    assert plain["geometry"] == one
    distinct = memory_parts(_spheres(10, False, shared=False), camera, 262144, 2)["geometry"]
    assert distinct == 10 * one >= 10 * memory.SCENE_BYTES_PER_TRIANGLE * faces
    sequence = memory_parts(_spheres(2000, True), camera, 262144, 2, frames=10)
    assert sequence["light tables"] == 2 * lit["light tables"]  # two frames' runners at a frame boundary


def test_the_refusal_names_what_the_memory_goes_to(monkeypatch):
    """2000 emissive spheres: the refusal advised "lower --res" (issue 32)."""
    monkeypatch.setattr(memory, "available_bytes", lambda: 8 * 2**30)
    with pytest.raises(UserError) as refused:
        check_memory(_spheres(2000, True), _camera(), 262144, 2, None)
    message = str(refused.value)
    assert "\n" not in message and "light tables" in message
    assert "lower --res" not in message and "try fewer or coarser emitting shapes" in message


def test_a_limit_beyond_the_machine_is_not_believed(monkeypatch):
    """--max-memory 100G on a 24 GB machine let the OOM killer end the render (issue 32)."""
    scene, camera = _spheres(2000, True), _camera()
    need = estimate_peak_bytes(scene, camera, 262144, 2)
    monkeypatch.setattr(memory, "machine_bytes", lambda: need // 2)
    with pytest.raises(UserError, match="more than the .* GiB this machine has in all") as refused:
        check_memory(scene, camera, 262144, 2, 100 * 2**30)
    assert "raise --max-memory" not in str(refused.value)
    monkeypatch.setattr(memory, "machine_bytes", lambda: need * 2)
    check_memory(scene, camera, 262144, 2, need)  # a limit the machine can give is the user's to set


def test_textures_environment_maps_and_kept_frames_are_counted():
    camera = _camera()
    scene = _spheres(1, False)
    base = estimate_peak_bytes(scene, camera, 262144, 2)
    texture = ImageTexture(np.zeros((256, 512, 3), np.float32))
    scene.instances[0] = dataclasses.replace(scene.instances[0], material=Material(texture=texture))
    assert estimate_peak_bytes(scene, camera, 262144, 2) - base == memory.TEXTURE_FACTOR * texture.pixels.nbytes
    kept = estimate_peak_bytes(scene, camera, 262144, 2, frames=100, kept_images=100)
    streamed = estimate_peak_bytes(scene, camera, 262144, 2, frames=100)
    assert kept - streamed == 100 * memory.IMAGE_BYTES_PER_PIXEL * camera.width * camera.height


PEAK = """
import sys
import numpy as np
sys.path.insert(0, {tests!r})
from test_farm_memory import _camera, _spheres
from realistic.renderer.job import RenderJob
from realistic.renderer.memory import estimate_peak_bytes
from realistic.renderer.passes import ThreadPasses, render

scene, camera = _spheres({count}, True), _camera(32, 24, 2)
job = RenderJob(scene, (camera,), "numpy", pass_samples=512)
estimate = estimate_peak_bytes(scene, camera, job.pass_size, 2)
result = render(job, ThreadPasses(2))[0]
assert result.image.max() > 0
with open("/proc/self/status") as status:
    peak = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmHWM:"))
print(peak, estimate)
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the peak RSS from Linux's /proc")
def test_a_render_of_many_emitting_spheres_peaks_within_its_estimate():
    out = subprocess.run([sys.executable, "-c", PEAK.format(tests=str(REPO / "tests"), count=40)], cwd=REPO,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    peak, estimate = map(int, out.stdout.split())
    assert peak <= estimate, (peak / 2**30, estimate / 2**30)
    assert estimate > memory.BASE_BYTES + 40 * len(sphere(0.02).faces) * memory.EMITTER_BYTES_PER_TRIANGLE


def test_a_farm_refuses_before_sending_a_job_its_workers_cannot_hold():
    """Each Dask worker holds the scene and its passes: a job beyond a worker's ``memory_limit`` is
    refused in one line naming that limit, before the scene is sent (it was not checked at all)."""
    distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
    from realistic.renderer.farm import DaskPasses
    from realistic.renderer.job import RenderJob
    from realistic.renderer.timing import StageClock

    scene = _spheres(40, emitting=False, shared=False)  # 40 unshared spheres: well over 64 MiB of geometry
    job = RenderJob(scene, (_camera(),), "numpy")
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, memory_limit="64MiB",
                                       dashboard_address=None)
    try:
        with distributed.Client(cluster) as client:
            with pytest.raises(UserError, match="memory_limit") as refused:
                DaskPasses(client).open(job, StageClock())
            assert "\n" not in str(refused.value) and "0.1 GiB" in str(refused.value)
            assert not client.who_has()  # nothing was sent
    finally:
        cluster.close()


def test_aov_columns_are_counted_per_pixel_and_per_ray_in_flight():
    """The AOVs' film columns and per-ray values were not in the estimate."""
    camera = _camera()
    plain = memory_parts(_spheres(1, False), camera, 262144, 2)
    with_aovs = memory_parts(_spheres(1, False), camera, 262144, 2, aov_columns=14)
    pixels = camera.width * camera.height
    assert with_aovs["film"] - plain["film"] == memory.AOV_BYTES_PER_COLUMN * 14 * pixels
    assert with_aovs["passes in flight"] > plain["passes in flight"]
