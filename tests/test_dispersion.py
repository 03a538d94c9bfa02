"""Spectral rendering with dispersion: glass indices, wavelength sampling, kernel against reference,
the colour pipeline's white point, and lateral colour in a rendered image."""

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kernel_reference import assert_kernel_matches, reference_camera
from realistic import load_lens, render
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng
from realistic.core.spectrum import (
    LAMBDA_MAX_NM,
    LAMBDA_MIN_NM,
    cie_rgb,
    cie_xyz,
    cie_xyz_integral,
    estimator_variance,
    rgb_basis,
    rgb_response,
    wavelength_pdf,
    wavelengths_nm,
)
from realistic.core.transforms import rotate, scale, translate
from realistic.optics.dispersion import LAMBDA_C_UM, LAMBDA_D_UM, LAMBDA_F_UM, refractive_index
from realistic.optics.paraxial import film_distance_for_focus
from realistic.optics.tracer import trace_from_film
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ glass indices

def test_cauchy_index_reproduces_nd_and_abbe_number_of_every_glass():
    lens = load_lens("dgauss100")
    glass = lens.abbe_v > 0
    assert glass.sum() >= 5
    n_d, n_f, n_c = (refractive_index(lens.index_d, lens.abbe_v, um * 1000) for um in
                     (LAMBDA_D_UM, LAMBDA_F_UM, LAMBDA_C_UM))
    np.testing.assert_allclose(n_d, lens.index_d, rtol=0, atol=1e-12)
    np.testing.assert_allclose((n_d[glass] - 1) / (n_f[glass] - n_c[glass]), lens.abbe_v[glass], rtol=1e-10)
    assert np.all(n_f[glass] > n_d[glass]) and np.all(n_d[glass] > n_c[glass])  # normal dispersion
    np.testing.assert_array_equal(n_f[~glass], n_d[~glass])  # air and V = 0: constant


def test_per_ray_wavelengths_trace_as_each_wavelength_alone():
    lens = load_lens("dgauss100")
    film = film_distance_for_focus(lens, 5000.0)
    gen = np.random.default_rng(4)
    count = 3000
    origins = np.column_stack([gen.uniform(-15, 15, (count, 2)), np.zeros(count)])
    directions = np.column_stack([gen.uniform(-0.3, 0.3, (count, 2)), np.ones(count)])
    wavelengths = np.array([400.0, 550.0, 700.0])[gen.integers(0, 3, count)]
    mixed = trace_from_film(lens, film, origins, directions, wavelengths)
    assert 0.2 < mixed.passed.mean() < 0.9
    for wavelength in (400.0, 550.0, 700.0):
        rows = wavelengths == wavelength
        alone = trace_from_film(lens, film, origins[rows], directions[rows], wavelength)
        np.testing.assert_array_equal(mixed.blocked_reason[rows], alone.blocked_reason)
        np.testing.assert_array_equal(mixed.direction[rows], alone.direction)


# ------------------------------------------------------------------ wavelength sampling

def _numeric_cdf(density, lo_nm=LAMBDA_MIN_NM, hi_nm=LAMBDA_MAX_NM, points=2_000_001):
    """(grid, CDF) of ``density`` by the trapezoidal rule on a fine grid, normalised to end at 1."""
    lam = np.linspace(lo_nm, hi_nm, points)
    p = density(lam)
    cdf = np.concatenate([[0.0], np.cumsum((p[1:] + p[:-1]) / 2 * np.diff(lam))])
    return lam, cdf / cdf[-1], cdf[-1]


def test_wavelength_density_integrates_to_one_and_inverse_cdf_hits_its_quantiles():
    lam, cdf, total = _numeric_cdf(wavelength_pdf)
    assert total == pytest.approx(1.0, abs=1e-5)
    u = (np.arange(10_000) + 0.5) / 10_000  # stratified
    sampled = wavelengths_nm(u).astype(np.float64)
    assert np.all(np.diff(sampled) > 0) and sampled.min() > LAMBDA_MIN_NM and sampled.max() < LAMBDA_MAX_NM
    np.testing.assert_allclose(np.interp(sampled, lam, cdf), u, atol=2e-6)
    # the density is continuous (piecewise linear), so response / pdf has no jumps to spoil stratification
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 100_001)
    assert np.abs(np.diff(wavelength_pdf(lam))).max() < 1e-3 * wavelength_pdf(lam).max()


def test_importance_density_beats_uniform_and_pbrt_v4_visible_density():
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 400_001)
    ours = estimator_variance(wavelength_pdf(lam), lam)
    uniform = estimator_variance(np.ones_like(lam), lam)
    sech2 = estimator_variance(1 / np.cosh(0.0072 * (lam - 538.0)) ** 2, lam)  # pbrt-v4 SampleVisibleWavelengths
    assert ours.sum() < 0.75 * sech2.sum() < 0.75 * uniform.sum()
    assert np.all(ours < uniform)


def test_expected_film_colour_of_a_spectrum_is_its_cie_integral():
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 400_001)
    u = (np.arange(1_000_000) + 0.5) / 1_000_000  # the estimator's expectation by stratified u
    sampled = wavelengths_nm(u).astype(np.float64)
    for spectrum in (lambda x: np.ones_like(x), lambda x: np.exp(-0.5 * ((x - 610.0) / 25.0) ** 2),
                     lambda x: 0.2 + 0.7 * (x < 500)):
        expected = np.trapezoid(cie_rgb(lam) * spectrum(lam)[:, None], lam, axis=0)
        estimate = np.mean(rgb_response(sampled).astype(np.float64) * spectrum(sampled)[:, None], axis=0)
        np.testing.assert_allclose(estimate, expected, atol=2e-3 * np.abs(expected).max())
    white = np.mean(rgb_response(sampled).astype(np.float64), axis=0)
    np.testing.assert_allclose(white, 1.0, atol=1e-4)  # the constant spectrum 1 is (1, 1, 1)


@pytest.mark.parametrize("spp", [1, 2, 3, 5, 8, 16, 33, 64, 100, 256, 1024])
def test_a_pixels_wavelengths_are_stratified_in_probability(spp):
    pixels = 200
    pixel = np.repeat(np.arange(pixels), spp)
    sample = np.tile(np.arange(spp), pixels)
    u = rng.stratified5(pixel, sample, seed=3)
    lam = wavelengths_nm(u[4]).astype(np.float64)
    assert lam.min() >= LAMBDA_MIN_NM and lam.max() < LAMBDA_MAX_NM
    # in probability (the numeric CDF of the density), a pixel's N wavelengths leave no cyclic gap
    # wider than 2.8 / N: the fifth R5 step's three-gap bound for every N up to 1024
    grid, cdf, _ = _numeric_cdf(wavelength_pdf)
    q = np.interp(lam, grid, cdf).reshape(pixels, spp)
    ordered = np.sort(q, axis=1)
    gaps = np.diff(np.concatenate([ordered, ordered[:, :1] + 1.0], axis=1), axis=1)
    assert gaps.max() < 2.8 / spp + 1e-5
    # jointly with the film position: once N >= 64, the (film x, wavelength) pairs of a pixel fill a
    # 4 x 4 grid of equal-probability cells evenly (no cell holds under half its share)
    if spp >= 64:
        cell = np.minimum(u[0].reshape(pixels, spp) * 4, 3).astype(int) * 4 + np.minimum(q * 4, 3).astype(int)
        counts = np.stack([(cell == c).sum(axis=1) for c in range(16)], axis=1)
        assert counts.min() >= spp / 16 / 2
    # and pixels are rotated independently: their first samples cover the range as the density says
    assert np.histogram(q[:, 0], bins=5, range=(0, 1))[0].min() > 20


def test_kernel_stratified_bits_equal_numpy_bit_for_bit_for_spectral_cameras(opencl_platform):
    host = opencl_platform
    camera = reference_camera("dgauss100", "pupil", spectral=True)
    first, count, seed = 5_001, 20_000, 0xFFFFFFFF
    bits = host.LensKernel(camera).sample_bits(SampleBlock(first, count, camera.spp), seed)
    ids = np.arange(first, first + count)
    pixel, sample = ids // camera.spp, ids % camera.spp
    np.testing.assert_array_equal(bits, np.stack(rng.kronecker_bits(pixel, sample, seed, rng.KRONECKER_R5)))
    np.testing.assert_array_equal(rng.to_unit_float(bits), np.stack(rng.stratified5(pixel, sample, seed)))


# ------------------------------------------------------------------ kernel against reference

@pytest.mark.parametrize("name, sampling, wavelengths", [("dgauss100", "pupil", 1), ("dgauss100", "pupil", 3),
                                                         ("dgauss", "rear", 3)])
def test_spectral_kernel_matches_reference_at_each_rays_wavelength(opencl_platform, name, sampling, wavelengths):
    host = opencl_platform
    camera = dataclasses.replace(reference_camera(name, sampling, spectral=True), wavelengths_per_sample=wavelengths)
    count, seed = camera.sample_count, 11
    kernel = host.LensKernel(camera).generate(SampleBlock(0, count, camera.spp), seed)
    ref = camera.generate_rays(SampleBlock(0, count, camera.spp), seed)
    assert len(ref.weight) == len(kernel.weight) == wavelengths * count  # K rays per sample, sample-major
    np.testing.assert_array_equal(ref.pixel, np.repeat(np.arange(count) // camera.spp, wavelengths))
    # float32 u - CDF loses ~1e-7 of probability: the wavelength moves by that over the density
    allowed = 1e-4 + 3e-7 / wavelength_pdf(ref.wavelength_nm)
    assert np.all(np.abs(kernel.wavelength_nm - ref.wavelength_nm) <= allowed)
    both = assert_kernel_matches(kernel, ref, camera, seed)
    assert both.mean() > 0.3

    # the wavelength matters far beyond that tolerance: the same rays traced at the d line differ
    d_line = dataclasses.replace(camera, spectral=False).generate_rays(SampleBlock(0, count, camera.spp), seed)
    same = both & np.repeat(d_line.weight > 0, wavelengths)  # each sample's K rays start as its one d-line ray
    moved = np.abs(np.repeat(d_line.direction, wavelengths, axis=0)[same] - ref.direction[same]).max(axis=1)
    far_from_d = np.abs(ref.wavelength_nm[same] - 587.6) > 100
    assert np.median(moved[far_from_d]) > 5 * 1e-5


def test_spectral_kernel_is_batch_size_independent(opencl_platform):
    host = opencl_platform
    kernel = host.LensKernel(reference_camera("dgauss100", "pupil", spectral=True))
    first, total = 1234, 40_000
    whole = kernel.generate(SampleBlock(first, total, kernel.camera.spp), seed=5)
    sizes = [1, 255, 257, 9_999]
    sizes.append(total - sum(sizes))
    starts = first + np.concatenate([[0], np.cumsum(sizes)[:-1]])
    parts = [kernel.generate(SampleBlock(int(s), n, kernel.camera.spp), seed=5) for s, n in zip(starts, sizes)]
    for field in ("origin", "direction", "weight", "pixel", "wavelength_nm"):
        assert np.array_equal(getattr(whole, field), np.concatenate([getattr(p, field) for p in parts])), field


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs objdump")
@pytest.mark.parametrize(("wavelengths", "per_item"), [(3, 1), (4, 1), (2, 2), (3, 3)])
def test_spectral_kernel_still_vectorises(opencl_platform, tmp_path, wavelengths, per_item):
    """A work item per wavelength (K = 3 divides by 3), or per sample (its K rays side by side)."""
    script = ("from realistic import load_lens\nfrom realistic.camera.lens_camera import LensCamera\n"
              "from realistic.camera.base import SampleBlock\nfrom realistic.camera.opencl_host import LensKernel\n"
              "camera = LensCamera(load_lens('dgauss100'), 75.0, 43.27, 64, 48, spp=4, spectral=True, "
              f"wavelengths_per_sample={wavelengths})\n"
              f"LensKernel(camera, rays_per_item={per_item}).generate(SampleBlock(0, 4096, camera.spp), 0)\n")
    # PoCL compiles from source into tmp_path, not a binary from realistic's disk cache
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path), "REALISTIC_CACHE_DIR": "off"}
    subprocess.run([sys.executable, "-c", script], check=True, env=env, cwd=REPO, timeout=120)
    (so,) = tmp_path.glob("pocl/kcache/**/generate_rays/**/*.so")
    code = subprocess.run(["objdump", "-d", str(so)], capture_output=True, text=True, check=True).stdout
    assert code.count("%ymm") + code.count("%zmm") > 500, "the work-group loop is not vectorised"
    assert "call" not in code, "a builtin call stops PoCL's vectoriser"


# ------------------------------------------------------------------ colour

def test_colour_matching_fit_has_the_cie_areas_and_exact_integrals():
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 400_001)
    numeric = np.trapezoid(cie_xyz(lam), lam, axis=0)
    np.testing.assert_allclose(cie_xyz_integral(), numeric, rtol=1e-9)
    # CIE 1931: the three functions have equal areas, about 106.86 nm over the visible range
    np.testing.assert_allclose(numeric, 106.86, rtol=2e-3)
    assert cie_xyz(np.array([555.0]))[0, 1] == pytest.approx(1.0, abs=0.01)  # peak of V(lambda)


def test_constant_spectrum_is_white_and_grey_rgb_stays_grey():
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 400_001)
    response = cie_rgb(lam)
    basis = rgb_basis(lam).astype(np.float64)
    # the CIE integral of a constant spectrum 1 is (1, 1, 1)
    np.testing.assert_allclose(np.trapezoid(response, lam, axis=0), 1.0, atol=2e-6)
    np.testing.assert_allclose(basis.sum(axis=1), 1.0, atol=1e-6)  # (1,1,1) -> constant 1, grey c -> constant c
    assert basis.min() >= 0
    for grey in (0.18, 0.5, 1.0):
        spectrum = basis @ np.array([grey, grey, grey])
        rgb = np.trapezoid(response * spectrum[:, None], lam, axis=0)
        np.testing.assert_allclose(rgb, grey, rtol=1e-5)
    # a saturated colour comes back close to itself: the round trip of the basis is near the identity
    round_trip = np.trapezoid(response[:, :, None] * basis[:, None, :], lam, axis=0)
    np.testing.assert_allclose(round_trip, np.eye(3), atol=0.06)


def _looking_down(lens_name: str, spectral: bool, width: int, height: int, spp: int, constant_index: bool = False):
    lens = load_lens(lens_name)
    if constant_index:
        lens = dataclasses.replace(lens, abbe_v=np.zeros_like(lens.abbe_v))
    film = film_distance_for_focus(lens, 1000.0)
    world = translate(0, 0, 1.0) @ rotate(180, (1, 0, 0)) @ scale(1e-3)
    return LensCamera(lens, film, 43.27, width, height, spp, world, spectral=spectral)


def test_spectral_path_without_dispersion_matches_rgb_path_within_noise(opencl_platform):
    scene = Scene()
    scene.add(quad(4.0, 4.0), material=Material((0.6, 0.6, 0.6)))
    scene.add(quad(0.2, 0.2), translate(0.05, 0.03, 0.3), Material((0.3, 0.3, 0.3)))
    scene.lights.append(AreaLight("disk", (0.4, 0.4), (8.0, 8.0, 8.0),
                                  translate(-0.3, 0.2, 1.2) @ rotate(180, (1, 0, 0))))
    images = {}
    for spectral in (False, True):
        camera = _looking_down("dgauss", spectral, 32, 32, 32, constant_index=True)
        images[spectral] = [render(scene, camera, "opencl", seed=seed) for seed in (1, 2)]
    assert images[False][0].min() > 0  # lit everywhere

    def blocks(image):  # 4 x 4 regions, channels apart
        return image.reshape(4, 8, 4, 8, 3).mean(axis=(1, 3))

    rgb, spec = [np.stack([blocks(i) for i in images[s]]) for s in (False, True)]
    # noise of a region's mean from the two seeds: var(a1 - a2) = 2 var(a)
    sigma = np.sqrt(np.mean((rgb[0] - rgb[1]) ** 2 + (spec[0] - spec[1]) ** 2) / 2 / 2)
    difference = spec.mean(axis=0) - rgb.mean(axis=0)
    assert sigma < 0.06 * rgb.mean()  # regions resolved to a few per cent
    assert np.abs(difference).max() < 4 * sigma
    whole_sigma = sigma / 4  # 16 regions
    np.testing.assert_allclose(spec.mean(axis=(0, 1, 2)), rgb.mean(axis=(0, 1, 2)), rtol=0, atol=4 * whole_sigma)


def test_white_scene_keeps_its_mean_colour_with_dispersion_on():
    """Energy: a spectrally flat white scene (grey floor, white light) has the same mean colour through
    the spectral estimator with the glasses' dispersion as through the RGB path, within noise."""
    scene = Scene()
    scene.add(quad(4.0, 4.0), material=Material((0.5, 0.5, 0.5)))
    scene.lights.append(AreaLight("disk", (0.5, 0.5), (6.0, 6.0, 6.0), translate(0, 0, 1.5) @ rotate(180, (1, 0, 0))))
    means = {}
    for spectral in (False, True):
        camera = _looking_down("dgauss", spectral, 24, 24, 16)
        means[spectral] = np.stack([render(scene, camera, "opencl", seed=seed).mean(axis=(0, 1))
                                    for seed in (1, 2, 3)]).astype(np.float64)
    sigma = np.sqrt(means[True].var(axis=0, ddof=1) / 3 + means[False].var(axis=0, ddof=1) / 3)
    difference = means[True].mean(axis=0) - means[False].mean(axis=0)
    assert np.all(np.abs(difference) < 4 * sigma + 2e-3 * means[False].mean()), (difference, sigma)


# ------------------------------------------------------------------ lateral colour

def _edge_offsets(camera: LensCamera, seed: int = 1) -> list[tuple[float, float]]:
    """(field height mm, red minus blue edge position in pixels, + outward) for both edges of a white bar
    that spans film heights of about 9.5 to 20 mm along the film's long axis.

    An edge's position per channel is the area under its profile normalised by the bar's level in that
    channel (a linear estimator: noise does not bias it, unlike a centroid of |gradient|).
    """
    depth_m = 2.0
    magnification = 0.0526  # dgauss100 focused at 2 m: film mm per object mm
    x0, x1 = 9.0 / magnification / 1000, 19.0 / magnification / 1000
    scene = Scene()
    scene.lights.append(AreaLight("quad", (x1 - x0, 0.3), (1.0, 1.0, 1.0),
                                  translate((x0 + x1) / 2, 0, depth_m) @ rotate(180, (1, 0, 0))))
    profile = render(scene, camera, "opencl", seed=seed).mean(axis=0).astype(np.float64)  # (W, 3)
    lit = np.flatnonzero(profile.mean(axis=1) > 0.5 * profile.mean(axis=1).max())
    first, last = lit[0], lit[-1]  # the bar's first and last bright pixels
    level = profile[first + 20:last - 20].mean(axis=0)  # the bar's level per channel
    centre = camera.width / 2
    pixel_mm = camera.film_size_mm[0] / camera.width
    half = 20
    result = []
    for edge, rising in ((first, True), (last + 1, False)):  # the boundary lies before pixel `edge`
        window = slice(edge - half, edge + half)
        covered = (profile[window] / level).sum(axis=0)  # bright pixels' worth in the window, per channel
        position = edge + half - covered if rising else edge - half + covered
        outward = np.sign(edge - centre)
        result.append((abs(edge - centre) * pixel_mm, float((position[0] - position[2]) * outward)))
    return result


def test_lateral_colour_grows_with_field_height_and_vanishes_without_dispersion():
    lens = load_lens("dgauss100")
    film = film_distance_for_focus(lens, 2000.0)

    def strip(spectral: bool, constant_index: bool = False) -> LensCamera:
        glass = dataclasses.replace(lens, abbe_v=np.zeros_like(lens.abbe_v)) if constant_index else lens
        return LensCamera(glass, film, 43.27, 1600, 32, spp=64, world_from_camera=scale(1e-3), spectral=spectral)

    # Same seed, same rays: the spectral render with constant indices carries the same colour noise
    # as the dispersive one, so their difference isolates what the glasses' dispersion does.
    dispersive = _edge_offsets(strip(True))
    constant = _edge_offsets(strip(True, constant_index=True))
    (h_mid, _), (h_corner, _) = dispersive
    assert 8 < h_mid < 11 and 19 < h_corner < 21.5
    mid, corner = (d - c for (_, d), (_, c) in zip(dispersive, constant))
    # a red/blue offset (a pixel is 27 um) the same way round at both heights, larger near the corner
    assert np.sign(mid) == np.sign(corner) and abs(mid) > 0.1 and abs(corner) > 1.1 * abs(mid), (mid, corner)
    # --dispersion off renders RGB at the d line: no offset at all
    assert all(abs(offset) < 0.01 for _, offset in _edge_offsets(strip(False)))


# ------------------------------------------------------------------ command line

def test_dispersion_option_defaults_to_the_lens_and_can_be_forced(tmp_path):
    from realistic.cli import build_parser
    from realistic.cli.scene_arguments import options_from_args
    from realistic.renderer.inputs import build_render_inputs

    def camera(*args: str) -> LensCamera:
        parsed = build_parser().parse_args(["render", "--res", "8x8", *args])
        return build_render_inputs(options_from_args(parsed, 1)).camera

    mesh = tmp_path / "tetrahedron.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    assert load_lens("dgauss").has_dispersion and camera(str(mesh)).spectral  # V numbers: on for a mesh
    assert not camera(str(mesh), "--dispersion", "off").spectral
    assert not camera().spectral  # the default scene renders as scenes/default.pbrt: off unless asked
    assert camera("--dispersion", "on").spectral
    assert camera("--lens", "dgauss100", "--dispersion", "on").spectral
