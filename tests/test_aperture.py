"""Shaped stops: geometry, light in proportion to the open area, and the shape of the defocus blur."""

import math

import numpy as np
import pytest
from PIL import Image

from conftest import flat_field_brightness, rays_the_pupil_table_loses
from realistic import UserError, load_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.optics.paraxial import film_distance_for_focus, stop_diameter_for_f_number
from realistic.optics.stop_shape import bladed_stop, mask_stop


@pytest.mark.parametrize("blades", [3, 5, 6, 9])
def test_straight_blades_make_the_inscribed_polygon(blades):
    diameter = 2.0
    stop = bladed_stop(blades, rotation_deg=17.0)
    # area of the regular N-gon with circumradius 1: N/2 sin(2 pi / N)
    assert stop.open_area_mm2(diameter) == pytest.approx(blades / 2 * math.sin(2 * math.pi / blades), rel=2e-3)
    corner = math.radians(17.0)
    inside = stop.inside(np.array([0.999 * math.cos(corner)]), np.array([0.999 * math.sin(corner)]), diameter)
    middle = math.radians(17.0) + math.pi / blades  # the middle of a side, at the apothem
    apothem = math.cos(math.pi / blades)
    side_x, side_y = apothem * math.cos(middle), apothem * math.sin(middle)
    just_in = stop.inside(np.array([0.999 * side_x]), np.array([0.999 * side_y]), diameter)
    just_out = stop.inside(np.array([1.001 * side_x]), np.array([1.001 * side_y]), diameter)
    assert inside[0] and just_in[0] and not just_out[0]


def test_curved_blades_go_from_polygon_to_circle():
    areas = [bladed_stop(5, curvature=c).open_area_mm2(2.0) for c in (0.0, 0.3, 0.7, 1.0)]
    assert all(a < b for a, b in zip(areas, areas[1:]))
    assert areas[-1] == pytest.approx(math.pi, rel=2e-3)


def test_bad_shapes_are_user_errors(tmp_path):
    with pytest.raises(UserError):
        bladed_stop(2)
    with pytest.raises(UserError):
        bladed_stop(6, curvature=1.5)
    dark = tmp_path / "dark.png"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(dark)
    with pytest.raises(UserError, match="no open pixel"):
        mask_stop(dark)


def centre_brightness(lens) -> float:
    return flat_field_brightness(lens, spp=512)


def test_brightness_follows_the_open_area(tmp_path):
    lens = load_lens("dgauss")
    lens = lens.with_stop_diameter(stop_diameter_for_f_number(lens, 4.0))  # the stop alone limits the axis
    diameter = lens.stop_diameter_mm
    circle = centre_brightness(lens)
    hexagon = centre_brightness(lens.with_stop_shape(bladed_stop(6)))
    assert hexagon / circle == pytest.approx(3 * math.sqrt(3) / (2 * math.pi), rel=0.02)
    # a square mask with the circle's open area gives the circle's brightness
    side = round(128 * math.sqrt(math.pi) / 2)
    pixels = np.zeros((128, 128), np.uint8)
    start = (128 - side) // 2
    pixels[start:start + side, start:start + side] = 255
    path = tmp_path / "square.png"
    Image.fromarray(pixels).save(path)
    square = mask_stop(path)
    assert square.open_area_mm2(diameter) == pytest.approx(math.pi * diameter**2 / 4, rel=0.01)
    assert centre_brightness(lens.with_stop_shape(square)) == pytest.approx(circle, rel=0.02)


def blur_outline(shape, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """Angles and outline radii of the defocus blur of an on-axis point 8 m away, the lens focused at 1 m.

    The rays from the film centre, where they cross the plane of the out-of-focus point, cover the
    blur's footprint: the point lights every film position whose footprint holds it, so the
    footprint's shape is the bokeh's (mirrored).
    """
    lens = load_lens("dgauss")
    lens = lens.with_stop_diameter(stop_diameter_for_f_number(lens, 2.8)).with_stop_shape(shape)
    film = film_distance_for_focus(lens, 1000.0)
    camera = LensCamera(lens, film, 1e-3, 1, 1, 200_000)
    rays = camera.generate_rays(SampleBlock(0, camera.sample_count, camera.spp), seed)
    ok = rays.weight > 0
    o, d = rays.origin[ok], rays.direction[ok]
    at = o[:, :2] + d[:, :2] * ((8000.0 - o[:, 2:3]) / d[:, 2:3])
    at -= at.mean(axis=0)
    angle = np.arctan2(at[:, 1], at[:, 0])
    bins = np.digitize(angle, np.linspace(-np.pi, np.pi, 73)) - 1
    radius = np.array([np.hypot(*at[bins == b].T).max() for b in range(72)])
    return np.linspace(-np.pi, np.pi, 73)[:-1] + np.pi / 72, radius


def test_bokeh_takes_the_shape_of_the_blades():
    _, circle = blur_outline(None)
    assert circle.min() / circle.max() > 0.98
    angle, hexagon = blur_outline(bladed_stop(6))
    assert hexagon.min() / hexagon.max() == pytest.approx(math.cos(math.pi / 6), abs=0.02)
    # six corners: the outline's sixfold harmonic is strong, and turning the blades by 30 degrees
    # turns it by half a period
    harmonic = np.sum(hexagon * np.exp(-6j * angle)) / np.sum(hexagon)
    _, turned = blur_outline(bladed_stop(6, rotation_deg=30.0))
    harmonic_turned = np.sum(turned * np.exp(-6j * angle)) / np.sum(turned)
    assert abs(harmonic) > 0.02 and abs(harmonic_turned) == pytest.approx(abs(harmonic), rel=0.15)
    assert abs(abs(np.angle(harmonic_turned / harmonic)) - math.pi) < 0.2


@pytest.mark.parametrize("kind", ["hexagon", "square mask"])
def test_pupil_bounds_hold_every_ray_a_shaped_stop_passes(kind, tmp_path):
    from realistic.optics.sampling import exit_pupil_table

    if kind == "hexagon":
        shape = bladed_stop(6, rotation_deg=10.0)
    else:  # a square whose corners reach beyond the stop's circle, not symmetric under rotation
        pixels = np.zeros((64, 64), np.uint8)
        pixels[4:60, 4:60] = 255
        path = tmp_path / "square.png"
        Image.fromarray(pixels).save(path)
        shape = mask_stop(path)
    lens = load_lens("dgauss").with_stop_shape(shape)
    film = film_distance_for_focus(lens, math.inf)
    table = exit_pupil_table(lens, film, 35.0)
    passed, lost = rays_the_pupil_table_loses(lens, film, table, seed=4, count=200_000)
    assert passed > 1000 and lost == 0
