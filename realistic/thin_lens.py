"""pbrt's ``perspective`` camera: a pinhole, or an ideal thin lens when it has a lens radius.

Used for pbrt scenes that ask for it (and as a comparison for the real lenses). Rays come in the
same ``RayBatch`` as the realistic camera's, from the same counter-based samples, with weight 1.

pbrt's screen window: the shorter image side spans [-1, 1], the longer [-aspect, aspect]; ``fov``
is the angle across the shorter side. Camera space looks down +z, +x is image right, +y image up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic import rng
from realistic.camera import RayBatch
from realistic.errors import UserError
from realistic.sampling import concentric_disk


@dataclass(frozen=True, eq=False)
class ThinLensCamera:
    fov_deg: float
    lens_radius: float  # scene units; 0 = pinhole
    focal_distance: float  # scene units along the camera's z
    width: int
    height: int
    spp: int
    world_from_camera: np.ndarray

    @property
    def sample_count(self) -> int:
        return self.width * self.height * self.spp

    def screen_window(self) -> tuple[float, float]:
        """Half extents (x, y) of the screen window."""
        aspect = self.width / self.height
        return (aspect, 1.0) if aspect > 1 else (1.0, 1.0 / aspect)


def build_thin_lens_camera(fov_deg: float, lens_radius: float, focal_distance: float, width: int, height: int,
                           spp: int, world_from_camera: np.ndarray) -> ThinLensCamera:
    if not 0 < fov_deg < 180:
        raise UserError(f"perspective camera fov must be between 0 and 180 degrees, got {fov_deg:g}")
    if lens_radius < 0 or (lens_radius > 0 and not focal_distance > 0):
        raise UserError(f"thin lens needs lensradius >= 0 and focaldistance > 0, got {lens_radius:g}, "
                        f"{focal_distance:g}")
    if width < 1 or height < 1 or spp < 1:
        raise UserError(f"resolution and samples must be positive, got {width}x{height}, {spp} spp")
    return ThinLensCamera(fov_deg, lens_radius, focal_distance, width, height, spp,
                          np.asarray(world_from_camera, dtype=np.float64))


def generate_thin_lens_rays(camera: ThinLensCamera, first_sample: int, count: int, seed: int = 0) -> RayBatch:
    """Rays for sample ids first_sample .. first_sample + count - 1."""
    ids = np.arange(first_sample, first_sample + count, dtype=np.int64)
    pixel = ids // camera.spp
    sample = ids % camera.spp
    u_x, u_y, u_lens, v_lens = rng.stratified4(pixel, sample, seed)
    half_x, half_y = camera.screen_window()
    x = (pixel % camera.width + u_x) / camera.width
    y = (pixel // camera.width + u_y) / camera.height
    tan_half = math.tan(math.radians(camera.fov_deg) / 2)
    direction = np.column_stack([(2 * x - 1) * half_x * tan_half, (1 - 2 * y) * half_y * tan_half, np.ones(count)])
    origin = np.zeros((count, 3))
    if camera.lens_radius > 0:
        lx, ly = concentric_disk(u_lens, v_lens)
        origin[:, 0], origin[:, 1] = lx * camera.lens_radius, ly * camera.lens_radius
        focus = direction * camera.focal_distance  # direction has z = 1
        direction = focus - origin
    m = camera.world_from_camera
    world_origin = origin @ m[:3, :3].T + m[:3, 3]
    world_direction = direction @ m[:3, :3].T
    world_direction /= np.linalg.norm(world_direction, axis=1, keepdims=True)
    return RayBatch(world_origin, world_direction, np.ones(count), pixel)
