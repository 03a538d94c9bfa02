"""The scene model: meshes stored once, instances with 4x4 transforms, materials, area lights.

Plain dataclasses and numpy arrays, so any front end (the CLI's mesh scene, the default scene,
a pbrt importer) builds the same objects. World units are the scene's own; transforms are numpy
(4, 4) object-to-world matrices acting on column vectors.

Analytic shapes are tessellated into ``Mesh`` objects by ``realistic.scene.shapes``. Area lights
are sampled analytically by the integrator and also tessellated so camera rays can see them.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from realistic.core import validation
from realistic.core.transforms import transform_points
from realistic.scene.materials import SurfaceMaterial

# The matte material and the textures live in ``scene.surfaces`` (which ``scene.materials`` builds
# on); named here too, where the scene's users have always found them.
from realistic.scene.surfaces import RGB as RGB
from realistic.scene.surfaces import CheckerTexture as CheckerTexture
from realistic.scene.surfaces import GridTexture as GridTexture
from realistic.scene.surfaces import ImageTexture as ImageTexture
from realistic.scene.surfaces import Material as Material
from realistic.scene.surfaces import Texture as Texture

if TYPE_CHECKING:
    from realistic.camera.base import Camera

#: What an instance is made of when its maker names no material: matte grey.
DEFAULT_MATERIAL = Material()


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangles in object space; ``normals`` per vertex (smooth shading) or None (face normals)."""

    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    normals: np.ndarray | None = None  # (V, 3) unit
    uv: np.ndarray | None = None  # (V, 2)
    name: str = ""

    def __repr__(self) -> str:
        """One line, no arrays."""
        extras = "".join(f", {what}" for what, there in (("normals", self.normals is not None),
                                                          ("uv", self.uv is not None)) if there)
        return f"Mesh({self.name!r}, {len(self.vertices):,} vertices, {len(self.faces):,} triangles{extras})"


@dataclass(frozen=True, eq=False)
class Instance:
    """One placement of a mesh (``Scene.meshes[mesh]``) in the world."""

    mesh: int
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    material: SurfaceMaterial = DEFAULT_MATERIAL


@dataclass(frozen=True, eq=False)
class AreaLight:
    """A one-sided uniform emitter of ``radiance`` in the object-space plane z = 0, emitting toward +z.

    ``shape`` "disk": radius ``size[0]`` about the origin; "quad": ``size[0]`` by ``size[1]``
    centred on the origin. The emitting side follows the transformed normal (inverse transpose),
    flipped by ``reverse_orientation`` as in pbrt.

    ``material``: what its surface reflects by, on both sides, besides emitting (pbrt gives an area
    light's shape the material in effect where it is declared); None for a pure emitter, at which
    paths end.
    """

    shape: str
    size: tuple[float, float]
    radiance: RGB
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    reverse_orientation: bool = False
    two_sided: bool = False
    material: SurfaceMaterial | None = None

    def __post_init__(self) -> None:
        validation.emission(self.radiance, "area light radiance")

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """World (centre, axis a, axis b, unit emitting normal); a point is c + a x + b y.

        For a disk (x, y) lies in the unit disk; for a quad in [-1, 1]^2.
        """
        m = np.asarray(self.transform, dtype=np.float64)
        half_x, half_y = (self.size[0], self.size[0]) if self.shape == "disk" else (self.size[0] / 2,
                                                                                     self.size[1] / 2)
        a = m[:3, 0] * half_x
        b = m[:3, 1] * half_y
        normal = np.linalg.inv(m[:3, :3]).T @ np.array([0.0, 0.0, 1.0])
        normal /= np.linalg.norm(normal)
        if self.reverse_orientation:
            normal = -normal
        return m[:3, 3].copy(), a, b, normal

    def area(self) -> float:
        _, a, b, _ = self.frame()
        cross = float(np.linalg.norm(np.cross(a, b)))
        return math.pi * cross if self.shape == "disk" else 4.0 * cross


@dataclass(eq=False)
class Scene:
    """Meshes (each stored once), their instances, lights and the background colour.

    The background is what camera rays that hit nothing see when the scene has no infinite light;
    it does not light the scene.
    ``realistic.render`` renders through ``camera`` when it is given none.
    """

    meshes: list[Mesh] = field(default_factory=list)
    instances: list[Instance] = field(default_factory=list)
    lights: list = field(default_factory=list)  # AreaLight or any light of ``realistic.scene.lights``
    background: RGB = (0.0, 0.0, 0.0)
    camera: Camera | None = None  # the scene's own view: a pbrt file's camera, a loaded mesh's framing
    light_samples: int = 1  # light samples per hit the scene asks for
    integrator: str = "directlighting"  # "directlighting" or "path" (``realistic.renderer.integrators``)
    max_depth: int = 5  # bounces of "path"; specular bounces of "directlighting" (pbrt's maxdepth)
    # the least scale of a camera ray's pixel footprint at high spp (``footprint.differential_scale``):
    # pbrt-v4's 1/8, 0 for a pbrt-v1..v3 file (its pbrt shrinks footprints by 1/sqrt(spp) without bound)
    differential_floor: float = 0.125
    metadata: dict = field(default_factory=dict)  # what an image header says of the scene's source (file, staging)

    def __repr__(self) -> str:
        """One line, no arrays: what the scene holds, how it is lit and seen."""
        triangles = sum(len(self.meshes[instance.mesh].faces) for instance in self.instances)
        lights = ", ".join(f"{count} {kind}" for kind, count in
                           sorted(Counter(type(light).__name__ for light in self.lights).items())) or "no lights"
        return (f"Scene({len(self.instances)} instances of {len(self.meshes)} meshes, {triangles:,} triangles, "
                f"{lights}, {self.integrator}, camera {self.camera!r})")

    @property
    def area_lights(self) -> list[AreaLight]:
        """The area lights among ``lights``, in order: embree geometry ``len(instances) + j`` is the j-th."""
        return [light for light in self.lights if isinstance(light, AreaLight)]

    def add_mesh(self, mesh: Mesh) -> int:
        """Store a mesh once; returns its index for ``Instance.mesh``."""
        self.meshes.append(mesh)
        return len(self.meshes) - 1

    def add(self, mesh: Mesh | int, transform: np.ndarray | None = None,
            material: SurfaceMaterial = DEFAULT_MATERIAL) -> Instance:
        """Place a mesh (a new one, or the index of a stored one) in the world."""
        index = self.add_mesh(mesh) if isinstance(mesh, Mesh) else mesh
        instance = Instance(index, np.eye(4) if transform is None else np.asarray(transform, float), material)
        self.instances.append(instance)
        return instance

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounding box (lo, hi) of all instances."""
        corners = [transform_points(inst.transform, self.meshes[inst.mesh].vertices) for inst in self.instances]
        points = np.concatenate(corners) if corners else np.zeros((1, 3))
        return points.min(axis=0), points.max(axis=0)
