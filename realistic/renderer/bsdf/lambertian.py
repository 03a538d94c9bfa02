"""Lambertian reflection: f = albedo / pi, sampled by cosine-weighted hemisphere directions."""

from __future__ import annotations

import numpy as np

from realistic.core.warp import concentric_disk
from realistic.renderer.bsdf.base import BSDFSample


def cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Directions (N, 3) about +z with density cos(theta) / pi, from uniform u (N, 2) (Malley's method)."""
    x, y = concentric_disk(u[:, 0], u[:, 1])
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return np.column_stack([x, y, z]).astype(np.float32)


class Lambertian:
    """Ideal diffuse reflection of ``albedo`` (N, C); no transmission."""

    def __init__(self, albedo: np.ndarray):
        self.albedo = np.asarray(albedo, np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same_side = (wo[:, 2] > 0) & (wi[:, 2] > 0)
        return self.albedo * (same_side / np.float32(np.pi)).astype(np.float32)[:, None]

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same_side = (wo[:, 2] > 0) & (wi[:, 2] > 0)
        return np.where(same_side, wi[:, 2] / np.float32(np.pi), 0.0).astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        wi = cosine_hemisphere(u)
        valid = (wo[:, 2] > 0) & (wi[:, 2] > 0)
        return BSDFSample(wi, self.evaluate(wo, wi), self.pdf(wo, wi), np.zeros(len(wi), bool), valid)
