"""Paraxial analysis and focusing, against derivations that share no code with the package."""

import math

import numpy as np
import pytest

from realistic import UserError, load_lens, parse_prescription
from realistic.optics.dispersion import LAMBDA_C_UM, LAMBDA_D_UM, LAMBDA_F_UM, refractive_index
from realistic.optics.paraxial import (
    film_distance_for_focus,
    focus_distance_for_film,
    nearest_focus_mm,
    paraxial_data,
    stop_diameter_for_f_number,
)


def system_matrix(surfaces):
    """ABCD matrix on (y, u) of [(R, n_before, n_after, gap_after), ...], the textbook way."""
    m = np.eye(2)
    for radius, n1, n2, gap in surfaces:
        power = 0.0 if radius in (0, math.inf) else (n2 - n1) / radius
        m = np.array([[1.0, 0.0], [-power / n2, n1 / n2]]) @ m
        if gap:
            m = np.array([[1.0, gap], [0.0, 1.0]]) @ m
    return m


def test_single_thick_lens_matches_lensmaker():
    r1, r2, t, n = 40.0, -60.0, 6.0, 1.6
    lens = parse_prescription(f"0 2 0 20\n{r1} {t} {n} 30\n{r2} 0 1 30\n")
    power = (n - 1) * (1 / r1 - 1 / r2 + (n - 1) * t / (n * r1 * r2))
    f = 1 / power
    bfl = f * (1 - (n - 1) * t / (n * r1))
    ffd = -f * (1 + (n - 1) * t / (n * r2))
    p = paraxial_data(lens)
    assert p.efl_mm == pytest.approx(f, rel=1e-12)
    assert p.bfl_mm == pytest.approx(bfl, rel=1e-12)
    # the stop sits 2 mm in front of the lens: front focal point measured from the stop
    assert p.ffd_mm == pytest.approx(ffd + 2.0, rel=1e-12)


def test_two_lens_system_matches_matrix_method():
    text = "50 5 1.7 30\n-80 10 1 30\n0 8 0 16\n-35 3 1.62 24\n120 0 1 24\n"
    lens = parse_prescription(text)
    rows = [(50, 1, 1.7, 5), (-80, 1.7, 1, 10), (0, 1, 1, 8), (-35, 1, 1.62, 3), (120, 1.62, 1, 0)]
    (a, b), (c, d) = system_matrix(rows)
    p = paraxial_data(lens)
    assert p.efl_mm == pytest.approx(-1 / c, rel=1e-12)
    assert p.bfl_mm == pytest.approx(-a / c, rel=1e-12)
    assert p.ffd_mm == pytest.approx(d / c, rel=1e-12)
    # Entrance pupil: the stop imaged backwards through the first two surfaces.
    front = system_matrix([(50, 1, 1.7, 5), (-80, 1.7, 1, 10)])
    # chief ray through the stop centre: y_stop = A y0 + B u0 = 0 with y0 = -z u0 from the pupil at z
    z_entrance = front[0, 1] / front[0, 0]
    assert p.entrance_pupil_mm == pytest.approx(z_entrance, rel=1e-12)
    assert p.entrance_pupil_diameter_mm == pytest.approx(16 / abs(front[0, 0]), rel=1e-12)
    # Exit pupil: the stop imaged forward through the rear lens (Gaussian imaging in the matrix form).
    rear = system_matrix([(0, 1, 1, 8), (-35, 1, 1.62, 3), (120, 1.62, 1, 0)])
    image_distance = -rear[0, 1] / rear[1, 1]  # object at the stop: image where y no longer depends on u
    assert p.exit_pupil_mm == pytest.approx(image_distance, rel=1e-12)
    magnification = rear[0, 0] + image_distance * rear[1, 0]
    assert p.exit_pupil_diameter_mm == pytest.approx(16 * abs(magnification), rel=1e-12)
    assert p.f_number == pytest.approx(p.efl_mm / p.entrance_pupil_diameter_mm)


# EFL and back focal distance of the bundled lenses: published figures (../shared/DESIGN.md).
PUBLISHED = {"dgauss": (50.358, 36.106), "wide": (22.023, 14.318), "fisheye": (9.991, 23.161),
             "telephoto": (249.567, 105.070), "dgauss100": (100.716, 72.212)}


@pytest.mark.parametrize("name", PUBLISHED)
def test_published_focal_lengths(name):
    p = paraxial_data(load_lens(name))
    efl, bfl = PUBLISHED[name]
    assert p.efl_mm == pytest.approx(efl, abs=6e-4)
    assert p.bfl_mm == pytest.approx(bfl, abs=6e-4)


def test_dgauss100_efl_at_f_and_c_lines():
    lens = load_lens("dgauss100")
    assert paraxial_data(lens, LAMBDA_F_UM * 1000).efl_mm == pytest.approx(100.633, abs=6e-4)
    assert paraxial_data(lens, LAMBDA_C_UM * 1000).efl_mm == pytest.approx(100.747, abs=6e-4)


def test_cauchy_index_reproduces_nd_and_abbe_number():
    n_d, v = np.array([1.67, 1.5]), np.array([47.1, 64.0])
    nf, nd, nc = (refractive_index(n_d, v, lam * 1000) for lam in (LAMBDA_F_UM, LAMBDA_D_UM, LAMBDA_C_UM))
    np.testing.assert_allclose(nd, n_d, rtol=1e-14)
    np.testing.assert_allclose((nd - 1) / (nf - nc), v, rtol=1e-12)


def paraxial_image_distance(lens, object_distance_from_front):
    """Where an axial point images, from the matrix method: rear vertex to image."""
    rows = []
    n_before = 1.0
    for i in range(lens.surface_count):
        n_after = lens.index_d[i]
        gap = lens.thickness_mm[i] if i < lens.surface_count - 1 else 0
        rows.append((lens.radius_mm[i] if lens.radius_mm[i] else math.inf, n_before, n_after, gap))
        n_before = n_after
    m = system_matrix(rows) @ np.array([[1, object_distance_from_front], [0, 1]])
    return -m[0, 1] / m[1, 1]


@pytest.mark.parametrize("name", ["dgauss", "telephoto", "wide"])
@pytest.mark.parametrize("times_nearest", [1.01, 4.0, 500.0])
def test_thick_lens_focus_images_the_object_on_the_film(name, times_nearest):
    lens = load_lens(name)
    focus_mm = nearest_focus_mm(lens) * times_nearest
    film = film_distance_for_focus(lens, focus_mm)
    object_from_front = focus_mm - film - lens.track_length_mm
    assert paraxial_image_distance(lens, object_from_front) == pytest.approx(film, rel=1e-9)
    assert focus_distance_for_film(lens, film) == pytest.approx(focus_mm, rel=1e-9)


def test_focus_at_infinity_is_the_back_focal_distance():
    lens = load_lens("dgauss")
    assert film_distance_for_focus(lens, math.inf) == pytest.approx(paraxial_data(lens).bfl_mm, rel=1e-12)


def test_focus_too_close_is_a_clear_error():
    lens = load_lens("dgauss")
    with pytest.raises(UserError, match="closer than the lens 'dgauss' can focus"):
        film_distance_for_focus(lens, 100.0)
    with pytest.raises(UserError, match="nothing is in focus"):
        focus_distance_for_film(lens, 30.0)


@pytest.mark.parametrize("name", ["dgauss", "telephoto", "wide"])
def test_stop_for_an_f_number_gives_that_f_number(name):
    lens = load_lens(name)
    for n in (5.6, 8.0, 16.0):
        stopped = lens.with_stop_diameter(stop_diameter_for_f_number(lens, n))
        assert paraxial_data(stopped).f_number == pytest.approx(n, rel=1e-12)
    with pytest.raises(UserError, match="faster than"):
        stop_diameter_for_f_number(lens, paraxial_data(lens).f_number * 0.9)
