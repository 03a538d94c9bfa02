"""Maps from the unit square to other domains that keep stratified samples stratified."""

from __future__ import annotations

import numpy as np


def concentric_disk(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shirley-Chiu concentric map of [0,1)^2 onto the unit disk (keeps strata compact)."""
    a = 2.0 * np.asarray(u1, dtype=np.float64) - 1.0
    b = 2.0 * np.asarray(u2, dtype=np.float64) - 1.0
    first = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, a, b)
        phi = np.where(first, (np.pi / 4) * (b / a), (np.pi / 2) - (np.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)
