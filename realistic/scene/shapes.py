"""Analytic shapes tessellated into meshes, finely enough that facets do not show at ordinary resolutions.

Sizes are positive finite lengths (``realistic.core.validation.positive_length``): a zero or
negative radius would give a mesh of no area or non-finite texture coordinates.
"""

from __future__ import annotations

import numpy as np

from realistic.core.validation import positive_length
from realistic.scene.model import AreaLight, Mesh

DEFAULT_SEGMENTS = 256


def disk(radius: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """Disk in the plane z = 0 facing +z; uv = (x, y) mapped from [-r, r] to [0, 1]."""
    radius = positive_length(radius, "disk radius")
    angle = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    rim = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(segments)])
    vertices = np.vstack([[0.0, 0.0, 0.0], rim])
    ring = np.arange(segments)
    faces = np.column_stack([np.zeros(segments, int), 1 + ring, 1 + (ring + 1) % segments])
    normals = np.tile([0.0, 0.0, 1.0], (segments + 1, 1))
    return Mesh(vertices, faces, normals, vertices[:, :2] / (2 * radius) + 0.5, "disk")


def quad(width: float, height: float) -> Mesh:
    """Rectangle ``width`` x ``height`` centred on the origin in z = 0 facing +z; uv over [0, 1]^2."""
    width, height = positive_length(width, "quad width"), positive_length(height, "quad height")
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
    radius = positive_length(radius, "sphere radius")
    rings = segments // 2
    theta = np.linspace(0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0, 2 * np.pi, segments + 1)[None, :]
    normals = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                        np.cos(theta) * np.ones_like(phi)], axis=-1).reshape(-1, 3)
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), 1 - theta / np.pi), axis=-1).reshape(-1, 2)
    return Mesh(normals * radius, _grid_faces(rings, segments), normals, uv, "sphere")


def cone(radius: float, height: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """Cone with its base disk of ``radius`` in z = 0 and apex at z = ``height`` (as pbrt's cone), open base."""
    radius, height = positive_length(radius, "cone radius"), positive_length(height, "cone height")
    stacks = 16
    s = np.linspace(0, 1, stacks + 1)[:, None]  # 0 at the base, 1 at the apex
    phi = np.linspace(0, 2 * np.pi, segments + 1)[None, :]
    r = radius * (1 - s)
    vertices = np.stack([r * np.cos(phi), r * np.sin(phi), height * s * np.ones_like(phi)], axis=-1).reshape(-1, 3)
    # the side's normal is (h cos phi, h sin phi, r) / |.|: finite for any aspect ratio (r / h could overflow)
    n = np.stack(np.broadcast_arrays(height * np.cos(phi), height * np.sin(phi), radius * np.ones_like(s)),
                 axis=-1).reshape(-1, 3)
    n /= np.max(np.abs(n), axis=1, keepdims=True)  # rescale before squaring, so 1e-300 or 1e300 stays finite
    uv = np.stack(np.broadcast_arrays(phi / (2 * np.pi), s), axis=-1).reshape(-1, 2)
    faces = _grid_faces(stacks, segments)[:, ::-1]  # rows run base to apex: reverse to wind outward
    return Mesh(vertices, faces, n / np.linalg.norm(n, axis=1, keepdims=True), uv, "cone")


def cylinder(radius: float, z0: float, z1: float, segments: int = DEFAULT_SEGMENTS) -> Mesh:
    """pbrt's cylinder about z from ``z0`` to ``z1`` (no caps), wound outward."""
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    vertices = np.vstack([np.column_stack([ring * radius, np.full(segments, z)]) for z in (z0, z1)])
    normals = np.vstack([np.column_stack([ring, np.zeros(segments)])] * 2)
    i = np.arange(segments)
    j = (i + 1) % segments
    faces = np.concatenate([np.column_stack([i, j, j + segments]),
                            np.column_stack([i, j + segments, i + segments])])
    return Mesh(vertices, faces, normals, None, "cylinder")


def light_mesh(light: AreaLight) -> Mesh:
    """An area light's emitter tessellated in its object space (so camera rays see it)."""
    if light.shape == "disk":
        return disk(light.size[0])
    return quad(light.size[0], light.size[1])
