"""The scene model: meshes stored once, instances with 4x4 transforms, materials, area lights.

Plain dataclasses and numpy arrays, so any front end (the CLI's mesh scene, the default scene,
a pbrt importer) builds the same objects. World units are the scene's own; transforms are numpy
(4, 4) object-to-world matrices acting on column vectors.

Analytic shapes (disk, sphere, cone, quad) are tessellated into ``Mesh`` objects here, finely
enough that facets do not show at ordinary resolutions. Area lights are sampled analytically by
the integrator and also tessellated so camera rays can see them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

RGB = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class Mesh:
    """Triangles in object space; ``normals`` per vertex (smooth shading) or None (face normals)."""

    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    normals: np.ndarray | None = None  # (V, 3) unit
    uv: np.ndarray | None = None  # (V, 2)
    name: str = ""


@dataclass(frozen=True)
class ImageTexture:
    """An RGB image (linear, rows top to bottom) repeated over uv; v = 0 is the image's bottom row."""

    pixels: np.ndarray  # (H, W, 3) float32, linear
    scale: tuple[float, float] = (1.0, 1.0)  # repetitions of the image per unit of u, v


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
    """Lambertian reflector: albedo = ``diffuse`` times the texture's colour when there is one."""

    diffuse: RGB = (0.5, 0.5, 0.5)
    texture: Texture | None = None


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

    def mesh(self) -> Mesh:
        """The emitter tessellated in object space (so camera rays see it)."""
        if self.shape == "disk":
            return disk(self.size[0])
        return quad(self.size[0], self.size[1])


@dataclass(eq=False)
class Scene:
    """Meshes (each stored once), their instances, area lights and the background colour.

    The background is what camera rays that hit nothing see; it does not light the scene.
    """

    meshes: list[Mesh] = field(default_factory=list)
    instances: list[Instance] = field(default_factory=list)
    lights: list[AreaLight] = field(default_factory=list)
    background: RGB = (0.0, 0.0, 0.0)

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


# Transforms ----------------------------------------------------------------------------------

def translate(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(x: float, y: float | None = None, z: float | None = None) -> np.ndarray:
    return np.diag([x, x if y is None else y, x if z is None else z, 1.0])


def rotate(angle_deg: float, axis: tuple[float, float, float]) -> np.ndarray:
    """Rotation by ``angle_deg`` about ``axis`` (right-handed, as pbrt's Rotate)."""
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    m = np.eye(4)
    m[:3, :3] = [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                 [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                 [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]]
    return m


def transform_points(m: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ m[:3, :3].T + m[:3, 3]


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 1.0, 0.0])) -> np.ndarray:
    """World-from-camera rotation and translation: camera +z toward target, +y up, +x right."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(np.asarray(up, float), forward)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross([0.0, 0.0, 1.0], forward)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(forward, right), forward, eye
    return m


# Tessellated analytic shapes -----------------------------------------------------------------

DEFAULT_SEGMENTS = 256


def disk(radius: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """Disk in the plane z = 0 facing +z; uv = (x, y) mapped from [-r, r] to [0, 1]."""
    angle = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    rim = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(segments)])
    vertices = np.vstack([[0.0, 0.0, 0.0], rim])
    ring = np.arange(segments)
    faces = np.column_stack([np.zeros(segments, int), 1 + ring, 1 + (ring + 1) % segments])
    normals = np.tile([0.0, 0.0, 1.0], (segments + 1, 1))
    return Mesh(vertices, faces, normals, vertices[:, :2] / (2 * radius) + 0.5, "disk")


def quad(width: float, height: float) -> Mesh:
    """Rectangle ``width`` x ``height`` centred on the origin in z = 0 facing +z; uv over [0, 1]^2."""
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    vertices = np.column_stack([(uv[:, 0] - 0.5) * width, (uv[:, 1] - 0.5) * height, np.zeros(4)])
    return Mesh(vertices, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0.0, 0.0, 1.0], (4, 1)), uv, "quad")


def _grid_faces(rows: int, cols: int) -> np.ndarray:
    """Two triangles per cell of a (rows+1) x (cols+1) vertex grid, counter-clockwise seen from outside."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (r * (cols + 1) + c).ravel()
    b, d = a + 1, a + cols + 1
    return np.concatenate([np.column_stack([a, d, b]), np.column_stack([b, d, d + 1])])


def sphere(radius: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """UV sphere about the origin, z the polar axis, smooth normals."""
    rings = segments // 2
    theta = np.linspace(0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0, 2 * np.pi, segments + 1)[None, :]
    normals = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                        np.cos(theta) * np.ones_like(phi)], axis=-1).reshape(-1, 3)
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), 1 - theta / np.pi), axis=-1).reshape(-1, 2)
    return Mesh(normals * radius, _grid_faces(rings, segments), normals, uv, "sphere")


def cone(radius: float, height: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """Cone with its base disk of ``radius`` in z = 0 and apex at z = ``height`` (as pbrt's cone), open base."""
    stacks = 16
    s = np.linspace(0, 1, stacks + 1)[:, None]  # 0 at the base, 1 at the apex
    phi = np.linspace(0, 2 * np.pi, segments + 1)[None, :]
    r = radius * (1 - s)
    vertices = np.stack([r * np.cos(phi), r * np.sin(phi), height * s * np.ones_like(phi)], axis=-1).reshape(-1, 3)
    slope = radius / height
    n = np.stack(np.broadcast_arrays(np.cos(phi), np.sin(phi), slope * np.ones_like(s)), axis=-1).reshape(-1, 3)
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), s), axis=-1).reshape(-1, 2)
    faces = _grid_faces(stacks, segments)[:, ::-1]  # rows run base to apex: reverse to wind outward
    return Mesh(vertices, faces, n / np.linalg.norm(n, axis=1, keepdims=True), uv, "cone")
