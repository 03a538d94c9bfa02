"""The camera: film geometry, sample ids to camera rays, and the camera-to-world transform.

A render is a range of *sample ids*; sample id i belongs to pixel i // spp (raster order, x
fastest) as that pixel's sample i % spp, so any render can be cut into passes of bounded size.
``generate_rays`` is the float64 numpy reference of the OpenCL kernel's ray generation: same
random numbers (``realistic.rng``), same film mapping, same samplers, same tracing rules.

Film mapping (lens frame, film at z = 0): the film is the resolution's aspect ratio with the given
diagonal; raster (x right, y down) maps to film x = -(x / W - 1/2) w, film y = (y / H - 1/2) h.
The lens inverts the image, so this flip makes it come out upright and unmirrored.

A *spectral* camera gives each sample a wavelength (``realistic.spectrum``: uniform over 380-780
nm, stratified within the pixel) and traces it with the glasses' indices at that wavelength, so
the lens's chromatic aberration reaches the image. A non-spectral camera traces at the d line.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from realistic import rng
from realistic.dispersion import D_LINE_NM
from realistic.errors import UserError
from realistic.prescription import LensSystem
from realistic.reference import trace_from_film
from realistic.sampling import ExitPupilTable, camera_weight, exit_pupil_table, rear_element_sampler
from realistic.spectrum import LAMBDA_MAX_NM, LAMBDA_MIN_NM, wavelengths_nm

LENS_SAMPLINGS = ("pupil", "rear")


@dataclass(frozen=True, eq=False)
class Camera:
    """Everything ray generation needs. ``world_from_lens`` maps lens-frame mm to world units."""

    lens: LensSystem
    film_distance_mm: float
    film_diagonal_mm: float
    width: int
    height: int
    spp: int
    world_from_lens: np.ndarray  # (4, 4)
    lens_sampling: str
    spectral: bool = False

    @property
    def pupil(self) -> ExitPupilTable:
        """Exit-pupil bounds for this lens, focus and film, built on first use (then cached); a
        spectral camera's boxes hold what passes at either end of the wavelength range as well as
        at the d line."""
        wavelengths = (LAMBDA_MIN_NM, D_LINE_NM, LAMBDA_MAX_NM) if self.spectral else (D_LINE_NM,)
        return exit_pupil_table(self.lens, self.film_distance_mm, self.film_diagonal_mm, wavelengths_nm=wavelengths)

    @property
    def film_size_mm(self) -> tuple[float, float]:
        scale = self.film_diagonal_mm / math.hypot(self.width, self.height)
        return self.width * scale, self.height * scale

    @property
    def sample_count(self) -> int:
        return self.width * self.height * self.spp


def build_camera(lens: LensSystem, film_distance_mm: float, film_diagonal_mm: float, width: int, height: int,
                 spp: int = 1, world_from_camera: np.ndarray | None = None, camera_origin_mm: float = 0.0,
                 lens_sampling: str = "pupil", spectral: bool = False) -> Camera:
    """A camera whose camera-space origin sits ``camera_origin_mm`` from the film toward the scene.

    pbrt-v3 puts the camera origin at the film centre (0); the classic homework puts it at the
    front lens vertex (film distance + track length).
    """
    if width < 1 or height < 1:
        raise UserError(f"resolution must be at least 1x1, got {width}x{height}")
    if spp < 1:
        raise UserError(f"samples per pixel must be at least 1, got {spp}")
    if lens_sampling not in LENS_SAMPLINGS:
        raise UserError(f"lens sampling must be one of {', '.join(LENS_SAMPLINGS)}, got {lens_sampling!r}")
    if not film_distance_mm > 0:
        raise UserError(f"film distance must be positive, got {film_distance_mm:g} mm")
    shift = np.eye(4)
    shift[2, 3] = -camera_origin_mm
    world = np.eye(4) if world_from_camera is None else np.asarray(world_from_camera, dtype=np.float64)
    return Camera(lens, film_distance_mm, film_diagonal_mm, width, height, spp, world @ shift, lens_sampling,
                  spectral)


def with_spectral(camera: Camera, spectral: bool) -> Camera:
    """The camera with spectral sampling on or off (its exit-pupil bounds follow)."""
    return dataclasses.replace(camera, spectral=spectral)


@dataclass(frozen=True)
class RayBatch:
    """Camera rays in world space; a vignetted ray has weight 0 and zero origin and direction."""

    origin: np.ndarray  # (N, 3)
    direction: np.ndarray  # (N, 3) unit
    weight: np.ndarray  # (N,) cos^4(theta) A / Z^2 in mm^0 (area over distance squared)
    pixel: np.ndarray  # (N,) raster index y * width + x
    wavelength_nm: np.ndarray | None = None  # (N,) for a spectral camera, else None


def film_points(camera: Camera, pixel: np.ndarray, u_x: np.ndarray, u_y: np.ndarray) -> np.ndarray:
    """Film points (N, 2) in mm for pixels and in-pixel offsets in [0, 1)."""
    w_mm, h_mm = camera.film_size_mm
    x = (pixel % camera.width) + u_x.astype(np.float64)
    y = (pixel // camera.width) + u_y.astype(np.float64)
    return np.column_stack([-(x / camera.width - 0.5) * w_mm, (y / camera.height - 0.5) * h_mm])


def generate_rays(camera: Camera, first_sample: int, count: int, seed: int = 0) -> RayBatch:
    """Camera rays for sample ids first_sample .. first_sample + count - 1 (reference implementation)."""
    ids = np.arange(first_sample, first_sample + count, dtype=np.int64)
    pixel = ids // camera.spp
    sample = ids % camera.spp
    u_x, u_y, u_lens, v_lens = rng.stratified4(pixel, sample, seed)
    film_xy = film_points(camera, pixel, u_x, u_y)
    if camera.lens_sampling == "pupil":
        sampler = camera.pupil
    else:
        sampler = rear_element_sampler(camera.lens, camera.film_distance_mm)
    targets, area = sampler.sample(film_xy, u_lens.astype(np.float64), v_lens.astype(np.float64))
    film = np.column_stack([film_xy, np.zeros(count)])
    wavelength = None
    if camera.spectral:
        wavelength = wavelengths_nm(rng.to_unit_float(rng.wavelength_bits(pixel, sample, seed)))
    traced = trace_from_film(camera.lens, camera.film_distance_mm, film, targets - film,
                             D_LINE_NM if wavelength is None else wavelength.astype(np.float64))
    weight = np.where(traced.passed, camera_weight(film, targets, area, sampler.plane_z_mm), 0.0)
    m = camera.world_from_lens
    origin = np.where(traced.passed[:, None], traced.origin @ m[:3, :3].T + m[:3, 3], 0.0)
    direction = np.where(traced.passed[:, None], traced.direction @ m[:3, :3].T, 0.0)
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    direction = np.divide(direction, length, out=np.zeros_like(direction), where=length > 0)
    return RayBatch(origin, direction, weight, pixel, wavelength)
