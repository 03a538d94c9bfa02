"""Ray-scene intersection with embreex: the embree scenes are built once per render.

Geometry ids: instance i of ``Scene.instances`` is geometry i; area light j (of
``Scene.area_lights``) is geometry ``len(instances) + j``. ``closest`` and ``occluded`` answer for
world rays whatever the layout below.

Geometry shared between instances. embreex 4.4 binds triangle meshes and single-ray queries only
(``EmbreeScene.run``, ``mesh_construction.TriangleMesh``; its ``rtcore_geometry.pxd`` leaves
instancing and every other geometry type out), so embree's own instances cannot be made. Instead a
two-level search in numpy over embree scenes:

- a mesh placed by at least two instances and of at least ``SHARE_MIN_FACES`` triangles is built
  once, in its own object space, as its own embree scene; its instances are world-space bounding
  boxes (exact boxes of the transformed vertices, padded by float32 rounding);
- everything else (meshes placed once, small meshes, the area lights' tessellations) is copied to
  world space into one flat embree scene, as before, and traced first;
- per batch, the candidate (ray, instance) pairs: a slab test against the union of the boxes clips
  each ray's segment [0, current hit]; the boxes, sorted along the axis they spread most on, that
  the clipped segment's extent on that axis overlaps are a contiguous range (two binary searches);
  a slab test per pair keeps those whose box the segment enters and gives the entry distance. In
  rounds, each ray visits its candidates in the order it meets them along that axis, skipping a
  box it would enter beyond its current hit: the ray's origin and direction go through the
  instance's inverse affine transform (the direction is not renormalised, so ``t`` is the world
  ray's), embree intersects it with the mesh's scene with ``tfar`` set to the current hit, and a
  nearer hit replaces it (embree's object-space ``Ng`` is taken to the world by the cofactor
  matrix det(L) L^-T, which is what the world edges' cross product gives). Most rays meet one or
  two boxes. ``occluded`` does the same with occlusion queries: any hit within the distance ends
  the ray.

Barycentrics and ``t`` are invariant under the affine map, so hits agree with a flat world-space
build to float32 rounding (``tests/test_intersect_instancing.py``; a ray through an edge may name
either triangle, as it may in any build). embree computes with vertices relative to the ray's
origin, so its Ng, u, v of a tiny triangle (a scanned mesh's, 1e-3 across) vary by 1e-4 with the
last bit of the origin; the two builds differ at that level, as the flat build does from itself
when the origins move by one float32 step. ``share=False`` builds the flat scene, as the renderer
did before. The box work costs about as much as embree's own traversal per ray, so a render of the
11-dragon scenes traces somewhat slower than through the flat scene, which in turn costs a
``TriangleMesh`` copy (about 0.3-0.4 s per 200k triangles: embreex fills embree's buffers element
by element) and its BVH per instance, and their memory. embreex's ``run`` releases the GIL and nothing here is
mutated after the constructor, so several threads may trace batches at once; every embree scene
is committed (its BVH built) in the constructor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from realistic.core.transforms import transform_points
from realistic.errors import UserError
from realistic.scene.model import Scene
from realistic.scene.shapes import light_mesh

#: A mesh placed more than once is shared (built once, in object space) from this many triangles up;
#: smaller ones are cheaper copied into the flat world-space scene than searched per instance.
SHARE_MIN_FACES = 4096
#: Rays per block of the box tests: bounds their temporaries.
SLAB_BLOCK = 1 << 16
#: An instance whose transform's linear part is worse conditioned than this is copied to world space.
MAX_SHARED_CONDITION = 1e4
_MISS_T = np.float32(1e37)  # embreex's tfar for a ray that hits nothing


@dataclass(frozen=True)
class Hits:
    """Closest hits of a batch: ``geom`` -1 for a miss; ``normal`` is embree's unnormalised Ng."""

    t: np.ndarray  # (N,) float32 (huge for misses)
    u: np.ndarray  # (N,) barycentric of vertex 1
    v: np.ndarray  # (N,) barycentric of vertex 2
    prim: np.ndarray  # (N,) int32
    geom: np.ndarray  # (N,) int32
    normal: np.ndarray  # (N, 3) float32


class _SharedMeshes:
    """The shared meshes' embree scenes and their instances' boxes and transforms: lists while
    building, then (``freeze``) arrays over the K shared instances sorted along the sweep axis."""

    def __init__(self) -> None:
        self.scenes: list[rtcore_scene.EmbreeScene] = []
        self.buffers: list = []  # embree keeps pointers to the vertex and index buffers
        self.geom: list[int] = []  # global geometry id per shared instance
        self.scene_of: list[int] = []
        self.to_object: list[np.ndarray] = []  # (3, 4) world -> object
        self.lo: list[np.ndarray] = []
        self.hi: list[np.ndarray] = []
        self.normal_to_world: list[np.ndarray] = []  # (3, 3) cofactor matrix of the linear part

    def add_mesh(self, mesh) -> int:
        scene = rtcore_scene.EmbreeScene()
        with np.errstate(over="ignore", invalid="ignore"):
            vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
        _check_finite(vertices, f"mesh {mesh.name}")
        faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        self.buffers.append((vertices, faces, TriangleMesh(scene, vertices, faces)))
        self.scenes.append(scene)
        return len(self.scenes) - 1

    def add_instance(self, geom: int, scene: int, transform: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        linear = np.asarray(transform, np.float64)[:3, :3]
        inverse = np.linalg.inv(linear)
        self.geom.append(geom)
        self.scene_of.append(scene)
        self.to_object.append(np.column_stack([inverse, -inverse @ np.asarray(transform, np.float64)[:3, 3]]))
        self.normal_to_world.append(np.linalg.det(linear) * inverse.T)
        # Pad the box by more than float32 rounding of world coordinates (embree's and the slab test's).
        pad = 1e-5 * (float(np.max(np.abs(np.concatenate([lo, hi])))) + float(np.max(hi - lo)))
        self.lo.append(lo - pad)
        self.hi.append(hi + pad)

    def freeze(self) -> None:
        """Arrays of the per-instance lists, sorted along the sweep axis; commits every scene."""
        lo, hi = np.array(self.lo).reshape(-1, 3), np.array(self.hi).reshape(-1, 3)
        # Sweep along the axis where the boxes are most spread out relative to their own sizes.
        spread = (hi.max(axis=0) - lo.min(axis=0)) / np.maximum((hi - lo).mean(axis=0), 1e-30)
        self.axis = int(np.argmax(spread))
        order = np.argsort(lo[:, self.axis], kind="stable")
        self.geom_ids = np.array(self.geom, np.int32)[order]
        self.scene_ids = np.array(self.scene_of, np.int64)[order]
        to_object = np.array(self.to_object, np.float64).reshape(-1, 3, 4)[order]
        # transposed, contiguous: rows @ matrix is a plain float32 GEMM
        self.linear_t = np.ascontiguousarray(to_object[:, :, :3].transpose(0, 2, 1), np.float32)
        self.offset = np.ascontiguousarray(to_object[:, :, 3], np.float32)
        self.cofactor_t = np.ascontiguousarray(
            np.array(self.normal_to_world, np.float64).reshape(-1, 3, 3)[order].transpose(0, 2, 1), np.float32)
        self.box_lo, self.box_hi = lo[order].astype(np.float32), hi[order].astype(np.float32)
        self.box_lo_t, self.box_hi_t = np.ascontiguousarray(self.box_lo.T), np.ascontiguousarray(self.box_hi.T)
        self.union_lo, self.union_hi = self.box_lo.min(axis=0), self.box_hi.max(axis=0)
        self.sweep_lo = self.box_lo[:, self.axis].copy()  # ascending
        self.sweep_hi = np.maximum.accumulate(self.box_hi[:, self.axis])  # running maximum, ascending
        one = np.zeros((1, 3), np.float32)
        for scene in self.scenes:
            scene.run(one, one + np.float32(1))

    def __len__(self) -> int:
        return len(self.geom)

    def local_rays(self, k: int, origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rays in instance k's object space (the direction not renormalised: same t)."""
        o = origin @ self.linear_t[k]
        o += self.offset[k]
        return o, direction @ self.linear_t[k]

    def candidates(self, origin: np.ndarray, direction: np.ndarray, limit: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(ray, instance, entry, rank) of every (ray, box) pair where the ray's segment [0, limit]
        meets the box: ``entry`` the distance at which it enters (0 inside), ``rank`` the box's
        place along the ray's way on the sweep axis (the order to visit them in)."""
        parts = [self._candidates(origin[start:start + SLAB_BLOCK], direction[start:start + SLAB_BLOCK],
                                  limit[start:start + SLAB_BLOCK], start)
                 for start in range(0, len(origin), SLAB_BLOCK)]
        return tuple(np.concatenate(column) for column in zip(*parts)) if parts else _NO_PAIRS

    def _candidates(self, origin: np.ndarray, direction: np.ndarray, limit: np.ndarray, first: int):
        o = np.ascontiguousarray(origin.T)
        with np.errstate(divide="ignore"):
            inv = np.float32(1) / np.ascontiguousarray(direction.T)
        near, far = _slab(o, inv, self.union_lo, self.union_hi)
        np.maximum(near, 0, out=near)
        np.minimum(far, limit, out=far)
        rows = np.flatnonzero(far >= near)
        if not len(rows):
            return _NO_PAIRS
        # The segment's extent along the sweep axis gives the boxes it may meet: a range of them.
        a = self.axis
        oa, da = o[a, rows], direction[rows, a]
        with np.errstate(invalid="ignore", over="ignore"):
            x0, x1 = oa + near[rows] * da, oa + far[rows] * da
        first_box = np.searchsorted(self.sweep_hi, np.fmin(x0, x1), side="left")
        last_box = np.searchsorted(self.sweep_lo, np.fmax(x0, x1), side="right")
        count = np.maximum(last_box - first_box, 0)
        total = int(count.sum())
        if not total:
            return _NO_PAIRS
        starts = np.cumsum(count) - count
        ray = np.repeat(rows, count)
        rank = np.arange(total) - np.repeat(starts, count)
        box = np.repeat(first_box, count) + rank
        backward = np.repeat(da < 0, count)
        rank = np.where(backward, np.repeat(count, count) - 1 - rank, rank)
        near, far = _slab(np.take(o, ray, axis=1), np.take(inv, ray, axis=1), np.take(self.box_lo_t, box, axis=1),
                          np.take(self.box_hi_t, box, axis=1))
        np.maximum(near, 0, out=near)
        keep = np.flatnonzero((far >= near) & (near <= limit[ray]))
        return ray[keep] + first, box[keep], near[keep], rank[keep]


_NO_PAIRS = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32), np.zeros(0, np.int64))


def _slab(o: np.ndarray, inv: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Near and far distances of rays (origins ``o`` and reciprocal directions ``inv``, (3, R)) to
    boxes [lo, hi] ((3,) or (3, R)). A ray lying in a face's plane gets NaN and counts as missing
    the box, which is right for the padded boxes here: their meshes lie strictly inside."""
    if lo.ndim == 1:
        lo, hi = lo[:, None], hi[:, None]
    with np.errstate(invalid="ignore", over="ignore"):
        a = lo - o
        a *= inv
        b = hi - o
        b *= inv
    low = np.minimum(a, b)
    high = np.maximum(a, b, out=a)
    near = np.maximum(low[0], low[1])
    np.maximum(near, low[2], out=near)
    far = np.minimum(high[0], high[1])
    np.minimum(far, high[2], out=far)
    return near, far


def _rounds(ray: np.ndarray, box: np.ndarray, entry: np.ndarray, rank: np.ndarray, limit: np.ndarray):
    """Yield (instance, pair indices) groups, round by round: in round r each ray visits its box of
    rank r if the box's entry is within the ray's ``limit`` (read again each round, as the caller
    shortens it, so a ray that has hit something nearer skips the boxes beyond)."""
    if not len(ray):
        return
    by_rank = np.argsort(_small(rank), kind="stable")
    bounds = np.searchsorted(rank[by_rank], np.arange(int(rank.max()) + 2))
    for r in range(len(bounds) - 1):
        pairs = by_rank[bounds[r]:bounds[r + 1]]
        pairs = pairs[entry[pairs] <= limit[ray[pairs]]]
        if not len(pairs):
            continue
        boxes = box[pairs]
        order = np.argsort(_small(boxes), kind="stable")
        edges = np.searchsorted(boxes[order], np.arange(int(boxes.max()) + 2))
        for k in np.flatnonzero(np.diff(edges)):
            yield int(k), pairs[order[edges[k]:edges[k + 1]]]


def _small(values: np.ndarray) -> np.ndarray:
    """Non-negative integers as int16 where they fit: numpy's stable sort of int16 is a radix sort."""
    return values.astype(np.int16) if len(values) and values.max() < 1 << 15 else values


class Intersector:
    """Closest-hit and occlusion queries on batches of rays against one scene.

    ``share`` False copies every instance to world space into one flat embree scene (the reference
    the shared build is tested against).
    """

    def __init__(self, scene: Scene, share: bool = True):
        if not scene.instances and not scene.lights:
            raise UserError("the scene is empty: nothing to render")
        self.instance_count = len(scene.instances)
        self._flat = rtcore_scene.EmbreeScene()
        self._flat_ids: list[int] = []  # global geometry id per flat embree geometry
        # Embree keeps pointers to the buffers: hold them for the scene's lifetime.
        self._meshes = []
        self._shared = _SharedMeshes()
        shared_scene = self._shared_meshes(scene) if share else {}
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        columns: dict[int, np.ndarray] = {}  # shared mesh -> its vertices as contiguous (3, V) rows
        for index, inst in enumerate(scene.instances):
            mesh = scene.meshes[inst.mesh]
            what = f"instance {index} ({mesh.name})"
            if id(mesh) in shared_scene and _invertible(inst.transform):
                # only the instance's world box: the linear map applied to (3, V) rows, reduced per row
                if id(mesh) not in columns:
                    columns[id(mesh)] = np.ascontiguousarray(np.asarray(mesh.vertices, np.float64).T)
                with np.errstate(over="ignore", invalid="ignore"):
                    world = np.asarray(inst.transform, np.float64)[:3, :3] @ columns[id(mesh)]
                    box_lo = world.min(axis=1) + inst.transform[:3, 3]
                    box_hi = world.max(axis=1) + inst.transform[:3, 3]
                    _check_finite(np.concatenate([box_lo, box_hi]).astype(np.float32), what)
                self._shared.add_instance(index, shared_scene[id(mesh)], inst.transform, box_lo, box_hi)
            else:
                with np.errstate(over="ignore", invalid="ignore"):
                    world = transform_points(inst.transform, mesh.vertices)
                self._add(world, mesh.faces, what, index)
                box_lo, box_hi = (world.min(axis=0), world.max(axis=0)) if len(world) else (lo, hi)
            lo, hi = np.minimum(lo, box_lo), np.maximum(hi, box_hi)
        if not scene.instances:
            lo, hi = np.zeros(3), np.zeros(3)
        for index, light in enumerate(scene.area_lights):
            mesh = light_mesh(light)
            self._add(transform_points(light.transform, mesh.vertices), mesh.faces, f"area light {index}",
                      self.instance_count + index)
            c, a, b, _ = light.frame()
            corners = c + np.array([a + b, a - b, -a + b, -a - b])
            lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
        self.extent = float(np.max(hi - lo)) if np.all(np.isfinite(hi - lo)) else 1.0
        # flat embree geometry id -> global id, shifted by one so a miss (-1) maps to -1
        self._flat_map = np.array([-1, *self._flat_ids], np.int32)
        if len(self._shared):
            self._shared.freeze()
        if self._flat_ids:
            one = np.zeros((1, 3), np.float32)
            self._flat.run(one, one + np.float32(1))  # builds the BVH before any thread uses it

    @property
    def shared_instances(self) -> int:
        """How many instances are searched through a shared mesh (not copied to world space)."""
        return len(self._shared)

    def _shared_meshes(self, scene: Scene) -> dict[int, int]:
        """Shared embree scene per mesh (by identity) placed at least twice, of SHARE_MIN_FACES or more."""
        uses: dict[int, int] = {}
        for inst in scene.instances:
            key = id(scene.meshes[inst.mesh])
            uses[key] = uses.get(key, 0) + 1
        shared = {}
        for inst in scene.instances:
            mesh = scene.meshes[inst.mesh]
            if id(mesh) not in shared and uses[id(mesh)] >= 2 and len(mesh.faces) >= SHARE_MIN_FACES:
                shared[id(mesh)] = self._shared.add_mesh(mesh)
        return shared

    def _add(self, vertices: np.ndarray, faces: np.ndarray, what: str, geom: int) -> None:
        with np.errstate(over="ignore", invalid="ignore"):
            vertices = np.ascontiguousarray(vertices, dtype=np.float32)
        _check_finite(vertices, what)
        faces = np.ascontiguousarray(faces, dtype=np.int32)
        self._meshes.append((vertices, faces, TriangleMesh(self._flat, vertices, faces)))
        self._flat_ids.append(geom)

    def closest(self, origin: np.ndarray, direction: np.ndarray) -> Hits:
        """Nearest hit along each ray (direction need not be unit; t is in its units)."""
        origin, direction = _f32(origin), _f32(direction)
        if self._flat_ids:
            result = self._flat.run(origin, direction, output=1)
            t, u, v, prim, geom, normal = (result["tfar"], result["u"], result["v"], result["primID"],
                                           self._flat_map[result["geomID"] + 1], result["Ng"])
        else:
            n = len(origin)
            t, u, v = np.full(n, _MISS_T), np.zeros(n, np.float32), np.zeros(n, np.float32)
            prim, geom, normal = np.full(n, -1, np.int32), np.full(n, -1, np.int32), np.zeros((n, 3), np.float32)
        if len(self._shared) and len(origin):
            shared = self._shared
            ray, box, entry, rank = shared.candidates(origin, direction, t)
            for k, pairs in _rounds(ray, box, entry, rank, t):
                r = ray[pairs]
                o, d = shared.local_rays(k, np.take(origin, r, axis=0), np.take(direction, r, axis=0))
                result = shared.scenes[shared.scene_ids[k]].run(o, d, t[r], output=1)
                hit = np.flatnonzero(result["geomID"] >= 0)
                if not len(hit):
                    continue
                near = r[hit]
                t[near] = result["tfar"][hit]
                u[near], v[near] = result["u"][hit], result["v"][hit]
                prim[near], geom[near] = result["primID"][hit], shared.geom_ids[k]
                normal[near] = result["Ng"][hit] @ shared.cofactor_t[k]
        return Hits(t, u, v, prim, geom, normal)

    def occluded(self, origin: np.ndarray, direction: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """True where something lies between t = 0 and t = ``distance`` (embreex answers True for a
        negative distance, and the shared search keeps that)."""
        origin, direction = _f32(origin), _f32(direction)
        dists = np.array(distance, dtype=np.float32).reshape(-1)
        if len(dists) == 1 and len(origin) != 1:
            dists = np.full(len(origin), dists[0], np.float32)
        if self._flat_ids:
            # embreex 4.4 returns 0 (occluded) or -1 (free) per ray and leaves ``dists`` as it was.
            blocked = np.asarray(self._flat.run(origin, direction, query="OCCLUDED", dists=dists.copy())) >= 0
        else:
            blocked = dists < 0  # what embreex answers for a negative distance
        if len(self._shared) and len(origin):
            shared = self._shared
            limit = np.where(blocked, np.float32(-np.inf), dists)  # a blocked ray visits no box
            ray, box, entry, rank = shared.candidates(origin, direction, limit)
            for k, pairs in _rounds(ray, box, entry, rank, limit):
                r = ray[pairs]
                o, d = shared.local_rays(k, np.take(origin, r, axis=0), np.take(direction, r, axis=0))
                hit = np.asarray(shared.scenes[shared.scene_ids[k]].run(o, d, query="OCCLUDED",
                                                                        dists=np.take(dists, r))) >= 0
                blocked[r[hit]] = True
                limit[r[hit]] = -np.inf
        return blocked

    def hit_distance(self, origin: np.ndarray, direction: np.ndarray) -> float | None:
        """Distance along one ray (origin and direction (3,)) to its closest hit; None for a miss."""
        hits = self.closest(np.reshape(origin, (1, 3)), np.reshape(direction, (1, 3)))
        return None if hits.geom[0] < 0 else float(hits.t[0])


def _invertible(transform: np.ndarray) -> bool:
    """Whether rays can go to the object space of ``transform`` without losing float32 precision."""
    with np.errstate(all="ignore"):
        linear = np.asarray(transform, np.float64)[:3, :3]
        return bool(np.all(np.isfinite(transform)) and np.linalg.cond(linear) < MAX_SHARED_CONDITION)


def _check_finite(vertices: np.ndarray, what: str) -> None:
    if not np.all(np.isfinite(vertices)):
        raise UserError(f"the scene's {what} has world coordinates that are not finite in single precision "
                        "(embree's), beyond about 3.4e38")


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)
