"""The ctypes binding of embree 4 (``realistic.scene.embree``) and its packet loops, against an
independent ray-triangle intersection.

The reference is Moller and Trumbore's (1997) closed form in float64 numpy, over every triangle
of the scene placed in world space. Random rays at random triangle soups, as flat meshes and as
instances under random affine maps, in batches of every size around the 16-ray packet, must get the
reference's closest hit (triangle, instance, t, barycentrics, normal); rays whose answer float32
rounding could change (a hit within 1e-4 of a triangle's edge, two hits as near in t) are left
out. The start-up check is exercised on the real library (it passes) and on fakes of it (another
version; a packet written past the assumed rows or without instance-primitive ids), which it refuses.
"""

from __future__ import annotations

import ctypes
import dataclasses
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import run_fresh
from lane_helpers import in_lanes
from realistic.errors import UserError
from realistic.scene import embree, packet_loop
from realistic.scene.embree import EmbreeScene
from realistic.scene.packet_loop import INST_PRIM, PACKET, ROWS, lane_rows, shadow_lanes

BATCHES = [0, 1, PACKET - 1, PACKET, PACKET + 1, 1000]
EDGE = 1e-4  # barycentric and relative-t margins of the rays left out as float32-ambiguous
GRAZING = 0.1  # rays hitting a triangle at a cosine below this are left out too (ill-conditioned barycentrics)


def soup(seed: int, count: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random triangles in [-1, 1]^3 (vertices (3 count, 3), faces (count, 3)); they may cross."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (3 * count, 3)).astype(np.float32), np.arange(3 * count).reshape(count, 3)


def affine(seed: int) -> np.ndarray:
    """A random 4x4 affine map: a well-conditioned linear part (shear and scale) and a shift."""
    rng = np.random.default_rng(seed)
    matrix = np.eye(4)
    matrix[:3, :3] = np.eye(3) * rng.uniform(0.5, 2, 3) + rng.uniform(-0.4, 0.4, (3, 3))
    matrix[:3, 3] = rng.uniform(-3, 3, 3)
    return matrix


@dataclasses.dataclass
class World:
    """A scene as the reference sees it: every triangle in world space, with the ids embree should
    report for it and its normal in its mesh's own space (embree's unnormalised Ng)."""

    triangles: np.ndarray  # (T, 3, 3) float64
    prim: np.ndarray
    geom: np.ndarray
    instance: np.ndarray
    normal: np.ndarray  # (T, 3)

    def add(self, vertices: np.ndarray, faces: np.ndarray, geom: int, instance: int, transform: np.ndarray) -> World:
        local = vertices.astype(np.float64)[faces]
        world = local @ transform[:3, :3].T + transform[:3, 3]
        normal = np.cross(local[:, 1] - local[:, 0], local[:, 2] - local[:, 0])
        count = len(faces)
        return World(np.concatenate([self.triangles, world]), np.concatenate([self.prim, np.arange(count)]),
                     np.concatenate([self.geom, np.full(count, geom)]),
                     np.concatenate([self.instance, np.full(count, instance)]), np.concatenate([self.normal, normal]))


EMPTY = World(np.zeros((0, 3, 3)), np.zeros(0, int), np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)))


def moller_trumbore(world: World, origin: np.ndarray, direction: np.ndarray,
                    tfar: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every ray against every triangle: (t, u, v) of each pair (inf where the ray misses, or hits
    outside [0, tfar]), the closest triangle of each ray (-1 for none), and which rays are
    ambiguous in float32 (a hit or a near miss within EDGE of an edge, a hit within EDGE of tfar,
    two hits within EDGE in t, or a grazing hit)."""
    o, d = origin.astype(np.float64)[:, None], direction.astype(np.float64)[:, None]
    v0, e1, e2 = (world.triangles[None, :, 0], world.triangles[None, :, 1] - world.triangles[None, :, 0],
                  world.triangles[None, :, 2] - world.triangles[None, :, 0])
    p = np.cross(d, e2)
    det = np.sum(e1 * p, axis=-1)
    cosine = np.abs(det) / (np.linalg.norm(d, axis=-1) * np.linalg.norm(np.cross(e1, e2), axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1 / det
        s = o - v0
        u = np.sum(s * p, axis=-1) * inv
        q = np.cross(s, e1)
        v = np.sum(d * q, axis=-1) * inv
        t = np.sum(e2 * q, axis=-1) * inv
    margin = np.minimum(np.minimum(u, v), 1 - u - v)
    in_range = (t >= 0) & (t <= tfar) & np.isfinite(t)
    t_hit = np.where(in_range & (margin > 0), t, np.inf)
    order = np.argsort(t_hit, axis=1)
    count = len(origin)
    closest = order[:, 0] if world.triangles.size else np.zeros(count, int)
    first = t_hit[np.arange(count), closest] if world.triangles.size else np.full(count, np.inf)
    closest = np.where(np.isfinite(first), closest, -1)
    ambiguous = np.any(in_range & (np.abs(margin) < EDGE), axis=1)
    ambiguous |= np.any(np.isfinite(t_hit) & (cosine < GRAZING), axis=1)
    ambiguous |= np.any((margin > 0) & (np.abs(t - tfar) < EDGE * tfar), axis=1)
    if world.triangles.shape[0] > 1:
        second = t_hit[np.arange(count), order[:, 1]]
        with np.errstate(invalid="ignore"):  # inf - inf where neither is hit
            ambiguous |= np.isfinite(first) & (second - first < EDGE * np.maximum(first, 1))
    return t_hit, u, v, closest, ambiguous


def random_rays(world: World, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays from around the scene, every other one aimed at a random point of a random triangle
    (it hits that one or a nearer one), the rest at random points in and near the scene (most
    miss); directions of varied length."""
    rng = np.random.default_rng(seed)
    origin = rng.uniform(-6, 6, (count, 3))
    target = rng.uniform(-4, 4, (count, 3))
    weights = rng.dirichlet(np.ones(3), count)
    on_triangle = np.einsum("nk,nkj->nj", weights, world.triangles[rng.integers(len(world.triangles), size=count)])
    target[::2] = on_triangle[::2]
    direction = (target - origin) * rng.uniform(0.2, 3, (count, 1))
    return origin.astype(np.float32), direction.astype(np.float32)


def assert_closest_hits(scene: EmbreeScene, world: World, count: int, seed: int, tfar: float = 1e37,
                        coherent: bool = False) -> None:
    origin, direction = random_rays(world, count, seed)
    hits = scene.intersect(origin, direction, tfar, coherent)
    t_all, u_all, v_all, closest, ambiguous = moller_trumbore(world, origin, direction, tfar)
    clear = ~ambiguous
    hit = clear & (closest >= 0)
    miss = clear & (closest < 0)
    assert len(hits.t) == count and hits.normal.shape == (count, 3)
    assert np.all(hits.geom[miss] == -1) and np.all(hits.prim[miss] == -1) and np.all(hits.instance[miss] == -1)
    # a miss's Ng, u and v are 0 (embree writes none: a lane that hit in an earlier packet leaves nothing)
    assert not (hits.u[miss].any() or hits.v[miss].any() or hits.normal[miss].any())
    np.testing.assert_array_equal(hits.t[miss], np.float32(tfar))
    rows, tri = np.flatnonzero(hit), closest[hit]
    np.testing.assert_array_equal(hits.geom[rows], world.geom[tri])
    np.testing.assert_array_equal(hits.prim[rows], world.prim[tri])
    np.testing.assert_array_equal(hits.instance[rows], world.instance[tri])
    np.testing.assert_allclose(hits.t[rows], t_all[rows, tri], rtol=2e-5)
    np.testing.assert_allclose(hits.u[rows], u_all[rows, tri], atol=5e-5)
    np.testing.assert_allclose(hits.v[rows], v_all[rows, tri], atol=5e-5)
    np.testing.assert_allclose(hits.normal[rows], world.normal[tri], rtol=1e-4, atol=1e-5)
    if count >= 100:  # the sample is a real test: most rays are decided, many of them hits
        assert clear.mean() > 0.9 and hit.sum() > count / 10 and miss.sum() > count / 10


def flat_scene(seed: int) -> tuple[EmbreeScene, World]:
    vertices, faces = soup(seed)
    scene = EmbreeScene()
    scene.add_triangles(vertices, faces, 7)
    scene.commit()
    return scene, EMPTY.add(vertices, faces, 7, -1, np.eye(4))


def instanced_scene(seed: int) -> tuple[EmbreeScene, World]:
    """Two meshes, each placed by two instances under random affine maps, and a mesh in world space."""
    top, world = EmbreeScene(), EMPTY
    for mesh in range(2):
        vertices, faces = soup(seed + mesh, count=12)
        inner = EmbreeScene()
        inner.add_triangles(vertices, faces, mesh)
        inner.commit()
        for copy in range(2):
            transform = affine(seed + 10 * mesh + copy)
            top.add_instance(inner, transform, 20 + 2 * mesh + copy)
            world = world.add(vertices, faces, mesh, 20 + 2 * mesh + copy, transform)
    vertices, faces = soup(seed + 5, count=10)
    top.add_triangles(vertices * 2, faces, 3)
    top.commit()
    return top, world.add(vertices * 2, faces, 3, -1, np.eye(4))


# ``coherent``: embree's traversal for coherent rays (camera rays) must find the same closest hits,
# whether or not a packet's rays are in fact coherent (these are scattered)
@pytest.mark.parametrize("coherent", [False, True])
@pytest.mark.parametrize("count", BATCHES)
def test_closest_hits_are_the_closed_form_ones_in_batches_of_any_size(count: int, coherent: bool) -> None:
    scene, world = flat_scene(1)
    assert_closest_hits(scene, world, count, seed=count, coherent=coherent)


@pytest.mark.parametrize("coherent", [False, True])
@pytest.mark.parametrize("count", BATCHES)
def test_instances_are_hit_where_their_transforms_put_their_meshes(count: int, coherent: bool) -> None:
    scene, world = instanced_scene(2)
    assert_closest_hits(scene, world, count, seed=100 + count, coherent=coherent)


@pytest.mark.parametrize("coherent", [False, True])
def test_a_ray_ends_at_tfar(coherent: bool) -> None:
    scene, world = instanced_scene(3)
    assert_closest_hits(scene, world, 1000, seed=4, tfar=0.7, coherent=coherent)


def test_coherent_camera_rays_find_the_closed_form_hits() -> None:
    """A pinhole's rays through a grid of pixels, 16 neighbours a packet as the renderer traces
    them, with embree's coherent traversal: the closed-form closest hits."""
    scene, world = instanced_scene(7)
    side = 48
    grid = (np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2) + 0.5) / side
    direction = np.column_stack([grid * 8 - 4, np.full(side * side, -10.0)]).astype(np.float32)
    origin = np.broadcast_to(np.float32([0, 0, 8]), direction.shape).copy()
    hits = scene.intersect(origin, direction, 1e37, coherent=True)
    t_all, _, _, closest, ambiguous = moller_trumbore(world, origin, direction, 1e37)
    rows = np.flatnonzero(~ambiguous & (closest >= 0))
    assert len(rows) > side * side / 10 and np.count_nonzero(~ambiguous) > 0.9 * side * side
    np.testing.assert_array_equal(hits.geom[rows], world.geom[closest[rows]])
    np.testing.assert_array_equal(hits.prim[rows], world.prim[closest[rows]])
    np.testing.assert_allclose(hits.t[rows], t_all[rows, closest[rows]], rtol=2e-5)
    missed = np.flatnonzero(~ambiguous & (closest < 0))
    assert np.all(hits.geom[missed] == -1)


def test_a_batch_answers_as_its_rays_one_at_a_time() -> None:
    scene, world = instanced_scene(4)
    origin, direction = random_rays(world, 37, seed=5)
    batch = scene.intersect(origin, direction)
    for i in range(len(origin)):
        one = scene.intersect(origin[i:i + 1], direction[i:i + 1])
        for name in ("t", "u", "v", "prim", "geom", "instance", "normal"):
            np.testing.assert_array_equal(getattr(one, name)[0], getattr(batch, name)[i])


@pytest.mark.parametrize("count", [PACKET + 1, 1000])
def test_occlusion_is_decided_by_the_distance(count: int) -> None:
    scene, world = instanced_scene(6)
    origin, direction = random_rays(world, count, seed=7)
    t_all, _, _, closest, ambiguous = moller_trumbore(world, origin, direction, 1e37)
    clear = ~ambiguous
    hit, miss = clear & (closest >= 0), clear & (closest < 0)
    t = np.where(closest >= 0, t_all[np.arange(count), np.maximum(closest, 0)], 1.0).astype(np.float32)
    assert np.all(scene.occluded(origin, direction, t * 1.001)[hit])
    assert not np.any(scene.occluded(origin, direction, t * 0.999)[hit])
    assert not np.any(scene.occluded(origin, direction, np.full(count, 1e30, np.float32))[miss])
    # a negative distance answers occluded (as embreex did, and callers rely on), a NaN not occluded
    rules = np.full(count, np.nan, np.float32)
    rules[::3], rules[1::3] = -1, -np.inf
    blocked = scene.occluded(origin, direction, rules)
    assert np.all(blocked[::3]) and np.all(blocked[1::3]) and not np.any(blocked[2::3])


def test_rays_not_traced_between_traced_ones_change_no_answer() -> None:
    """The occlusion loop packs only the rays it traces into packets: each traced ray's answer is
    the one it gets alone, whatever is skipped around it (negative, -inf and NaN distances)."""
    scene, world = instanced_scene(8)
    count = 5 * PACKET + 3
    origin, direction = random_rays(world, count, seed=9)
    t_all, _, _, closest, ambiguous = moller_trumbore(world, origin, direction, 1e37)
    t = np.where(closest >= 0, t_all[np.arange(count), np.maximum(closest, 0)], 1.0).astype(np.float32)
    distance = np.where(np.arange(count) % 2 == 0, t * 1.001, t * 0.999).astype(np.float32)
    skipped = np.random.default_rng(10).random(count) < 0.4
    distance[skipped] = np.array([-1, -np.inf, np.nan], np.float32)[np.arange(count) % 3][skipped]
    blocked = scene.occluded(origin, direction, distance)
    alone = [bool(scene.occluded(origin[i:i + 1], direction[i:i + 1], distance[i:i + 1])[0]) for i in range(count)]
    assert blocked.tolist() == alone
    assert np.array_equal(blocked[skipped], distance[skipped] < 0)
    traced = ~skipped & ~ambiguous & (closest >= 0)
    assert np.array_equal(blocked[traced], (np.arange(count) % 2 == 0)[traced])


@pytest.mark.parametrize("per, width", [(1, 1), (1, 3), (3, 2), (4, 3)])
def test_lanes_hold_each_value_where_the_kernel_puts_it(per: int, width: int) -> None:
    """``shadow_lanes`` reads value c of hit i's k-th ray where shade.cl's ``LANE_AT`` stores it, at
    ((i / 16 per + k) width + c) 16 + i % 16 of the flat output, and ``lane_rows`` gives it at
    [i, k, c] as a copy, so a row outlives the kernel's next launch into the same output."""
    hits = 2 * PACKET
    flat = np.arange(hits * per * width + 7, dtype=np.float32)
    rows = lane_rows(shadow_lanes(flat, per, width, hits))
    i, k, c = np.meshgrid(np.arange(hits), np.arange(per), np.arange(width), indexing="ij")
    assert np.array_equal(rows, flat[((i // PACKET * per + k) * width + c) * PACKET + i % PACKET])
    assert not np.shares_memory(rows, flat)
    # a length's lanes, (hits / 16, per, 16)
    i, k = np.meshgrid(np.arange(hits), np.arange(per), indexing="ij")
    length = lane_rows(shadow_lanes(flat, per, 1, hits)[:, :, 0])
    assert np.array_equal(length, flat[(i // PACKET * per + k) * PACKET + i % PACKET])


@pytest.mark.parametrize("per", [1, 3, 8])
def test_rays_in_lanes_answer_as_their_rows(per: int) -> None:
    """``occluded_lanes`` gives each ray in lanes the answer ``occluded`` gives it in point-major rows
    (hit i's k-th ray in row i per + k), skipped ones too (negative, -inf and NaN lengths), in the
    lanes' shape."""
    scene, world = instanced_scene(11)
    count = 7 * PACKET * per
    origin, direction = random_rays(world, count, seed=12)
    t_all, _, _, closest, _ = moller_trumbore(world, origin, direction, 1e37)
    t = np.where(closest >= 0, t_all[np.arange(count), np.maximum(closest, 0)], 1.0).astype(np.float32)
    rng = np.random.default_rng(per)
    distance = (t * rng.choice([0.999, 1.001], count)).astype(np.float32)
    skipped = rng.random(count) < 0.3
    distance[skipped] = np.array([-1, -np.inf, np.nan], np.float32)[np.arange(count) % 3][skipped]
    expected = scene.occluded(origin, direction, distance)
    assert 0 < np.count_nonzero(expected[~skipped]) < np.count_nonzero(~skipped)
    blocked = scene.occluded_lanes(in_lanes(origin, per), in_lanes(direction, per), in_lanes(distance, per))
    assert blocked.shape == (count // (PACKET * per), per, PACKET)
    assert np.array_equal(blocked, in_lanes(expected, per))


def test_rays_in_lanes_of_another_shape_are_refused() -> None:
    scene, _ = instanced_scene(13)
    rays, length = np.zeros((2, 3, 3, PACKET), np.float32), np.ones((2, 3, PACKET), np.float32)
    for origin, vector, lengths in ((rays, rays[:, :2], length), (rays, rays, length[:1]),
                                    (rays[..., :8], rays[..., :8], length[..., :8])):
        with pytest.raises(ValueError, match="shadow rays in lanes"):
            scene.occluded_lanes(origin, vector, lengths)


@pytest.mark.parametrize("coherent", [False, True])  # True: every thread passes embree the one shared arguments
def test_several_threads_tracing_at_once_get_the_answers_of_one(coherent: bool) -> None:
    scene, world = instanced_scene(8)
    batches = [random_rays(world, 5000, seed) for seed in range(8)]
    alone = [(scene.intersect(o, d, coherent=coherent), scene.occluded(o, d, np.full(len(o), 4, np.float32)))
             for o, d in batches]
    together: list = [None] * len(batches)
    start = threading.Barrier(len(batches))

    def trace(i: int) -> None:
        o, d = batches[i]
        start.wait()
        together[i] = scene.intersect(o, d, coherent=coherent), scene.occluded(o, d, np.full(len(o), 4, np.float32))

    workers = [threading.Thread(target=trace, args=(i,)) for i in range(len(batches))]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    for (hits, blocked), (again, blocked_again) in zip(alone, together):
        for field in dataclasses.fields(hits):
            np.testing.assert_array_equal(getattr(hits, field.name), getattr(again, field.name))
        np.testing.assert_array_equal(blocked, blocked_again)


def test_a_trace_releases_the_gil() -> None:
    """While another thread traces a large batch, this one keeps waking from 1 ms sleeps: the
    longest gap between its wakes, over the trace, stays far below the trace's length (holding the
    GIL would stall it throughout). Thousands of large triangles crossing each other make every ray
    slow to trace."""
    vertices, faces = soup(9, count=3000)
    scene = EmbreeScene()
    scene.add_triangles(vertices, faces, 0)
    scene.commit()
    origin, direction = random_rays(EMPTY.add(vertices, faces, 0, -1, np.eye(4)), 200_000, seed=10)
    scene.intersect(origin[:16], direction[:16])  # compiled (or loaded) before timing
    span: list[float] = []

    def trace() -> None:
        span.append(time.perf_counter())
        scene.intersect(origin, direction)
        span.append(time.perf_counter())

    worker = threading.Thread(target=trace)
    wakes = []
    worker.start()
    while worker.is_alive():
        time.sleep(0.001)
        wakes.append(time.perf_counter())
    worker.join()
    start, end = span
    assert end - start > 0.1, "the batch traced too fast to tell"
    gaps = np.diff([start, *(w for w in wakes if start < w < end), end])
    assert np.max(gaps) < (end - start) / 2


#: One closest-hit and one occlusion query in a process of its own: its answers, and the closest
#: loop's cache hits and misses (numba's dispatcher statistics)
ONE_TRACE = """
import numpy as np
from realistic.scene import packet_loop
from realistic.scene.embree import EmbreeScene
scene = EmbreeScene()
scene.add_triangles(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]), 4)
scene.commit()
origin, direction = np.array([[0.25, 0.25, 2]], np.float32), np.array([[0, 0, -1]], np.float32)
hits, blocked = scene.intersect(origin, direction), scene.occluded(origin, direction, np.array([3], np.float32))
stats = packet_loop.closest_loop().stats
print(hits.geom[0], hits.t[0], blocked[0], sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))
"""


def test_the_loops_one_process_caches_trace_in_another(tmp_path: Path) -> None:
    """The cached code holds no address of the process that compiled it (embree's function is an
    argument): another process, its libraries mapped elsewhere, loads it and gets the same answers."""
    compiled = run_fresh(ONE_TRACE, NUMBA_CACHE_DIR=str(tmp_path)).stdout.split()
    loaded = run_fresh(ONE_TRACE, NUMBA_CACHE_DIR=str(tmp_path)).stdout.split()
    assert compiled == ["4", "2.0", "True", "0", "1"] and loaded == ["4", "2.0", "True", "1", "0"]


def test_the_loaded_library_passes_the_start_up_check() -> None:
    library = embree.embree_library()
    assert library.lib.rtcGetDeviceProperty(library.device, 0) in embree.TESTED_VERSIONS
    assert embree.configuration_problems(library) == []
    packet = embree.probe_packet(library)  # the probe's hit as the loops read it; no row past ROWS written
    assert list(packet[[packet_loop.GEOM, packet_loop.INST, INST_PRIM], 0]) == [embree.PROBE_GEOM,
                                                                                 embree.PROBE_INSTANCE, 0]
    assert np.all(packet[ROWS:] == embree.SENTINEL)


class OtherVersion:
    """The real library, but reporting embree 4.5.0."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self._lib = lib

    def __getattr__(self, name: str) -> Any:
        return getattr(self._lib, name)

    def rtcGetDeviceProperty(self, device: int, prop: int) -> int:
        return {0: 40500, 1: 4, 2: 5, 3: 0}.get(prop, self._lib.rtcGetDeviceProperty(device, prop))


def scribbling(library: embree.Library, scribble: Callable[[np.ndarray], None]) -> embree.Library:
    """``library`` whose rtcIntersect16 calls the real one, then ``scribble(packet)`` on the
    (rows, 16) int32 packet, as an embree built otherwise would have written it."""

    def intersect16(valid: int, scene: int, address: int, arguments: int | None) -> None:
        library.intersect16(valid, scene, address, arguments)
        scribble(np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctypes.c_int32)),
                                       (embree.PROBE_ROWS, PACKET)))

    function = packet_loop.PacketFunction(intersect16)
    return dataclasses.replace(library, intersect16=function)


def two_instance_levels(packet: np.ndarray) -> None:
    """RTC_MAX_INSTANCE_LEVEL_COUNT 2: instID[1] (invalid) after instID[0], instPrimID two rows on."""
    packet[INST_PRIM + 2, 0], packet[INST_PRIM + 1, 0], packet[INST_PRIM, 0] = -1, packet[INST_PRIM, 0], -1


def no_instance_arrays(packet: np.ndarray) -> None:
    """Built without instance arrays: no instPrimID row."""
    packet[INST_PRIM, 0] = embree.SENTINEL


@pytest.mark.parametrize("fake, difference", [
    (lambda library: dataclasses.replace(library, lib=OtherVersion(library.lib)), "version 4.5.0, where 4.4.x"),
    (lambda library: scribbling(library, two_instance_levels), f"wrote row {ROWS + 1} of the packet"),
    (lambda library: scribbling(library, no_instance_arrays), "instPrimID"),
])
def test_a_library_built_otherwise_is_refused_in_one_line(monkeypatch: pytest.MonkeyPatch,
                                                           fake: Callable[[embree.Library], embree.Library],
                                                           difference: str) -> None:
    real = embree.embree_library()
    faked = fake(real)
    assert any(difference in problem for problem in embree.configuration_problems(faked))
    monkeypatch.setattr(embree, "library_candidates", lambda: [real.path])
    monkeypatch.setattr(embree, "open_library",
                        lambda path: dataclasses.replace(faked, device=real.lib.rtcNewDevice(None)))
    with pytest.raises(UserError) as refused:
        embree.embree_library.__wrapped__()
    message = str(refused.value)
    assert "\n" not in message and str(real.path) in message and difference in message
    assert ("4.5.0" if "version" in difference else real.version()) in message


def test_bad_meshes_and_uncommitted_scenes_are_refused() -> None:
    scene = EmbreeScene()
    with pytest.raises(ValueError, match="vertex 3 of 3"):
        scene.add_triangles(np.eye(3, dtype=np.float32), np.array([[0, 1, 3]]), 0)
    with pytest.raises(RuntimeError, match="commit"):
        scene.intersect(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    with pytest.raises(RuntimeError, match="commit"):
        scene.occluded(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), np.ones(1, np.float32))


def test_the_library_is_the_one_embreex_ships() -> None:
    assert any("embree4" in path.name for path in embree.library_candidates())
    assert embree.embree_library().path == next(embree.library_candidates())


def test_no_system_library_is_looked_for_when_the_wheel_s_loads(monkeypatch: pytest.MonkeyPatch) -> None:
    """``ctypes.util.find_library`` (ldconfig, gcc and ld run on Linux) is left alone when the
    embreex wheel's library is the one used: every render started the three processes."""
    def refused(name: str) -> None:
        raise AssertionError(f"find_library({name!r}) was called")

    monkeypatch.setattr(embree.ctypes.util, "find_library", refused)
    library = embree.embree_library.__wrapped__()  # loaded afresh, with a device of its own
    library.lib.rtcReleaseDevice(library.device)
    assert library.path == embree.embree_library().path

