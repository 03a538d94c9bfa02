"""Row-wise operations on batches of 3-vectors, shared by shading and texture footprints."""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (N, 3) arrays (column arithmetic: several times faster than einsum)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def normalise(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` (N, 3) scaled to unit length; zero rows stay zero."""
    length = np.sqrt(dot(v, v))[:, None]
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)
