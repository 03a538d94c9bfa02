"""pbrt's perspective camera: pinhole projection and thin-lens focusing."""

import math

import numpy as np
import pytest

from realistic.camera.base import SampleBlock
from realistic.camera.thin_lens import ThinLensCamera
from realistic.errors import UserError


def test_pinhole_rays_project_like_pbrt():
    # 200 x 100 image, fov 40 degrees across the shorter (vertical) side
    camera = ThinLensCamera(40, 0, 1, 200, 100, 1, np.eye(4))
    rays = camera.generate_rays(SampleBlock(0, camera.sample_count, camera.spp), seed=3)
    tan_half = math.tan(math.radians(20))
    # the point each ray reaches at z = 10, projected back the textbook way
    points = rays.origin + rays.direction * (10 / rays.direction[:, 2:3])
    x = (points[:, 0] / (10 * tan_half * 2) + 1) / 2 * 200  # screen x spans [-2, 2] (aspect 2)
    y = (1 - points[:, 1] / (10 * tan_half)) / 2 * 100
    assert np.all(np.floor(x) == rays.pixel % 200)
    assert np.all(np.floor(y) == rays.pixel // 200)


def test_thin_lens_rays_meet_the_pinhole_ray_on_the_focal_plane():
    world = np.eye(4)
    world[:3, 3] = (1, 2, 3)
    pinhole = ThinLensCamera(30, 0, 1, 16, 16, 8, world)
    lens = ThinLensCamera(30, 0.2, 4.0, 16, 16, 8, world)
    a = pinhole.generate_rays(SampleBlock(0, pinhole.sample_count, pinhole.spp), seed=1)
    b = lens.generate_rays(SampleBlock(0, lens.sample_count, lens.spp), seed=1)
    assert np.ptp(b.origin[:, 0]) > 0.2  # the lens really spreads the origins
    on_plane_a = a.origin + a.direction * ((4.0 + 3 - a.origin[:, 2:3]) / a.direction[:, 2:3])
    on_plane_b = b.origin + b.direction * ((4.0 + 3 - b.origin[:, 2:3]) / b.direction[:, 2:3])
    np.testing.assert_allclose(on_plane_a, on_plane_b, atol=1e-12)


@pytest.mark.parametrize("args", [(0, 0, 1), (180, 0, 1), (30, 0.1, 0), (30, -1, 1)])
def test_bad_parameters_are_user_errors(args):
    with pytest.raises(UserError):
        ThinLensCamera(*args, 8, 8, 1, np.eye(4))
