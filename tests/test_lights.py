"""Light sampling against closed forms: environment-map densities, and the irradiance a point, spot
and distant light put on a white Lambertian plane (reflected radiance E / pi)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from realistic.core.distribution import Distribution2D
from realistic.renderer.light_sampler import LightSampler
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import (
    DistantLight,
    InfiniteLight,
    PointLight,
    SpotLight,
    equal_area_sphere_to_square,
    equal_area_square_to_sphere,
)
from realistic.scene.model import Material, Scene
from realistic.scene.shapes import quad


def _env(mapping: str) -> InfiniteLight:
    rng = np.random.default_rng(4)
    image = (rng.random((16, 16 if mapping == "equal-area" else 32, 3)) ** 4).astype(np.float32)
    image[3, 5] = 50.0  # a sun
    return InfiniteLight((1.0, 1.0, 1.0), image, mapping, np.eye(4))


@pytest.mark.parametrize("mapping", ["latlong", "equal-area"])
def test_environment_pdf_integrates_to_one_over_the_sphere(mapping):
    """Midpoint quadrature over (theta, phi), independent of either map's parameterisation."""
    sampler = LightSampler(_sceneless([_env(mapping)]), 1.0)
    rows, cols = 800, 1600
    theta = (np.arange(rows) + 0.5) / rows * math.pi
    phi = (np.arange(cols) + 0.5) / cols * 2 * math.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    w = np.column_stack([(np.sin(t) * np.cos(p)).ravel(), (np.sin(t) * np.sin(p)).ravel(), np.cos(t).ravel()])
    integral = (sampler.pdf_environment(w) * np.sin(t).ravel()).sum() * (math.pi / rows) * (2 * math.pi / cols)
    assert abs(integral - 1.0) < 5e-3


@pytest.mark.parametrize("mapping", ["latlong", "equal-area"])
def test_environment_samples_follow_their_pdf(mapping):
    """A histogram of sampled directions over the map's texels matches the pdf integrated per texel."""
    light = _env(mapping)
    sampler = LightSampler(_sceneless([light]), 1.0)
    n = 200000
    rng = np.random.default_rng(6)
    sample = sampler.sample(np.zeros((n, 3)), rng.random(n), rng.random(n), rng.random(n), None)
    h, w = light.image.shape[:2]
    uv = light.to_uv(sample.wi.astype(np.float64))
    cells = np.clip((uv[:, 1] * h).astype(int), 0, h - 1) * w + np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    counts = np.bincount(cells, minlength=h * w) / n
    expected = sampler.environments[0].distribution.density.ravel() / (h * w)
    assert np.abs(counts - expected).max() < 5 * np.sqrt(expected.max() / n)
    # the density the sample reports is the one pdf_environment gives for its direction
    np.testing.assert_allclose(sample.pdf, sampler.pdf_environment(sample.wi.astype(np.float64)), rtol=1e-4)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_equal_area_map_round_trips(u, v):
    w = equal_area_square_to_sphere(np.array([[u, v]]))
    assert abs(np.linalg.norm(w) - 1.0) < 1e-9
    back = equal_area_sphere_to_square(w)
    # the square's border folds onto itself (octahedral wrap): compare directions there
    again = equal_area_square_to_sphere(back)
    np.testing.assert_allclose(again, w, atol=1e-7)


def test_equal_area_map_preserves_area():
    """Uniform points in the square give uniform directions: each octant holds 1/8 of them."""
    uv = np.random.default_rng(7).random((200000, 2))
    w = equal_area_square_to_sphere(uv)
    octant = (w[:, 0] > 0) * 4 + (w[:, 1] > 0) * 2 + (w[:, 2] > 0)
    np.testing.assert_allclose(np.bincount(octant, minlength=8) / len(uv), 1 / 8, atol=0.004)
    assert abs(np.mean(w[:, 2] > 0.5) - 0.25) < 0.004  # a cap of height 1/2 is 1/4 of the sphere


def _sceneless(lights) -> Scene:
    scene = Scene()
    scene.lights.extend(lights)
    return scene


def _plane_radiance(light, points: np.ndarray) -> np.ndarray:
    """Radiance reflected straight up by a white Lambertian floor z = 0 at ``points``."""
    scene = Scene()
    scene.add(quad(100.0, 100.0), np.eye(4), Material((1.0, 1.0, 1.0)))
    scene.lights.append(light)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 0, 0.0, 1, "direct")
    origin = (points + [0.0, 0.0, 1.0]).astype(np.float32)
    direction = np.tile(np.float32([0.0, 0.0, -1.0]), (len(points), 1))
    return integrator.radiance(origin, direction, np.arange(len(points)), np.zeros(len(points), int))[0]


POINTS = np.array([[x, y, 0.0] for x in (-3.0, -1.0, 0.0, 0.5, 2.0) for y in (-2.0, 0.0, 1.5)])


def test_point_light_irradiance_is_inverse_square_cosine():
    position, intensity = np.array([0.3, -0.2, 2.0]), 7.0
    got = _plane_radiance(PointLight((intensity,) * 3, position), POINTS)[:, 1]
    to = position - POINTS
    r2 = (to ** 2).sum(axis=1)
    expected = intensity * (to[:, 2] / np.sqrt(r2)) / r2 / math.pi
    np.testing.assert_allclose(got, expected, rtol=1e-4)


@pytest.mark.parametrize("kind", ["quartic", "smoothstep"])
def test_spot_light_irradiance_follows_pbrts_falloff(kind):
    position, intensity = np.array([0.0, 0.0, 2.0]), 5.0
    to_world = np.eye(4)
    to_world[:3, :3] = np.diag([1.0, -1.0, -1.0])  # cone axis down (-z), a proper rotation
    to_world[:3, 3] = position
    total, start = math.radians(40.0), math.radians(25.0)
    light = SpotLight((intensity,) * 3, to_world, math.cos(total), math.cos(start), kind)
    got = _plane_radiance(light, POINTS)[:, 0]
    to = position - POINTS
    r = np.sqrt((to ** 2).sum(axis=1))
    cos_axis = to[:, 2] / r  # angle to the downward axis equals the angle of incidence here
    t = np.clip((cos_axis - math.cos(total)) / (math.cos(start) - math.cos(total)), 0, 1)
    falloff = t ** 4 if kind == "quartic" else t * t * (3 - 2 * t)
    expected = intensity * falloff * cos_axis / r ** 2 / math.pi
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-7)
    assert (expected == 0).any() and ((expected > 0) & (falloff < 1)).any()  # outside and within the falloff


def test_distant_light_irradiance_is_radiance_times_cosine():
    towards = np.array([1.0, 0.0, 2.0]) / math.sqrt(5.0)
    got = _plane_radiance(DistantLight((3.0, 2.0, 1.0), towards), POINTS)
    np.testing.assert_allclose(got, np.outer(np.ones(len(POINTS)), [3.0, 2.0, 1.0]) * towards[2] / math.pi,
                               rtol=1e-5)


def test_distribution_of_zeros_is_uniform_and_rejects_negative_weights():
    d = Distribution2D(np.zeros((2, 3)))
    np.testing.assert_allclose(d.density, 1.0)
    with pytest.raises(ValueError):
        Distribution2D(np.array([[1.0, -1.0]]))


def test_environment_without_a_map_reads_as_a_white_map_of_one_texel():
    """pbrt's infinite light without a map is one of a single texel of 1: every lookup is white."""
    uv = np.random.default_rng(3).random((50, 2))
    bare = InfiniteLight((2.0, 1.0, 0.5))
    white = InfiniteLight((2.0, 1.0, 0.5), np.ones((1, 1, 3), np.float32))
    assert np.array_equal(bare.texels(uv), white.texels(uv))
    assert np.array_equal(bare.texels(uv), np.ones((50, 3)))


def _rotated(light: InfiniteLight, radiance: tuple[float, float, float]) -> InfiniteLight:
    """``light`` turned by a rotation about an oblique axis (no signed permutation: every row of
    the world-to-light matrix mixes all three components), with ``radiance``."""
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + math.sin(0.7) * k + (1 - math.cos(0.7)) * k @ k  # Rodrigues
    return InfiniteLight(radiance, light.image, light.mapping, m)


@pytest.mark.parametrize("mapping", ["latlong", "equal-area", None])
def test_escaping_rays_read_each_map_as_its_texels_and_density(mapping):
    """``escaping`` (one map lookup for both) gives what the light's own definitions give: the nearest
    texel at ``to_uv`` times the radiance, rounded once to float32, and the pick probability times
    the map's ``Distribution2D.pdf`` at that uv times the mapping's Jacobian (1 / 4 pi without a map)."""
    light = _rotated(_env(mapping or "latlong"), (0.3, 1.7, 0.9))
    if mapping is None:
        light = InfiniteLight(light.radiance, None, "latlong", light.light_to_world)
    sampler = LightSampler(_sceneless([light, PointLight((5.0, 5.0, 5.0), np.array([0.0, 2.0, 0.0]))]), 1.0)
    d = np.random.default_rng(8).normal(size=(20000, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rgb, pdf = sampler.escaping(d, None, camera=False, density=True)
    uv = light.to_uv(d)
    expected = (light.texels(uv) * np.asarray(light.radiance)).astype(np.float32)
    assert rgb.dtype == np.float32 and np.array_equal(rgb, expected)
    if mapping is None:
        density = np.full(len(d), 1 / (4 * math.pi))
    else:
        density = sampler.environments[0].distribution.pdf(uv) * sampler.environments[0].jacobian(uv)
    np.testing.assert_allclose(pdf, sampler.probability[0] * density, rtol=1e-9)  # uv in float64, as to_uv
    # camera rays and specular bounces read no density; the radiance is the same
    rgb_alone, none = sampler.escaping(d, None, camera=True, density=False)
    assert np.array_equal(rgb_alone, rgb) and not none.any()


def test_escaping_rays_sum_every_infinite_light():
    """Two maps under one sampler: radiances add (within float32 rounding of the float64 sum),
    densities add weighted by each light's pick probability."""
    lights = [_rotated(_env("latlong"), (1.0, 0.5, 0.25)), _env("equal-area")]
    sampler = LightSampler(_sceneless(lights), 1.0)
    d = np.random.default_rng(9).normal(size=(5000, 3))
    rgb, pdf = sampler.escaping(d, None, camera=False, density=True)
    expected = sum(light.texels(light.to_uv(d)) * np.asarray(light.radiance) for light in lights)
    np.testing.assert_allclose(rgb, expected, rtol=2e-7)
    alone = [LightSampler(_sceneless([light]), 1.0).pdf_environment(d) for light in lights]
    np.testing.assert_allclose(pdf, sum(p * a for p, a in zip(sampler.probability, alone, strict=True)), rtol=1e-12)
