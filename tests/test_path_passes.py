"""Path-traced renders do not depend on how samples are cut into passes or threads: every bounce and
light sample draws fixed dimensions of the counter-based generator."""

import math

import numpy as np

from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.transforms import rotate, translate
from realistic.renderer.job import RenderJob
from realistic.renderer.light_sampler import LightSampler
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.path import _add_rows
from realistic.scene.lights import DistantLight, InfiniteLight, PointLight, SpotLight
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad, sphere


def _scene() -> Scene:
    scene = Scene(integrator="path", max_depth=4)
    scene.add(quad(10.0, 10.0), np.eye(4), Material((0.7, 0.6, 0.5)))
    scene.add(sphere(0.5, 32), translate(0, 0, 0.5), Material((0.9, 0.9, 0.9)))
    scene.lights.append(AreaLight("disk", (0.3, 0.3), (20.0, 20.0, 20.0), translate(0, 0, 3) @ rotate(180, (1, 0, 0))))
    scene.lights.append(InfiniteLight((0.2, 0.3, 0.4)))
    return scene


def test_path_tracing_is_independent_of_pass_size_and_threads():
    camera = ThinLensCamera(50.0, 0.0, 1.0, 12, 10, 3, translate(0, -4, 1.5) @ rotate(-80, (1, 0, 0)))
    a = render(RenderJob(_scene(), (camera,), "numpy", seed=2, pass_samples=37), ThreadPasses(threads=2))[0].image
    b = render(RenderJob(_scene(), (camera,), "numpy", seed=2, pass_samples=1000), ThreadPasses(threads=1))[0].image
    np.testing.assert_array_equal(a, b)
    assert a.min() > 0  # every pixel sees the sky or a lit surface


def test_lights_are_picked_in_proportion_to_their_power():
    """pbrt-v3's powers: point 4 pi I, spot 2 pi I (1 - (cos_start + cos_total) / 2), distant and
    infinite pi r^2 L over the scene's bounding sphere of radius r, area pi A L."""
    scene = Scene()
    spot_frame = np.eye(4)
    lights = [PointLight((2.0, 2.0, 2.0), np.zeros(3)),
              SpotLight((3.0, 3.0, 3.0), spot_frame, math.cos(0.5), math.cos(0.3)),
              DistantLight((1.0, 1.0, 1.0), np.array([0.0, 0.0, 1.0])),
              InfiniteLight((0.5, 0.5, 0.5)),
              AreaLight("quad", (2.0, 3.0), (4.0, 4.0, 4.0))]
    scene.lights.extend(lights)
    extent = 2.0
    radius = extent * math.sqrt(3) / 2
    power = np.array([4 * math.pi * 2, 2 * math.pi * 3 * (1 - (math.cos(0.3) + math.cos(0.5)) / 2),
                      math.pi * radius ** 2, math.pi * radius ** 2 * 0.5, math.pi * 6.0 * 4.0])
    np.testing.assert_allclose(LightSampler(scene, extent).probability, power / power.sum())


def test_adding_rows_matches_fancy_indexing():
    """``path._add_rows`` (the bounce's scatter of contributions) adds exactly as out[rows] += value
    does for distinct rows, RGB and spectral (one channel)."""
    generator = np.random.default_rng(5)
    for channels in (3, 1):
        out = generator.random((50, channels), dtype=np.float32)
        rows = generator.permutation(50)[:20].astype(np.int32)
        value = generator.random((20, channels), dtype=np.float32)
        expected = out.copy()
        expected[rows] += value
        _add_rows(out, rows, value)
        assert np.array_equal(out, expected)
