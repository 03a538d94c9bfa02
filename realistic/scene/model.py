"""The scene model: meshes stored once, instances with 4x4 transforms, materials, area lights.

Plain dataclasses and numpy arrays, so any front end (the CLI's mesh scene, the default scene,
a pbrt importer) builds the same objects. World units are the scene's own; transforms are numpy
(4, 4) object-to-world matrices acting on column vectors.

Analytic shapes are tessellated into ``Mesh`` objects by ``realistic.scene.shapes``. Area lights
are sampled analytically by the integrator and also tessellated so camera rays can see them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from realistic.core import validation
from realistic.core.transforms import transform_points
from realistic.errors import UserError
from realistic.scene.mipmap import MipMap

if TYPE_CHECKING:
    from realistic.camera.base import Camera

RGB = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangles in object space; ``normals`` per vertex (smooth shading) or None (face normals)."""

    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    normals: np.ndarray | None = None  # (V, 3) unit
    uv: np.ndarray | None = None  # (V, 2)
    name: str = ""


@dataclass(frozen=True, eq=False)
class ImageTexture:
    """An RGB image (linear, rows top to bottom) repeated over uv, looked up through a MIP map.

    ``v_origin`` says which row v = 0 is: "bottom" (pbrt-v3 and v4 flip images on load) or "top"
    (pbrt-v1 and v2 look up the file's first row at v = 0); the pbrt dialect decides. ``filter``
    ("point", "bilinear", "trilinear", "ewa"), ``max_anisotropy`` and ``wrap`` ("repeat", "black",
    "clamp") are pbrt's imagemap parameters; the defaults are pbrt-v3's. A lookup without a
    footprint reads level 0 bilinearly whatever the filter.
    """

    pixels: np.ndarray  # (H, W, 3) float32, linear
    scale: tuple[float, float] = (1.0, 1.0)  # repetitions of the image per unit of u, v
    v_origin: str = "bottom"
    filter: str = "ewa"
    max_anisotropy: float = 8.0
    wrap: str = "repeat"
    offset: tuple[float, float] = (0.0, 0.0)  # pbrt's udelta, vdelta: added to the scaled u, v

    def __post_init__(self) -> None:
        validation.texture_filter(self.filter)
        validation.texture_wrap(self.wrap)
        validation.max_anisotropy(self.max_anisotropy)
        for name, value in zip(("uscale", "vscale", "udelta", "vdelta"), (*self.scale, *self.offset)):
            validation.finite(value, f"image texture {name}")

    @cached_property
    def mipmap(self) -> MipMap:
        """The MIP map of ``pixels``, built on first use and kept."""
        return MipMap(self.pixels, self.wrap, self.max_anisotropy)


@dataclass(frozen=True)
class GridTexture:
    """Thin lines of ``line`` colour on ``base`` colour, ``cells`` cells per unit of u and v."""

    base: RGB = (0.8, 0.8, 0.8)
    line: RGB = (0.1, 0.1, 0.1)
    cells: float = 10.0
    line_width: float = 0.04  # fraction of a cell


@dataclass(frozen=True)
class CheckerTexture:
    """Alternating squares, ``cells`` per unit of u and v."""

    even: RGB = (0.8, 0.8, 0.8)
    odd: RGB = (0.2, 0.2, 0.2)
    cells: float = 10.0


Texture = ImageTexture | GridTexture | CheckerTexture


@dataclass(frozen=True)
class Material:
    """Matte reflector: albedo = ``diffuse`` times the texture's colour when there is one.

    ``sigma`` is the Oren-Nayar roughness in degrees (the standard deviation of the facet slope
    angle, pbrt's ``matte`` sigma); 0 is Lambertian. Other materials: ``realistic.scene.materials``.
    """

    diffuse: RGB = (0.5, 0.5, 0.5)
    texture: Texture | None = None
    sigma: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= validation.finite(self.sigma, "matte sigma (degrees)") <= 90.0:
            raise UserError(f"matte sigma (degrees) must be between 0 and 90, got {self.sigma:g}")


@dataclass(frozen=True, eq=False)
class Instance:
    """One placement of a mesh (``Scene.meshes[mesh]``) in the world."""

    mesh: int
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    material: Material = Material()


@dataclass(frozen=True, eq=False)
class AreaLight:
    """A one-sided uniform emitter of ``radiance`` in the object-space plane z = 0, emitting toward +z.

    ``shape`` "disk": radius ``size[0]`` about the origin; "quad": ``size[0]`` by ``size[1]``
    centred on the origin. The emitting side follows the transformed normal (inverse transpose),
    flipped by ``reverse_orientation`` as in pbrt.
    """

    shape: str
    size: tuple[float, float]
    radiance: RGB
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    reverse_orientation: bool = False
    two_sided: bool = False

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
    metadata: dict = field(default_factory=dict)  # what an image header says of the scene's source (file, staging)

    @property
    def area_lights(self) -> list[AreaLight]:
        """The area lights among ``lights``, in order: embree geometry ``len(instances) + j`` is the j-th."""
        return [light for light in self.lights if isinstance(light, AreaLight)]

    def add_mesh(self, mesh: Mesh) -> int:
        """Store a mesh once; returns its index for ``Instance.mesh``."""
        self.meshes.append(mesh)
        return len(self.meshes) - 1

    def add(self, mesh: Mesh | int, transform: np.ndarray | None = None,
            material: Material = Material()) -> Instance:
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
