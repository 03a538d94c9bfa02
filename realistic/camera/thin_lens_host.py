"""OpenCL host of the thin-lens (pbrt perspective) camera's rays: ``kernels/thin_lens.cl`` on a ``Device``.

The numpy ``ThinLensCamera.generate_rays`` costs about as much per sample as tracing the rays into
the scene, so the OpenCL backend makes these rays on the device as it does a real lens's
(``opencl_host.LensKernel``), from the same random numbers, sample addresses and pixel filter. Only
the pixel filter is compiled in (``opencl_host.filter_lines``); the field of view, resolution,
focus and lens radius are kernel arguments, so one build serves every perspective camera with that
filter. Launches are padded as the lens kernel's are (``opencl_host.LaunchSizes``) and write
straight into the arrays returned.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from realistic.camera.base import RayBatch, SampleBlock
from realistic.camera.opencl_host import ROWS, LaunchSizes, filter_lines
from realistic.camera.thin_lens import ThinLensCamera
from realistic.device.opencl import LOCAL_SIZE, Device, OutputBlock, TypedKernel, kernel_source

KERNEL_FILE = "thin_lens.cl"


def thin_lens_program(camera: ThinLensCamera) -> tuple[str, str]:
    """``Device.build_program``'s source and name for the camera's kernel (its pixel filter's)."""
    return "\n".join(filter_lines(camera.pixel_filter)) + "\n" + kernel_source(KERNEL_FILE), KERNEL_FILE


def kernel_constants(camera: ThinLensCamera) -> tuple[np.generic, ...]:
    """The kernel's camera arguments after ``world``: width, 1 / width (float64), 1 / width and
    1 / height, the screen window's half extents times tan(fov / 2), the lens radius and the focal
    distance (1 for a pinhole, whose rays then aim along the screen line itself)."""
    half_x, half_y = camera.screen_window()
    tan_half = math.tan(math.radians(camera.fov_deg) / 2)
    focus = camera.focal_distance if camera.lens_radius > 0 else 1.0
    f = np.float32
    return (np.uint32(camera.width), np.float64(1) / np.float64(camera.width), f(1) / f(camera.width),
            f(1) / f(camera.height), f(half_x * tan_half), f(half_y * tan_half), f(camera.lens_radius), f(focus))


class ThinLensKernel:
    """``thin_lens.cl`` built for one camera's pixel filter; ``generate`` is ``generate_rays`` in
    float32. Safe to call from several threads: launches are serialised on one lock (PoCL spreads
    one launch over every core)."""

    def __init__(self, camera: ThinLensCamera, device: Device | None = None):
        """``device``: where to build and launch (None: ``Device.for_spec()``, the default device)."""
        device = device or Device.for_spec()
        self.camera, self.device = camera, device
        self.queue = device.queue()
        self._lock = threading.Lock()
        self._world = device.copied_buffer(camera.world_from_camera[:3, :4], np.float32)
        self._constants = kernel_constants(camera)
        program = device.build_program(*thin_lens_program(camera))
        self._generate = TypedKernel(program, "generate_rays")
        self._sizes = LaunchSizes()  # padded as the first launch decides (``opencl_host.SMALL_GRID_LIMIT``)

    def generate(self, block: SampleBlock, seed: int = 0) -> RayBatch:
        """Rays of the block's samples, as ``ThinLensCamera.generate_rays`` makes them (float32)."""
        count = block.count
        with self._lock:  # written in place, read back at once (Device.run_into), as LensKernel.generate does
            address, padded = self._sizes.layout(block)
            outputs = OutputBlock(self.device, (((ROWS, padded), np.float32), ((padded,), np.int32)))
            out, pixels = outputs.arrays
            self.device.run_into(self.queue, self._generate, (padded,), (LOCAL_SIZE,),
                                 (*address, np.uint32(seed & 0xFFFFFFFF), self._world, *self._constants,
                                  np.uint32(padded)), outputs)
        return RayBatch(origin=out[0:3, :count].T, direction=out[3:6, :count].T, weight=out[6, :count],
                        pixel=pixels[:count])
