"""Staging: a mesh set on a grid floor under a disk light, the default scene, and framing a subject.

World units are metres in these setups (``MM_PER_METRE`` = 1000): a loaded mesh is scaled so its
largest bounding-box side is ``MESH_SIZE`` m, set on the floor y = 0, +y up. ``auto_eye`` places
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
from realistic.scene.meshes import MeshObject
from realistic.scene.model import AreaLight, GridTexture, Material, Scene
from realistic.scene.pbrt.importer import import_world
from realistic.scene.shapes import quad

MESH_SIZE = 1.0
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
    """The objects of a mesh file normalised to MESH_SIZE, resting on a grid floor, lit from above."""
    points = np.concatenate([transform_points(o.transform, o.mesh.vertices) for o in objects])
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = float(np.max(hi - lo))
    if not size > 0:
        raise UserError("the mesh has zero size (all its vertices at one point)")
    k = MESH_SIZE / size
    centre = (lo + hi) / 2
    place = scale(k) @ translate(-centre[0], -lo[1], -centre[2])
    scene = Scene(background=(0.02, 0.02, 0.03))
    for obj in objects:
        material = Material(obj.colour if obj.colour is not None else MESH_COLOUR)
        scene.add(obj.mesh, place @ obj.transform, material)
    _stage(scene, 40.0, 4.0, 1.5, 40.0)
    extent = (hi - lo) * k
    return Setup(scene, np.array([0.0, extent[1] / 2, 0.0]), float(np.linalg.norm(extent)) / 2)


def default_setup() -> Setup:
    """The default scene, ``scenes/default.pbrt``: its world, and its camera's eye and focus target."""
    scene, parsed = import_world(data_file("scenes/default.pbrt"))
    scene.background = (0.02, 0.02, 0.03)  # a dim sky (pbrt files have no background) so the horizon reads
    world_from_camera = np.linalg.inv(parsed.camera.transform)
    eye = world_from_camera[:3, 3]
    forward = world_from_camera[:3, 2] / np.linalg.norm(world_from_camera[:3, 2])
    target = eye + forward * parsed.camera.params.get_float("focusdistance")
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
