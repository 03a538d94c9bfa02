"""The interface every camera implements, and the ray batch it produces.

A render is the range of *sample ids* 0 .. width * height * spp - 1; sample id i belongs to pixel
i // spp (raster order, x fastest) as that pixel's sample i % spp, so any render can be cut into
passes of bounded size. A camera turns a range of sample ids into a ``RayBatch`` of world-space
rays; ``ray_generator`` binds the backend (OpenCL kernel or numpy reference) and the seed once, so
the renderer calls every camera the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from realistic.errors import UserError

#: Ray generation backends: the OpenCL kernel, or the float64 numpy reference (never a fallback).
BACKENDS = ("opencl", "numpy")


@dataclass(frozen=True)
class RayBatch:
    """Camera rays in world space; a vignetted ray has weight 0 and zero origin and direction."""

    origin: np.ndarray  # (N, 3)
    direction: np.ndarray  # (N, 3) unit
    weight: np.ndarray  # (N,) cos^4(theta) A / Z^2 (1 for a thin lens) times the pixel filter's factor (may be < 0)
    pixel: np.ndarray  # (N,) raster index y * width + x
    wavelength_nm: np.ndarray | None = None  # (N,) for a spectral camera, else None


#: ``(first_sample, count) -> RayBatch``: a camera's rays with the backend and seed already chosen.
RayGenerator = Callable[[int, int], RayBatch]

Metadata = dict[str, str | int | float]

#: ``(origin, direction) -> distance`` to the first hit along a world-space ray, None for a miss.
HitDistance = Callable[[np.ndarray, np.ndarray], "float | None"]


class Camera(Protocol):
    """What the renderer, the CLI and the Python API need of a camera.

    Implemented by ``LensCamera`` (a real lens traced surface by surface) and ``ThinLensCamera``
    (pbrt's perspective camera). Cameras are immutable: ``dataclasses.replace`` makes variants.
    """

    width: int
    height: int
    spp: int

    @property
    def sample_count(self) -> int:
        """width * height * spp: the sample ids a render of this camera covers."""

    def generate_rays(self, first_sample: int, count: int, seed: int = 0) -> RayBatch:
        """Rays of sample ids first_sample .. first_sample + count - 1, by the numpy reference."""

    def prepare(self) -> None:
        """Build ahead what ray generation needs (a lens camera's exit-pupil table), so that a
        render can time it as a stage of its own; ``ray_generator`` builds it otherwise."""

    def ray_generator(self, backend: str = "opencl", seed: int = 0, cl_device: str | None = None) -> RayGenerator:
        """The rays of any range of sample ids from ``backend`` (see ``BACKENDS``) with ``seed``."""

    def metadata(self) -> Metadata:
        """What an image header should say about this camera (lens, stop, focus, film...)."""

    def pixel_spread_radians(self) -> float:
        """Angle one pixel subtends seen from the scene (near the image centre): a camera ray's
        footprint at distance d is about d times this, for filtering textures."""

    def with_dispersion(self, spectral: bool | None) -> Camera:
        """This camera with spectral sampling on, off, or (None) as its lens suggests."""

    def autofocused(self, x: float, y: float, hit_distance: HitDistance) -> Camera:
        """Refocused on what raster point (x, y) sees (``hit_distance``: the scene along a ray)."""


def split_sample_ids(first_sample: int, count: int, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """(pixel, sample within the pixel) int64 arrays of sample ids first_sample .. + count - 1."""
    ids = np.arange(first_sample, first_sample + count, dtype=np.int64)
    return ids // spp, ids % spp


def check_backend(backend: str) -> None:
    """Raise UserError for a backend name not in ``BACKENDS``."""
    if backend not in BACKENDS:
        raise UserError(f"unknown backend {backend!r} (choose {', '.join(BACKENDS)})")
