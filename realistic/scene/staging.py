"""Staging: a mesh set on a grid floor under a disk light, the default scene, and framing a subject.

World units are metres in these setups (``MM_PER_METRE`` = 1000): a loaded mesh is scaled so its
largest bounding-box side (of its triangles with an area) is ``MESH_SIZE`` m, set on the floor y = 0,
+y up; ``mesh_setup`` refuses a mesh that would not render right at that scale. ``auto_eye`` places
the camera so the subject fills the frame; ``LensCamera.looking_at`` builds the camera there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic.camera.lens_camera import MM_PER_METRE
from realistic.core.data_files import data_file
from realistic.core.transforms import rotate, scale, transform_points, translate
from realistic.errors import UserError
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, nearest_focus_mm, thick_lens
from realistic.scene.meshes import MAX_COORDINATE, MeshObject, faces_with_area
from realistic.scene.model import AreaLight, GridTexture, Material, Mesh, Scene
from realistic.scene.pbrt.importer import import_world
from realistic.scene.shapes import quad

MESH_SIZE = 1.0
MIN_MESH_EXTENT = 1e-12  # file units: a smaller mesh is taken for a units error or a corrupt file
MESH_COLOUR = (0.75, 0.35, 0.22)
GRID_SPACING = 0.1  # m between floor grid lines
VIEW_DIRECTION = np.array([0.55, 0.35, -1.0])  # from the target toward the eye


@dataclass
class Setup:
    """A scene and where to look: ``target`` is aimed at and focused on; ``radius`` bounds the subject."""

    scene: Scene
    target: np.ndarray
    radius: float
    eye: np.ndarray | None = None  # None: placed so the subject fills the frame


def _stage(scene: Scene, floor_size: float, light_height: float, light_radius: float, radiance: float) -> None:
    """Grid floor (y = 0, lines every GRID_SPACING) and a disk light facing down."""
    grid = GridTexture(base=(0.75, 0.75, 0.75), line=(0.08, 0.08, 0.08), cells=floor_size / GRID_SPACING)
    scene.add(quad(floor_size, floor_size), rotate(-90, (1, 0, 0)), Material((1.0, 1.0, 1.0), grid))
    scene.lights.append(AreaLight("disk", (light_radius, light_radius), (radiance,) * 3,
                                  translate(0, light_height, 0) @ rotate(90, (1, 0, 0))))


def mesh_setup(objects: list[MeshObject]) -> Setup:
    """The objects of a mesh file normalised to MESH_SIZE, resting on a grid floor, lit from above.

    The size is that of the triangles with an area (a stray vertex, unused or only in degenerate faces,
    would shrink the subject to a speck). A mesh is refused when staging it would render wrong: a size
    outside ``MIN_MESH_EXTENT`` to ``MAX_COORDINATE`` file units, or no triangle left with an area once
    scaled to MESH_SIZE in the renderer's float32 coordinates (a bounding box far larger than every
    triangle, as a far vertex makes).
    """
    where = next((o.source for o in objects if o.source), "the mesh")
    with np.errstate(all="ignore"):
        points = np.concatenate([transform_points(o.transform, o.mesh.vertices[_visible(o.mesh)]) for o in objects])
        if not len(points):
            raise UserError(f"{where}: no triangle has a non-zero area")
        if not np.all(np.isfinite(points)) or np.abs(points).max() > MAX_COORDINATE:
            raise UserError(f"{where}: the mesh is placed beyond the ±{MAX_COORDINATE:.0e} accepted")
        lo, hi = points.min(axis=0), points.max(axis=0)
        size = float(np.max(hi - lo))
    if not size > 0:
        raise UserError(f"{where}: the mesh has zero size (all its vertices at one point)")
    if size < MIN_MESH_EXTENT:
        raise UserError(f"{where}: the mesh is {size:.3g} file units across, smaller than the "
                        f"{MIN_MESH_EXTENT:.0e} that can be staged")
    k = MESH_SIZE / size
    centre = (lo + hi) / 2
    place = scale(k) @ translate(-centre[0], -lo[1], -centre[2])
    if not any(_resolvable(o.mesh, place @ o.transform) for o in objects):
        raise UserError(f"{where}: no triangle is large enough to resolve at the mesh's size ({size:.3g} file "
                        f"units across, scaled to {MESH_SIZE:g} m in float32): is a vertex far from the rest?")
    scene = Scene(background=(0.02, 0.02, 0.03))
    for obj in objects:
        material = Material(obj.colour if obj.colour is not None else MESH_COLOUR)
        scene.add(obj.mesh, place @ obj.transform, material)
    _stage(scene, 40.0, 4.0, 1.5, 40.0)
    extent = (hi - lo) * k
    return Setup(scene, np.array([0.0, extent[1] / 2, 0.0]), float(np.linalg.norm(extent)) / 2)


def _visible(mesh: Mesh) -> np.ndarray:
    """Which vertices belong to a triangle with a non-zero area (in the mesh's own units)."""
    visible = np.zeros(len(mesh.vertices), dtype=bool)
    visible[mesh.faces[faces_with_area(mesh)].ravel()] = True
    return visible


def _resolvable(mesh: Mesh, transform: np.ndarray, chunk: int = 1 << 16) -> bool:
    """Whether any triangle keeps a non-zero area in world float32 coordinates (as the intersector sees it)."""
    for start in range(0, len(mesh.faces), chunk):
        corners = mesh.vertices[mesh.faces[start:start + chunk]].reshape(-1, 3)
        world = transform_points(transform, corners).astype(np.float32).astype(np.float64).reshape(-1, 3, 3)
        cross = np.cross(world[:, 1] - world[:, 0], world[:, 2] - world[:, 0])
        if np.any(cross != 0):
            return True
    return False


def default_setup() -> Setup:
    """The default scene, ``scenes/default.pbrt``: its world, and its camera's eye and focus target."""
    path = data_file("scenes/default.pbrt")
    scene, parsed, _ = import_world(path)
    camera = parsed.camera
    if camera is None:
        raise UserError(f"{path} has no Camera: reinstall the package")
    scene.background = (0.02, 0.02, 0.03)  # a dim sky (pbrt files have no background) so the horizon reads
    world_from_camera = np.linalg.inv(camera.transform)
    eye = world_from_camera[:3, 3]
    forward = world_from_camera[:3, 2] / np.linalg.norm(world_from_camera[:3, 2])
    target = eye + forward * camera.params.get_float("focusdistance")
    return Setup(scene, target, 0.3, eye=eye)


def auto_eye(setup: Setup, lens: LensSystem, film_short_side_mm: float) -> np.ndarray:
    """An eye position from which the subject's bounding sphere about fills the frame."""
    direction = VIEW_DIRECTION / np.linalg.norm(VIEW_DIRECTION)
    image_mm = thick_lens(lens).focal_length_mm
    distance = setup.radius
    for _ in range(2):  # refine the image distance for the focus at that distance
        half_angle = math.atan(film_short_side_mm / 2 / image_mm)
        distance = max(0.85 * setup.radius / math.sin(half_angle), 1.5 * nearest_focus_mm(lens) / MM_PER_METRE)
        t = thick_lens(lens)
        image_mm = film_distance_for_focus(lens, distance * MM_PER_METRE) + t.rear_principal_from_rear_vertex_mm
    return setup.target + direction * distance
