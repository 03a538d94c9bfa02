"""Geometry shared between instances: embree's instances answer as the flat world-space build does.

A mesh placed several times is built once in its own space and placed by embree instances
(``realistic.scene.intersect``); ``Intersector(scene, share=False)`` copies every instance to world
space. Hits must agree to float32 rounding:
the same instance and triangle, t to 1e-5 relative, the same barycentrics and normal direction,
and renders to 1e-5 relative.
"""

import threading

import numpy as np
import pytest

import realistic as rl
import realistic.renderer.passes as passes
from realistic.core.transforms import rotate, scale, transform_points, translate
from realistic.scene import intersect
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, Material, Mesh, Scene
from realistic.scene.shapes import quad, sphere


def bumpy_ball(segments: int = 48) -> Mesh:
    """A non-convex closed mesh (rays can hit it twice), no vertex normals."""
    ball = sphere(0.5, segments)
    v = ball.vertices
    bumps = 1 + 0.15 * np.sin(7 * v[:, :1]) * np.cos(5 * v[:, 1:2])
    return Mesh(v * bumps, ball.faces, None, None, "bumpy")


#: Rotated, scaled non-uniformly, mirrored, overlapping boxes, one far off.
TRANSFORMS = [translate(0, 0.5, 0),
              translate(0.6, 0.5, 0.2) @ rotate(30, (1, 1, 0)) @ scale(1.5, 0.5, 1),
              translate(-1, 0.6, 0.3) @ scale(-1, 1, 1) @ rotate(70, (0, 1, 0)),
              translate(0.2, 1.2, -0.4) @ scale(0.3, 2, 0.7) @ rotate(-40, (0, 0, 1)),
              translate(2, 0.5, 1) @ scale(1, 1, -2),
              translate(-40, 3, 25) @ rotate(15, (0, 0, 1)) @ scale(3)]


def instanced_scene(floor: bool = True, light: bool = True, mesh: Mesh | None = None) -> Scene:
    scene = Scene()
    index = scene.add_mesh(mesh or bumpy_ball())
    if floor:
        scene.add(quad(10, 10), rotate(-90, (1, 0, 0)))
    for k, transform in enumerate(TRANSFORMS):
        scene.add(index, transform, Material((0.2 + 0.1 * k, 0.5, 0.7)))
    if light:
        scene.lights.append(AreaLight("disk", (1.0, 1.0), (5, 5, 5), translate(0, 4, 0) @ rotate(90, (1, 0, 0))))
    return scene


@pytest.fixture(autouse=True)
def share_small_meshes(monkeypatch):
    monkeypatch.setattr(intersect, "SHARE_MIN_FACES", 64)


def random_rays(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Origins in and around the instances (many inside a box), directions of varied lengths; a
    few rays start far away and look at the far instance or past everything."""
    rng = np.random.default_rng(seed)
    origin = rng.uniform(-3, 3, (n, 3))
    origin[:, 1] = rng.uniform(0.01, 3, n)
    direction = rng.normal(size=(n, 3)) * rng.uniform(0.1, 3, (n, 1))
    far = rng.random(n) < 0.05
    origin[far] = [0, 2, 0]
    direction[far] = [-40, 1, 25] + rng.normal(scale=4, size=(far.sum(), 3))
    direction[:5] = [[1, 0, 0], [0, 1, 0], [0, 0, -1], [0, -1e-3, 1], [0, 0, 0]]  # axis-parallel, null
    return origin.astype(np.float32), direction.astype(np.float32)


def assert_same_hits(flat, shared, origin, direction):
    """Same instance and triangle (or, at most 1 in 1000, the neighbour across an edge hit at the same
    t); t to 1e-5 relative, u, v (to 1e-3 of a triangle) and the normal's direction to float32
    rounding. The flat build rounds world coordinates to float32, so t is compared as what that
    rounding allows: 1e-6 of the coordinates along a grazing ray, and 1e-5 relative where the hit
    is neither grazing nor near."""
    assert np.array_equal(flat.geom, shared.geom)
    hit = flat.geom >= 0
    assert np.array_equal(flat.t[~hit], shared.t[~hit])
    differ = hit & (flat.prim != shared.prim)
    edge = lambda h: np.minimum(np.minimum(h.u, h.v), 1 - h.u - h.v)  # noqa: E731
    assert np.all(np.maximum(edge(flat), edge(shared))[differ] < 1e-3), "a different triangle off an edge"
    assert differ.sum() <= 1e-3 * hit.sum()
    same = hit & ~differ
    o, d, t, t2, n = origin[hit], direction[hit], flat.t[hit], shared.t[hit], flat.normal[hit]
    length = np.linalg.norm(d, axis=1)
    world = t * length
    cosine = np.abs(np.einsum("ij,ij->i", n, d)) / (np.linalg.norm(n, axis=1) * length)
    rounding = 1e-6 * (np.abs(o).max(axis=1) + world) / np.maximum(cosine, 1e-3)
    assert np.all(np.abs(t - t2) * length <= rounding + 1e-5 * world)
    plain = same[hit] & (world > 0.1) & (cosine > 0.1)
    assert plain.sum() > 0.5 * hit.sum()
    np.testing.assert_allclose(t2[plain], t[plain], rtol=1e-5)
    for name in ("u", "v"):
        np.testing.assert_allclose(getattr(shared, name)[hit][plain], getattr(flat, name)[hit][plain], atol=1e-3)
    unit = lambda v: v / np.linalg.norm(v, axis=1, keepdims=True)  # noqa: E731
    np.testing.assert_allclose(unit(shared.normal[same]), unit(flat.normal[same]), atol=1e-3)


@pytest.mark.parametrize("floor, light", [(True, True), (False, False)])
def test_closest_hits_agree_with_the_flat_build(floor, light):
    scene = instanced_scene(floor, light)
    flat, shared = Intersector(scene, share=False), Intersector(scene)
    assert flat.shared_instances == 0 and shared.shared_instances == len(TRANSFORMS)
    assert shared.extent == pytest.approx(flat.extent, rel=1e-12)
    origin, direction = random_rays(40000)
    a, b = flat.closest(origin, direction), shared.closest(origin, direction)
    assert 0.05 < np.mean(a.geom >= 0) < 0.9  # both hits and misses
    boxes = [transform_points(t, scene.meshes[0].vertices) for t in TRANSFORMS]
    starts_inside = [np.all((origin >= box.min(axis=0)) & (origin <= box.max(axis=0)), axis=1) for box in boxes]
    assert np.sum(np.any(starts_inside, axis=0)) > 1000
    assert np.sum(a.geom == len(TRANSFORMS) - 1 + floor) > 100  # the far instance
    assert_same_hits(a, b, origin, direction)


def test_instanced_normals_are_the_cofactor_products_in_float32():
    """``closest`` names an instanced hit by its instance and takes embree's object-space normal to
    the world by the instance's cofactor matrix, in float32, summed in order (the numpy formula
    below); hits outside instances keep embree's geometry id and normal."""
    shared = Intersector(instanced_scene())
    origin, direction = random_rays(40000, seed=4)
    raw = shared._embree.intersect(origin, direction, float(intersect._MISS_T))
    hits = shared.closest(origin, direction)
    inside = raw.instance >= 0
    assert 1000 < inside.sum() < len(origin) - 1000
    m = shared._normal_to_world_t[raw.instance[inside]]
    n = raw.normal[inside]
    expected = (n[:, 0, None] * m[:, 0] + n[:, 1, None] * m[:, 1]) + n[:, 2, None] * m[:, 2]
    assert np.array_equal(hits.normal[inside], expected) and np.array_equal(hits.geom[inside], raw.instance[inside])
    assert np.array_equal(hits.normal[~inside], raw.normal[~inside])
    assert np.array_equal(hits.geom[~inside], raw.geom[~inside])


def test_occlusion_agrees_with_the_flat_build():
    scene = instanced_scene()
    flat, shared = Intersector(scene, share=False), Intersector(scene)
    origin, direction = random_rays(40000, seed=2)
    distance = np.random.default_rng(3).uniform(-0.2, 1.5, len(origin)).astype(np.float32)
    a, b = flat.occluded(origin, direction, distance), shared.occluded(origin, direction, distance)
    assert 0.2 < a.mean() < 0.8
    # a hit within float32 rounding of the distance may go either way
    hits = flat.closest(origin, direction)
    marginal = np.abs(hits.t - distance) <= 1e-5 * np.maximum(hits.t, 1e-3)
    assert np.array_equal(a[~marginal], b[~marginal])
    assert np.array_equal(a[distance < 0], b[distance < 0])  # embreex answered True there; so do both builds
    empty = Intersector(instanced_scene(False, False))
    assert np.array_equal(empty.occluded(origin, direction, distance),
                          Intersector(instanced_scene(False, False), share=False).occluded(origin, direction, distance))


def test_small_or_single_meshes_stay_in_the_flat_scene(monkeypatch):
    monkeypatch.setattr(intersect, "SHARE_MIN_FACES", 10 ** 9)
    assert Intersector(instanced_scene()).shared_instances == 0
    monkeypatch.setattr(intersect, "SHARE_MIN_FACES", 64)
    single = Scene()
    single.add(bumpy_ball())
    single.add(bumpy_ball(), translate(2, 0, 0))  # two meshes with the same data, one instance each
    assert Intersector(single).shared_instances == 0
    flattened = instanced_scene()
    flattened.add(0, scale(1, 1, 1e-9))  # singular: searched in world space
    assert Intersector(flattened).shared_instances == len(TRANSFORMS)


def test_threads_trace_one_intersector_at_once():
    scene = instanced_scene()
    shared = Intersector(scene)
    origin, direction = random_rays(20000, seed=4)
    expected = shared.closest(origin, direction)
    results = [None] * 4

    def trace(i):
        results[i] = shared.closest(origin, direction)

    threads = [threading.Thread(target=trace, args=(i,)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for result in results:
        assert np.array_equal(result.geom, expected.geom) and np.array_equal(result.t, expected.t)


def test_a_render_through_the_shared_build_matches_the_flat_one(monkeypatch):
    scene = instanced_scene(mesh=sphere(0.5, 32))  # smooth normals: an edge hit shades as its neighbour
    assert Intersector(scene).shared_instances == len(TRANSFORMS)
    camera = rl.LensCamera.looking_at(rl.load_lens("dgauss"), (0.5, 2.5, 6), (0.3, 0.6, 0), width=40, height=30,
                                      spp=4)
    shared = rl.render(scene, camera, "numpy")
    monkeypatch.setattr(passes, "Intersector", lambda s: Intersector(s, share=False))
    flat = rl.render(scene, camera, "numpy")
    assert shared.mean() > 0
    np.testing.assert_allclose(shared, flat, rtol=1e-5, atol=1e-5 * float(flat.max()))
