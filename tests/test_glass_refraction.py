"""Glass in the path integrator against closed forms: where refracted rays go and how much light a
lossless dielectric lets through (smooth: all of it; pbrt-v4's single-scattering rough glass: at
most all of it).

Rays are followed bounce by bounce through ``PathIntegrator._shade`` (the integrator's own
next-bounce step), with the glass's Kr or Kt set to 0 so that only transmitted (or only reflected)
paths survive. Expected values come from Snell's law on the true geometry: a slab shifts a ray
sideways by t sin(i - r) / cos r and leaves it parallel to itself; a ball of index n focuses a ray
at height h at h / sin(2 (i - r)) from its centre (paraxial limit n D / (4 (n - 1))); a ray inside
glass beyond the critical angle asin(1 / n) is reflected whole.
"""

import numpy as np
import pytest

from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import InfiniteLight
from realistic.scene.materials import Dielectric
from realistic.scene.model import Mesh, Scene
from realistic.scene.shapes import sphere

ETA = 1.5
THICKNESS = 0.7


def _slab(material: Dielectric) -> Scene:
    """Two faces of a glass slab between z = -THICKNESS and z = 0, each wound to face out (no vertex normals)."""
    big = 3.0
    top = [(-big, -big, 0.0), (big, -big, 0.0), (big, big, 0.0), (-big, big, 0.0)]
    bottom = [(x, y, -THICKNESS) for x, y, _ in top]
    faces = [(0, 1, 2), (0, 2, 3), (4, 6, 5), (4, 7, 6)]
    scene = Scene()
    scene.add(Mesh(np.array(top + bottom, float), np.array(faces), None, None, "slab"), np.eye(4), material)
    return scene


def _follow(scene: Scene, origin: np.ndarray, direction: np.ndarray, bounces: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origins and directions of the rays after ``bounces`` surface interactions, and which rays survived."""
    integrator = PathIntegrator(scene, Intersector(scene), 1, 0, 0.0, 10, "path")
    n = len(origin)
    o, d = np.asarray(origin, np.float32), np.asarray(direction, np.float32)
    path, beta = np.arange(n), np.ones((n, 3), np.float32)
    pixel, sample = np.arange(n), np.zeros(n, np.int64)
    for depth in range(bounces):
        hits = integrator.intersector.closest(o, d)
        surface = np.flatnonzero(hits.geom >= 0)
        state = integrator._shade(hits, surface, path, o, d, beta, None, pixel, sample, depth)
        path, o, d, beta = state["path"], state["origin"], state["direction"], state["beta"]
    alive = np.zeros(n, bool)
    alive[path] = True
    out_o, out_d = np.zeros((n, 3)), np.zeros((n, 3))
    out_o[path], out_d[path] = o, d
    return out_o, out_d, alive


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.mark.parametrize("degrees", [10.0, 35.0, 60.0])
def test_slab_transmits_parallel_to_the_incident_ray_shifted_by_the_closed_form(degrees):
    i = np.radians(degrees)
    r = np.arcsin(np.sin(i) / ETA)
    n = 256
    origin = np.tile([-np.tan(i), 0.0, 1.0], (n, 1)) + np.column_stack([np.zeros(n), np.linspace(-0.5, 0.5, n),
                                                                        np.zeros(n)])
    direction = np.tile([np.sin(i), 0.0, -np.cos(i)], (n, 1))
    o, d, alive = _follow(_slab(Dielectric(ETA, (0.0, 0.0, 0.0))), origin, direction, 2)
    assert alive.sum() > n // 2  # about 1 - F of them twice
    np.testing.assert_allclose(d[alive], direction[alive], atol=2e-5)
    offset = o[alive] - origin[alive]
    shift = np.linalg.norm(offset - np.sum(offset * direction[alive], axis=1, keepdims=True) * direction[alive],
                           axis=1)
    # each new ray starts SHADOW_OFFSET (1 + extent / 100) off its surface, about 1e-4 here, twice
    np.testing.assert_allclose(shift, THICKNESS * np.sin(i - r) / np.cos(r), atol=4e-4)


def test_ray_inside_glass_beyond_the_critical_angle_is_reflected():
    """60 degrees from the normal inside n = 1.5 (critical angle 41.8 degrees): every ray reflects,
    whatever the lobe choice, and keeps all its throughput."""
    i = np.radians(60.0)
    n = 256
    origin = np.tile([0.0, 0.0, -THICKNESS / 2], (n, 1)) + np.column_stack([np.zeros(n), np.linspace(-1, 1, n),
                                                                           np.zeros(n)])
    direction = np.tile([np.sin(i), 0.0, np.cos(i)], (n, 1))
    o, d, alive = _follow(_slab(Dielectric(ETA, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))), origin, direction, 1)
    assert alive.all()
    np.testing.assert_allclose(d, np.tile([np.sin(i), 0.0, -np.cos(i)], (n, 1)), atol=2e-6)
    assert np.all(o[:, 2] < 0)  # still inside the slab


def _ball_focus(h: np.ndarray, n: float, radius: float) -> np.ndarray:
    """Distance from a glass ball's centre at which a ray parallel to the axis at height h crosses it."""
    i = np.arcsin(h / radius)
    r = np.arcsin(np.sin(i) / n)
    return h / np.sin(2 * (i - r))


def test_ball_lens_focuses_behind_itself_at_the_closed_form_distance():
    """Rays along -y at heights h from the y axis (kept off the tessellation's poles and seam) cross
    the axis behind the ball where Snell's law on a sphere puts them; the paraxial rays at n D / (4 (n - 1))."""
    radius = 1.0
    scene = Scene()
    scene.add(sphere(radius, 1024), np.eye(4), Dielectric(ETA, (0.0, 0.0, 0.0)))
    h = np.concatenate([np.linspace(0.01, 0.05, 16), np.linspace(0.2, 0.5, 16)])
    side = _unit(np.tile([1.0, 0.0, 0.3], (len(h), 1)))
    origin = h[:, None] * side + np.array([0.0, 5.0, 0.0])
    direction = np.tile([0.0, -1.0, 0.0], (len(h), 1))
    o, d, alive = _follow(scene, origin, direction, 2)
    assert alive.sum() > len(h) // 2
    o, d, side, h = o[alive], d[alive], side[alive], h[alive]
    # where the exit ray meets the y axis: its height along ``side`` falls to zero
    height, slope = np.sum(o * side, axis=1), np.sum(d * side, axis=1)
    assert np.all(d[:, 1] < 0) and np.all(height > 0) and np.all(slope < 0)  # toward the axis: an inverted image
    crossing = o - (height / slope)[:, None] * d
    np.testing.assert_allclose(-crossing[:, 1], _ball_focus(h, ETA, radius), rtol=2e-3)
    paraxial = ETA * 2 * radius / (4 * (ETA - 1))
    np.testing.assert_allclose(-crossing[h < 0.06, 1], paraxial, rtol=2e-3)


def _furnace(material: Dielectric, origin: np.ndarray, direction: np.ndarray, seed: int = 3) -> tuple[float, float]:
    scene = Scene()
    scene.add(sphere(1.0, 96), np.eye(4), material)
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0)))
    n = len(origin)
    integrator = PathIntegrator(scene, Intersector(scene), 1, seed, 0.0, 60, "path")
    radiance, _ = integrator.radiance(origin.astype(np.float32), direction.astype(np.float32), np.arange(n),
                                      np.zeros(n, np.int64))
    value = radiance[:, 0].astype(np.float64)
    return float(value.mean()), float(value.std() / np.sqrt(n))


N = 20000


def _outside_rays(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    origin = np.tile([0.0, 0.0, 5.0], (n, 1))
    return origin, _unit(rng.uniform(-0.9, 0.9, (n, 3)) - origin)


def _inside_rays(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays from points within R / n of the centre (never beyond the critical angle: none are trapped)."""
    rng = np.random.default_rng(1)
    origin = _unit(rng.normal(size=(n, 3))) * (rng.uniform(0, 1, (n, 1)) ** (1 / 3) * 0.6)
    return origin, _unit(rng.normal(size=(n, 3)))


@pytest.mark.parametrize("where", ["outside", "inside"])
def test_smooth_glass_sphere_in_a_white_furnace_reads_one(where):
    origin, direction = (_outside_rays if where == "outside" else _inside_rays)(N)
    mean, error = _furnace(Dielectric(ETA), origin, direction)
    assert abs(mean - 1.0) < 4 * error + 2e-3


@pytest.mark.parametrize("where", ["outside", "inside"])
@pytest.mark.parametrize("alpha", [0.01, 0.05, 0.3])
def test_rough_glass_sphere_in_a_white_furnace_gains_nothing_and_tends_to_one(where, alpha):
    """pbrt-v4's rough dielectric is single-scattering: each bounce keeps G / G1 <= 1 of the light
    (what would scatter again among the microfacets is lost), so the furnace reads at most 1, and
    1 in the smooth limit (within 1 % at alpha 0.01)."""
    origin, direction = (_outside_rays if where == "outside" else _inside_rays)(N)
    mean, error = _furnace(Dielectric(ETA, roughness_u=alpha, roughness_v=alpha), origin, direction)
    assert mean < 1.0 + 4 * error
    if alpha <= 0.01:
        assert mean > 0.99 - 4 * error
