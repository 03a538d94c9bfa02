"""The device layer and the render backends: scenes stay plain data after an OpenCL render (they
pickle, and a Dask worker renders the same Scene object), and ``--cl-device`` reaches every kernel,
the EWA textures' included."""

import pickle

import numpy as np
import pytest

from realistic.camera.lens_camera import LensCamera
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.optics.formats import load_lens
from realistic.renderer.backends import NumpyBackend, backend_for
from realistic.renderer.farm import DaskPasses
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import render
from realistic.scene.model import ImageTexture
from test_ewa_hits import instanced_scene

pytestmark = pytest.mark.usefixtures("opencl_platform")

PASS = 1536


def ewa_scene_and_camera():
    """``test_ewa_hits``' scene of EWA image textures on instances, seen through dgauss (48 x 32, 2 spp)."""
    scene, eye, target = instanced_scene()
    camera = LensCamera.looking_at(load_lens("dgauss"), eye, target, None, FULL_FRAME_DIAGONAL_MM, 48, 32, 2)
    return scene, camera


def ewa_maps(scene) -> list:
    """The maps of the image textures, which the device filters whatever their filter."""
    return [inst.material.texture.mipmap for inst in scene.instances if isinstance(inst.material.texture, ImageTexture)]


def test_backends_are_made_once_per_process_name_and_device():
    assert backend_for("opencl") is backend_for("opencl")
    assert backend_for("opencl", "0:0") is not backend_for("opencl")
    assert isinstance(backend_for("numpy"), NumpyBackend)


def test_an_ewa_scene_pickles_after_an_opencl_render_and_a_dask_worker_renders_it():
    """After an OpenCL render that filtered EWA textures on the device, the Scene holds no OpenCL
    object: it pickles, and a one-worker process cluster renders the same Scene object to the same
    image (the worker makes its own device)."""
    distributed = pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
    scene, camera = ewa_scene_and_camera()
    assert ewa_maps(scene)
    image = render(RenderJob(scene, (camera,), "opencl", seed=5, pass_samples=PASS))[0].image
    assert image.max() > 0
    assert pickle.loads(pickle.dumps(scene)).instances  # raised "cannot pickle 'pyopencl._cl.Context'" before
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        with distributed.Client(cluster) as client:
            farmed = render(RenderJob(scene, (camera,), "opencl", seed=5, pass_samples=PASS),
                            DaskPasses(client, task_samples=2 * PASS))[0].image
    finally:
        cluster.close()
    assert np.array_equal(farmed, image)


def test_the_cl_device_reaches_the_ewa_kernel(monkeypatch):
    """A render on ``cl_device`` puts its EWA textures' texels on that device (it was ignored: the
    maps' kernels were made on the default device)."""
    from realistic.device.opencl import Device
    from realistic.renderer import opencl_backend

    made = []
    real = opencl_backend.EwaKernel

    def recording(mipmap, device):
        made.append((mipmap, device))
        return real(mipmap, device)

    monkeypatch.setattr(opencl_backend, "EwaKernel", recording)
    scene, camera = ewa_scene_and_camera()
    spec = "0:0"
    render(RenderJob(scene, (camera,), "opencl", seed=5, cl_device=spec, pass_samples=PASS))
    maps = ewa_maps(scene)
    assert {id(m) for m, _ in made} == {id(m) for m in maps}
    assert all(device is Device.for_spec(spec) for _, device in made)
    assert Device.for_spec(spec) is not Device.for_spec()
