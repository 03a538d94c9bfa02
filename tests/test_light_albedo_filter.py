"""The albedo of an image-textured material on an area light, seen through ``DirectLighting``
(``_light_albedo``, the light's own tessellation), filters the image over each camera ray's pixel
footprint as ``PathIntegrator`` does (the light in its per-geometry tables), where it had read the
image's finest level at the hit's uv whatever the footprint.
"""

import numpy as np
import pytest

from realistic.core.transforms import translate
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Plastic
from realistic.scene.model import AreaLight, ImageTexture, Material, Scene

N = 400
DIFFUSE = np.array([0.8, 0.6, 0.4])
#: A 64 x 64 checker of one-texel cells, 0 and 1: every level of its MIP map past the finest is 0.5
#: everywhere (each texel of level 1 averages one 2 x 2 block: two of each).
CHECKER = np.repeat((np.indices((64, 64)).sum(axis=0) % 2).astype(np.float32)[:, :, None], 3, axis=2)


def _scene(material: Material | Plastic, mirrored: bool = False) -> Scene:
    """A 2 x 2 quad light (uv over [0, 1]^2, so a texel of a 64-texel image is 2/64 wide) at z = 5,
    emitting toward the origin and reflecting by ``material``; ``mirrored``: reflected in x and with
    its orientation reversed, so that its uv and outside come from its transform."""
    facing = translate(0, 0, 5.0) @ np.diag([-1.0 if mirrored else 1.0, 1.0, -1.0, 1.0])
    return Scene(lights=[AreaLight("quad", (2.0, 2.0), (1.0, 1.0, 1.0), facing, reverse_orientation=mirrored,
                                   material=material)])


def _rays(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """N camera rays from the origin, each meeting the quad."""
    rng = np.random.default_rng(seed)
    direction = np.column_stack([rng.uniform(-0.18, 0.18, (N, 2)), np.ones(N)])
    return np.zeros((N, 3), np.float32), (direction / np.linalg.norm(direction, axis=1, keepdims=True)).astype(
        np.float32)


def _albedo(integrator_type: type[DirectLighting], scene: Scene, spread: float, seed: int = 1) -> np.ndarray:
    """The albedo (N, 3) ``integrator_type`` (path: one bounce) gives ``_rays`` on ``scene`` for a
    camera whose pixels subtend ``spread`` radians."""
    origin, direction = _rays(seed)
    hits = Intersector(scene).closest(origin, direction)
    assert np.all(hits.geom == 0)  # all on the light (geometry 0: the scene has no instance)
    args = (scene, Intersector(scene), 1, 0, spread) + ((1,) if integrator_type is PathIntegrator else ())
    return integrator_type(*args).first_hits(origin, direction, hits).albedo.astype(np.float64)


@pytest.mark.parametrize("texture_filter", ["ewa", "trilinear", "point"])
def test_a_wide_footprint_on_a_light_reads_the_checkers_mean(texture_filter):
    """A footprint of about 8 texels (5 units away, pixels of 0.05 radians) picks a level of the
    checker's MIP map past the finest, so the Lambertian light's albedo is DIFFUSE / 2 at every hit,
    for each filter that reads coarser levels; the finest level alone (no footprint) reads anything
    from 0 to DIFFUSE between the cells."""
    scene = _scene(Material(tuple(DIFFUSE), ImageTexture(CHECKER, filter=texture_filter)))
    np.testing.assert_allclose(_albedo(DirectLighting, scene, 0.05), np.tile(DIFFUSE / 2, (N, 1)), rtol=1e-6)
    point_sampled = _albedo(DirectLighting, scene, 0.0)
    assert point_sampled[:, 0].min() < 0.2 * DIFFUSE[0] and point_sampled[:, 0].max() > 0.8 * DIFFUSE[0]


@pytest.mark.parametrize("mirrored", [False, True])
@pytest.mark.parametrize("spread", [0.002, 0.01])
def test_an_image_textured_light_filters_as_through_the_path_integrator(spread, mirrored):
    """A plastic light whose Kd is a random image: its albedo through ``DirectLighting`` is the one
    ``PathIntegrator`` gives at one bounce, for footprints of under a texel to a few (levels blended)."""
    pixels = np.random.default_rng(7).random((64, 64, 3)).astype(np.float32)
    scene = _scene(Plastic(ImageTexture(pixels, scale=(2.0, 3.0)), (0.3, 0.3, 0.3), 0.2), mirrored)
    fast, path = _albedo(DirectLighting, scene, spread), _albedo(PathIntegrator, scene, spread)
    np.testing.assert_allclose(fast, path, rtol=1e-5, atol=1e-6)
    assert np.abs(fast - _albedo(DirectLighting, scene, 0.0)).max() > 1e-2  # the footprint matters here
