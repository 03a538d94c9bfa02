"""The area-light table both integrators sample: rows as the lights' frames say, and points uniform
by area on disks and quads (closed forms: on a disk of radius R, E[r^2] = R^2 / 2; on a w by h
quad, each side's coordinate has variance w^2 / 12 and h^2 / 12; both means are the centre)."""

import numpy as np
import pytest

from realistic.core.transforms import rotate, translate
from realistic.renderer.area_lights import AreaLightTable
from realistic.scene.model import AreaLight

N = 200_000


def _lights() -> list[AreaLight]:
    return [AreaLight("disk", (0.5, 0.5), (1.0, 2.0, 3.0), translate(1.0, 2.0, 3.0) @ rotate(30, (1, 0, 0))),
            AreaLight("quad", (2.0, 0.5), (4.0, 4.0, 4.0), translate(-1.0, 0.0, 2.0) @ rotate(90, (0, 1, 0)),
                      two_sided=True)]


def test_rows_are_the_lights_frames_areas_and_flags():
    lights = _lights()
    table = AreaLightTable.of(lights)
    assert len(table) == 2
    for j, light in enumerate(lights):
        centre, a, b, normal = light.frame()
        np.testing.assert_allclose(table.centre[j], centre, rtol=1e-6)
        np.testing.assert_allclose(table.a[j], a, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(table.b[j], b, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(table.normal[j], normal, rtol=1e-6, atol=1e-7)
        assert table.area[j] == light.area()
        assert table.disk[j] == (light.shape == "disk")
        assert table.two_sided[j] == light.two_sided
        np.testing.assert_array_equal(table.radiance[j], light.radiance)


def test_no_lights_make_an_empty_table():
    table = AreaLightTable.of([])
    assert len(table) == 0 and table.centre.shape == (0, 3) and table.radiance.shape == (0, 3)


@pytest.mark.parametrize("slot", [0, 1])
def test_points_lie_on_the_light_uniformly_by_area(slot):
    lights = _lights()
    table = AreaLightTable.of(lights)
    rng = np.random.default_rng(3)
    u1, u2 = rng.random(N), rng.random(N)
    q = table.points(np.full(N, slot), u1, u2).astype(np.float64)
    centre, a, b, normal = lights[slot].frame()
    offset = q - centre
    np.testing.assert_allclose(offset @ normal, 0.0, atol=1e-5)  # in the light's plane
    x, y = offset @ a / (a @ a), offset @ b / (b @ b)  # coordinates in units of the half axes
    assert abs(x.mean()) < 5 * x.std() / np.sqrt(N) and abs(y.mean()) < 5 * y.std() / np.sqrt(N)
    if lights[slot].shape == "disk":
        r2 = x * x + y * y
        assert r2.max() <= 1 + 1e-5
        assert abs(r2.mean() - 0.5) < 5 * r2.std() / np.sqrt(N)  # E[r^2] = 1/2 of the unit disk
    else:
        assert np.abs(x).max() <= 1 + 1e-5 and np.abs(y).max() <= 1 + 1e-5
        for c in (x, y):  # uniform on [-1, 1]: variance 1/3
            assert abs((c * c).mean() - 1 / 3) < 5 * (c * c).std() / np.sqrt(N)


def test_a_lights_points_do_not_depend_on_the_others_in_the_batch():
    table = AreaLightTable.of(_lights())
    rng = np.random.default_rng(4)
    u1, u2 = rng.random(1000), rng.random(1000)
    slot = rng.integers(0, 2, 1000)
    mixed = table.points(slot, u1, u2)
    for j in (0, 1):
        rows = slot == j
        np.testing.assert_array_equal(mixed[rows], table.points(slot[rows], u1[rows], u2[rows]))
