"""The device layer and the render backends: scenes stay plain data after an OpenCL render (they
pickle, and a Dask worker renders the same Scene object), and ``--cl-device`` reaches every kernel,
the EWA textures' included."""

import pickle

import numpy as np
import pytest

from realistic.camera.lens_camera import LensCamera
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.device.opencl import LOCAL_SIZE, Device, OutputBlock, TypedKernel, cl
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


SCALARS = """__kernel void scalars(uint a, int b, float c, double d, __global double* values, __global int* ids) {
    size_t i = get_global_id(0);
    if (i == 0) { values[0] = a; values[1] = b; values[2] = c; values[3] = d; }
    ids[i] = (int) i;
}"""


def test_a_typed_kernel_passes_each_scalar_type_exactly_at_its_first_launch_and_after():
    """``TypedKernel`` tells pyopencl its scalar arguments' types at its first launch, from the numpy
    scalars passed, and packs them as those types from then on: uint32, int32, float32 and float64
    values reach the kernel exactly (a float64 value that float32 cannot hold included), launch after
    launch, through ``Device.run_into`` and its ``OutputBlock``."""
    device = Device.for_spec()
    kernel = TypedKernel(cl.Program(device.context, SCALARS).build(), "scalars")
    queue = device.queue()
    for a, b, c, d in ((2**32 - 1, -7, np.float32(1 / 3), 0.1), (0, 2**31 - 1, np.float32(-0.0), 1e300),
                       (12345, -(2**31), np.float32(3e-45), -2.5e-310)):
        outputs = OutputBlock(device, (((4,), np.float64), ((LOCAL_SIZE,), np.int32)))
        values, ids = outputs.arrays
        device.run_into(queue, kernel, (LOCAL_SIZE,), (LOCAL_SIZE,),
                        (np.uint32(a), np.int32(b), np.float32(c), np.float64(d)), outputs)
        expected = np.array([a, b, float(c), d], np.float64)
        assert values.tobytes() == expected.tobytes()
        assert np.array_equal(ids, np.arange(LOCAL_SIZE))


def test_an_output_block_lays_its_outputs_out_at_the_sub_buffer_alignment():
    """``OutputBlock``: one host array holding each output (of its shape and dtype, an empty one
    too) from an offset that is a multiple of the device's sub-buffer alignment, one buffer over it and
    a sub-buffer per output, each of the output's size (one element for an empty output)."""
    device = Device.for_spec()
    align = device.devices[0].mem_base_addr_align // 8
    shapes = (((7, 300), np.float32), ((0,), np.uint8), ((301,), np.int32), ((5, 3), np.float64))
    block = OutputBlock(device, shapes)
    try:
        assert len(block.arrays) == len(block.parts) == len(shapes)
        base = block.block.ctypes.data
        for array, part, (shape, dtype) in zip(block.arrays, block.parts, shapes):
            assert array.shape == shape and array.dtype == dtype and array.flags.c_contiguous
            if array.size:
                assert (array.ctypes.data - base) % align == 0
                assert np.shares_memory(array, block.block)
            assert part.size == max(array.nbytes, np.dtype(dtype).itemsize)
    finally:
        block.release()
