"""Ray-scene intersection with embreex: the embree scene is built once per render.

Geometry ids: instance i of ``Scene.instances`` is geometry i; area light j (of
``Scene.area_lights``) is geometry ``len(instances) + j``. embreex has no instancing, so each
instance's triangles are transformed to world space here (the scene model still stores each
mesh once). ``run()`` releases the GIL, so several threads may trace batches at once after the
BVH is built (done in the constructor).
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
    """Closest-hit and occlusion queries on batches of rays against one scene."""

    def __init__(self, scene: Scene):
        if not scene.instances and not scene.lights:
            raise UserError("the scene is empty: nothing to render")
        self._embree = rtcore_scene.EmbreeScene()
        self.instance_count = len(scene.instances)
        # Embree keeps pointers to the buffers: hold them for the scene's lifetime.
        self._meshes = []
        for index, inst in enumerate(scene.instances):
            mesh = scene.meshes[inst.mesh]
            self._add(transform_points(inst.transform, mesh.vertices), mesh.faces, f"instance {index} ({mesh.name})")
        for index, light in enumerate(scene.area_lights):
            mesh = light_mesh(light)
            self._add(transform_points(light.transform, mesh.vertices), mesh.faces, f"area light {index}")
        lo, hi = _bounds(scene)
        self.extent = float(np.max(hi - lo)) if np.all(np.isfinite(hi - lo)) else 1.0
        one = np.zeros((1, 3), np.float32)
        self._embree.run(one, one + np.float32(1))  # builds the BVH before any thread uses it

    def _add(self, vertices: np.ndarray, faces: np.ndarray, what: str) -> None:
        with np.errstate(over="ignore", invalid="ignore"):
            vertices = np.ascontiguousarray(vertices, dtype=np.float32)
        if not np.all(np.isfinite(vertices)):
            raise UserError(f"the scene's {what} has world coordinates that are not finite in single precision "
                            "(embree's), beyond about 3.4e38")
        faces = np.ascontiguousarray(faces, dtype=np.int32)
        self._meshes.append((vertices, faces, TriangleMesh(self._embree, vertices, faces)))

    def closest(self, origin: np.ndarray, direction: np.ndarray) -> Hits:
        """Nearest hit along each ray (direction need not be unit; t is in its units)."""
        result = self._embree.run(_f32(origin), _f32(direction), output=1)
        return Hits(result["tfar"], result["u"], result["v"], result["primID"], result["geomID"], result["Ng"])

    def occluded(self, origin: np.ndarray, direction: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """True where something lies between t = 0 and t = ``distance``; distance < 0 skips the ray."""
        dists = np.array(distance, dtype=np.float32)
        # embreex 4.4 returns 0 (occluded) or -1 (free) per ray and leaves ``dists`` as it was.
        result = self._embree.run(_f32(origin), _f32(direction), query="OCCLUDED", dists=dists)
        return np.asarray(result) >= 0

    def hit_distance(self, origin: np.ndarray, direction: np.ndarray) -> float | None:
        """Distance along one ray (origin and direction (3,)) to its closest hit; None for a miss."""
        hits = self.closest(np.reshape(origin, (1, 3)), np.reshape(direction, (1, 3)))
        return None if hits.geom[0] < 0 else float(hits.t[0])


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = scene.bounds()
    for light in scene.area_lights:
        c, a, b, _ = light.frame()
        corners = c + np.array([a + b, a - b, -a + b, -a - b])
        lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
    return lo, hi
