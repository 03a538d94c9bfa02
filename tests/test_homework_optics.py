"""The classic assignment's four cameras: properties derived from the lens, checked on their rays.

The gallery images show the same things; these tests measure them on the camera rays the renders
are made of: the fisheye's circular image, the telephoto's narrow field, brightness falling off
toward the corners, and the plane in focus where ``filmdistance`` puts it.
"""

import math

import numpy as np
import pytest

from conftest import shared_file
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.optics.paraxial import focus_distance_for_film, paraxial_data, thick_lens
from realistic.renderer.inputs import RenderInputs, RenderOptions, build_render_inputs

HOMEWORK = ["dgauss", "fisheye", "telephoto", "wide"]


def homework_camera(lens, width=8, height=8, spp=1) -> RenderInputs:
    return build_render_inputs(RenderOptions(scene=shared_file(f"scenes/pbrt/dof-dragons.{lens}.pbrt"),
                                             resolution=(width, height), spp=spp))


def pixel_mean_weight(camera):
    rays = camera.generate_rays(SampleBlock(0, camera.sample_count, camera.spp), seed=1)
    return np.bincount(rays.pixel, rays.weight, camera.width * camera.height).reshape(camera.height, camera.width) \
        / camera.spp


def pixel_radius_mm(camera):
    w_mm, h_mm = camera.film_size_mm
    x = (np.arange(camera.width) + 0.5) / camera.width * w_mm - w_mm / 2
    y = (np.arange(camera.height) + 0.5) / camera.height * h_mm - h_mm / 2
    return np.hypot(x[None, :], y[:, None])


@pytest.mark.parametrize("lens", HOMEWORK)
def test_sharpest_cone_is_the_one_the_lens_core_puts_in_focus(lens):
    imported = homework_camera(lens)
    camera = imported.scene.camera
    to_lens = np.linalg.inv(camera.world_from_lens)
    cones = imported.scene.instances[1:]
    depth = np.array([(to_lens @ [*(c.transform[:3, 3] + [0, 0.075, 0]), 1])[2] for c in cones])  # mm from film
    # the bundle of rays through one point at the film centre: its width at each cone's depth
    point = LensCamera(camera.lens, camera.film_distance_mm, 1e-3, 1, 1, 20_000)
    rays = point.generate_rays(SampleBlock(0, point.sample_count, point.spp), seed=2)
    o, d = rays.origin[rays.weight > 0], rays.direction[rays.weight > 0]
    width = [np.sqrt(np.mean(np.sum((o[:, :2] + d[:, :2] * ((z - o[:, 2:3]) / d[:, 2:3])) ** 2, axis=1)))
             for z in depth]
    in_focus = focus_distance_for_film(camera.lens, camera.film_distance_mm)
    assert np.argmin(width) == np.argmin(np.abs(depth - in_focus))


def test_fisheye_image_is_a_circle():
    camera = homework_camera("fisheye", 48, 48, 16).scene.camera
    lit = pixel_mean_weight(camera) > 0
    radius = pixel_radius_mm(camera)
    table = camera.pupil  # the lens's image circle: beyond it no ray of a dense grid passes
    circle = (np.flatnonzero(table.area_mm2() > 0)[-1] + 1) * table.film_radius_mm / len(table.bounds)
    pixel = camera.film_size_mm[0] / camera.width
    assert circle < 0.7 * camera.film_size_mm[0] / 2  # the corners of the film stay black
    assert not lit[radius > circle + pixel].any()
    assert lit[radius < circle - 2 * pixel].all()


def chief_angle_deg(camera, column):
    """Angle to the axis of the mean ray through the middle row's pixel ``column``."""
    rays = camera.generate_rays(SampleBlock(0, camera.sample_count, camera.spp), seed=3)
    pick = (rays.pixel == (camera.height // 2) * camera.width + column) & (rays.weight > 0)
    to_lens = np.linalg.inv(camera.world_from_lens[:3, :3])
    d = (rays.direction[pick] @ to_lens.T).mean(axis=0)
    return math.degrees(math.atan2(math.hypot(d[0], d[1]), d[2]))


def test_telephoto_sees_a_narrow_field_and_the_dgauss_a_wide_one():
    tele = homework_camera("telephoto", 31, 31, 64).scene.camera
    normal = homework_camera("dgauss", 31, 31, 64).scene.camera
    for camera, lo, hi in ((tele, 4, 7), (normal, 20, 30)):
        # Gaussian optics (no distortion): a pixel h from the centre images an object point
        # Y = h s_o / s_i off the axis in the plane in focus, and the chief ray reaches it from the
        # entrance pupil. A column halfway out keeps the lenses' distortion below 0.5 %.
        t = thick_lens(camera.lens)
        d = camera.film_distance_mm
        in_focus = focus_distance_for_film(camera.lens, d)
        s_i = d + t.rear_principal_from_rear_vertex_mm
        s_o = in_focus - (d + t.front_principal_from_rear_vertex_mm)
        entrance_pupil_z = d + camera.lens.track_length_mm - paraxial_data(camera.lens).entrance_pupil_mm
        column = camera.width // 4
        h = camera.film_size_mm[0] * (0.5 - (column + 0.5) / camera.width)
        expected = math.degrees(math.atan(h * s_o / s_i / (in_focus - entrance_pupil_z)))
        assert chief_angle_deg(camera, column) == pytest.approx(expected, rel=0.01)
        assert lo < chief_angle_deg(camera, 0) < hi  # half the horizontal field of view


@pytest.mark.parametrize("lens", ["dgauss", "wide", "telephoto"])
def test_brightness_falls_off_toward_the_corners(lens):
    camera = homework_camera(lens, 24, 24, 64).scene.camera
    weight = pixel_mean_weight(camera)
    radius = pixel_radius_mm(camera)
    rings = np.digitize(radius, np.linspace(0, radius.max() + 1e-9, 7)) - 1
    mean = [weight[rings == k].mean() for k in range(6)]
    assert all(b <= a * 1.01 for a, b in zip(mean, mean[1:]))
    assert mean[-1] < 0.9 * mean[0]
