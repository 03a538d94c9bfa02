"""Film-side samplers: disk mapping, weights, rear-element coverage and exit-pupil bounds."""

import numpy as np
import pytest

from conftest import rays_the_pupil_table_loses
from realistic import load_lens
from realistic.core.warp import concentric_disk
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.sampling import (
    camera_weight,
    exit_pupil_table,
    pass_fractions,
    rear_element_sampler,
    rear_surface_depths_mm,
)

LENSES = ["dgauss", "wide", "fisheye", "telephoto", "dgauss100"]


def test_concentric_disk_is_uniform_and_inside():
    rng = np.random.default_rng(0)
    u1, u2 = rng.random(200_000), rng.random(200_000)
    x, y = concentric_disk(u1, u2)
    r2 = x * x + y * y
    assert r2.max() <= 1 + 1e-12
    counts, _ = np.histogram(r2, bins=10, range=(0, 1))  # uniform in area <=> r^2 uniform
    assert np.all(np.abs(counts / counts.mean() - 1) < 0.03)
    angle_counts, _ = np.histogram(np.arctan2(y, x), bins=8, range=(-np.pi, np.pi))
    assert np.all(np.abs(angle_counts / angle_counts.mean() - 1) < 0.03)


def test_concentric_disk_keeps_strata_compact():
    # The image of each of 16 x 16 strata spans a small part of the disk.
    g = (np.arange(16) + 0.5) / 16
    for i in range(16):
        for j in range(16):
            u1 = g[i] + (np.array([-1, 1, -1, 1]) * 0.49 / 16)
            u2 = g[j] + (np.array([-1, -1, 1, 1]) * 0.49 / 16)
            x, y = concentric_disk(u1, u2)
            assert np.hypot(x - x.mean(), y - y.mean()).max() < 0.25


def test_weight_is_cos4_area_over_distance_squared():
    film = np.zeros((2, 3))
    plane = np.array([[0.0, 0.0, 10.0], [10.0, 0.0, 10.0]])
    w = camera_weight(film, plane, np.array([2.0, 2.0]), 10.0)
    assert w[0] == pytest.approx(2.0 / 100)
    assert w[1] == pytest.approx(np.cos(np.pi / 4) ** 4 * 2.0 / 100)


@pytest.mark.parametrize("name", LENSES)
def test_rear_sampler_covers_the_real_rear_element(name):
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    sampler = rear_element_sampler(lens, film)
    rng = np.random.default_rng(5)
    count = 20_000
    film_xy = rng.uniform(-25, 25, (count, 2))
    # points on the rear element's cap itself, uniformly over its clear aperture
    rho = lens.aperture_mm[-1] / 2 * np.sqrt(rng.random(count))
    phi = rng.uniform(0, 2 * np.pi, count)
    radius = lens.radius_mm[-1]
    z = film - radius + np.sign(radius) * np.sqrt(radius**2 - rho**2)
    cap = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])
    # where the ray from the film point to the cap point crosses the sampler's plane
    s = sampler.plane_z_mm / cap[:, 2]
    crossing = film_xy + s[:, None] * (cap[:, :2] - film_xy)
    reach = sampler.radius_mm(np.hypot(film_xy[:, 0], film_xy[:, 1]))
    assert np.all(np.hypot(crossing[:, 0], crossing[:, 1]) <= reach * (1 + 1e-12))
    near, far = rear_surface_depths_mm(lens, film)
    assert near <= z.min() + 1e-9 and z.max() <= far + 1e-9


@pytest.fixture(scope="module", params=LENSES)
def pupil_setup(request):
    lens = load_lens(request.param)
    film = film_distance_for_focus(lens, np.inf)
    return lens, film, exit_pupil_table(lens, film, 35.0)


def test_pupil_bounds_never_lose_a_passing_ray(pupil_setup):
    lens, film, table = pupil_setup
    passed, lost = rays_the_pupil_table_loses(lens, film, table, seed=9)
    assert passed > 1000 and lost == 0


def test_pupil_box_on_axis_matches_paraxial_exit_pupil(pupil_setup):
    lens, film, _ = pupil_setup
    lens = lens.with_stop_diameter(lens.stop_diameter_mm / 4)  # small stop: the paraxial regime
    table = exit_pupil_table(lens, film, 35.0)
    p = paraxial_data(lens)
    exit_pupil_z = film - p.exit_pupil_mm  # lens frame: the film is at z = 0
    expected_half_width = p.exit_pupil_diameter_mm / 2 * table.plane_z_mm / exit_pupil_z
    # The box is the passing grid points' bounds grown by one grid step; in y it does not depend on
    # how far the film point moves within the first interval.
    y_half = table.bounds[0, 3]
    step = table.padding_mm[0, 1]
    assert expected_half_width * 0.99 <= y_half <= expected_half_width * 1.01 + step


def test_pupil_sampling_passes_twice_the_rays_at_the_film_corner(pupil_setup):
    lens, film, table = pupil_setup
    corner = 17.5 * 0.999
    if lens.name == "fisheye":
        # its image circle ends before 17.5 mm (no ray passes there): use 90 % of the circle's radius
        lit = np.flatnonzero(table.area_mm2() > 0)
        assert lit[-1] < len(table.bounds) - 1
        corner = 0.9 * (lit[-1] + 1) * table.film_radius_mm / len(table.bounds)
    if lens.name == "dgauss100":
        corner *= 2  # the 100 mm lens covers the same field on a film twice the size
        table = exit_pupil_table(lens, film, 70.0)
    fractions = pass_fractions(lens, film, table, corner, samples=50_000)
    assert fractions["pupil"] >= 2 * fractions["rear"] > 0


@pytest.mark.parametrize("name", LENSES)
def test_pupil_bounds_hold_at_a_small_stop(name):
    """A pupil far smaller than the search's coarse grid cells is still found and bounded."""
    lens = load_lens(name)
    lens = lens.with_stop_diameter(lens.stop_diameter_mm / 8)
    film = film_distance_for_focus(lens, np.inf)
    table = exit_pupil_table(lens, film, 35.0)
    assert table.area_mm2()[0] > 0
    passed, lost = rays_the_pupil_table_loses(lens, film, table, seed=3)
    assert passed > 100 and lost == 0


@pytest.mark.parametrize("name", LENSES)
def test_pupil_bounds_hold_out_to_the_edge_of_the_image_circle(name):
    """On a 54 mm film every lens but the telephoto vignettes to a sliver or to nothing; where the
    pupil is a moving sliver its interval is searched at radii inside it, and no passing ray is lost."""
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    table = exit_pupil_table(lens, film, 54.0)
    passed, lost = rays_the_pupil_table_loses(lens, film, table, seed=5, film_radius_mm=27.0)
    assert passed > 1000 and lost == 0


def test_the_pupil_search_traces_every_wavelength_at_once_as_it_would_one_by_one():
    """The search's pass test traces a ray per direction and wavelength in one call; a direction
    passes where any of its wavelengths does, as tracing each wavelength apart says."""
    from realistic.optics.pupil_search import _Passes
    from realistic.optics.tracer import trace_from_film

    lens = load_lens("canon-rf50-f1.2")
    film = film_distance_for_focus(lens, np.inf)
    wavelengths = (400.0, 587.56, 700.0)
    rng = np.random.default_rng(2)
    film_x, x, y = rng.uniform(0, 18, 3000), rng.uniform(-30, 30, 3000), rng.uniform(0, 30, 3000)
    plane_z = film + 20.0
    passes = _Passes(lens, film, plane_z, wavelengths)(film_x, x, y)
    origins = np.column_stack([film_x, np.zeros_like(film_x), np.zeros_like(film_x)])
    directions = np.column_stack([x - film_x, y, np.full_like(x, plane_z)])
    each = [trace_from_film(lens, film, origins, directions, w).passed for w in wavelengths]
    assert np.array_equal(passes, np.logical_or.reduce(each))
    assert 0 < passes.sum() < len(passes) and not np.array_equal(each[0], each[2])  # the wavelengths differ


def test_bisecting_several_edges_together_finds_what_each_alone_finds():
    """The search bisects a pupil's left, right and upper edges in one trace per step; each set of
    brackets ends where it ends bisected on its own."""
    from realistic.optics.pupil_search import _bisect, _Passes

    lens = load_lens("canon-ef24-f1.4")
    film = film_distance_for_focus(lens, np.inf)
    passes = _Passes(lens, film, film + 20.0, (587.56,))
    rng = np.random.default_rng(5)
    film_x = rng.uniform(0, 18, (4, 6))
    ys = rng.uniform(0, 10, (4, 6))
    left = (film_x, np.zeros((4, 6)), np.full((4, 6), -40.0), ys, True, rng.random((4, 6)) < 0.7)
    right = (film_x, np.zeros((4, 6)), np.full((4, 6), 40.0), ys, True, rng.random((4, 6)) < 0.7)
    upper = (film_x, np.zeros((4, 6)), np.full((4, 6), 40.0), rng.uniform(-5, 5, (4, 6)), False,
             rng.random((4, 6)) < 0.7)
    together = _bisect(passes, [left, right, upper])
    for problem, edge in zip((left, right, upper), together):
        (alone,) = _bisect(passes, [problem])
        assert np.array_equal(edge, alone)
        assert np.all(edge[~problem[5]] == 0.0) and np.any(edge[problem[5]] != 0.0)
