"""The stop shapes pbrt-v4's apertures are built from (realistic.optics.stop_shape): blades inside a
smaller circle, polygon masks and dithered transmission, against closed forms."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.optics.stop_shape import bladed_stop, polygon_stop, transmission_stop

DIAMETER = 2.0  # mm: the stop's radius is 1, the units polygons are given in


def shoelace(vertices: np.ndarray) -> float:
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


@pytest.mark.parametrize("blades", [3, 5, 6, 9])
@pytest.mark.parametrize("extent", [0.3, 0.8, 1.0])
def test_blades_inside_a_smaller_circle_have_the_regular_polygons_area(blades, extent):
    shape = bladed_stop(blades, 17.0, 0.0, extent)
    radius = extent * DIAMETER / 2
    exact = blades / 2 * radius**2 * math.sin(2 * math.pi / blades)
    assert shape.open_area_mm2(DIAMETER) == pytest.approx(exact, rel=3e-3)
    assert shape.reach_mm(DIAMETER) == pytest.approx(radius)


@pytest.mark.parametrize("extent", [0.0, -0.5, 1.5, math.nan])
def test_an_extent_outside_the_stop_is_refused(extent):
    with pytest.raises(UserError, match="blade extent"):
        bladed_stop(5, 0.0, 0.0, extent)


@st.composite
def star_shaped_polygons(draw):
    """Simple polygons: vertices at increasing angles, each at its own radius (0.2 to 1)."""
    count = draw(st.integers(3, 12))
    angles = np.sort(np.array(draw(st.lists(st.floats(0, 2 * math.pi, exclude_max=True), min_size=count,
                                            max_size=count, unique=True))))
    if np.min(np.diff(np.append(angles, angles[0] + 2 * math.pi))) < 0.05:
        angles = np.linspace(0, 2 * math.pi, count, endpoint=False)
    radii = np.array(draw(st.lists(st.floats(0.2, 1.0), min_size=count, max_size=count)))
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


@given(star_shaped_polygons(), st.booleans())
def test_a_polygon_mask_opens_the_polygons_area_whichever_way_it_winds(vertices, reverse):
    polygon = vertices[::-1] if reverse else vertices
    shape = polygon_stop(polygon, "test")
    pixel = DIAMETER / shape.mask.shape[0]
    perimeter = float(np.sum(np.linalg.norm(np.roll(vertices, -1, axis=0) - vertices, axis=1)))
    # a pixel is open when its centre is inside: the error is at most the boundary's half-pixel band
    assert shape.open_area_mm2(DIAMETER) == pytest.approx(shoelace(vertices), abs=perimeter * pixel / 2 + 1e-9)
    assert shape.mask.tolist() == polygon_stop(vertices, "test").mask.tolist()


def test_a_polygon_mask_has_its_first_row_at_plus_y():
    triangle = np.array([[-1.0, 0.2], [1.0, 0.2], [0.0, 1.0]])  # the upper part of the stop only
    shape = polygon_stop(triangle, "test")
    assert shape.mask[:40].any() and not shape.mask[70:].any()
    assert shape.inside(np.array([0.0, 0.0]), np.array([0.5, -0.5]), DIAMETER).tolist() == [True, False]


@pytest.mark.parametrize("level", [0.1, 0.25, 0.5, 0.77, 1.0])
def test_dithered_transmission_opens_the_fraction_its_level_asks_for(level):
    levels = np.full((256, 256), level)
    levels[0, 0] = 1.0  # the peak that levels are scaled by
    shape = transmission_stop(levels, "test")
    assert shape.mask.shape == (128, 128)
    assert shape.mask.mean() == pytest.approx(level, abs=1 / 64 + 1e-3)
    blocks = shape.mask.reshape(16, 8, 16, 8).mean(axis=(1, 3))
    assert np.all(np.abs(blocks - level) <= 1 / 64 + 1 / 32)  # every 8 x 8 block, not just the whole


def test_dithered_transmission_follows_a_ramp_row_by_row():
    ramp = np.tile(np.linspace(0, 1, 128), (128, 1)).T  # row 0 closed, the last row open
    shape = transmission_stop(ramp, "test")
    rows = shape.mask.reshape(16, 8, 128).mean(axis=(1, 2))
    expected = ramp.reshape(16, 8, 128).mean(axis=(1, 2))
    np.testing.assert_allclose(rows, expected, atol=0.03)


@pytest.mark.parametrize("levels", [np.zeros((8, 8)), np.full((8, 8), np.nan), -np.ones((8, 8))])
def test_a_transmission_with_nothing_open_is_one_line_naming_its_source(levels):
    with pytest.raises(UserError, match=r"^stop\.png: the aperture's transmission") as err:
        transmission_stop(levels, "stop.png")
    assert "\n" not in str(err.value)
