"""Lambertian reflection: f = albedo / pi, sampled by cosine-weighted hemisphere directions.

Two-sided, as every reflection lobe here (pbrt's ``SameHemisphere``): a pair of directions on one
side of the surface reflects, whichever side that is, so the integrator may or may not flip the
shading normal toward the viewer.
"""

from __future__ import annotations

import numpy as np

from realistic.core.warp import concentric_disk
from realistic.renderer.bsdf.base import BSDFSample


def cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Directions (N, 3) about +z with density cos(theta) / pi, from uniform u (N, 2) (Malley's method)."""
    x, y = concentric_disk(u[:, 0], u[:, 1])
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return np.column_stack([x, y, z]).astype(np.float32)


def cosine_pdf(wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """Density (N,) of cosine-weighted directions on wo's side of the surface."""
    return np.where(wo[:, 2] * wi[:, 2] > 0, np.abs(wi[:, 2]) / np.float32(np.pi), 0.0).astype(np.float32)


def cosine_on_side(wo: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Cosine-weighted directions (N, 3) on wo's side of the surface."""
    wi = cosine_hemisphere(u)
    wi[:, 2] *= np.where(wo[:, 2] < 0, -1.0, 1.0).astype(np.float32)
    return wi


class CosineSampled:
    """Base of the reflection lobes sampled by cosine-weighted directions on wo's side (their
    ``evaluate`` is their own): Lambertian, Oren-Nayar, the coated diffuse base, measured BRDFs."""

    has_specular = False
    only_specular = False

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return cosine_pdf(wo, wi)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        wi = cosine_on_side(wo, u)
        pdf = self.pdf(wo, wi)
        return BSDFSample(wi, self.evaluate(wo, wi), pdf, np.zeros(len(wi), bool), pdf > 0)


class Lambertian(CosineSampled):
    """Ideal diffuse reflection of ``albedo`` (N, C); no transmission."""

    def __init__(self, albedo: np.ndarray):
        self.albedo = np.asarray(albedo, np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same_side = wo[:, 2] * wi[:, 2] > 0
        return self.albedo * (same_side / np.float32(np.pi)).astype(np.float32)[:, None]
