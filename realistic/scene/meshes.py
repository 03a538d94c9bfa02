"""Loading mesh files with trimesh (OBJ, PLY, STL, GLB/GLTF, OFF), one ``MeshObject`` per object.

Bad files raise a one-line ``UserError`` naming the file and what is wrong with it, never trimesh's or
numpy's internal error text (an ``IndexError``, a missing optional module) and never a raw warning:
when trimesh cannot read a file, ``realistic.scene.mesh_diagnosis`` looks at the file itself to say what
is wrong, and where (header line, face line, byte counts). A file trimesh reads is still refused when it
would render wrong (``realistic.scene.mesh_text_checks`` reads the text trimesh would misread):

- an OBJ face index 0 (OBJ counts from 1; trimesh would silently take it as the first vertex), and OBJ
  statements trimesh skips without a word (indented, or a tab after the keyword);
- an ASCII STL facet without exactly 3 vertex lines of 3 numbers (trimesh would shift later vertices);
- vertices that are not three finite numbers, face indices outside the vertex list;
- a coordinate, or a file transform placing one, beyond ``MAX_COORDINATE`` file units; a non-finite or
  singular transform;
- no triangle with a non-zero area (every face degenerate: repeated or collinear vertices).
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from realistic.core.input_files import input_file
from realistic.errors import UserError
from realistic.scene.mesh_diagnosis import no_triangles_message, unreadable_message
from realistic.scene.mesh_text_checks import check_ascii_stl, check_obj_text
from realistic.scene.model import RGB, Mesh

if TYPE_CHECKING:  # imported where used at run time (slow, with the scipy it imports); no cycle involved
    import trimesh

FORMATS = ("obj", "ply", "stl", "glb", "gltf", "off")
#: Largest |coordinate| accepted, in file units, as given and as placed by the file's transforms. Real
#: models stay far below it; beyond it a file is almost surely corrupt (a stray 1e30), and a staged or
#: rendered scene (float32 hit points, about 7 significant digits) could not resolve its detail anyway.
MAX_COORDINATE = 1e12
MAX_CONDITION = 1e12  # a file transform's 3x3 part must be invertible to about float64 precision
_NO_COLOUR = (102, 102, 102)  # trimesh's default colour: the file gave none


@dataclass(frozen=True, eq=False)
class MeshObject:
    """One object of a file: its mesh, where the file places it, and its diffuse colour if given."""

    mesh: Mesh
    transform: np.ndarray  # (4, 4) object to file frame
    colour: RGB | None
    source: str = ""  # the file it came from, for messages


def _colour(geometry: trimesh.Trimesh) -> RGB | None:
    """The object's diffuse colour (OBJ Kd, glTF base colour, PLY/OFF face or vertex colours)."""
    import trimesh.visual  # loaded already: only trimesh's meshes come here

    visual = geometry.visual
    material = getattr(visual, "material", None)
    if material is not None:
        rgba = np.asarray(material.main_color, dtype=float)
    elif isinstance(visual, trimesh.visual.ColorVisuals) and visual.kind is not None:
        rgba = np.asarray(visual.main_color, dtype=float)
    else:
        return None
    if tuple(int(c) for c in rgba[:3]) == _NO_COLOUR:
        return None
    red, green, blue = (float(c) / 255.0 for c in rgba[:3])
    return red, green, blue


def _mesh(geometry: trimesh.Trimesh, name: str) -> Mesh:
    vertices = np.asarray(geometry.vertices, dtype=np.float64)
    faces = np.asarray(geometry.faces, dtype=np.int64)
    # trimesh keeps normals read from the file in its cache; computing them would need scipy.
    normals = np.asarray(geometry.vertex_normals, dtype=np.float64) if "vertex_normals" in geometry._cache else None
    if normals is not None and (normals.shape != vertices.shape or not np.all(np.isfinite(normals))):
        normals = None
    uv = getattr(geometry.visual, "uv", None)
    uv = np.asarray(uv, dtype=np.float64) if uv is not None and len(uv) == len(vertices) else None
    if uv is not None and (uv.shape != (len(vertices), 2) or not np.all(np.isfinite(uv))):
        uv = None
    return Mesh(vertices, faces, normals, uv, name)


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """No numpy floating-point warnings or other warnings from trimesh reach the user; checks follow."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def load_mesh_file(path: str | Path) -> list[MeshObject]:
    """Every triangle mesh in a file, placed as the file places it; bad files raise UserError."""
    path = Path(path)
    _check_path(path)
    extension = path.suffix.lower().lstrip(".")
    if extension == "ply":
        mesh = read_ply(path)
        if mesh is not None:
            _check_object(path, path.name, mesh, np.eye(4))
            objects = [MeshObject(mesh, np.eye(4), None, str(path))]
            with _quiet():
                if not any_face_with_area(mesh):
                    raise UserError(f"{path}: no triangle has a non-zero area (every face has repeated or "
                                    "collinear vertices)")
            return objects
    import trimesh  # slow to import, with scipy: only for what the fast path above does not read

    if extension == "obj":
        check_obj_text(path)
    logging.getLogger("trimesh").setLevel(logging.ERROR)
    try:
        with _quiet():
            # load's return type covers all its ``force`` values; "scene" returns a Scene
            loaded = cast(trimesh.Scene, trimesh.load(str(path), force="scene", process=False))
            objects = []
            for node in loaded.graph.nodes_geometry:
                transform, name = loaded.graph[node]
                geometry = loaded.geometry[name]
                if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
                    continue
                mesh = _mesh(geometry, str(name))
                transform = np.asarray(transform, dtype=np.float64)
                _check_object(path, str(name), mesh, transform)
                objects.append(MeshObject(mesh, transform, _colour(geometry), str(path)))
            if extension == "stl" and objects:
                check_ascii_stl(path)
    except UserError:
        raise
    except Exception as err:  # trimesh raises many types for malformed files
        raise UserError(unreadable_message(path, extension, err)) from None
    if not objects:
        raise UserError(no_triangles_message(path, extension))
    with _quiet():
        if not any(any_face_with_area(o.mesh) for o in objects):
            raise UserError(f"{path}: no triangle has a non-zero area (every face has repeated or collinear "
                            "vertices)")
    return objects


#: Vertex properties holding texture coordinates, in the order trimesh tries them.
_PLY_UV = (("texture_u", "texture_v"), ("u", "v"), ("s", "t"))
_PLY_INDICES = ("vertex_indices", "vertex_index")
#: Properties that only trimesh reads (colours, per-corner uv): a file with any goes to it.
_PLY_FOR_TRIMESH = ("red", "green", "blue", "alpha", "texcoord")


def read_ply(path: Path) -> Mesh | None:
    """The mesh of a PLY file, ASCII or binary, read with plyfile (milliseconds for a scanner's binary
    triangles, without trimesh's slow import): vertex x, y, z with optional normals (nx, ny, nz) and
    uv, and faces triangulated as trimesh does. None for what plyfile cannot parse and for anything else
    (colours, per-face uv, other elements, no triangle), which trimesh then reads or diagnoses. The
    result is what trimesh gives for the same file (``tests/test_meshes_ply.py``)."""
    import plyfile

    data = None
    # Faces of 3 (then 4) indices each are memory-mapped (plyfile's known_list_len, which checks every
    # row's count: other faces fail as a face element error); mixed polygons are read row by row.
    for length in (3, 4, None):
        known = {} if length is None else {"face": {name: length for name in _PLY_INDICES}}
        try:
            with _quiet():
                data = plyfile.PlyData.read(str(path), known_list_len=known)
            break
        except plyfile.PlyElementParseError as err:
            if length is None or err.element is None or err.element.name != "face":
                return None
        except Exception:  # plyfile raises its parse errors, numpy's and the codecs' for malformed files
            return None
    if data is None or sorted(element.name for element in data.elements) != ["face", "vertex"]:
        return None
    vertex, face = data["vertex"].data, data["face"].data
    index_name = next((name for name in _PLY_INDICES if name in (face.dtype.names or ())), None)
    if index_name is None or {*(vertex.dtype.names or ()), *(face.dtype.names or ())} & set(_PLY_FOR_TRIMESH):
        return None
    index = data["face"].ply_property(index_name)
    if not isinstance(index, plyfile.PlyListProperty) or np.dtype(index.val_dtype).kind not in "iu":
        return None
    vertices, faces = _ply_columns(vertex, ("x", "y", "z")), _triangulated(face[index_name])
    if vertices is None or not len(vertices) or not len(faces):
        return None
    normals = _ply_columns(vertex, ("nx", "ny", "nz"))
    uv = next((columns for pair in _PLY_UV if (columns := _ply_columns(vertex, pair)) is not None), None)
    return Mesh(vertices, faces, _finite_or_none(normals), _finite_or_none(uv), path.name)


def _finite_or_none(values: np.ndarray | None) -> np.ndarray | None:
    """``values`` when all finite (trimesh's normals and uv are dropped otherwise too, ``_mesh``)."""
    return values if values is not None and np.all(np.isfinite(values)) else None


def _ply_columns(data: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """(N, len(names)) float64 of an element's numeric scalar properties; None when one is missing."""
    if not all(name in (data.dtype.names or ()) and data.dtype[name].kind in "iuf" for name in names):
        return None
    return np.column_stack([data[name] for name in names]).astype(np.float64)


def _triangulated(lists: np.ndarray) -> np.ndarray:
    """(F, 3) int64 triangles of polygon index lists as trimesh makes them (``triangulate_quads``):
    the triangles, then each quad's (0, 1, 2), then each quad's (2, 3, 0), then fans of the larger
    polygons; lists of fewer than 3 indices are dropped."""
    fans = [np.empty((0, 3), np.int64)]
    if lists.dtype != object:  # memory-mapped rows of one length, 3 or 4
        rows = {k: lists.astype(np.int64) if lists.shape[1] == k else np.empty((0, k), np.int64) for k in (3, 4)}
    else:
        lengths = np.fromiter((len(row) for row in lists), np.int64, len(lists))
        rows = {k: np.array([row for row in lists[lengths == k]], np.int64).reshape(-1, k) for k in (3, 4)}
        fans += [np.column_stack([np.full(len(fan) - 2, fan[0]), fan[1:-1], fan[2:]]).astype(np.int64)
                 for fan in lists[lengths > 4]]
    quads = rows[4]
    return np.concatenate([rows[3], quads[:, [0, 1, 2]], quads[:, [2, 3, 0]], *fans])


def _check_path(path: Path) -> None:
    input_file(path, "mesh file")  # missing, a directory, a FIFO or a device: said as such
    if path.stat().st_size == 0:
        raise UserError(f"{path}: the mesh file is empty")
    extension = path.suffix.lower().lstrip(".")
    if extension not in FORMATS:
        raise UserError(f"{path}: unsupported mesh format {path.suffix!r} (supported: {', '.join(FORMATS)})")


def _check_object(path: Path, name: str, mesh: Mesh, transform: np.ndarray) -> None:
    vertices, faces = mesh.vertices, mesh.faces
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        count = vertices.shape[1] if vertices.ndim == 2 else 0
        raise UserError(f"{path}: object {name!r} has vertices of {count} coordinates, not 3")
    if not np.all(np.isfinite(vertices)):
        raise UserError(f"{path}: object {name!r} has non-finite vertex coordinates")
    peak = float(np.abs(vertices).max()) if len(vertices) else 0.0
    if peak > MAX_COORDINATE:
        raise UserError(f"{path}: object {name!r} has a vertex coordinate of {peak:.3g}, beyond the "
                        f"±{MAX_COORDINATE:.0e} accepted")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise UserError(f"{path}: object {name!r} has face indices outside its vertex list")
    if transform.shape != (4, 4) or not np.all(np.isfinite(transform)):
        raise UserError(f"{path}: object {name!r} is placed by a non-finite transform")
    if not np.linalg.cond(transform[:3, :3]) <= MAX_CONDITION:
        raise UserError(f"{path}: object {name!r} is placed by a singular transform (a zero scale)")
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    corners = np.array([[(lo, hi)[(i >> axis) & 1][axis] for axis in range(3)] for i in range(8)])
    placed = corners @ transform[:3, :3].T + transform[:3, 3]
    if not np.abs(placed).max() <= MAX_COORDINATE:
        raise UserError(f"{path}: object {name!r} is placed by the file's transforms beyond the "
                        f"±{MAX_COORDINATE:.0e} accepted")


def any_face_with_area(mesh: Mesh, chunk: int = 1 << 12) -> bool:
    """``faces_with_area(mesh).any()``, stopping at the first block of faces with an area (a real
    mesh's first)."""
    size = _size(mesh.vertices)
    return size > 0 and any(_with_area(mesh.vertices, mesh.faces[start:start + chunk], size).any()
                            for start in range(0, len(mesh.faces), chunk))


def faces_with_area(mesh: Mesh, chunk: int = 1 << 16) -> np.ndarray:
    """Per face, whether the triangle has a non-zero area (relative to the object's size, so tiny
    objects count); in chunks, so a large mesh needs no large temporaries."""
    has_area = np.zeros(len(mesh.faces), dtype=bool)
    size = _size(mesh.vertices)
    if not size > 0:
        return has_area
    for start in range(0, len(mesh.faces), chunk):
        has_area[start:start + chunk] = _with_area(mesh.vertices, mesh.faces[start:start + chunk], size)
    return has_area


def _size(vertices: np.ndarray) -> float:
    return float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0


def _with_area(vertices: np.ndarray, faces: np.ndarray, size: float) -> np.ndarray:
    triangles = vertices[faces] / size
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    return np.any(cross != 0, axis=1)
