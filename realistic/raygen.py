"""Choosing how camera rays are made: the OpenCL kernel or the numpy reference.

A ray generator is a callable ``(first_sample, count) -> RayBatch`` bound to one camera and seed.
The numpy backend is an explicit choice (``--backend numpy``), never a silent fallback.
"""

from __future__ import annotations

from typing import Callable

from realistic.camera import Camera, RayBatch, generate_rays
from realistic.errors import UserError

BACKENDS = ("opencl", "numpy")
RayGenerator = Callable[[int, int], RayBatch]


def ray_generator(camera: Camera, backend: str = "opencl", seed: int = 0, cl_device: str | None = None
                  ) -> RayGenerator:
    """A function making the camera rays of a range of sample ids with the chosen backend."""
    if backend == "numpy":
        return lambda first, count: generate_rays(camera, first, count, seed)
    if backend == "opencl":
        raise UserError("the OpenCL backend is not built yet: use --backend numpy")
    raise UserError(f"unknown backend {backend!r} (choose {', '.join(BACKENDS)})")
