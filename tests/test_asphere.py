"""Even aspheres in the float64 tracer: the hyperbolic singlet, sphere identity, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic import load_lens
from realistic.errors import LensFileError
from realistic.optics.asphere import sag_and_slope, sag_mm, sag_slope, significant
from realistic.optics.lens import build_lens
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.tracer import ASPHERE, trace_from_film

GLASS = 1.5168
RADIUS = -30.0  # rear face, convex toward the film
THICKNESS = 6.0
SEMI = 12.0


def singlet(conic: float):
    """Stop, flat front face, curved rear face of conic ``conic``; film at the paraxial focus."""
    bfl = abs(RADIUS) / (GLASS - 1)
    return build_lens("singlet", [1, 2, 3], [0.0, math.inf, RADIUS], [2.0, THICKNESS, bfl],
                      [0.0, GLASS, 0.0], [0.0, 0.0, 0.0], [2 * SEMI, 2 * SEMI + 2, 2 * SEMI + 2],
                      conic=[0.0, 0.0, conic]), bfl


def exit_directions(lens, bfl: float) -> np.ndarray:
    """Rays from the on-axis film point at the paraxial focus to rim heights up to ~SEMI."""
    heights = np.linspace(0.5, SEMI * 0.95, 40)
    targets = np.column_stack([heights, np.zeros_like(heights), np.full_like(heights, bfl)])
    result = trace_from_film(lens, bfl, np.zeros_like(targets), targets)
    assert result.passed.all()
    return result.direction


def test_hyperbolic_singlet_focuses_a_collimated_beam_to_a_point():
    """A hyperbola of eccentricity n (k = -n^2) images the point at infinity inside glass onto its
    far focus without aberration (Descartes' ovoid for an object at infinity). By reversibility, rays
    from that focus leave the flat face parallel to the axis; the angle times the focal length is
    the spot radius a collimated beam would form, which must be float64 rounding. The spherical
    twin (k = 0) shows its spherical aberration: a spot orders of magnitude larger."""
    lens, bfl = singlet(-GLASS**2)
    assert paraxial_data(lens).bfl_mm == pytest.approx(bfl, rel=1e-12)
    spot = bfl * np.max(np.hypot(*exit_directions(lens, bfl)[:, :2].T))
    assert spot < 1e-12
    sphere, _ = singlet(0.0)
    sphere_spot = bfl * np.max(np.hypot(*exit_directions(sphere, bfl)[:, :2].T))
    assert sphere_spot > 1e-2


def test_zero_conic_and_coefficients_trace_bit_for_bit_as_spheres():
    """Explicit k = 0 and coefficients 0 must not change a single bit of a traced spherical lens."""
    plain = load_lens("dgauss")
    count = plain.surface_count
    explicit = build_lens("dgauss", list(range(1, count + 1)), list(plain.radius_mm), list(plain.thickness_mm),
                          list(plain.index_d), list(plain.abbe_v), list(plain.aperture_mm),
                          conic=[0.0] * count, coefficients=[[0.0] * 9] * count)
    assert not explicit.aspheric.any()
    rng = np.random.default_rng(3)
    film = np.column_stack([rng.uniform(-15, 15, (5000, 2)), np.zeros(5000)])
    targets = np.column_stack([rng.uniform(-20, 20, (5000, 2)), np.full(5000, 40.0)])
    a = trace_from_film(plain, 40.0, film, targets - film)
    b = trace_from_film(explicit, 40.0, film, targets - film)
    assert a.passed.sum() > 100
    np.testing.assert_array_equal(a.origin, b.origin)
    np.testing.assert_array_equal(a.direction, b.direction)
    np.testing.assert_array_equal(a.blocked_reason, b.blocked_reason)


def test_sag_slope_is_the_derivative_of_the_sag():
    """The slope formula against a central difference of the sag, for conics and a polynomial."""
    rho2 = np.linspace(1.0, 80.0, 50)
    coefficients = np.array([2e-5, -3e-7, 1e-9, 0, 0, 0, 0, 0, 1e-24])
    for c, k in ((1 / 30, 0.0), (-1 / 25, -2.3), (1 / 40, -1.0), (0.0, 5.0)):
        eps = 1e-4
        numeric = (sag_mm(rho2 + eps, c, k, coefficients) - sag_mm(rho2 - eps, c, k, coefficients)) / (2 * eps)
        np.testing.assert_allclose(sag_slope(rho2, c, k, coefficients), numeric, rtol=1e-6, atol=1e-9)


def test_asphere_blocks_rays_outside_its_clear_aperture_with_reason_asphere():
    lens, bfl = singlet(-GLASS**2)
    targets = np.array([[SEMI + 3.0, 0.0, bfl]])
    result = trace_from_film(lens, bfl, np.zeros((1, 3)), targets)
    assert result.blocked_reason[0] == ASPHERE and result.blocked_surface[0] == 2


@pytest.mark.parametrize("conic, coefficients, message", [
    (-GLASS**2, [0.0], None),
    (3.0, [], "conic"),  # an oblate ellipsoid of R 30 ends at a semi-diameter of 15 mm
    (math.nan, [], "finite"),
    (0.0, [1e-5] * 10, "at most 9"),
])
def test_asphere_validation(conic, coefficients, message):
    def build():
        return build_lens("x.dat", [1, 2, 3], [0.0, math.inf, RADIUS], [2.0, THICKNESS, 50.0],
                          [0.0, GLASS, 0.0], [0.0] * 3, [20.0, 32.0, 32.0],
                          conic=[0.0, 0.0, conic], coefficients=[[], [], coefficients])
    if message is None:
        assert build().asphere_count == 1
    else:
        with pytest.raises(LensFileError, match=message) as err:
            build()
        assert err.value.line == 3


def test_the_stop_cannot_be_aspheric():
    with pytest.raises(LensFileError, match="stop"):
        build_lens("x.dat", [1, 2, 3], [0.0, math.inf, RADIUS], [2.0, THICKNESS, 50.0], [0.0, GLASS, 0.0],
                   [0.0] * 3, [20.0, 32.0, 32.0], conic=[-1.0, 0.0, 0.0])


def plain_sag_and_slope(rho2, c, k, coefficients):
    """The sag and its slope as ``realistic.optics.asphere``'s docstring writes them: Horner over all
    of A4 .. A20 from zero, each term on its own."""
    root = np.sqrt(1.0 - (1.0 + k) * c * c * rho2)
    poly, dpoly = np.zeros_like(rho2), np.zeros_like(rho2)
    for m, a in zip(range(len(coefficients) + 1, 1, -1), coefficients[::-1]):
        poly, dpoly = poly * rho2 + a, dpoly * rho2 + m * a
    return c * rho2 / (1.0 + root) + poly * rho2 * rho2, c / (2.0 * root) + dpoly * rho2


@given(st.lists(st.floats(-5.0, 5.0), min_size=9, max_size=9), st.integers(0, 9), st.floats(-3.0, 3.0),
       st.floats(-0.5, 0.5))
def test_the_sag_and_its_slope_are_the_plain_formulas_bit_for_bit(values, zeros_on_top, conic, curvature):
    """``sag_and_slope`` (one square root for both), from all nine coefficients or from those up to
    the highest nonzero one (``significant``), gives what the plain formulas give, bit for bit where
    the radius is finite (and NaN where they do for inf and NaN radii)."""
    coefficients = np.array(values[:9 - zeros_on_top] + [0.0] * zeros_on_top)
    short = significant(coefficients)
    assert len(short) == (np.flatnonzero(coefficients)[-1] + 1 if coefficients.any() else 0)
    rho2 = np.array([0.0, 1e-12, 0.3, 2.0, 40.0, 1e30, np.inf, np.nan])
    finite = np.isfinite(rho2)
    with np.errstate(all="ignore"):
        plain = plain_sag_and_slope(rho2, curvature, conic, coefficients)
        for got in (sag_and_slope(rho2, curvature, conic, coefficients), sag_and_slope(rho2, curvature, conic, short),
                    (sag_mm(rho2, curvature, conic, short), sag_slope(rho2, curvature, conic, short))):
            for a, b in zip(got, plain):
                assert np.array_equal(a[finite].view(np.int64), b[finite].view(np.int64))
                assert np.array_equal(a[~finite], b[~finite], equal_nan=True)


@pytest.mark.parametrize("name", ["phone-us10101561", "canon-rf50-f1.2", "dgauss"])
def test_the_tracer_stopping_blocked_rays_early_changes_no_bit(name):
    """Without ``path`` the tracer drops each blocked ray at its surface; with it, it traces every
    ray through every surface, as before. Both give the same rays, surfaces and reasons, bit for bit,
    at one wavelength and at one per ray."""
    lens = load_lens(name)
    film = film_distance_for_focus(lens, math.inf)
    rng = np.random.default_rng(4)
    count = 4000
    reach = lens.aperture_mm[-1]
    origins = np.column_stack([rng.uniform(-15, 15, count), rng.uniform(-15, 15, count), np.zeros(count)])
    targets = np.column_stack([rng.uniform(-reach, reach, (count, 2)), np.full(count, film)])
    for wavelength in (587.56, rng.uniform(400.0, 700.0, count)):
        every = trace_from_film(lens, film, origins, targets - origins, wavelength, path=[])
        early = trace_from_film(lens, film, origins, targets - origins, wavelength)
        assert 0 < early.passed.sum() < count
        for a, b in ((early.origin, every.origin), (early.direction, every.direction),
                     (early.blocked_surface, every.blocked_surface), (early.blocked_reason, every.blocked_reason)):
            assert np.array_equal(np.asarray(a).view(np.uint8), np.asarray(b).view(np.uint8))
