"""Several wavelengths per spectral camera sample: the K wavelengths of a sample are one per 1/K of
the density's probability, its K rays share the film and lens positions and the sample id (so the
light samples), the film takes 1/K of each, a white scene keeps its colour, colour noise falls with
K, and nothing changes for a non-spectral camera. The kernel-against-reference check for K = 3 is
in test_dispersion.py (``test_spectral_kernel_matches_reference_at_each_rays_wavelength``)."""

import dataclasses

import numpy as np
import pytest

from realistic import load_lens, render
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng, validation
from realistic.core.spectrum import (
    DEFAULT_WAVELENGTHS_PER_SAMPLE,
    LAMBDA_MAX_NM,
    LAMBDA_MIN_NM,
    rgb_response,
    stratified_response_variance,
    wavelength_pdf,
    wavelengths_nm,
)
from realistic.core.transforms import rotate, scale, translate
from realistic.errors import UserError
from realistic.optics.paraxial import film_distance_for_focus
from realistic.renderer.checkpoint import RenderIdentity
from realistic.renderer.film import pass_sums
from realistic.renderer.job import PassSettings, RenderJob
from realistic.renderer.memory import PASS_BYTES_PER_SAMPLE, estimate_peak_bytes
from realistic.renderer.runner import PassRunner
from realistic.renderer.timing import StageClock
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad


def _probability(lam: np.ndarray) -> np.ndarray:
    """The density's CDF at ``lam`` (numerically, on a fine grid): where a wavelength sits in probability."""
    grid = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 2_000_001)
    p = wavelength_pdf(grid)
    cdf = np.concatenate([[0.0], np.cumsum((p[1:] + p[:-1]) / 2 * np.diff(grid))])
    return np.interp(lam, grid, cdf / cdf[-1])


def _camera(spectral: bool, wavelengths: int = DEFAULT_WAVELENGTHS_PER_SAMPLE, width: int = 24, height: int = 24,
            spp: int = 4, constant_index: bool = False) -> LensCamera:
    """dgauss (Abbe numbers: dispersive) focused at 1 m, looking down -z at the z = 0 plane from 1 m."""
    lens = load_lens("dgauss")
    if constant_index:
        lens = dataclasses.replace(lens, abbe_v=np.zeros_like(lens.abbe_v))
    film = film_distance_for_focus(lens, 1000.0)
    world = translate(0, 0, 1.0) @ rotate(180, (1, 0, 0)) @ scale(1e-3)
    return LensCamera(lens, film, 43.27, width, height, spp, world, spectral=spectral,
                      wavelengths_per_sample=wavelengths)


def _grey_scene(albedo: float = 0.5) -> Scene:
    """A grey diffuse floor under a white disk light: spectrally flat everywhere."""
    scene = Scene()
    scene.add(quad(4.0, 4.0), material=Material((albedo, albedo, albedo)))
    scene.lights.append(AreaLight("disk", (0.5, 0.5), (6.0, 6.0, 6.0), translate(0, 0, 1.5) @ rotate(180, (1, 0, 0))))
    return scene


# ------------------------------------------------------------------ the K wavelengths of a sample

@pytest.mark.parametrize("wavelengths", [2, 3, 4, 5, 7, 16])
def test_a_samples_wavelengths_take_one_stratum_each_of_the_density(wavelengths):
    pixels, spp = 50, 16
    pixel, sample = np.repeat(np.arange(pixels), spp), np.tile(np.arange(spp), pixels)
    u = rng.spectral_rays(pixel, sample, 9, wavelengths)
    assert all(len(row) == pixels * spp * wavelengths for row in u)
    # the K rays of a sample share its film and lens numbers, which are stratified5's
    single = rng.stratified5(pixel, sample, 9)
    for d in range(4):
        np.testing.assert_array_equal(u[d], np.repeat(single[d], wavelengths))
    # and ray j's wavelength sits at (q0 + j) / K in the density's probability, q0 the sample's
    # one-wavelength number: exactly one in each 1/K of probability
    q = _probability(wavelengths_nm(u[4]).astype(np.float64)).reshape(-1, wavelengths)
    q0 = _probability(wavelengths_nm(single[4]).astype(np.float64))
    np.testing.assert_allclose(q, (q0[:, None] + np.arange(wavelengths)) / wavelengths, atol=1e-5)
    strata = np.arange(wavelengths) / wavelengths
    assert np.all(q >= strata - 1e-5) and np.all(q < strata + 1 / wavelengths + 1e-5)
    # over a pixel's spp samples the spp x K wavelengths are as evenly spread as R5's fifth
    # dimension: no cyclic gap wider than 2.8 / (spp K) (R5's three-gap bound)
    ordered = np.sort(q.reshape(pixels, spp * wavelengths), axis=1)
    gaps = np.diff(np.concatenate([ordered, ordered[:, :1] + 1.0], axis=1), axis=1)
    assert gaps.max() < 2.8 / (spp * wavelengths)


def test_one_wavelength_per_sample_is_the_single_wavelength_scheme():
    pixel, sample = np.repeat(np.arange(40), 8), np.tile(np.arange(8), 40)
    for ours, theirs in zip(rng.spectral_rays(pixel, sample, 3, 1), rng.stratified5(pixel, sample, 3)):
        np.testing.assert_array_equal(ours, theirs)
    assert rng.wavelength_step(4) == 1 << 30 and rng.wavelength_step(3) == 1431655765


def test_stratified_wavelengths_remove_most_of_the_response_variance():
    one = stratified_response_variance(1)
    for k in (3, 4, 8):
        assert np.all(stratified_response_variance(k) < 0.05 * one), k
    # the mean response over the K strata is still the constant (1, 1, 1): unbiased for any K
    u = (np.arange(1 << 15) + 0.5) / (1 << 15)
    for k in (2, 3, 5):
        mean = np.mean([rgb_response(wavelengths_nm((u + j / k) % 1.0)).astype(np.float64).mean(axis=0)
                        for j in range(k)], axis=0)
        np.testing.assert_allclose(mean, 1.0, atol=2e-4)


# ------------------------------------------------------------------ rays of a sample

def test_a_samples_rays_share_film_and_lens_position_and_differ_only_by_dispersion():
    block_samples = 24 * 24 * 4
    constant = _camera(True, 3, constant_index=True)
    rays = constant.generate_rays(SampleBlock(0, block_samples, constant.spp), seed=4)
    assert len(rays.weight) == 3 * block_samples
    for field in ("origin", "direction", "weight", "pixel"):
        grouped = getattr(rays, field).reshape(block_samples, 3, -1)
        np.testing.assert_array_equal(grouped, np.repeat(grouped[:, :1], 3, axis=1), err_msg=field)
    assert np.all(np.abs(np.diff(rays.wavelength_nm.reshape(-1, 3), axis=1)) > 1.0)
    # the same samples through the dispersive glass: each wavelength bends its own way
    rays = _camera(True, 3).generate_rays(SampleBlock(0, block_samples, 4), seed=4)
    passed = (rays.weight.reshape(-1, 3) > 0).all(axis=1)
    spread = np.abs(np.diff(rays.direction.reshape(-1, 3, 3), axis=1)).max(axis=(1, 2))[passed]
    assert passed.mean() > 0.5 and np.median(spread) > 1e-5


def test_non_spectral_cameras_ignore_wavelengths_per_sample():
    a, b = _camera(False, 1), _camera(False, 7)
    block = SampleBlock(0, 24 * 24 * 4, 4)
    ra, rb = a.generate_rays(block, 2), b.generate_rays(block, 2)
    for field in ("origin", "direction", "weight", "pixel"):
        np.testing.assert_array_equal(getattr(ra, field), getattr(rb, field))
    assert rb.wavelength_nm is None and a.rays_per_sample == b.rays_per_sample == 1
    assert "wavelengthsPerSample" not in b.metadata()
    try:
        from realistic.camera.opencl_host import camera_header
    except ImportError:
        return
    assert camera_header(a) == camera_header(b)  # the same kernel: bit-identical renders


def test_the_film_takes_each_of_a_samples_k_rays_at_one_kth_and_shares_its_sample_id():
    camera = _camera(True, 3, width=8, height=6, spp=5)
    block = SampleBlock.of_pixels(2, 40, 1, 3)  # samples 1..3 of pixels 2..41
    seen = {}

    class Spy:  # radiance 1 everywhere; records what the renderer asks
        def radiance(self, origin, direction, pixel, sample, clock=None, wavelength_nm=None, hits=None, albedo=None):
            seen.update(pixel=pixel, sample=sample, wavelength=wavelength_nm)
            return np.ones((len(origin), 3), np.float32), 0

    runner = PassRunner(_grey_scene(), camera, PassSettings("numpy", seed=5), StageClock())
    runner.integrator = Spy()
    result = runner(0, block)
    rays = camera.generate_rays(block, 5)
    alive = rays.weight != 0
    np.testing.assert_array_equal(seen["sample"], np.repeat(block.ids()[1], 3)[alive])
    np.testing.assert_array_equal(seen["pixel"], rays.pixel[alive])
    value = np.repeat(rays.weight[alive, None], 3, axis=1) / 3  # the integrator's radiance: the film weighs it
    np.testing.assert_allclose(result.sums, pass_sums(rays.pixel[alive], value, 2, 40), rtol=1e-5)
    assert result.count == block.count and result.primary_rays == alive.sum()


# ------------------------------------------------------------------ images

@pytest.mark.parametrize("wavelengths", [3, 4])
def test_white_scene_estimate_converges_to_the_rgb_colour(wavelengths):
    """Energy: a spectrally flat scene through the dispersive lens has, with K wavelengths per
    sample, the RGB render's colour: per channel within noise, and grey (R = G = B) to far less
    than one wavelength per sample leaves."""
    scene = _grey_scene()
    images = {}
    for spectral in (False, True):
        camera = _camera(spectral, wavelengths, width=24, height=24, spp=16)
        images[spectral] = np.stack([render(scene, camera, "numpy", seed=seed) for seed in (1, 2, 3)]).astype(float)
    means = {mode: image.mean(axis=(1, 2)) for mode, image in images.items()}  # (seeds, 3)
    sigma = np.sqrt(means[True].var(axis=0, ddof=1) / 3 + means[False].var(axis=0, ddof=1) / 3)
    difference = means[True].mean(axis=0) - means[False].mean(axis=0)
    assert np.all(np.abs(difference) < 4 * sigma + 2e-3 * means[False].mean()), (difference, sigma)
    # the whole image is grey within 0.5 % per channel (the RGB render's is grey exactly)
    spectral_colour = means[True].mean(axis=0)
    np.testing.assert_allclose(spectral_colour / spectral_colour.mean(), 1.0, atol=5e-3)


def test_colour_noise_of_a_grey_scene_falls_with_wavelengths_per_sample():
    """Across the samples of a grey diffuse scene (one sample per pixel), the colour (each channel
    minus the mean of the three, relative to the image's mean level) varies far less with K = 3 or 4
    shared-sample wavelengths than with one (fixed seed)."""
    scene = _grey_scene()
    spread = {}
    for wavelengths in (1, 3, 4):
        image = render(scene, _camera(True, wavelengths, width=48, height=48, spp=1), "numpy", seed=7)
        pixels = image.reshape(-1, 3).astype(np.float64)
        chroma = pixels - pixels.mean(axis=1, keepdims=True)
        spread[wavelengths] = float(np.mean(chroma**2) / pixels.mean() ** 2)
    # one wavelength: per-sample response variances of several units; K = 3, 4: a tenth or less
    assert spread[1] > 0.3, spread
    assert spread[3] < 0.05 * spread[1] and spread[4] < 0.05 * spread[1], spread


# ------------------------------------------------------------------ options, memory, identity

def test_wavelengths_per_sample_is_validated_and_reaches_the_camera():
    from realistic.renderer.inputs import RenderOptions, build_render_inputs

    for bad in (0, -1, validation.MAX_WAVELENGTHS_PER_SAMPLE + 1, 2.5, True, "3"):
        with pytest.raises(UserError, match="wavelengths per sample"):
            LensCamera(load_lens("dgauss"), 50.0, wavelengths_per_sample=bad)
        with pytest.raises(UserError, match="wavelengths per sample"):
            RenderOptions(wavelengths_per_sample=bad)
    camera = build_render_inputs(RenderOptions(resolution=(8, 8), dispersion=True, wavelengths_per_sample=5)).camera
    assert camera.spectral and camera.wavelengths_per_sample == 5 and camera.rays_per_sample == 5
    assert camera.metadata()["wavelengthsPerSample"] == 5
    default = build_render_inputs(RenderOptions(resolution=(8, 8), dispersion=True)).camera
    assert default.wavelengths_per_sample == DEFAULT_WAVELENGTHS_PER_SAMPLE
    with pytest.raises(UserError, match="applies to spectral renders"):
        build_render_inputs(RenderOptions(resolution=(8, 8), wavelengths_per_sample=3))  # dispersion off


def test_cli_takes_wavelengths_per_sample_for_render_and_bench():
    from realistic.cli import build_parser
    from realistic.cli.scene_arguments import options_from_args

    for command in ("render", "bench"):
        args = build_parser().parse_args([command, "--dispersion", "on", "--wavelengths-per-sample", "6"])
        assert options_from_args(args, 1).wavelengths_per_sample == 6
        with pytest.raises(UserError, match="wavelengths per sample must be between 1 and 16, got 0"):
            build_parser().parse_args([command, "--wavelengths-per-sample", "0"])


def test_memory_estimate_and_checkpoint_identity_count_the_wavelengths():
    scene = _grey_scene()
    base = estimate_peak_bytes(scene, _camera(False, 4), 1000, 2)
    one = estimate_peak_bytes(scene, _camera(True, 1), 1000, 2)
    four = estimate_peak_bytes(scene, _camera(True, 4), 1000, 2)
    assert one == base and four - base == 3 * PASS_BYTES_PER_SAMPLE * 1000 * 2  # 3 more rays per sample in flight
    ids = {k: RenderIdentity.of(scene, _camera(True, k), 0, 1000, "opencl", 1).camera for k in (3, 4)}
    assert ids[3] != ids[4]  # a checkpoint made with K = 3 does not resume with K = 4


def test_bench_counts_a_spectral_samples_k_rays():
    from realistic.renderer.convergence import measure_sample_counts

    scene = _grey_scene()
    rows = {k: measure_sample_counts(RenderJob(scene, (_camera(True, k, width=12, height=12),), "numpy"), [2],
                                     progress=False)[0][0]
            for k in (1, 3)}
    # the same samples, so about the same share of rays vignetted, whatever K
    assert 0.0 <= rows[3]["vignetted_fraction"] < 1.0
    assert rows[3]["vignetted_fraction"] == pytest.approx(rows[1]["vignetted_fraction"], abs=0.05)


def test_spectral_noise_bench_reports_each_k_with_times(tmp_path):
    """bench/spectral_noise.py end to end at a toy size: a row per (spp, K) with RGB and spectral
    relative RMSE, their ratio and the renders' times (nothing about their values is asserted)."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    pytest.importorskip("realistic.camera.opencl_host")
    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, str(root / "bench" / "spectral_noise.py"), "--scenes", "default", "--res",
                    "12x10", "--spps", "1,2", "--reference-spp", "4", "--wavelengths-per-sample", "1,3",
                    "--repeats", "1", "--out", str(tmp_path)], check=True, capture_output=True, timeout=300)
    result = json.loads((tmp_path / "spectral_noise.json").read_text())
    assert [(r["spp"], r["wavelengths_per_sample"]) for r in result["rows"]] == [(1, 1), (1, 3), (2, 1), (2, 3)]
    for row in result["rows"]:
        assert row["resolution"] == [12, 10] and row["ratio"] == pytest.approx(row["rel_rmse_spectral"] /
                                                                               row["rel_rmse_rgb"])
        assert row["seconds_rgb"] > 0 and row["seconds_spectral"] > 0
    assert "used, K = 3 per sample" in result["densities"]
    assert len(list(tmp_path.glob("reference-default-12x10-spectral-k3-4spp-*.npy"))) == 1
