"""The ghost kernel (kernels/ghost.cl through realistic.camera.ghost_host) against the float64
reference (realistic.optics.ghosts): the same rays pass, land in the same place and carry the same
Fresnel weights, for every ghost of a lens with spheres, aspheres, coatings and a bladed stop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from realistic import load_lens
from realistic.camera.ghost_host import GhostKernel
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.ghosts import GhostPath, GhostTrace, ghost_paths, trace_direct, trace_ghost
from realistic.optics.glass.catalogue import find_glass
from realistic.optics.lens import LensSystem, build_lens
from realistic.optics.paraxial import paraxial_data
from realistic.optics.stop_shape import bladed_stop, polygon_stop
from test_ghosts import collimated_bundle, plate

pytestmark = pytest.mark.usefixtures("opencl_platform")

#: Film positions agree to this fraction of their distance from the axis (at least 1 mm), and
#: directions at the film to ``DIRECTION_TOLERANCE``, where a ray lands within ``FILM_REACH_MM`` of
#: it; farther out (ghost rays leaving the rear surface at 80 deg to the axis, far beyond any film)
#: float32's rounding of the direction is magnified as 1 / cos^2 of the angle.
POSITION_TOLERANCE = 1e-4
FILM_REACH_MM = 50.0
#: Directions at the film (within reach) and weights (every ray) agree to this.
DIRECTION_TOLERANCE = 1e-5
WEIGHT_TOLERANCE = 1e-5
#: Apertures scaled by 1 +- this in the reference mark rays on an edge, whose fate rounding decides.
EDGE = 1e-5


def _reference(lens: LensSystem, film: float, path: GhostPath | None, origins: np.ndarray,
               directions: np.ndarray, wavelengths: float | np.ndarray = D_LINE_NM) -> GhostTrace:
    return (trace_direct(lens, film, origins, directions, wavelengths) if path is None
            else trace_ghost(lens, film, path, origins, directions, wavelengths))


def _assert_matches(lens: LensSystem, film: float, path: GhostPath | None, origins: np.ndarray,
                    directions: np.ndarray, kernel: GhostKernel) -> int:
    """The kernel's trace of ``path`` matches the reference's; returns the rays that passed."""
    ref = _reference(lens, film, path, origins, directions)
    got = kernel.trace(film, path, origins, directions)
    wider, narrower = (_reference(dataclasses.replace(lens, aperture_mm=lens.aperture_mm * (1 + s * EDGE)), film,
                                  path, origins, directions) for s in (1, -1))
    sure = wider.passed == narrower.passed
    assert np.count_nonzero(~sure) <= 0.01 * len(origins) + 2, path
    np.testing.assert_array_equal(got.passed[sure], ref.passed[sure], err_msg=str(path))
    both = ref.passed & got.passed
    distance = np.hypot(*ref.film_xy[both].T)
    near = distance <= FILM_REACH_MM
    error = np.hypot(*(got.film_xy[both] - ref.film_xy[both]).T)
    assert np.all(error[near] <= POSITION_TOLERANCE * np.maximum(distance[near], 1.0)), path
    np.testing.assert_allclose(got.direction[both][near], ref.direction[both][near], rtol=0, atol=DIRECTION_TOLERANCE)
    np.testing.assert_allclose(got.weight[sure], ref.weight[sure], rtol=0, atol=WEIGHT_TOLERANCE, err_msg=str(path))
    assert np.all(got.weight[~got.passed] == 0) and np.all(np.isnan(got.film_xy[~got.passed]))
    return int(both.sum())


@pytest.mark.parametrize("coating", ["none", "mgf2"])
@pytest.mark.parametrize("angle", [0.0, 8.0])
def test_kernel_matches_reference_for_every_ghost_of_dgauss(coating: str, angle: float) -> None:
    lens = load_lens("dgauss").with_coating(coating)
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2 * 1.1, angle)
    kernel = GhostKernel(lens)
    paths = ghost_paths(lens, threshold=1e-5)
    assert len(paths) >= 10
    passed = [_assert_matches(lens, film, path, origins, directions, kernel) for path in [None, *paths]]
    assert min(passed[:4]) > 50


def test_kernel_matches_reference_through_aspheres() -> None:
    lens = load_lens("phone-us10101561").with_coating("none")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 10.0)
    kernel = GhostKernel(lens)
    paths = [p for p in ghost_paths(lens) if lens.aspheric[p.first] or lens.aspheric[p.second]]
    assert paths
    for path in [None, *paths[:10]]:
        _assert_matches(lens, film, path, origins, directions, kernel)


def test_kernel_clips_at_a_bladed_stop_as_the_reference_does() -> None:
    lens = load_lens("dgauss").with_coating("none").with_stop_shape(bladed_stop(6, 10.0))
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 5.0, across=61)
    kernel = GhostKernel(lens)
    for path in [None, *ghost_paths(lens)[:6]]:
        _assert_matches(lens, film, path, origins, directions, kernel)
    round_stop = trace_direct(dataclasses.replace(lens, stop_shape=None), film, origins, directions)
    assert kernel.trace(film, None, origins, directions).passed.sum() < round_stop.passed.sum()  # the blades cut


def test_kernel_clips_at_an_image_stop_as_the_reference_does() -> None:
    """A stop given as a mask (a triangle, pixels of ``polygon_stop``): common.cl's stop_mask."""
    triangle = np.array([[0.0, 1.0], [-0.9, -0.5], [0.9, -0.5]])
    lens = load_lens("dgauss").with_coating("none").with_stop_shape(polygon_stop(triangle, "triangle"))
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 0.0, across=61)
    kernel = GhostKernel(lens)
    for path in [None, *ghost_paths(lens)[:3]]:
        _assert_matches(lens, film, path, origins, directions, kernel)
    round_stop = trace_direct(dataclasses.replace(lens, stop_shape=None), film, origins, directions)
    assert 0 < kernel.trace(film, None, origins, directions).passed.sum() < 0.8 * round_stop.passed.sum()


def test_kernel_gives_the_plate_ghost_r1_r2_of_the_direct_image() -> None:
    n = 1.6
    lens = plate(index=n)
    origins, directions = collimated_bundle(lens, 30.0, 4.0)
    kernel = GhostKernel(lens)
    (ghost,) = ghost_paths(lens, threshold=0.0)
    ratio = kernel.trace(30.0, ghost, origins, directions).weight / kernel.trace(30.0, None, origins, directions).weight
    np.testing.assert_allclose(ratio, ((n - 1) / (n + 1)) ** 4, rtol=1e-5)


def test_rays_per_work_item_change_nothing() -> None:
    """Each work item's rays are traced apart (kernels/ghost.cl): 1 or 4 per item, every ray's
    result is the same bit for bit, for counts that do and do not fill the last work item."""
    lens = load_lens("dgauss").with_coating("none")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 3.0, across=31)
    path = ghost_paths(lens)[0]
    one, four = GhostKernel(lens, rays_per_item=1), GhostKernel(lens, rays_per_item=4)
    for count in (len(origins), 1001, 3):
        a, b = (k.trace(film, path, origins[:count], directions[:count]) for k in (one, four))
        for field in ("film_xy", "direction", "weight", "passed"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert len(four.trace(film, path, origins[:0], directions[:0]).weight) == 0


def _catalogue_doublet() -> LensSystem:
    """An achromat of N-BK7 and N-SF5 (Schott's Sellmeier formulas) before the stop."""
    glass = [find_glass("N-BK7"), find_glass("N-SF5"), None, None]
    lens = build_lens("doublet.dat", [1, 2, 3, 4], [60.0, -40.0, -150.0, 0.0], [6.0, 2.5, 3.0, 80.0],
                      [1.5, 1.6, 1.0, 1.0], [0.0] * 4, [24.0, 24.0, 24.0, 16.0], glass=glass)
    assert all(g is not None for g in lens.glass[:2])
    return lens


@pytest.mark.parametrize("name", ["dgauss", "doublet"])
def test_kernel_traces_one_wavelength_per_ray_as_the_reference(name: str) -> None:
    """Each ray's own wavelength (a spectral camera's), through Cauchy and catalogue glasses: the
    kernel's indices, interpolated in its table of each medium, give the reference's traces."""
    lens = (load_lens(name) if name == "dgauss" else _catalogue_doublet()).with_coating("mgf2")
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, lens.aperture_mm[0] / 2, 4.0)
    wavelengths = np.random.default_rng(5).uniform(380.0, 780.0, len(origins))
    kernel = GhostKernel(lens)
    for path in [None, *ghost_paths(lens, threshold=1e-5)[:6]]:
        ref = _reference(lens, film, path, origins, directions, wavelengths)
        got = kernel.trace(film, path, origins, directions, wavelengths)
        both = ref.passed & got.passed
        assert both.any() and np.count_nonzero(ref.passed != got.passed) <= 0.01 * len(origins) + 2, path
        near = np.hypot(*ref.film_xy[both].T) <= FILM_REACH_MM
        error = np.hypot(*(got.film_xy[both] - ref.film_xy[both]).T)[near]
        assert np.all(error <= POSITION_TOLERANCE * np.maximum(np.hypot(*ref.film_xy[both][near].T), 1.0)), path
        np.testing.assert_allclose(got.weight[both], ref.weight[both], rtol=0, atol=WEIGHT_TOLERANCE)
    blue = kernel.trace(film, None, origins, directions, 400.0)
    red = kernel.trace(film, None, origins, directions, 700.0)
    both = blue.passed & red.passed
    assert np.max(np.abs(blue.film_xy[both] - red.film_xy[both])) > 1e-3  # the glasses disperse


def test_kernel_meets_a_stop_touching_a_flat_face_as_the_reference() -> None:
    """A stop 0 mm behind a plano-convex lens's flat face: the ray meets it where it leaves the face
    (not required to be ahead), on every pass, in both traces."""
    lens = build_lens("touching.dat", [1, 2, 3], [50.0, 0.0, 0.0], [5.0, 0.0, 45.0], [1.5, 1.0, 1.0], [0.0] * 3,
                      [20.0, 20.0, 12.0]).with_coating("none")
    assert lens.stop == 2 and lens.thickness_mm[1] == 0
    film = paraxial_data(lens).bfl_mm
    origins, directions = collimated_bundle(lens, film, 9.0, 3.0)
    kernel = GhostKernel(lens)
    passed = [_assert_matches(lens, film, path, origins, directions, kernel) for path in [None, GhostPath(0, 1)]]
    assert min(passed) > 0.2 * len(origins)
