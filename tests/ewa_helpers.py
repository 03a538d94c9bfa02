"""pbrt-v3's EWA ellipse (src/core/mipmap.h, MIPMap::EWA) in its own float64 formulas, for the tests
that check ``MipMap.ewa`` and its kernel against pbrt independently of ``realistic.scene.mipmap``."""

import numpy as np


def pbrt_ellipse(shape: tuple[int, ...], st_: np.ndarray, axis0: np.ndarray, axis1: np.ndarray
                 ) -> tuple[float, float, float, float, float]:
    """The lookup's centre (s, t) in texels of a level of ``shape`` (h, w, ...) and its ellipse's
    coefficients (a, b, c) over F: a texel at (x, y) is inside where
    a (x - s)^2 + b (x - s)(y - t) + c (y - t)^2 < 1 (A = a0t^2 + a1t^2 + 1,
    B = -2 (a0s a0t + a1s a1t), C = a0s^2 + a1s^2 + 1, F = A C - B^2 / 4)."""
    h, w = shape[:2]
    s, t = st_[0] * w - 0.5, st_[1] * h - 0.5
    d0, d1 = axis0 * (w, h), axis1 * (w, h)
    a, b, c = d0[1] ** 2 + d1[1] ** 2 + 1, -2 * (d0[0] * d0[1] + d1[0] * d1[1]), d0[0] ** 2 + d1[0] ** 2 + 1
    f = a * c - b * b / 4
    return s, t, a / f, b / f, c / f
