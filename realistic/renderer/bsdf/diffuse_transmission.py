"""Lambertian reflection and transmission (pbrt-v4 ``DiffuseTransmissionBxDF``): f = R / pi for a
pair on one side of the surface, T / pi for a pair on opposite sides; the side is chosen in
proportion to the mean of R and of T, then the direction by the cosine."""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf.base import BSDFSample
from realistic.renderer.bsdf.lambertian import cosine_on_side


class DiffuseTransmission:
    """Reflectance ``r`` and transmittance ``t`` (N, C)."""

    has_specular = False
    only_specular = False

    def __init__(self, r: np.ndarray, t: np.ndarray):
        self.r, self.t = np.asarray(r, np.float32), np.asarray(t, np.float32)
        pr, pt = self.r.mean(axis=1), self.t.mean(axis=1)
        total = pr + pt
        self.p_reflect = np.where(total > 0, pr / np.where(total > 0, total, 1.0), 0.5).astype(np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same = (wo[:, 2] * wi[:, 2] > 0)[:, None]
        opposite = (wo[:, 2] * wi[:, 2] < 0)[:, None]
        return ((self.r * same + self.t * opposite) / np.float32(np.pi)).astype(np.float32)

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        side = wo[:, 2] * wi[:, 2]
        chance = np.where(side > 0, self.p_reflect, np.where(side < 0, 1.0 - self.p_reflect, 0.0))
        return (chance * np.abs(wi[:, 2]) / np.float32(np.pi)).astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        wi = cosine_on_side(wo, u)
        wi[:, 2] *= np.where(u_lobe < self.p_reflect, 1.0, -1.0).astype(np.float32)
        pdf = self.pdf(wo, wi)
        return BSDFSample(wi, self.evaluate(wo, wi), pdf, np.zeros(len(wo), bool), pdf > 0)
