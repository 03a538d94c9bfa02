"""Emitting spheres sampled by the cone they subtend (issue 34; pbrt-v3 ``src/shapes/sphere.cpp`` and
pbrt-v4 ``src/pbrt/shapes.h``, ``Sphere::Sample`` at a reference point) against sampling by area.

Closed form: a sphere of radius r and radiance L whose centre lies at distance d along a point's
normal fills the cone of half-angle asin(r / d), where it gives irradiance E = pi L (r / d)^2. Our
sphere is a mesh inscribed in it (256 segments: its faces lie within 1 - cos(pi / 128) = 3e-4 of
the sphere), so both strategies estimate that mesh's irradiance, a few 1e-4 below E.
"""

import math

import numpy as np
import pytest

from realistic.renderer.light_sampler import LightSampler
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import EmissiveInstance, sphere_in_world
from realistic.scene.model import Material, Scene
from realistic.scene.shapes import quad, sphere

N = 20000
RADIUS, DISTANCE, RADIANCE = 0.5, 1.5, 2.0


def _sphere_scene(cone: bool, transform: np.ndarray | None = None) -> Scene:
    scene = Scene()
    placement = np.eye(4) if transform is None else transform
    if transform is None:
        placement[:3, 3] = (0.0, 0.0, DISTANCE)
    scene.add(sphere(RADIUS), placement, Material((0.0, 0.0, 0.0)))
    scene.lights.append(EmissiveInstance(0, (RADIANCE,) * 3, sphere=sphere_in_world(placement, RADIUS)
                                         if cone else None))
    return scene


def _irradiance_samples(scene: Scene, seed: int = 0) -> np.ndarray:
    """E estimates L cos / pdf at the origin, normal +z, one light sample each (the sphere is convex:
    what a sample reaches on it is unoccluded)."""
    rng = np.random.default_rng(seed)
    sampler = LightSampler(scene, 1.0)
    u = rng.random((3, N))
    ls = sampler.sample(np.zeros((N, 3), np.float32), u[0], u[1], u[2], None)
    with np.errstate(divide="ignore", invalid="ignore"):
        values = np.where(ls.valid, ls.radiance[:, 0] * np.maximum(ls.wi[:, 2], 0.0) / ls.pdf, 0.0)
    return values.astype(np.float64)


@pytest.mark.parametrize("cone", [True, False])
def test_irradiance_from_a_sphere_is_the_closed_form_by_either_strategy(cone):
    values = _irradiance_samples(_sphere_scene(cone))
    expected = math.pi * RADIANCE * (RADIUS / DISTANCE) ** 2
    mean, error = values.mean(), values.std() / math.sqrt(N)
    assert abs(mean - expected) < 4 * error + 1e-3 * expected


def test_the_cone_strategy_is_far_less_noisy_than_sampling_by_area():
    cone, area = _irradiance_samples(_sphere_scene(True)), _irradiance_samples(_sphere_scene(False))
    assert cone.var() < 0.1 * area.var()


def test_a_scaled_and_rotated_sphere_keeps_its_world_centre_and_radius():
    angle = 0.7
    rotation = np.array([[math.cos(angle), -math.sin(angle), 0, 0], [math.sin(angle), math.cos(angle), 0, 0],
                         [0, 0, 1, 0], [0, 0, 0, 1]])
    transform = np.diag([2.0, 2.0, 2.0, 1.0]) @ rotation
    transform[:3, 3] = (0.0, 0.0, 3.0)
    assert sphere_in_world(transform, RADIUS) == ((0.0, 0.0, 3.0), pytest.approx(2 * RADIUS))
    assert sphere_in_world(np.diag([1.0, 2.0, 1.0, 1.0]), RADIUS) is None  # an ellipsoid: sampled by area
    values = _irradiance_samples(_sphere_scene(True, transform))
    expected = math.pi * RADIANCE * (2 * RADIUS / 3.0) ** 2
    assert abs(values.mean() - expected) < 4 * values.std() / math.sqrt(N) + 1e-3 * expected


def test_the_mis_density_of_a_direction_is_the_one_it_was_sampled_with():
    """pdf_instance (the MIS weight of a BSDF-sampled direction hitting the sphere) equals the cone
    density the light sample had, from outside; from inside the sphere both are the area density."""
    scene = _sphere_scene(True)
    sampler = LightSampler(scene, 1.0)
    intersector = Intersector(scene)
    rng = np.random.default_rng(3)
    for origin, inside in (((0.0, 0.0, 0.0), False), ((0.0, 0.0, DISTANCE + 0.1), True)):
        u = rng.random((3, 2000))
        point = np.tile(np.float32(origin), (2000, 1))
        ls = sampler.sample(point, u[0], u[1], u[2], None)
        rows = np.flatnonzero(ls.valid)
        hits = intersector.closest(point[rows], ls.wi[rows])
        assert np.all(hits.geom == 0)
        found = point[rows] + hits.t[:, None] * ls.wi[rows]
        assert np.allclose(found, ls.target[rows], atol=1e-4)
        density = sampler.pdf_instance(0, point[rows].astype(np.float64), found, hits.normal)
        assert np.allclose(density, ls.pdf[rows], rtol=1e-3)
        sin2 = RADIUS ** 2 / DISTANCE ** 2
        assert inside or np.allclose(ls.pdf[rows], 1 / (2 * math.pi * (1 - math.sqrt(1 - sin2))), rtol=1e-9)


@pytest.mark.parametrize("mis", [True, False])
def test_a_floor_under_a_sphere_light_reads_the_closed_form_with_and_without_mis(mis):
    """A Lambertian floor of albedo a at the foot of the sphere reflects a E / pi: with MIS the light
    and BSDF samples' weights must sum to one for that (the cone's density on both sides)."""
    albedo = 0.5
    scene = _sphere_scene(True)
    scene.add(quad(40.0, 40.0), np.eye(4), Material((albedo,) * 3))
    n = 40000
    origin = np.tile(np.float32([3.0, 0.0, 1.0]), (n, 1))
    direction = -origin / np.linalg.norm(origin, axis=1, keepdims=True)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 5, 0.0, 1, "path", mis=mis)
    radiance, _ = integrator.radiance(origin, direction.astype(np.float32), np.arange(n), np.zeros(n, int))
    values = radiance[:, 0].astype(np.float64)
    expected = albedo / math.pi * math.pi * RADIANCE * (RADIUS / DISTANCE) ** 2
    assert abs(values.mean() - expected) < 4 * values.std() / math.sqrt(n) + 2e-3 * expected
