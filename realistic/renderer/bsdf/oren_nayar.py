"""Oren-Nayar rough diffuse reflection (pbrt's ``matte`` with sigma), two-sided: a pair of
directions on one side of the surface reflects, whichever side that is.

pbrt-v3 ``src/core/reflection.cpp`` (``OrenNayar``): sigma in degrees, A = 1 - s / (2 (s + 0.33)),
B = 0.45 s / (s + 0.09) with s = sigma^2 in radians^2, and
f = R / pi (A + B max(0, cos(phi_i - phi_o)) sin(alpha) tan(beta)), alpha = max(theta_i, theta_o),
beta = min(theta_i, theta_o). sigma 0 is Lambertian (A = 1, B = 0). Cosine-weighted sampling.
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf.lambertian import CosineSampled


class OrenNayar(CosineSampled):
    """Rough diffuse reflection of ``albedo`` (N, C) with facet slope deviation ``sigma_degrees`` (N,)."""


    def __init__(self, albedo: np.ndarray, sigma_degrees: np.ndarray | float):
        self.albedo = np.asarray(albedo, np.float32)
        s2 = np.radians(np.broadcast_to(np.asarray(sigma_degrees, np.float64), (len(self.albedo),))) ** 2
        self.a = (1.0 - s2 / (2.0 * (s2 + 0.33))).astype(np.float32)
        self.b = (0.45 * s2 / (s2 + 0.09)).astype(np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        cos_i, cos_o = np.abs(wi[:, 2]), np.abs(wo[:, 2])
        sin_i = np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
        sin_o = np.sqrt(np.maximum(0.0, 1.0 - cos_o * cos_o))
        both = (sin_i > 1e-4) & (sin_o > 1e-4)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_dphi = (wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1]) / (sin_i * sin_o)
            incident_steeper = cos_i > cos_o
            sin_alpha = np.where(incident_steeper, sin_o, sin_i)
            tan_beta = np.where(incident_steeper, sin_i / cos_i, sin_o / cos_o)
        term = np.where(both, np.maximum(0.0, cos_dphi) * sin_alpha * tan_beta, 0.0)
        shape = (self.a + self.b * np.nan_to_num(term)) / np.float32(np.pi)
        same = wo[:, 2] * wi[:, 2] > 0
        return (self.albedo * (shape * same)[:, None]).astype(np.float32)
