"""Shared by the kernel tests: cameras to compare on, and the kernel-against-reference check.

The kernel (float32) and the reference (float64) must agree on every ray's verdict except near
an aperture edge or a pupil-interval edge, and on its geometry within the issue's tolerances.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np

from realistic import load_lens
from realistic.camera.base import RayBatch, SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng
from realistic.core.spectrum import wavelengths_nm
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.sampling import rear_element_sampler
from realistic.optics.tracer import trace_from_film

EDGE_MM = 1e-4
CENTRE_MM = 0.05


def world_from_camera() -> np.ndarray:
    """A rigid transform (rotation about a skew axis, translation in mm), so tolerances stay mm."""
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = 0.7
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    m[:3, 3] = [120.0, -35.0, 410.0]
    return m


def camera_for_lens(lens, spectral: bool = False) -> LensCamera:
    """64 x 48 pixels x 33 samples (101,376) over a 43.27 mm film, focused at 5 m: centre to corners."""
    film = film_distance_for_focus(lens, 5000.0)
    return LensCamera(lens, film, 43.27, 64, 48, spp=33, world_from_camera=world_from_camera(),
                      origin="front_vertex", spectral=spectral)


@cache
def reference_camera(name: str, sampling: str, spectral: bool = False) -> LensCamera:
    camera = camera_for_lens(load_lens(name), spectral)
    return camera if sampling == "pupil" else dataclasses.replace(camera, lens_sampling=sampling)


def edge_rays(camera: LensCamera, block: SampleBlock, seed: int) -> np.ndarray:
    """Rays whose verdict (at their own wavelength) flips when every clear aperture grows or shrinks
    by EDGE_MM, and, for pupil sampling, rays whose film point lies within EDGE_MM of a radial
    interval edge (float32 and float64 may pick neighbouring exit-pupil boxes there) or within
    CENTRE_MM of the film centre (where the box's polar angle is ill-conditioned)."""
    pixel, sample = block.ids()
    if camera.spectral:  # the camera's K rays per sample, at their own wavelengths
        u = rng.spectral_rays(pixel, sample, seed, camera.wavelengths_per_sample)
        pixel = np.repeat(pixel, camera.wavelengths_per_sample)
    else:
        u = rng.stratified4(pixel, sample, seed)
    count = len(pixel)
    u_x, u_y, u_lens, v_lens = u[:4]
    wavelength = wavelengths_nm(u[4]).astype(np.float64) if camera.spectral else D_LINE_NM
    film_xy, _ = camera.filtered_film_points(pixel, u_x, u_y)
    film = np.column_stack([film_xy, np.zeros(count)])
    near_interval_edge = np.zeros(count, dtype=bool)
    if camera.lens_sampling == "pupil":
        sampler = camera.pupil
        step = sampler.film_radius_mm / len(sampler.bounds)
        radius = np.hypot(film_xy[:, 0], film_xy[:, 1]) / step
        near_interval_edge = np.abs(radius - np.round(radius)) * step < EDGE_MM
        # within CENTRE_MM of the film centre the box's rotation angle comes from float32 film
        # coordinates with ~1e-6 mm of cancellation error, so the kernel's target turns by ~1e-6 / rho
        near_interval_edge |= radius * step < CENTRE_MM
    else:
        sampler = rear_element_sampler(camera.lens, camera.film_distance_mm)
    targets, _ = sampler.sample(film_xy, u_lens.astype(np.float64), v_lens.astype(np.float64))
    verdicts = [trace_from_film(dataclasses.replace(camera.lens, aperture_mm=camera.lens.aperture_mm + 2 * d),
                                camera.film_distance_mm, film, targets - film, wavelength).passed
                for d in (-EDGE_MM, EDGE_MM)]
    return (verdicts[0] != verdicts[1]) | near_interval_edge


def assert_kernel_matches(kernel: RayBatch, ref: RayBatch, camera: LensCamera, seed: int,
                          direction_atol: float = 1e-5, block: SampleBlock | None = None) -> np.ndarray:
    """The tolerances of the kernel check on the rays of ``block`` (None: sample ids 0 .. N / K - 1,
    K the camera's rays per sample);
    returns the mask of rays both pass. ``direction_atol`` is widened only for lenses whose float32
    arithmetic is shown to lose more (see its callers)."""
    np.testing.assert_array_equal(kernel.pixel, ref.pixel)
    k_pass, r_pass = kernel.weight != 0, ref.weight != 0  # negative filter lobes weigh < 0
    edge = edge_rays(camera, block or SampleBlock(0, len(ref.weight) // camera.rays_per_sample, camera.spp), seed)
    assert edge.mean() < 0.01, "the edge allowance must stay a small minority of the rays"
    disagree = (k_pass != r_pass) & ~edge
    assert not disagree.any(), f"{disagree.sum()} rays get a different pass/blocked verdict, e.g. ids " \
                               f"{np.flatnonzero(disagree)[:5]}"
    assert 0.02 < r_pass.mean(), "too few rays pass for the comparison to mean anything"
    assert np.all(kernel.origin[~k_pass] == 0) and np.all(kernel.direction[~k_pass] == 0)
    both = k_pass & r_pass & ~edge  # on a pupil-interval edge float32 may take the neighbouring box
    np.testing.assert_allclose(kernel.direction[both], ref.direction[both], rtol=0, atol=direction_atol)
    np.testing.assert_allclose(kernel.origin[both], ref.origin[both], rtol=0, atol=1e-3)
    np.testing.assert_allclose(kernel.weight[both], ref.weight[both], rtol=1e-4, atol=0)
    return both


def aspherised_dgauss():
    """The bundled double Gauss with its front and rear surfaces made conic with r^4 and r^6 terms:
    large enough departures (tenths of a millimetre at the rim) that a spherical trace would differ."""
    lens = load_lens("dgauss")
    conic = lens.conic.copy()
    coefficients = lens.aspheric_coefficients.copy()
    conic[0], coefficients[0, :2] = -0.6, (-3e-6, 2e-9)
    conic[-1], coefficients[-1, :2] = 1.5, (4e-6, -1e-8)
    return dataclasses.replace(lens, conic=conic, aspheric_coefficients=coefficients)
