"""The point-spread function rendered with camera rays: energy, position and defocus."""

import math

import numpy as np
import pytest

from realistic.camera.psf import point_spread
from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.forward_trace import trace_object_point
from realistic.optics.paraxial import paraxial_data


def stopped_dgauss():
    return load_lens("dgauss").with_stop_diameter(4.0)


def test_psf_energy_is_the_flux_through_the_entrance_pupil():
    """Sum of E * pixel area = L * pi r^2 * (projected solid angle pi sin^2(alpha) of the entrance pupil)."""
    lens = stopped_dgauss()
    para = paraxial_data(lens)
    radius = 0.5
    psf = point_spread(lens, 2000.0, 0.0, pixel_mm=0.004, size=48, spp=128, source_radius_mm=radius)
    pupil_z = psf.film_distance_mm + lens.track_length_mm - para.entrance_pupil_mm
    distance = psf.source_centre_mm[2] - pupil_z
    a = para.entrance_pupil_diameter_mm / 2
    expected = math.pi * radius**2 * math.pi * a * a / (distance * distance + a * a)
    assert psf.flux == pytest.approx(expected, rel=0.01)
    assert psf.image[0].sum() == psf.image[-1].sum() == 0  # the window holds all of it


def test_defocus_spreads_the_psf_but_keeps_its_energy():
    lens = stopped_dgauss()
    sharp = point_spread(lens, 2000.0, 0.0, pixel_mm=0.004, size=64, spp=64, source_radius_mm=0.5)
    blurred = point_spread(lens, 2000.0, 0.0, focus_mm=1500.0, pixel_mm=0.004, size=64, spp=64,
                           source_radius_mm=0.5)
    assert blurred.flux == pytest.approx(sharp.flux, rel=0.02)
    assert blurred.image.max() < 0.5 * sharp.image.max()


def test_off_axis_psf_lands_where_the_forward_trace_says():
    """Camera rays (film to scene) and forward rays (object to film) agree on the image point."""
    lens = stopped_dgauss()
    psf = point_spread(lens, 3000.0, 10.0, pixel_mm=0.004, size=32, spp=32, source_radius_mm=0.5)
    size = psf.image.shape[0]
    rows, cols = np.mgrid[0:size, 0:size]
    total = psf.image.sum()
    # Raster to film: x runs opposite to columns, y along rows (LensCamera.film_points).
    film_x = psf.centre_film_mm[0] - ((cols + 0.5 - size / 2) * psf.pixel_mm * psf.image).sum() / total
    film_y = psf.centre_film_mm[1] + ((rows + 0.5 - size / 2) * psf.pixel_mm * psf.image).sum() / total
    para = paraxial_data(lens)
    distance = 3000.0 - (psf.film_distance_mm + lens.track_length_mm - para.entrance_pupil_mm)
    landing = trace_object_point(lens, 10.0, object_distance_mm=distance, samples_across=64).at(
        psf.film_distance_mm).mean(axis=0)
    assert film_x == pytest.approx(landing[0], abs=psf.pixel_mm)
    assert film_y == pytest.approx(landing[1], abs=psf.pixel_mm)
    assert landing[1] < 0  # the image of a point above the axis is inverted on the film


def test_psf_refuses_a_point_behind_the_front_of_the_lens():
    with pytest.raises(UserError, match="not in front of the lens"):
        point_spread(load_lens("dgauss"), 50.0, focus_mm=1000.0)


def test_the_opencl_rays_give_the_numpy_psf(opencl_platform):
    """The kernel's float32 rays and the float64 reference land the same light in the same pixels."""
    lens = stopped_dgauss()
    reference = point_spread(lens, 3000.0, 5.0, pixel_mm=0.004, size=24, spp=32, source_radius_mm=0.5)
    kernel = point_spread(lens, 3000.0, 5.0, pixel_mm=0.004, size=24, spp=32, source_radius_mm=0.5,
                          backend="opencl")
    assert kernel.flux == pytest.approx(reference.flux, rel=1e-3)
    np.testing.assert_allclose(kernel.image, reference.image, atol=1e-3 * reference.image.max())
