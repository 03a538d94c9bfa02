"""The interface every camera implements, and the ray batch it produces.

A render is the set of (pixel, sample) pairs, pixels in raster order (x fastest), samples 0 .. spp - 1
of each. A ``SampleBlock`` names a batch of them: a run of pixels times a slice of each pixel's
samples, so a render can be cut into passes of bounded size that each cover the frame evenly. A
camera turns a block into a ``RayBatch`` of world-space rays (``generate_rays``, the numpy
reference); a render backend (``realistic.renderer.backends``) binds the OpenCL kernel or the
reference and the seed once (a ``RayGenerator``), so the renderer calls every camera the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import Field, dataclass
from typing import Any, ClassVar, Protocol

import numpy as np

from realistic.errors import UserError
from realistic.optics.lens import LensSystem
from realistic.optics.stop_shape import StopShape

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


@dataclass(frozen=True)
class SampleBlock:
    """``count`` consecutive pairs of the sequence that gives each pixel the samples
    ``first_sample .. first_sample + samples - 1``: pair t (t = first, first + 1, ...) is sample
    ``first_sample + t % samples`` of pixel ``t // samples``. With ``samples = spp`` and
    ``first_sample = 0``, t is today's sample id (pixel * spp + sample); a pass takes a slice
    (``samples < spp``) of a run of whole pixels (``of_pixels``)."""

    first: int
    count: int
    samples: int  # the slice width: samples of each pixel in this sequence
    first_sample: int = 0

    def __post_init__(self) -> None:
        if self.first < 0 or self.count < 1 or self.samples < 1 or self.first_sample < 0:
            raise ValueError(f"invalid sample block {self}")

    @classmethod
    def of_pixels(cls, first_pixel: int, pixel_count: int, first_sample: int, samples: int) -> SampleBlock:
        """Samples first_sample .. + samples - 1 of each of pixels first_pixel .. + pixel_count - 1."""
        return cls(first_pixel * samples, pixel_count * samples, samples, first_sample)

    @property
    def first_pixel(self) -> int:
        return self.first // self.samples

    @property
    def pixel_count(self) -> int:
        """Pixels with at least one sample in the block."""
        return (self.first + self.count - 1) // self.samples - self.first_pixel + 1

    def ids(self) -> tuple[np.ndarray, np.ndarray]:
        """(pixel, sample within the pixel) int64 arrays of the block's pairs, in launch order."""
        t = np.arange(self.first, self.first + self.count, dtype=np.int64)
        return t // self.samples, self.sample_ids()

    def sample_ids(self) -> np.ndarray:
        """``ids()[1]`` alone: one pixel's slice of sample numbers repeated, which the renderer needs
        per pass and costs a twentieth of the division and remainder over every pair."""
        offset = self.first % self.samples
        pixels = -(-(offset + self.count) // self.samples)
        one_pixel = np.arange(self.first_sample, self.first_sample + self.samples, dtype=np.int64)
        return np.tile(one_pixel, pixels)[offset:offset + self.count]

    def samples_per_pixel(self) -> np.ndarray:
        """How many samples each of the block's ``pixel_count`` pixels gets."""
        pixels = np.arange(self.first_pixel, self.first_pixel + self.pixel_count, dtype=np.int64)
        end = self.first + self.count
        return np.minimum(end, (pixels + 1) * self.samples) - np.maximum(self.first, pixels * self.samples)


#: ``SampleBlock -> RayBatch``: a camera's rays with the backend and seed already chosen.
RayGenerator = Callable[[SampleBlock], RayBatch]

Metadata = dict[str, str | int | float]

#: ``(origin, direction) -> distance`` to the first hit along a world-space ray, None for a miss.
HitDistance = Callable[[np.ndarray, np.ndarray], "float | None"]


class Camera(Protocol):
    """What the renderer, the CLI and the Python API need of a camera.

    Implemented by ``LensCamera`` (a real lens traced surface by surface) and ``ThinLensCamera``
    (pbrt's perspective camera). Cameras are immutable: ``dataclasses.replace`` makes variants.
    """

    #: Every camera is a dataclass, so that ``dataclasses.replace`` applies to it.
    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]

    # Read-only (properties), as the frozen dataclasses that implement them hold them.
    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...

    @property
    def spp(self) -> int: ...

    @property
    def world_from_camera(self) -> np.ndarray:
        """(4, 4) from camera space (+z toward the scene) to world units."""

    @property
    def sample_count(self) -> int:
        """width * height * spp: the sample ids a render of this camera covers."""

    @property
    def rays_per_sample(self) -> int:
        """Camera rays ``generate_rays`` makes per sample, consecutively (a spectral lens camera's
        wavelengths per sample; else 1)."""

    def generate_rays(self, block: SampleBlock, seed: int = 0) -> RayBatch:
        """Rays of the block's samples, in its order, by the numpy reference."""

    def prepare(self) -> None:
        """Build ahead what ray generation needs (a lens camera's exit-pupil table), so that a
        render can time it as a stage of its own; ray generation builds it otherwise."""

    def metadata(self) -> Metadata:
        """What an image header should say about this camera (lens, stop, focus, film...)."""

    def pixel_spread_radians(self) -> float:
        """Angle one pixel subtends seen from the scene (near the image centre): a camera ray's
        footprint at distance d is about d times this, for filtering textures."""

    def with_dispersion(self, spectral: bool | None) -> Camera:
        """This camera with spectral sampling on, off, or (None) as its lens suggests."""

    def autofocused(self, x: float, y: float, hit_distance: HitDistance) -> Camera:
        """Refocused on what raster point (x, y) sees (``hit_distance``: the scene along a ray)."""

    def with_focus(self, distance: float) -> Camera:
        """Focused ``distance`` scene units from the film plane (``--focus``)."""

    def with_stop(self, *, f_number: float | None = None, aperture_mm: float | None = None,
                  shape: StopShape | None = None) -> Camera:
        """The stop sized for an f-number or a diameter, and shaped (``--fstop``, ``--aperture``, ``--blades``)."""

    def with_lens(self, lens: LensSystem | str, *, film_diagonal_mm: float | str | None = None) -> Camera:
        """A real lens at this camera's pose (``--lens``, ``--film-diagonal``)."""


def check_backend(backend: str) -> None:
    """Raise UserError for a backend name not in ``BACKENDS``."""
    if backend not in BACKENDS:
        raise UserError(f"unknown backend {backend!r} (choose {', '.join(BACKENDS)})")
