"""pbrt's ``perspective`` camera: a pinhole, or an ideal thin lens when it has a lens radius.

Used for pbrt scenes that ask for it (and as a comparison for the real lenses). Rays come in the
same ``RayBatch`` as the realistic camera's, from the same counter-based samples, with weight 1.
``generate_rays`` is the float64 reference; the OpenCL backend makes the same rays with
``kernels/thin_lens.cl`` (``camera/thin_lens_host``), since in numpy they cost as much as tracing them.

The film position is drawn from the pixel filter (``realistic.core.pixel_filter``), as the
realistic camera draws it; the filter's factor is the ray's weight (1 for box and triangle).

pbrt's screen window: the shorter image side spans [-1, 1], the longer [-aspect, aspect]; ``fov``
is the angle across the shorter side. Camera space looks down +z, +x is image right, +y image up.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from realistic.camera.base import HitDistance, Metadata, RayBatch, SampleBlock
from realistic.camera.lens_camera import (
    MM_PER_METRE,
    NEAREST_FOCUS_MARGIN,
    FilmDiagonal,
    LensCamera,
    film_diagonal_for_fov_mm,
    film_diagonal_value,
)
from realistic.core import rng, validation
from realistic.core.pixel_filter import PIXEL_BOX, PixelFilter
from realistic.core.transforms import scale, transform_points, transform_vectors
from realistic.core.warp import concentric_disk
from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, nearest_focus_mm
from realistic.optics.stop_shape import StopShape

NOT_A_LENS = "needs a lens camera; this scene's camera is pbrt's perspective"


@dataclass(frozen=True, eq=False)
class ThinLensCamera:
    """pbrt's perspective camera; validated on construction."""

    fov_deg: float
    lens_radius: float  # scene units; 0 = pinhole
    focal_distance: float  # scene units along the camera's z
    width: int
    height: int
    spp: int
    world_from_camera: np.ndarray
    pixel_filter: PixelFilter = PIXEL_BOX

    def __post_init__(self) -> None:
        if not 0 < self.fov_deg < 180:
            raise UserError(f"perspective camera fov must be between 0 and 180 degrees, got {self.fov_deg:g}")
        if self.lens_radius < 0 or (self.lens_radius > 0 and not self.focal_distance > 0):
            raise UserError(f"thin lens needs lensradius >= 0 and focaldistance > 0, got {self.lens_radius:g}, "
                            f"{self.focal_distance:g}")
        validation.resolution(self.width, self.height)
        validation.samples_per_pixel(self.spp)
        object.__setattr__(self, "world_from_camera", np.asarray(self.world_from_camera, dtype=np.float64))

    def __repr__(self) -> str:
        """One line, no arrays: field of view, film, and the thin lens (scene units) if any."""
        lens = (f"lens radius {self.lens_radius:.4g}, focus {self.focal_distance:.4g}" if self.lens_radius > 0
                else "pinhole")
        return f"ThinLensCamera(fov {self.fov_deg:.4g} deg, {self.width}x{self.height}, {self.spp} spp, {lens})"

    @property
    def sample_count(self) -> int:
        return self.width * self.height * self.spp

    @property
    def rays_per_sample(self) -> int:
        return 1

    def screen_window(self) -> tuple[float, float]:
        """Half extents (x, y) of the screen window."""
        aspect = self.width / self.height
        return (aspect, 1.0) if aspect > 1 else (1.0, 1.0 / aspect)

    def generate_rays(self, block: SampleBlock, seed: int = 0) -> RayBatch:
        """Rays for the block's samples, in its order."""
        pixel, sample = block.ids()
        count = block.count
        u_x, u_y, u_lens, v_lens = rng.stratified4(pixel, sample, seed)
        half_x, half_y = self.screen_window()
        dx, dy, weight = self.pixel_filter.offsets(u_x, u_y)
        x = (pixel % self.width + (0.5 + dx)) / self.width
        y = (pixel // self.width + (0.5 + dy)) / self.height
        tan_half = math.tan(math.radians(self.fov_deg) / 2)
        direction = np.column_stack([(2 * x - 1) * half_x * tan_half, (1 - 2 * y) * half_y * tan_half,
                                     np.ones(count)])
        origin = np.zeros((count, 3))
        if self.lens_radius > 0:
            lens_x, lens_y = concentric_disk(u_lens, v_lens)
            origin[:, 0], origin[:, 1] = lens_x * self.lens_radius, lens_y * self.lens_radius
            focus = direction * self.focal_distance  # direction has z = 1
            direction = focus - origin
        world_direction = transform_vectors(self.world_from_camera, direction)
        world_direction /= np.linalg.norm(world_direction, axis=1, keepdims=True)
        return RayBatch(transform_points(self.world_from_camera, origin), world_direction, weight, pixel)

    def prepare(self) -> None:
        """Nothing to build ahead: a thin lens samples its aperture disk directly."""

    def metadata(self) -> Metadata:
        return {"lens": "thin lens (pbrt perspective)", "fovDegrees": float(self.fov_deg),
                "lensRadius": float(self.lens_radius), "focusDistanceSceneUnits": float(self.focal_distance),
                "pixelFilter": self.pixel_filter.describe()}

    def pixel_spread_radians(self) -> float:
        """Angle one pixel subtends at the image centre: the screen window's 2 tan(fov / 2) over the
        shorter side's pixel count."""
        return 2 * math.tan(math.radians(self.fov_deg) / 2) / min(self.width, self.height)

    def with_dispersion(self, spectral: bool | None) -> ThinLensCamera:
        """The camera itself: a thin lens has no glass to disperse (asking for dispersion is an error)."""
        if spectral:
            raise UserError(f"--dispersion on {NOT_A_LENS}")
        return self

    def camera_direction(self, x: float, y: float) -> np.ndarray:
        """The pinhole ray's camera-space direction (z = 1) through raster point (x, y) (pixels)."""
        half_x, half_y = self.screen_window()
        tan_half = math.tan(math.radians(self.fov_deg) / 2)
        return np.array([(2 * x / self.width - 1) * half_x * tan_half, (1 - 2 * y / self.height) * half_y * tan_half,
                         1.0])

    def with_focus(self, distance: float) -> ThinLensCamera:
        """The thin lens focused ``distance`` scene units along the view axis (pbrt's
        ``focaldistance``; a pinhole, with no lens radius, is sharp everywhere anyway)."""
        return dataclasses.replace(self, focal_distance=validation.positive_length(distance, "focus distance"))

    def with_stop(self, *, f_number: float | None = None, aperture_mm: float | None = None,
                  shape: StopShape | None = None) -> ThinLensCamera:
        """Refused: pbrt's thin lens has a radius in scene units but no focal length or stop to size
        in mm; ``with_lens`` puts a real lens there first."""
        raise UserError('the stop options (--fstop, --aperture, --blades, --aperture-mask) need a real lens, and '
                        'this camera is pbrt\'s perspective: give --lens too (with_lens)')

    def with_lens(self, lens: LensSystem | str, *, film_diagonal_mm: FilmDiagonal = None) -> LensCamera:
        """A real lens in place of the thin lens, at the same pose (film centre at the pinhole, camera
        space in metres as pbrt-v3/v4's realistic camera reads it), resolution, samples and filter,
        focused where the thin lens was (at infinity for a pinhole). The film: ``film_diagonal_mm``
        in mm or ``"auto"``, or None: the one that keeps this camera's field of view along the
        shorter image side (``film_diagonal_for_fov_mm``, pbrt's ``fov`` convention)."""
        lens = load_lens(lens) if isinstance(lens, str) else lens
        focus_mm = self.focal_distance * MM_PER_METRE if self.lens_radius > 0 else math.inf
        focus_mm = max(focus_mm, NEAREST_FOCUS_MARGIN * nearest_focus_mm(lens))
        film_distance = film_distance_for_focus(lens, focus_mm)
        film = film_diagonal_value(film_diagonal_mm)
        fov_film = film_diagonal_for_fov_mm(lens, film_distance, self.fov_deg, self.width, self.height)
        camera = LensCamera(lens, film_distance, validation.film_diagonal_mm(fov_film), self.width, self.height,
                            self.spp, self.world_from_camera @ scale(1.0 / MM_PER_METRE), "film",
                            pixel_filter=self.pixel_filter)
        return camera if film is None else camera.with_film(film)

    def autofocused(self, x: float, y: float, hit_distance: HitDistance) -> ThinLensCamera:
        """Focused (``with_focus``) on the depth along the view axis of what the pinhole ray through
        raster point (x, y) hits; ``hit_distance(origin, direction)`` is the scene along a world ray."""
        direction = transform_vectors(self.world_from_camera, self.camera_direction(x, y)[None, :])[0]
        length = float(np.linalg.norm(direction))
        distance = hit_distance(self.world_from_camera[:3, 3], direction / length)
        if distance is None:
            raise UserError(f"--focus-on {x:g},{y:g}: the view through that point hits nothing to focus on")
        return self.with_focus(distance / length)  # camera-space depth: the direction has z = 1
