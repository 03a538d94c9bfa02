"""The GGX (Trowbridge-Reitz) microfacet distribution, anisotropic, batched over hits.

D, Smith's Lambda and G, and sampling of the visible normals (Heitz 2018, "Sampling the GGX
Distribution of Visible Normals", JCGT 7(4)), whose density of a reflected direction is
G1(wo) D(wh) / (4 |cos theta_o|), as pbrt-v3/v4 (``src/core/microfacet.cpp``,
``TrowbridgeReitzDistribution``). Directions are local (normal +z) and taken in the upper
hemisphere (callers mirror the lower one). ``alpha`` converts a scene's roughness by its rule
(``realistic.scene.materials``).
"""

from __future__ import annotations

import numpy as np

from realistic.core.vectors import normalise

#: Below this alpha a lobe is a mirror (pbrt-v4 ``TrowbridgeReitzDistribution::EffectivelySmooth``).
SMOOTH_ALPHA = 1e-3


def alpha(roughness: np.ndarray, rule: str) -> np.ndarray:
    """GGX alpha (N,) from scene roughness by ``rule``: "alpha", "pbrt-v3" (pbrt-v3
    ``RoughnessToAlpha``: a quartic in log(max(r, 1e-3))), "sqrt" (pbrt-v4) or "blinn" (pbrt-v2's
    exponent 1 / r as the Beckmann width sqrt(2 / (1 / r + 2)), Walter et al. 2007)."""
    r = np.maximum(np.asarray(roughness, np.float64), 0.0)
    if rule == "pbrt-v3":
        x = np.log(np.maximum(r, 1e-3))
        return (1.62142 + 0.819955 * x + 0.1734 * x ** 2 + 0.0171201 * x ** 3 + 0.000640711 * x ** 4).astype(
            np.float32)
    if rule == "sqrt":
        return np.sqrt(r).astype(np.float32)
    if rule == "blinn":
        return np.sqrt(2.0 * r / (1.0 + 2.0 * r)).astype(np.float32)
    return r.astype(np.float32)


class GGX:
    """Anisotropic GGX with widths ``alpha_x``, ``alpha_y`` (N,) along the local x and y axes."""

    def __init__(self, alpha_x: np.ndarray, alpha_y: np.ndarray):
        self.ax = np.maximum(np.asarray(alpha_x, np.float64), 1e-4)
        self.ay = np.maximum(np.asarray(alpha_y, np.float64), 1e-4)

    def d(self, wh: np.ndarray) -> np.ndarray:
        """Normal distribution D(wh) (N,), wh in the upper hemisphere (0 below)."""
        wh = np.asarray(wh, np.float64)
        x, y, z = wh[:, 0] / self.ax, wh[:, 1] / self.ay, wh[:, 2]
        denominator = x * x + y * y + z * z
        with np.errstate(divide="ignore", invalid="ignore"):
            value = 1.0 / (np.pi * self.ax * self.ay * denominator * denominator)
        return np.where(z > 0, value, 0.0)

    def lambda_(self, w: np.ndarray) -> np.ndarray:
        """Smith's Lambda(w) (N,)."""
        w = np.asarray(w, np.float64)
        z2 = w[:, 2] ** 2
        tan2 = (self.ax ** 2 * w[:, 0] ** 2 + self.ay ** 2 * w[:, 1] ** 2) / np.maximum(z2, 1e-30)
        return 0.5 * (np.sqrt(1.0 + tan2) - 1.0)

    def g1(self, w: np.ndarray) -> np.ndarray:
        return 1.0 / (1.0 + self.lambda_(w))

    def g(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        """Height-correlated masking-shadowing G(wo, wi) (N,)."""
        return 1.0 / (1.0 + self.lambda_(wo) + self.lambda_(wi))

    def sample_visible(self, wo: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Microfacet normals (N, 3) distributed as D_wo, for wo in the upper hemisphere."""
        wo = np.asarray(wo, np.float64)
        v = np.column_stack([self.ax * wo[:, 0], self.ay * wo[:, 1], wo[:, 2]])
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        length2 = v[:, 0] ** 2 + v[:, 1] ** 2
        inv = np.where(length2 > 0, 1.0 / np.sqrt(np.maximum(length2, 1e-30)), 0.0)
        t1 = np.where((length2 > 0)[:, None], np.column_stack([-v[:, 1] * inv, v[:, 0] * inv, np.zeros(len(v))]),
                      np.array([1.0, 0.0, 0.0]))
        t2 = np.cross(v, t1)
        r = np.sqrt(u[:, 0].astype(np.float64))
        phi = 2.0 * np.pi * u[:, 1].astype(np.float64)
        p1, p2 = r * np.cos(phi), r * np.sin(phi)
        s = 0.5 * (1.0 + v[:, 2])
        p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
        n = p1[:, None] * t1 + p2[:, None] * t2 + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[:, None] * v
        wh = np.column_stack([self.ax * n[:, 0], self.ay * n[:, 1], np.maximum(1e-9, n[:, 2])])
        return wh / np.linalg.norm(wh, axis=1, keepdims=True)

    def reflection_pdf(self, wo: np.ndarray, wh: np.ndarray) -> np.ndarray:
        """Density (N,) of the direction reflected about wh when wh ~ D_wo: G1(wo) D(wh) / (4 cos_o)."""
        return self.g1(wo) * self.d(wh) / (4.0 * np.maximum(np.asarray(wo, np.float64)[:, 2], 1e-30))


def half_vector(wo: np.ndarray, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit half vectors (N, 3) of upper-hemisphere pairs, and where they exist (wo + wi != 0)."""
    h = np.asarray(wo, np.float64) + np.asarray(wi, np.float64)
    ok = np.einsum("ij,ij->i", h, h) > 1e-20
    return normalise(np.where(ok[:, None], h, [0.0, 0.0, 1.0])), ok


def upper(wo: np.ndarray, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both directions mirrored through the surface where wo is below it, and whether the pair
    lies on one side (reflection)."""
    flip = np.where(wo[:, 2] < 0, -1.0, 1.0).astype(np.float32)[:, None]
    same = wo[:, 2] * wi[:, 2] > 0
    return wo * flip, wi * flip, same
