"""Furnace tests of the path and MIS direct-lighting integrators against closed forms.

A convex Lambertian object of albedo a under a constant environment of radiance 1 reflects exactly
a (it never sees itself, and the whole sphere of directions brings radiance 1). A camera inside a
closed Lambertian sphere of albedo a whose inner surface emits radiance 1 sees L = 1 + a L, so
1 / (1 - a); a path of at most d bounces sees the partial sum of that series to a^d.
"""

import numpy as np
import pytest

from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.spectrum import rgb_response
from realistic.core.transforms import translate
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import EmissiveInstance, InfiniteLight
from realistic.scene.model import Material, Scene
from realistic.scene.shapes import sphere

N = 40000


def _mean_and_error(values: np.ndarray) -> tuple[float, float]:
    return float(values.mean()), float(values.std() / np.sqrt(len(values)))


def _rays_at_sphere(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    origin = np.tile([0.0, 0.0, 5.0], (n, 1)).astype(np.float32)
    target = rng.uniform(-0.5, 0.5, (n, 3))
    direction = target - origin
    return origin, (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)


def _convex_scene(a: float) -> Scene:
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material((a, a, a)))
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0)))
    return scene


@pytest.mark.parametrize("mode", ["direct", "path"])
@pytest.mark.parametrize("spectral", [False, True])
def test_convex_object_in_a_white_furnace_reads_its_albedo(mode, spectral):
    a = 0.7
    scene = _convex_scene(a)
    origin, direction = _rays_at_sphere(N)
    wavelength = np.random.default_rng(1).uniform(400, 700, N) if spectral else None
    integrator = PathIntegrator(scene, Intersector(scene), 1, 3, 0.0, 5, mode)
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int), None, wavelength)
    value = radiance[:, 0]
    if spectral:  # radiance times the film's weight: the spectral value is their quotient (the largest weight's)
        response = rgb_response(wavelength)
        column = np.abs(response).argmax(axis=1)
        value = radiance[np.arange(N), column] / response[np.arange(N), column]
    mean, error = _mean_and_error(value)
    assert abs(mean - a) < 4 * error + 1e-3


def test_white_furnace_through_a_thin_lens_camera():
    """Every pixel of a thin-lens render reads a where it sees the sphere and 1 where it sees the sky."""
    a = 0.4
    camera = ThinLensCamera(40.0, 0.05, 5.0, 16, 16, 64, translate(0, 0, -5.0))
    scene = _convex_scene(a)
    scene.integrator = "path"
    image = render(RenderJob(scene, (camera,), "numpy", seed=5), ThreadPasses(threads=1))[0].image[..., 0]
    centre, corner = image[6:10, 6:10], image[0, 0]
    assert abs(centre.mean() - a) < 0.02 and abs(corner - 1.0) < 1e-4


def _inside_sphere(a: float) -> Scene:
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material((a, a, a)))
    scene.lights.append(EmissiveInstance(0, (1.0, 1.0, 1.0), two_sided=True))
    return scene


@pytest.mark.parametrize("depth", [0, 1, 2, 3])
def test_closed_emitting_sphere_partial_sums(depth):
    a = 0.5
    scene = _inside_sphere(a)
    rng = np.random.default_rng(2)
    direction = rng.normal(size=(N, 3))
    direction = (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)
    origin = np.zeros((N, 3), np.float32)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 4, 0.0, depth, "path")
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    mean, error = _mean_and_error(radiance[:, 0])
    assert abs(mean - sum(a ** k for k in range(depth + 1))) < 4 * error + 2e-3


def test_closed_emitting_sphere_converges_to_the_series():
    a = 0.6
    scene = _inside_sphere(a)
    rng = np.random.default_rng(3)
    direction = rng.normal(size=(N, 3))
    direction = (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(np.float32)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 5, 0.0, 200, "path")
    radiance, _ = integrator.radiance(np.zeros((N, 3), np.float32), direction, np.arange(N), np.zeros(N, int))
    mean, error = _mean_and_error(radiance[:, 0])
    assert abs(mean - 1 / (1 - a)) < 4 * error + 5e-3


@pytest.mark.parametrize("mapping,shape", [("latlong", (16, 32, 3)), ("equal-area", (16, 16, 3))])
def test_white_furnace_through_an_environment_map(mapping, shape):
    """A map of ones samples by its (sin-weighted) texel distribution and still reads the albedo."""
    a = 0.5
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material((a, a, a)))
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0), np.ones(shape, np.float32), mapping))
    origin, direction = _rays_at_sphere(N)
    integrator = PathIntegrator(scene, Intersector(scene), 1, 8, 0.0, 3, "path")
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
    mean, error = _mean_and_error(radiance[:, 0])
    assert abs(mean - a) < 4 * error + 2e-3


@pytest.mark.parametrize("mapping", ["latlong", "equal-area"])
def test_environment_map_mis_agrees_with_light_sampling_alone(mapping):
    """Under a map with a bright sun, MIS and light sampling alone estimate the same direct light."""
    rng = np.random.default_rng(11)
    image = (0.2 + rng.random((16, 16 if mapping == "equal-area" else 32, 3))).astype(np.float32)
    image[2:4, 3:5] = 40.0
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material((0.8, 0.8, 0.8)))
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0), image, mapping))
    origin, direction = _rays_at_sphere(N)
    means = []
    for mis in (True, False):
        integrator = PathIntegrator(scene, Intersector(scene), 1, 9, 0.0, 1, "direct", mis=mis)
        radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int))
        means.append(_mean_and_error(radiance[:, 0]))
    (m1, e1), (m2, e2) = means
    assert abs(m1 - m2) < 4 * np.hypot(e1, e2)
