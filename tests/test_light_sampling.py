"""Stratified light samples (``realistic.core.rng.light_bits``) and what they do to direct lighting.

The sequence: Sobol's first two dimensions against scipy's (an independent implementation, Gray-code
order), numbers in [0, 1), a pure function of each (pixel, sample, k, light samples, seed). Its
stratification per pixel: the spp x L light points form a (0, m, 2)-net (one point in each
elementary box of area 1 / N, every shape), the L points of one camera sample too, and the picks
one per 1 / N strip; iid hashed numbers fail the same checks on almost every pixel. Unbiasedness: each
(sample, k)'s numbers are uniform over pixels and independent of the camera's numbers (chi-square),
and on a soft-shadow scene the image mean agrees with the iid numbers' within statistical error,
while the per-pixel variance (two seeds: mean((a - b)^2) / 2) is far lower.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats
from scipy.stats import qmc

from realistic.core import rng
from realistic.core.transforms import rotate, translate
from realistic.renderer.direct_lighting import DirectLighting
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad

PIXELS = 2000


def pixel_points(spp: int, light_samples: int, seed: int, pixels: int = PIXELS) -> np.ndarray:
    """(3, pixels, spp * light_samples) float64: u0, u1, u2 of every light sample of every pixel,
    light sample k of camera sample s at column s * light_samples + k."""
    pixel = np.repeat(np.arange(pixels), spp)
    sample = np.tile(np.arange(spp), pixels)
    columns = [np.array(rng.light_uniforms(pixel, sample, k, light_samples, seed), np.float64)
               .reshape(3, pixels, spp) for k in range(light_samples)]
    return np.stack(columns, axis=-1).reshape(3, pixels, spp * light_samples)


def iid_points(n: int, seed: int, pixels: int = PIXELS) -> np.ndarray:
    """The same layout from independent hashed numbers (the integrator's former light numbers)."""
    pixel = np.repeat(np.arange(pixels), n)
    sample = np.tile(np.arange(n), pixels)
    return np.array([rng.uniform(pixel, sample, dim, seed) for dim in (4, 5, 6)], np.float64).reshape(3, pixels, n)


def is_net(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Per row: whether the row's N = 2^m points (u1, u2) have exactly one point in each elementary
    box [a / 2^i, (a + 1) / 2^i) x [b / 2^(m - i), (b + 1) / 2^(m - i)), for every i = 0 .. m."""
    n = u1.shape[-1]
    m = int(math.log2(n))
    ok = np.ones(u1.shape[:-1], bool)
    for i in range(m + 1):
        box = np.floor(u1 * 2**i).astype(np.int64) * 2 ** (m - i) + np.floor(u2 * 2 ** (m - i)).astype(np.int64)
        ok &= np.all(np.sort(box, axis=-1) == np.arange(n), axis=-1)
    return ok


def strip_counts(u: np.ndarray) -> np.ndarray:
    """Per row of N numbers, how many fall in each of N equal strips of [0, 1)."""
    n = u.shape[-1]
    strips = np.minimum(np.floor(u * n).astype(np.int64), n - 1)
    return np.stack([np.count_nonzero(strips == j, axis=-1) for j in range(n)], axis=-1)


def test_sobol_dimensions_match_scipy():
    """scipy's unscrambled Sobol' (Joe and Kuo's direction numbers) enumerates points in Gray-code
    order: its point i is ours at index i ^ (i >> 1)."""
    i = np.arange(4096, dtype=np.uint32)
    d0, d1 = rng.sobol2_digits(i ^ (i >> np.uint32(1)))
    expected = qmc.Sobol(2, scramble=False).random(4096)
    np.testing.assert_array_equal(rng.reverse_bits(d0) / 2.0**32, expected[:, 0])
    np.testing.assert_array_equal(rng.reverse_bits(d1) / 2.0**32, expected[:, 1])


@given(st.integers(0, 2**32 - 1))
def test_reverse_bits_reverses_the_binary_digits(x):
    assert int(rng.reverse_bits(np.uint32(x))) == int(format(x, "032b")[::-1], 2)


@given(st.integers(0, 2**32 - 1), st.integers(0, 2**31 - 1), st.integers(1, 64), st.integers(0, 2**32 - 1))
def test_numbers_are_in_the_unit_interval_and_per_element(pixel, sample, light_samples, seed):
    """Every number is float32 in [0, 1), and an element's numbers do not depend on the batch (nor
    the point on whether the pick is asked for)."""
    ks = np.arange(light_samples)
    batch = np.array([rng.light_uniforms(np.array([pixel, 3]), np.array([sample, 9]), k, light_samples, seed)
                      for k in ks])
    alone = np.array([rng.light_uniforms(np.array([pixel]), np.array([sample]), k, light_samples, seed) for k in ks])
    assert batch.dtype == np.float32 and np.all((batch >= 0) & (batch < 1))
    np.testing.assert_array_equal(batch[:, :, :1], alone)
    point_only = rng.light_uniforms(np.array([pixel]), np.array([sample]), light_samples - 1, light_samples, seed,
                                    pick=False)
    np.testing.assert_array_equal(point_only[1:], alone[-1, 1:])
    assert point_only[0] == 0


@pytest.mark.parametrize("spp, light_samples", [(16, 1), (16, 4), (4, 16), (64, 1)])
def test_a_pixels_light_points_form_a_net(spp, light_samples):
    """N = spp x L a power of two: every pixel's N points (u1, u2) are a (0, m, 2)-net and its N
    picks lie one per 1 / N strip; iid numbers fail both on nearly every pixel."""
    u = pixel_points(spp, light_samples, seed=3)
    assert np.all(is_net(u[1], u[2]))
    assert np.all(strip_counts(u[0]) == 1)
    iid = iid_points(spp * light_samples, seed=3)
    assert np.mean(is_net(iid[1], iid[2])) < 0.01
    assert np.mean(np.all(strip_counts(iid[0]) == 1, axis=-1)) < 0.01


def test_each_camera_samples_light_points_form_a_net():
    """L = 4 light samples per camera sample: each camera sample's four points lie one per quadrant
    (and one per quarter strip of either axis), as well as the pixel's 64 forming a net."""
    u = pixel_points(16, 4, seed=8).reshape(3, PIXELS, 16, 4)
    assert np.all(is_net(u[1], u[2]))


@pytest.mark.parametrize("spp, light_samples", [(6, 1), (5, 3), (12, 2)])
def test_other_sample_counts_stay_spread(spp, light_samples):
    """N not a power of two: the N points are N of an aligned block of the next power of two's net,
    so no 1 / N strip of u1, u2 or the pick holds more than two points on any of the pixels; iid
    numbers exceed that on a good part of them (all of them within it: odds below 0.7^2000)."""
    n = spp * light_samples
    u = pixel_points(spp, light_samples, seed=5)
    assert all(np.all(strip_counts(u[d]) <= 2) for d in range(3))
    iid = iid_points(n, seed=5)
    assert np.mean(np.all(strip_counts(iid[1]) <= 2, axis=-1)) < 0.7


def test_each_sample_is_uniform_and_independent_of_the_camera_numbers():
    """For one (sample, k), the numbers over many pixels are uniform in 3-D (chi-square over 4^3
    cells), and (u1, camera film x) and (u2, lens u) are uniform in 2-D: unbiased per sample."""
    pixels = 40000
    pixel = np.arange(pixels)
    sample = np.full(pixels, 5)
    u0, u1, u2 = rng.light_uniforms(pixel, sample, 2, 4, seed=1)
    film_x, _, lens_u, _ = rng.stratified4(pixel, sample, seed=1)

    def p_value(*columns: np.ndarray) -> float:
        cells = np.zeros(pixels, np.int64)
        for c in columns:
            cells = cells * 4 + np.floor(c * 4).astype(np.int64)
        counts = np.bincount(cells, minlength=4 ** len(columns))
        return stats.chisquare(counts).pvalue

    assert p_value(u0, u1, u2) > 1e-4
    assert p_value(u1, film_x) > 1e-4
    assert p_value(u2, lens_u) > 1e-4


# ------------------------------------------------------------------ a soft-shadow scene

GRID = 24  # pixels per side of the floor patch


@pytest.fixture(scope="module")
def soft_shadow():
    """A floor under a big disk light (radius 1, 3 up) and a dim quad light, a square blocker half
    way up: the patch seen below it is umbra, penumbra and open floor."""
    scene = Scene(background=(0.0, 0.0, 0.0))
    scene.add(quad(20.0, 20.0), rotate(-90, (1, 0, 0)), Material((0.8, 0.8, 0.8)))
    scene.add(quad(1.0, 1.0), translate(0.0, 1.5, 0.0) @ rotate(90, (1, 0, 0)), Material((0.5, 0.5, 0.5)))
    scene.lights.append(AreaLight("disk", (1.0, 1.0), (10.0, 10.0, 10.0),
                                  translate(0.0, 3.0, 0.0) @ rotate(90, (1, 0, 0))))
    scene.lights.append(AreaLight("quad", (0.5, 0.5), (4.0, 4.0, 4.0),
                                  translate(2.0, 2.0, 1.0) @ rotate(120, (1, 0, 0))))
    return scene, Intersector(scene)


def floor_estimates(scene: Scene, intersector: Intersector, spp: int, light_samples: int, seed: int) -> np.ndarray:
    """Per pixel, the mean over spp samples of the radiance seen straight down at the pixel's floor
    point (one fixed point per pixel: only the light samples vary)."""
    xs = np.linspace(-1.8, 1.8, GRID)
    x, z = (a.ravel() for a in np.meshgrid(xs, xs))
    origin = np.repeat(np.column_stack([x, np.full_like(x, 1.0), z]), spp, axis=0).astype(np.float32)
    direction = np.tile(np.array([[0.0, -1.0, 0.0]], np.float32), (len(origin), 1))
    pixel = np.repeat(np.arange(GRID * GRID), spp)
    sample = np.tile(np.arange(spp), GRID * GRID)
    radiance, _ = DirectLighting(scene, intersector, light_samples, seed).radiance(origin, direction, pixel, sample)
    return radiance[:, 0].astype(np.float64).reshape(GRID * GRID, spp).mean(axis=1)


def _iid_light_uniforms(pixel, sample, k, light_samples, seed, pick=True):
    """The integrator's former light numbers: independent hashes at dimensions 4 + 3k .. 6 + 3k."""
    return [rng.uniform(pixel, sample, dim, seed) for dim in (4 + 3 * k, 5 + 3 * k, 6 + 3 * k)]


@pytest.mark.parametrize("spp, light_samples", [(4, 4), (16, 1)])
def test_soft_shadows_are_unbiased_and_less_noisy(soft_shadow, monkeypatch, spp, light_samples):
    scene, intersector = soft_shadow
    seeds = (1, 2, 3, 4)
    new = np.array([floor_estimates(scene, intersector, spp, light_samples, s) for s in seeds])
    monkeypatch.setattr(rng, "light_uniforms", _iid_light_uniforms)
    old = np.array([floor_estimates(scene, intersector, spp, light_samples, s) for s in seeds])
    # per-pixel variance of one render, from pairs of seeds
    var_new = np.mean((new[0::2] - new[1::2]) ** 2) / 2
    var_old = np.mean((old[0::2] - old[1::2]) ** 2) / 2
    assert var_old > 0 and var_new < 0.4 * var_old
    # image means: pixels are independent (per-pixel scrambles), each mean over len(seeds) renders
    pixels = GRID * GRID
    error = math.sqrt((var_new + var_old) / (len(seeds) * pixels))
    assert abs(new.mean() - old.mean()) < 4 * error
    # the scene has shadows to stratify: the blocker removes a clear part of the light
    assert new.mean(axis=0).min() < 0.5 * new.mean(axis=0).max()
