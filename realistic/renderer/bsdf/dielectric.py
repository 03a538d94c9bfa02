"""Smooth glass: specular reflection and refraction chosen in proportion to the Fresnel reflectance.

pbrt-v3 ``FresnelSpecular`` (``src/core/reflection.cpp``): with F the dielectric reflectance at
wo, reflect with probability F (value F Kr / |cos_i|) or refract with probability 1 - F (value
(1 - F) Kt / |cos_i|), so each sample carries Kr or Kt: a white glass neither gains nor loses
energy. wo with z > 0 is outside (index 1), z < 0 inside (index ``eta``), so the integrator must
hand this BSDF the surface's outward normal, unflipped. Radiance is not scaled by the squared
index ratio on crossing (as pbrt-v2; pbrt-v3/v4 do in radiance mode): the factors cancel for a
ray that enters and leaves a closed object.

``thin`` (pbrt-v4 ``ThinDielectricBxDF``): a slab whose inner reflections add up,
R' = R + T^2 R / (1 - R^2), T' = 1 - R', with transmission straight through (wi = -wo).
Only ``sample`` produces directions; ``evaluate`` and ``pdf`` are zero.
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf import fresnel
from realistic.renderer.bsdf.base import BSDFSample


class Dielectric:
    """Specular glass of index ``eta`` (N,) with reflection tint ``kr`` and transmission tint ``kt`` (N, C)."""

    has_specular = True
    only_specular = True

    def __init__(self, eta: np.ndarray | float, kr: np.ndarray, kt: np.ndarray, thin: bool = False):
        self.kr, self.kt = np.asarray(kr, np.float32), np.asarray(kt, np.float32)
        self.eta = np.broadcast_to(np.asarray(eta, np.float32), (len(self.kr),))
        self.thin = thin

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return np.zeros_like(self.kr)

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return np.zeros(len(wo), np.float32)

    def reflectance(self, wo: np.ndarray) -> np.ndarray:
        """The probability (N,) that light arriving along wo is reflected."""
        r = fresnel.dielectric(wo[:, 2], self.eta)
        if not self.thin:
            return r
        r = fresnel.dielectric(np.abs(wo[:, 2]), self.eta).astype(np.float64)
        t = 1.0 - r
        with np.errstate(divide="ignore", invalid="ignore"):
            r_slab = np.where(r < 1.0, r + t * t * r / (1.0 - r * r), 1.0)
        return r_slab.astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        r = self.reflectance(wo)
        if self.thin:
            transmitted, ok = (-wo).astype(np.float32), np.ones(len(wo), bool)
        else:
            transmitted, ok = fresnel.refract_z(wo, self.eta)
        reflect = (u_lobe < r) | ~ok
        wi = np.where(reflect[:, None], fresnel.reflect_z(wo), transmitted).astype(np.float32)
        pdf = np.where(reflect, r, 1.0 - r).astype(np.float32)
        cos = np.abs(wi[:, 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            value = np.where(reflect[:, None], self.kr, self.kt) * (pdf / cos)[:, None]
        valid = (pdf > 0) & (cos > 0)
        return BSDFSample(wi, np.nan_to_num(value).astype(np.float32), pdf, np.ones(len(wo), bool), valid)
