"""Ray-scene intersection with embree: one embree scene per render, built once.

Geometry ids: instance i of ``Scene.instances`` is geometry i; area light j (of
``Scene.area_lights``) is geometry ``len(instances) + j``. ``closest`` and ``occluded`` answer for
world rays whatever the layout below.

Geometry shared between instances (``scene/embree``: embree's C API on the library embreex
ships): a mesh placed by at least two instances and of at least ``SHARE_MIN_FACES`` triangles is
built once, in its own object space, as its own embree scene, and each of its instances is an
embree instance of that scene under the instance's transform (embree's two-level BVH; the eleven
dragons of ``scenes/dof-dragons`` cost one dragon's BVH and memory). Everything else (meshes placed
once, small meshes, the area lights' tessellations) is copied to world space. embree reports an
instanced hit's normal in the mesh's object space; the cofactor matrix det(L) L^-T of the
instance's linear part takes it to the world, which is what the world edges' cross product gives.

Barycentrics and ``t`` are invariant under the affine map (embree does not renormalise the
direction), so hits agree with a flat world-space build to float32 rounding
(``tests/test_intersect_instancing.py``; a ray through an edge may name either triangle, as it may
in any build). ``share=False`` builds the flat scene. Nothing is mutated after the constructor and
embree's queries release the GIL, so several threads may trace batches at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realistic.core.jit import compiled, compiled_loops
from realistic.core.transforms import transform_points
from realistic.errors import UserError
from realistic.scene.embree import EmbreeScene
from realistic.scene.model import Scene
from realistic.scene.shapes import light_mesh

#: A mesh placed more than once is shared (built once, in object space) from this many triangles up;
#: smaller ones are cheaper copied to world space than traced through an instance.
SHARE_MIN_FACES = 4096
#: An instance whose transform's linear part is worse conditioned than this is copied to world space.
MAX_SHARED_CONDITION = 1e4
_MISS_T = np.float32(1e37)  # the tfar a ray that hits nothing keeps


def _instances_to_world(instance: np.ndarray, normal_to_world_t: np.ndarray, geom: np.ndarray,
                        normal: np.ndarray) -> None:
    """Where a hit is on an embree instance (``instance`` >= 0), make ``geom`` that instance and
    take its float32 normal to the world: row n times the instance's (3, 3) ``normal_to_world_t``,
    summed in float32 in order ((n0 m0k + n1 m1k) + n2 m2k, as numpy's einsum made it). A numba
    loop (``core.jit``): one pass, where numpy picked, gathered and scattered the rows."""
    for i in range(len(instance)):
        which = instance[i]
        if which >= 0:
            geom[i] = which
            x, y, z = normal[i, 0], normal[i, 1], normal[i, 2]
            for k in range(3):
                normal[i, k] = (x * normal_to_world_t[which, 0, k] + y * normal_to_world_t[which, 1, k]
                                + z * normal_to_world_t[which, 2, k])


def instances_to_world(instance: np.ndarray, normal_to_world_t: np.ndarray, geom: np.ndarray,
                       normal: np.ndarray) -> None:
    """``_instances_to_world``, compiled, or in numpy where the loops do not run compiled
    (``core.jit.use_compiled_loops``): the same float32 products, summed in the same order."""
    if compiled_loops():
        compiled(_instances_to_world)(instance, normal_to_world_t, geom, normal)
        return
    rows = np.flatnonzero(instance >= 0)
    which = instance[rows]
    geom[rows] = which
    n, m = normal[rows], normal_to_world_t[which]
    normal[rows] = (n[:, 0:1] * m[:, 0] + n[:, 1:2] * m[:, 1]) + n[:, 2:3] * m[:, 2]


def compile_intersect_loops() -> None:
    """Compile (or load from numba's cache) ``_instances_to_world`` for the types ``closest``
    passes, on no rows (a render does this as it starts: ``runner.compile_pass_loops``)."""
    ids = np.empty(0, np.int32)
    compiled(_instances_to_world)(ids, np.empty((0, 3, 3), np.float32), ids, np.empty((0, 3), np.float32))


@dataclass(frozen=True)
class Hits:
    """Closest hits of a batch: ``geom`` -1 for a miss; ``normal`` is embree's unnormalised Ng."""

    t: np.ndarray  # (N,) float32 (huge for misses)
    u: np.ndarray  # (N,) barycentric of vertex 1
    v: np.ndarray  # (N,) barycentric of vertex 2
    prim: np.ndarray  # (N,) int32
    geom: np.ndarray  # (N,) int32
    normal: np.ndarray  # (N, 3) float32


class Intersector:
    """Closest-hit and occlusion queries on batches of rays against one scene.

    ``share`` False copies every instance to world space into one flat embree scene (the reference
    the shared build is tested against).
    """

    def __init__(self, scene: Scene, share: bool = True):
        if not scene.instances and not scene.lights:
            raise UserError("the scene is empty: nothing to render")
        self.instance_count = len(scene.instances)
        self._embree = EmbreeScene()
        children = self._shared_meshes(scene) if share else {}
        # per global geometry id: the map of an instanced hit's normal to the world, transposed
        self._normal_to_world_t = np.zeros((self.instance_count, 3, 3), np.float32)
        self.shared_instances = 0
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        columns: dict[int, np.ndarray] = {}  # shared mesh -> its vertices as contiguous (3, V) rows
        for index, inst in enumerate(scene.instances):
            mesh = scene.meshes[inst.mesh]
            what = f"instance {index} ({mesh.name})"
            if id(mesh) in children and _invertible(inst.transform):
                # only the instance's world box: the linear map applied to (3, V) rows, reduced per row
                if id(mesh) not in columns:
                    columns[id(mesh)] = np.ascontiguousarray(np.asarray(mesh.vertices, np.float64).T)
                linear = np.asarray(inst.transform, np.float64)[:3, :3]
                with np.errstate(over="ignore", invalid="ignore"):
                    world = linear @ columns[id(mesh)]
                    box_lo = world.min(axis=1) + inst.transform[:3, 3]
                    box_hi = world.max(axis=1) + inst.transform[:3, 3]
                    _check_finite(np.concatenate([box_lo, box_hi]).astype(np.float32), what)
                self._embree.add_instance(children[id(mesh)], inst.transform, index)
                self._normal_to_world_t[index] = (np.linalg.det(linear) * np.linalg.inv(linear)).astype(np.float32)
                self.shared_instances += 1
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
        self._embree.commit()

    @staticmethod
    def _shared_meshes(scene: Scene) -> dict[int, EmbreeScene]:
        """An embree scene, in object space, per mesh (by identity) placed at least twice, of
        SHARE_MIN_FACES triangles or more."""
        uses: dict[int, int] = {}
        for inst in scene.instances:
            key = id(scene.meshes[inst.mesh])
            uses[key] = uses.get(key, 0) + 1
        shared = {}
        for inst in scene.instances:
            mesh = scene.meshes[inst.mesh]
            if id(mesh) not in shared and uses[id(mesh)] >= 2 and len(mesh.faces) >= SHARE_MIN_FACES:
                child = EmbreeScene()
                child.add_triangles(_finite_f32(mesh.vertices, f"mesh {mesh.name}"), mesh.faces, 0)
                child.commit()
                shared[id(mesh)] = child
        return shared

    def _add(self, vertices: np.ndarray, faces: np.ndarray, what: str, geom: int) -> None:
        self._embree.add_triangles(_finite_f32(vertices, what), faces, geom)

    def closest(self, origin: np.ndarray, direction: np.ndarray, coherent: bool = False) -> Hits:
        """Nearest hit along each ray (direction need not be unit; t is in its units). Camera rays
        are ``coherent``: embree traces them with its traversal for such rays (``EmbreeScene.intersect``)."""
        hits = self._embree.intersect(origin, direction, float(_MISS_T), coherent)
        instances_to_world(hits.instance, self._normal_to_world_t, hits.geom, hits.normal)
        return Hits(hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal)

    def occluded(self, origin: np.ndarray, direction: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """True where something lies between t = 0 and t = ``distance``, and where ``distance`` is
        negative (as embreex answered)."""
        dists = np.asarray(distance, dtype=np.float32).reshape(-1)  # read, never written: no copy
        if len(dists) == 1 and len(origin) != 1:
            dists = np.full(len(origin), dists[0], np.float32)
        return self._embree.occluded(origin, direction, dists)

    def occluded_lanes(self, origin: np.ndarray, vector: np.ndarray, length: np.ndarray) -> np.ndarray:
        """``occluded`` for the shading kernel's shadow rays, in lanes (``EmbreeScene.occluded_lanes``):
        the answers in ``length``'s shape, each hit's rays traced together."""
        return self._embree.occluded_lanes(origin, vector, length)

    def hit_distance(self, origin: np.ndarray, direction: np.ndarray) -> float | None:
        """Distance along one ray (origin and direction (3,)) to its closest hit; None for a miss."""
        hits = self.closest(np.reshape(origin, (1, 3)), np.reshape(direction, (1, 3)))
        return None if hits.geom[0] < 0 else float(hits.t[0])


def _invertible(transform: np.ndarray) -> bool:
    """Whether rays can go to the object space of ``transform`` without losing float32 precision."""
    with np.errstate(all="ignore"):
        linear = np.asarray(transform, np.float64)[:3, :3]
        return bool(np.all(np.isfinite(transform)) and np.linalg.cond(linear) < MAX_SHARED_CONDITION)


def _finite_f32(vertices: np.ndarray, what: str) -> np.ndarray:
    """The vertices as float32, refused when float32 cannot hold them."""
    with np.errstate(over="ignore", invalid="ignore"):
        vertices = np.ascontiguousarray(vertices, dtype=np.float32)
    _check_finite(vertices, what)
    return vertices


def _check_finite(vertices: np.ndarray, what: str) -> None:
    if not np.all(np.isfinite(vertices)):
        raise UserError(f"the scene's {what} has world coordinates that are not finite in single precision "
                        "(embree's), beyond about 3.4e38")

