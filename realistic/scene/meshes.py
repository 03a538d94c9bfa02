"""Loading mesh files with trimesh (OBJ, PLY, STL, GLB/GLTF, OFF), one ``MeshObject`` per object."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.scene.model import RGB, Mesh

FORMATS = ("obj", "ply", "stl", "glb", "gltf", "off")
_NO_COLOUR = (102, 102, 102)  # trimesh's default colour: the file gave none


@dataclass(frozen=True, eq=False)
class MeshObject:
    """One object of a file: its mesh, where the file places it, and its diffuse colour if given."""

    mesh: Mesh
    transform: np.ndarray  # (4, 4) object to file frame
    colour: RGB | None


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
    return Mesh(vertices, faces, normals, uv, name)


def load_mesh_file(path: str | Path) -> list[MeshObject]:
    """Every triangle mesh in a file, placed as the file places it; bad files raise UserError."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such mesh file")
    if path.stat().st_size == 0:
        raise UserError(f"{path}: the mesh file is empty")
    extension = path.suffix.lower().lstrip(".")
    if extension not in FORMATS:
        raise UserError(f"{path}: unsupported mesh format {path.suffix!r} (supported: {', '.join(FORMATS)})")
    logging.getLogger("trimesh").setLevel(logging.ERROR)
    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as err:  # trimesh raises many types for malformed files
        raise UserError(f"{path}: not a readable {extension.upper()} mesh ({err})") from None
    objects = []
    for node in loaded.graph.nodes_geometry:
        transform, name = loaded.graph[node]
        geometry = loaded.geometry[name]
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        mesh = _mesh(geometry, str(name))
        if not np.all(np.isfinite(mesh.vertices)):
            raise UserError(f"{path}: object {name!r} has non-finite vertex coordinates")
        if mesh.faces.min() < 0 or mesh.faces.max() >= len(mesh.vertices):
            raise UserError(f"{path}: object {name!r} has face indices outside its vertex list")
        objects.append(MeshObject(mesh, np.asarray(transform, dtype=np.float64), _colour(geometry)))
    if not objects:
        raise UserError(f"{path}: the file holds no triangles")
    return objects
