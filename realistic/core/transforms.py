"""4x4 homogeneous transforms acting on column vectors, and applying them to batches of points.

The one home of the matrices every part builds (pbrt's Translate, Scale, Rotate and LookAt, the
camera-to-world transform) and of the two batch operations that use them.
"""

from __future__ import annotations

import math

import numpy as np


def translate(x: float, y: float, z: float) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, 3] = (x, y, z)
    return matrix


def scale(x: float, y: float | None = None, z: float | None = None) -> np.ndarray:
    """Scale by (x, y, z); one argument scales uniformly."""
    return np.diag([x, x if y is None else y, x if z is None else z, 1.0])


def rotate(angle_deg: float, axis: tuple[float, float, float]) -> np.ndarray:
    """Rotation by ``angle_deg`` about ``axis`` (right-handed, as pbrt's Rotate)."""
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    matrix = np.eye(4)
    matrix[:3, :3] = [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                      [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                      [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]]
    return matrix


def look_at(eye: np.ndarray, target: np.ndarray, up: tuple[float, float, float] = (0.0, 1.0, 0.0)) -> np.ndarray:
    """World-from-camera rotation and translation: camera +z toward target, +y up, +x right."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(np.asarray(up, float), forward)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross([0.0, 0.0, 1.0], forward)
    right /= np.linalg.norm(right)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = right, np.cross(forward, right), forward, eye
    return matrix


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (N, 3) or (3,) through ``matrix`` (rotation, scale and translation)."""
    return transform_vectors(matrix, points) + matrix[:3, 3]


def transform_vectors(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Directions (N, 3) or (3,) through ``matrix`` (no translation; not renormalised).

    einsum, not ``@``: a matrix product this large goes to OpenBLAS, whose threads then spin on
    cores the render needs; einsum runs in this thread."""
    return np.einsum("ij,...j->...i", matrix[:3, :3], vectors)
