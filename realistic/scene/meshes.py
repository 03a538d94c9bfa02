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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.scene.mesh_diagnosis import no_triangles_message, unreadable_message
from realistic.scene.mesh_text_checks import check_ascii_stl, check_obj_text
from realistic.scene.model import RGB, Mesh

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


def _colour(geometry) -> RGB | None:
    """The object's diffuse colour (OBJ Kd, glTF base colour, PLY/OFF face or vertex colours)."""
    visual = geometry.visual
    material = getattr(visual, "material", None)
    if material is not None:
        rgba = np.asarray(material.main_color, dtype=float)
    elif getattr(visual, "kind", None) is not None:
        rgba = np.asarray(visual.main_color, dtype=float)
    else:
        return None
    if tuple(int(c) for c in rgba[:3]) == _NO_COLOUR:
        return None
    return tuple(float(c) / 255.0 for c in rgba[:3])


def _mesh(geometry, name: str) -> Mesh:
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
def _quiet():
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
        mesh = read_plain_binary_ply(path)
        if mesh is not None:
            _check_object(path, path.name, mesh, np.eye(4))
            objects = [MeshObject(mesh, np.eye(4), None, str(path))]
            with _quiet():
                if not any_face_with_area(mesh):
                    raise UserError(f"{path}: no triangle has a non-zero area (every face has repeated or "
                                    "collinear vertices)")
            return objects
    import trimesh  # about 1.5 s with the scipy it imports: only for what the fast path above does not read

    if extension == "obj":
        check_obj_text(path)
    logging.getLogger("trimesh").setLevel(logging.ERROR)
    try:
        with _quiet():
            loaded = trimesh.load(str(path), force="scene", process=False)
            objects = []
            for node in loaded.graph.nodes_geometry:
                transform, name = loaded.graph[node]
                geometry = loaded.geometry[name]
                if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
                    continue
                mesh = _mesh(geometry, str(name))
                transform = np.asarray(transform, dtype=np.float64)
                _check_object(path, name, mesh, transform)
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


_PLY_FLOATS = {"float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_COUNTS = {"uchar": "u1", "uint8": "u1"}
_PLY_INDICES = {"int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4"}


def read_plain_binary_ply(path: Path) -> Mesh | None:
    """The mesh of a binary PLY of the plainest layout (as scanners' files are: vertices with float x,
    y, z only, then triangles as a uchar-counted int list), read with numpy in milliseconds; None for
    anything else (ASCII, other properties or elements, polygons, a size that does not add up), which
    trimesh then reads. The result is what trimesh gives for the same file (``tests/test_meshes_ply.py``)."""
    with open(path, "rb") as file:
        head = file.read(4096)
        end = head.find(b"end_header\n")
        if not head.startswith(b"ply\n") or end < 0:
            return None
        lines = [line.split() for line in head[:end].decode("ascii", "replace").splitlines()[1:]]
        lines = [line for line in lines if line and line[0] not in ("comment", "obj_info")]
        layout = [line for line in lines if line[0] != "format"]
        formats = [line for line in lines if line[0] == "format"]
        if len(formats) != 1 or formats[0][1:] not in (["binary_little_endian", "1.0"], ["binary_big_endian", "1.0"]):
            return None
        order = "<" if formats[0][1] == "binary_little_endian" else ">"
        if (len(layout) != 6 or layout[0][:2] != ["element", "vertex"] or layout[4][:2] != ["element", "face"]
                or [line[-1] for line in layout[1:4]] != ["x", "y", "z"] or len(layout[5]) != 5
                or layout[5][:2] != ["property", "list"] or layout[5][4] not in ("vertex_indices", "vertex_index")):
            return None
        kinds = [line[1] for line in layout[1:4] if len(line) == 3 and line[0] == "property"]
        if len(kinds) != 3 or len(set(kinds)) != 1 or kinds[0] not in _PLY_FLOATS:
            return None
        if layout[5][2] not in _PLY_COUNTS or layout[5][3] not in _PLY_INDICES:
            return None
        try:
            n, m = int(layout[0][2]), int(layout[4][2])
        except (ValueError, IndexError):
            return None
        if n <= 0 or m <= 0 or len(layout[0]) != 3 or len(layout[4]) != 3:
            return None
        vertex = np.dtype((order + _PLY_FLOATS[kinds[0]], 3))
        face = np.dtype([("count", "u1"), ("index", order + _PLY_INDICES[layout[5][3]], 3)])
        file.seek(end + len(b"end_header\n"))
        body = file.read()
    if len(body) != n * vertex.itemsize + m * face.itemsize:
        return None
    vertices = np.frombuffer(body, vertex, n).astype(np.float64)
    faces = np.frombuffer(body, face, m, offset=n * vertex.itemsize)
    if not np.all(faces["count"] == 3):
        return None
    return Mesh(vertices.reshape(n, 3), faces["index"].astype(np.int64), None, None, path.name)


def _check_path(path: Path) -> None:
    if path.is_dir():
        raise UserError(f"{path}: is a directory, not a mesh file")
    if not path.exists():
        raise UserError(f"{path}: no such mesh file")
    if not path.is_file():
        raise UserError(f"{path}: not a regular file")
    if path.stat().st_size == 0:
        raise UserError(f"{path}: the mesh file is empty")
    extension = path.suffix.lower().lstrip(".")
    if extension not in FORMATS:
        raise UserError(f"{path}: unsupported mesh format {path.suffix!r} (supported: {', '.join(FORMATS)})")


def _check_object(path: Path, name, mesh: Mesh, transform: np.ndarray) -> None:
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
