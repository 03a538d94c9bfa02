"""pbrt shapes as our meshes: the analytic ones (sphere, disk, cone, cylinder) tessellated,
trianglemesh, plymesh (a file named by several shapes is loaded once), loopsubdiv (subdivided as
pbrt does: ``realistic.scene.loop_subdivision``) and pbrt-v4's bilinearmesh (two triangles per
patch). Bad points or indices are errors; sizes that leave nothing to render and parameters we
cannot honour are warnings with file and line."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from realistic.core.transforms import translate
from realistic.errors import UserError
from realistic.scene.loop_subdivision import levels_that_fit, loop_subdivide
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import Mesh
from realistic.scene.pbrt.dialect import ParameterNames
from realistic.scene.pbrt.parser import ShapeRecord
from realistic.scene.pbrt.values import located
from realistic.scene.shapes import cone, cylinder, disk, sphere

#: Shapes pbrt defines by an equation, whose front is their object-space outside.
QUADRICS = ("sphere", "cone", "cylinder")


def box_corners(vertices: np.ndarray) -> np.ndarray:
    """The 8 corners of the bounding box of (N, 3) points, as (8, 4) homogeneous points."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def is_sound(mesh: Mesh) -> bool:
    """Whether a tessellated or loaded mesh has finite points, faces, unit normals and finite uv."""
    if not (len(mesh.vertices) and len(mesh.faces) and np.all(np.isfinite(mesh.vertices))):
        return False
    if mesh.normals is not None and not np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0):
        return False
    return mesh.uv is None or bool(np.all(np.isfinite(mesh.uv)))


def reach_of(transform: np.ndarray, corners: np.ndarray) -> float:
    """How far from the origin a box (its corners) reaches once transformed; inf on overflow."""
    with np.errstate(over="ignore", invalid="ignore"):
        reach = float(np.max(np.abs(corners @ transform.T)[:, :3]))
    return reach if np.isfinite(reach) else np.inf


class ShapeMeshes:
    """Tessellates or loads shapes; ``warn(where, message)`` reports what is not honoured,
    ``find(name, directory, where, what)`` resolves a file a shape names and ``names`` are the
    scene's pbrt version's parameter names."""

    def __init__(self, warn: Callable[[str, str], None], find: Callable[[str, Path, str, str], Path],
                 names: ParameterNames):
        self.warn, self.find, self.names = warn, find, names
        # a mesh file named by several shapes is loaded once: path -> its objects
        self.loaded: dict[Path, list[tuple[Mesh, np.ndarray]]] = {}
        # an analytic shape is tessellated once per size: (type, sizes) -> its mesh, so that a thousand
        # equal spheres are one mesh placed a thousand times (embree then shares it: intersect.py)
        self.tessellated: dict[tuple[str, tuple[float, ...]], Mesh] = {}

    def usable(self, shape: ShapeRecord) -> bool:
        """False (with a warning) for an analytic shape whose sizes leave nothing we can render."""
        p = shape.params
        sizes = {"sphere": ["radius"], "disk": ["radius"], "cone": ["radius", "height"],
                 "cylinder": ["radius"]}.get(shape.type, [])
        defaults = {"radius": 1.0, "height": 1.0}
        for name in sizes:
            value = p.get_float(name, defaults[name])
            if not value > 0:
                self.warn(shape.where, f'{shape.type} {name} {value:g} (only positive sizes are rendered; '
                                       f"shape skipped)")
                return False
        if shape.type == "cylinder" and p.get_float("zmin", -1.0) == p.get_float("zmax", 1.0):
            self.warn(shape.where, "cylinder with zmin = zmax (no height; shape skipped)")
            return False
        return True

    def meshes(self, shape: ShapeRecord) -> list[tuple[Mesh, np.ndarray]]:
        """The shape tessellated, with the transform from its object space to the record's space."""
        p = shape.params
        if shape.type == "trianglemesh":
            return [(self.triangle_mesh(shape), np.eye(4))]
        if shape.type == "bilinearmesh":
            return [(self.bilinear_mesh(shape), np.eye(4))]
        if shape.type == "loopsubdiv":
            return [(self.loop_subdivision(shape), np.eye(4))]
        if shape.type == "plymesh":
            filename = p.get_string("filename")
            if not filename:
                raise UserError(f"{shape.where}: plymesh has no filename")
            if p.has("displacement"):  # pbrt-v4 src/pbrt/shapes.cpp tessellates and displaces along N
                self.warn(shape.where, 'plymesh "displacement" (the mesh is rendered undisplaced)')
            path = self.find(filename, shape.directory, shape.where, "plymesh file").resolve()
            if path not in self.loaded:
                self.loaded[path] = [(obj.mesh, obj.transform) for obj in load_mesh_file(path)]
            return self.loaded[path]
        if shape.type == "disk":
            if p.get_float("innerradius", 0.0):
                self.warn(shape.where, "disk innerradius (rendered as a full disk)")
            return [(self._once("disk", disk, p.get_float("radius", 1.0)),
                     translate(0, 0, p.get_float("height", 0.0)))]
        if shape.type == "sphere":
            if p.has("zmin") or p.has("zmax") or p.get_float("phimax", 360.0) != 360.0:
                self.warn(shape.where, "partial sphere (zmin, zmax, phimax; rendered whole)")
            return [(self._once("sphere", sphere, p.get_float("radius", 1.0)), np.eye(4))]
        if shape.type == "cone":
            if p.get_float("phimax", 360.0) != 360.0:
                self.warn(shape.where, "partial cone (phimax; rendered whole)")
            return [(self._once("cone", cone, p.get_float("radius", 1.0), p.get_float("height", 1.0)), np.eye(4))]
        if shape.type == "cylinder":
            z0, z1 = p.get_float("zmin", -1.0), p.get_float("zmax", 1.0)
            return [(self._once("cylinder", cylinder, p.get_float("radius", 1.0), min(z0, z1), max(z0, z1)),
                     np.eye(4))]
        self.warn(shape.where, f'Shape "{shape.type}" (skipped)')
        return []

    def _once(self, kind: str, tessellate: Callable[..., Mesh], *sizes: float) -> Mesh:
        """``tessellate(*sizes)``, made once per ``kind`` and sizes for the whole import."""
        key = (kind, sizes)
        if key not in self.tessellated:
            self.tessellated[key] = tessellate(*sizes)
        return self.tessellated[key]

    def triangle_mesh(self, shape: ShapeRecord) -> Mesh:
        """pbrt's trianglemesh: bad points or indices are errors; uv or N that do not fit are dropped
        with a warning, as pbrt does."""
        vertices, indices = self._indexed_points(shape, 3, "triangle")
        return self._mesh_with_attributes(shape, vertices, indices.reshape(-1, 3))

    def loop_subdivision(self, shape: ShapeRecord) -> Mesh:
        """pbrt's loopsubdiv: the triangle control mesh of "P" and "indices" subdivided "levels" times
        (the name per version: ``ParameterNames``; default 3) and pushed to its limit surface, with
        pbrt's limit normals. Fewer levels (with a warning) where 4^levels times the triangles would
        pass ``MAX_TRIANGLES``; none below 0 (pbrt's loop then runs no level either)."""
        vertices, indices = self._indexed_points(shape, 3, "triangle")
        faces = indices.reshape(-1, 3)
        given = [name for name in self.names.subdivision_levels if shape.params.has(name)]
        name = given[0] if given else self.names.subdivision_levels[0]
        value = shape.params.get_float(name, 3.0)
        if not (np.isfinite(value) and value == int(value)):
            raise UserError(f'{shape.where}: loopsubdiv "{name}" must be a whole number, got {value:g}')
        levels = max(int(value), 0)
        fitting = levels_that_fit(len(faces), levels)
        if fitting < levels:
            self.warn(shape.where, f'loopsubdiv "{name}" {value:g} would make 4^{value:g} x {len(faces):,} '
                                   f"triangles (subdivided {fitting} times)")
        with located(shape.where):
            subdivided = loop_subdivide(vertices, faces, fitting)
        return Mesh(subdivided.vertices, subdivided.faces, subdivided.normals, None, shape.type)

    def bilinear_mesh(self, shape: ShapeRecord) -> Mesh:
        """pbrt-v4's bilinearmesh (src/pbrt/shapes.cpp, BilinearPatch::CreateMesh): each patch's four
        indices are its corners p00, p10, p01, p11 (default [0 1 2 3] for four points). Each patch is
        split into the triangles (p00, p10, p11) and (p00, p11, p01), which face the way pbrt's
        dp/du x dp/dv does and are exact for planar patches; a warped patch is approximated."""
        vertices, indices = self._indexed_points(shape, 4, "patch")
        p00, p10, p01, p11 = indices.reshape(-1, 4).T
        faces = np.column_stack([p00, p10, p11, p00, p11, p01]).reshape(-1, 3)
        self.warn(shape.where, "bilinearmesh (each bilinear patch is rendered as two triangles)")
        return self._mesh_with_attributes(shape, vertices, faces)

    def _indexed_points(self, shape: ShapeRecord, corners: int, unit: str) -> tuple[np.ndarray, np.ndarray]:
        """A mesh shape's "P" as (N, 3) points and its "indices" (``corners`` per ``unit``), checked."""
        p, where, kind = shape.params, shape.where, shape.type
        points = np.asarray(p.get_floats("P", []), dtype=np.float64)
        if len(points) == 0 or len(points) % 3:
            raise UserError(f'{where}: {kind} "point P" needs 3 values per point, got {len(points)} values')
        vertices = points.reshape(-1, 3)
        if not np.all(np.isfinite(vertices)):
            raise UserError(f'{where}: {kind} "point P" has a value that is not a finite number')
        default = [float(i) for i in range(corners)] if len(vertices) == corners else []  # pbrt's default
        given = p.get_floats("indices", default)
        if len(given) == 0 or len(given) % corners:
            raise UserError(f'{where}: {kind} "integer indices" needs {corners} per {unit}, got {len(given)} '
                            f"values")
        indices = np.asarray(given, dtype=np.float64)
        bad = (indices != np.floor(indices)) | (indices < 0) | (indices >= len(vertices))
        if np.any(bad):
            raise UserError(f"{where}: {kind} index {indices[np.argmax(bad)]:g} is not a point number (0 to "
                            f'{len(vertices) - 1} for the {len(vertices)} points of "P")')
        return vertices, indices.astype(np.int64)

    def _mesh_with_attributes(self, shape: ShapeRecord, vertices: np.ndarray, faces: np.ndarray) -> Mesh:
        """The mesh with the shape's per-point uv and unit normals where they fit the points."""
        uv = self._per_point(shape, ("uv", "st"), 2, len(vertices))
        normals = self._per_point(shape, ("N",), 3, len(vertices))
        if normals is not None:
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            if np.all(length > 0):
                normals = normals / length
            else:
                self.warn(shape.where, f'{shape.type} "N" with a zero-length normal (normals ignored)')
                normals = None
        return Mesh(vertices, faces, normals, uv, shape.type)

    def _per_point(self, shape: ShapeRecord, names: tuple[str, ...], width: int, points: int) -> np.ndarray | None:
        """A per-point array (uv or normals) of a trianglemesh, or None (with a warning when it does
        not fit the points: pbrt discards it too)."""
        for name in names:
            values = shape.params.get_floats(name)
            if values:
                break
        else:
            return None
        if len(values) != width * points:
            self.warn(shape.where, f'{shape.type} "{name}" has {len(values)} values, not {width} for each of '
                                   f"the {points} points ({name} ignored)")
            return None
        return np.asarray(values, dtype=np.float64).reshape(-1, width)

