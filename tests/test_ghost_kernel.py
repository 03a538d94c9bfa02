"""The ghost kernel (kernels/ghost.cl through realistic.camera.ghost_host) against the float64
reference (realistic.optics.ghosts): the same rays pass, land in the same place and carry the same
Fresnel weights, for every ghost of a lens with spheres, aspheres, coatings and a bladed stop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from realistic import load_lens
from realistic.camera.ghost_host import GhostKernel
from realistic.optics.ghosts import GhostPath, GhostTrace, ghost_paths, trace_direct, trace_ghost
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data
from realistic.optics.stop_shape import bladed_stop
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
               directions: np.ndarray) -> GhostTrace:
    return (trace_direct(lens, film, origins, directions) if path is None
            else trace_ghost(lens, film, path, origins, directions))


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


def test_kernel_gives_the_plate_ghost_r1_r2_of_the_direct_image() -> None:
    n = 1.6
    lens = plate(index=n)
    origins, directions = collimated_bundle(lens, 30.0, 4.0)
    kernel = GhostKernel(lens)
    (ghost,) = ghost_paths(lens, threshold=0.0)
    ratio = kernel.trace(30.0, ghost, origins, directions).weight / kernel.trace(30.0, None, origins, directions).weight
    np.testing.assert_allclose(ratio, ((n - 1) / (n + 1)) ** 4, rtol=1e-5)
