"""Choosing how camera rays are made: the OpenCL kernel or the numpy reference.

A ray generator is a callable ``(first_sample, count) -> RayBatch`` bound to one camera and seed.
The numpy backend is an explicit choice (``--backend numpy``), never a silent fallback. The OpenCL
backend returns float32 arrays (origin and direction as (N, 3) views of structure-of-arrays
buffers, pixel as int32); the numpy backend float64 and int64.

pbrt's ``perspective`` camera (``ThinLensCamera``) has no lens to trace: its rays are a few
arithmetic operations per sample and come from numpy whatever the backend.
"""

from __future__ import annotations

from typing import Callable

from realistic.camera import Camera, RayBatch, generate_rays
from realistic.errors import UserError
from realistic.thin_lens import ThinLensCamera, generate_thin_lens_rays

BACKENDS = ("opencl", "numpy")
RayGenerator = Callable[[int, int], RayBatch]


def ray_generator(camera: Camera | ThinLensCamera, backend: str = "opencl", seed: int = 0,
                  cl_device: str | None = None) -> RayGenerator:
    """A function making the camera rays of a range of sample ids with the chosen backend."""
    if backend not in BACKENDS:
        raise UserError(f"unknown backend {backend!r} (choose {', '.join(BACKENDS)})")
    if isinstance(camera, ThinLensCamera):
        return lambda first, count: generate_thin_lens_rays(camera, first, count, seed)
    if backend == "numpy":
        return lambda first, count: generate_rays(camera, first, count, seed)
    from realistic.opencl_host import LensKernel  # imports pyopencl, so only when chosen

    kernel = LensKernel(camera, cl_device)
    return lambda first, count: kernel.generate(first, count, seed)
