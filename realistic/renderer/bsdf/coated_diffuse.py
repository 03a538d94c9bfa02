"""The diffuse base under a smooth dielectric coat (the closest form here of pbrt-v4 ``coateddiffuse``).

Light enters the coat with probability 1 - F(cos_i), is reflected by the Lambertian base of albedo
R, bounces between base and coat (the coat reflects diffuse light back in with the hemispherical
internal reflectance F_int = 1 - (1 - F_ext) / eta^2, F_ext the external one), and leaves with
probability 1 - F(cos_o), scaled by 1 / eta^2 for the solid-angle change:

    f = (1 - F(cos_i)) (1 - F(cos_o)) R / (pi eta^2 (1 - R F_int)),

reciprocal, and with the coat's own reflection added (``conductor.MicrofacetReflection`` with the
dielectric Fresnel) a white base under a smooth coat reflects everything: the diffuse albedo is
(1 - F(cos_o)) (1 - F_int) / (1 - F_int) = 1 - F(cos_o). The same as Weidlich and Wilkie's layered
model (2007) with a non-absorbing, infinitely thin layer; pbrt-v4 simulates the layer stochastically.
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf import fresnel
from realistic.renderer.bsdf.lambertian import CosineSampled


def hemispherical_reflectance(eta: float) -> float:
    """F_ext = 2 int_0^1 F(mu) mu dmu for light arriving from outside (midpoint rule, 4096 steps)."""
    mu = (np.arange(4096) + 0.5) / 4096
    return float(2.0 * np.mean(fresnel.dielectric(mu, eta).astype(np.float64) * mu))


class CoatedLambertian(CosineSampled):
    """The coated base's lobe for albedo ``albedo`` (N, C) under a coat of index ``eta``."""


    def __init__(self, albedo: np.ndarray, eta: float):
        self.albedo = np.asarray(albedo, np.float32)
        self.eta = float(eta)
        #: F_int, the coat's internal reflectance of diffuse light
        self.internal = internal = 1.0 - (1.0 - hemispherical_reflectance(self.eta)) / self.eta ** 2
        self.scale = (self.albedo / (np.pi * self.eta ** 2 * (1.0 - self.albedo * internal))).astype(np.float32)
        self.albedo_estimate = (self.albedo * (1 - internal) / (1 - self.albedo * internal)).mean(axis=1)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same = wo[:, 2] * wi[:, 2] > 0
        t = (1.0 - fresnel.dielectric(np.abs(wi[:, 2]), self.eta)) * (1.0 - fresnel.dielectric(np.abs(wo[:, 2]),
                                                                                                  self.eta))
        return (self.scale * (t * same).astype(np.float32)[:, None]).astype(np.float32)
