"""The BSDF of a scene material at a batch of hits.

Parameters that may be textures are looked up through ``hits`` (``HitParameters``); a
``ScaledTexture`` is its constant times its texture. Roughness is turned into GGX alpha per hit
by the material's rule (``microfacet.alpha``).
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf import fresnel
from realistic.renderer.bsdf.base import BSDF, HitParameters
from realistic.renderer.bsdf.coated_diffuse import CoatedLambertian
from realistic.renderer.bsdf.conductor import MicrofacetReflection
from realistic.renderer.bsdf.dielectric import Dielectric as DielectricBSDF
from realistic.renderer.bsdf.diffuse_transmission import DiffuseTransmission as DiffuseTransmissionBSDF
from realistic.renderer.bsdf.lambertian import Lambertian
from realistic.renderer.bsdf.measured import MeasuredBRDF
from realistic.renderer.bsdf.microfacet import alpha
from realistic.renderer.bsdf.mix import WeightedSum
from realistic.renderer.bsdf.oren_nayar import OrenNayar
from realistic.renderer.bsdf.rough_dielectric import RoughDielectric
from realistic.renderer.bsdf.substrate import FresnelBlend
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Measured,
    Mirror,
    Mix,
    Plastic,
    ScaledTexture,
    Substrate,
    SurfaceMaterial,
)
from realistic.scene.measured import load_measured
from realistic.scene.metals import reflectance_table
from realistic.scene.model import Material


def colour(hits: HitParameters, value: object) -> np.ndarray:
    """A colour parameter at the hits (N, C)."""
    if isinstance(value, ScaledTexture):
        return hits.colour(value.scale) * hits.colour(value.texture)
    return hits.colour(value)


def scalar(hits: HitParameters, value: object) -> np.ndarray:
    """A float parameter at the hits (N,)."""
    if isinstance(value, ScaledTexture):
        return np.float32(np.mean(value.scale)) * hits.scalar(value.texture)
    return hits.scalar(value)


def _channels(hits: HitParameters) -> np.ndarray:
    """(N, C, 3): how an RGB value becomes the rays' C channels (the identity for RGB rays)."""
    return np.stack([hits.colour(c) for c in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))], axis=-1)


def bsdf_for(material: SurfaceMaterial, hits: HitParameters) -> BSDF:
    """``material``'s BSDF with its parameters (constants or textures) looked up at ``hits``."""
    if isinstance(material, Material):
        albedo = hits.colour(material.diffuse)
        if material.texture is not None:
            albedo = albedo * hits.colour(material.texture)
        return Lambertian(albedo) if material.sigma == 0 else OrenNayar(albedo, material.sigma)
    if isinstance(material, Plastic):
        kd, ks = colour(hits, material.diffuse), colour(hits, material.specular)
        a = alpha(scalar(hits, material.roughness), material.rule)
        coat_eta = np.float32(material.eta)
        coat = MicrofacetReflection(ks, a, a, lambda c, rows: fresnel.dielectric(c, coat_eta)[:, None])
        return WeightedSum([Lambertian(kd), coat], [np.ones_like(kd)] * 2, [kd.mean(axis=1), ks.mean(axis=1)])
    if isinstance(material, CoatedDiffuse):
        base = CoatedLambertian(colour(hits, material.reflectance), material.eta)
        a = alpha(scalar(hits, material.roughness), material.rule)
        coat_eta = np.float32(material.eta)
        coat = MicrofacetReflection(np.ones_like(base.albedo), a, a,
                                    lambda c, rows: fresnel.dielectric(c, coat_eta)[:, None])

        def chances(wo: np.ndarray) -> list[np.ndarray]:
            """Each lobe's share of the albedo at wo: the coat's F(cos_o), the base the rest."""
            f = fresnel.dielectric(np.abs(wo[:, 2]), coat_eta)
            return [(1 - f) * base.albedo_estimate, f]

        return WeightedSum([base, coat], [np.ones_like(base.albedo)] * 2, chances)
    if isinstance(material, Conductor):
        ax = alpha(scalar(hits, material.roughness_u), material.rule)
        ay = alpha(scalar(hits, material.roughness_v), material.rule)
        if material.spectra is None:
            eta, k = colour(hits, material.eta), colour(hits, material.k)
            return MicrofacetReflection(colour(hits, material.scale), ax, ay,
                                        lambda c, rows: fresnel.conductor(c, eta[rows], k[rows]))
        table, channels = reflectance_table(*material.spectra), _channels(hits)
        return MicrofacetReflection(colour(hits, material.scale), ax, ay, lambda c, rows: np.einsum(
            "ncj,nj->nc", channels[rows], fresnel.tabulated(c, table)))
    if isinstance(material, Mirror):
        kr = colour(hits, material.reflectance)
        zero = np.zeros(len(kr), np.float32)
        return MicrofacetReflection(kr, zero, zero)
    if isinstance(material, Dielectric):
        kr, kt = colour(hits, material.reflectance), colour(hits, material.transmittance)
        if material.thin or material.roughness_u == material.roughness_v == 0.0:
            return DielectricBSDF(material.eta, kr, kt, material.thin)
        ru, rv = scalar(hits, material.roughness_u), scalar(hits, material.roughness_v)
        # smooth where both are 0 before the remapping (pbrt-v3 GlassMaterial's isSpecular; the
        # pbrt-v3 polynomial maps 0 to alpha 0.05)
        smooth = (ru == 0) & (rv == 0)
        ax, ay = (np.where(smooth, 0.0, alpha(r, material.rule)).astype(np.float32) for r in (ru, rv))
        return RoughDielectric(material.eta, kr, kt, ax, ay)
    if isinstance(material, Substrate):
        ax = alpha(scalar(hits, material.roughness_u), material.rule)
        ay = alpha(scalar(hits, material.roughness_v), material.rule)
        return FresnelBlend(colour(hits, material.diffuse), colour(hits, material.specular), ax, ay)
    if isinstance(material, DiffuseTransmission):
        return DiffuseTransmissionBSDF(colour(hits, material.reflectance), colour(hits, material.transmittance))
    if isinstance(material, Measured):
        return MeasuredBRDF(load_measured(material.path), _channels(hits))
    if isinstance(material, Mix):
        amount = np.clip(scalar(hits, material.amount), 0.0, 1.0).astype(np.float32)
        first, second = bsdf_for(material.first, hits), bsdf_for(material.second, hits)
        ones = np.ones((len(amount), 1), np.float32)
        return WeightedSum([first, second], [ones * (1 - amount)[:, None], ones * amount[:, None]],
                           [1 - amount, amount])
    raise TypeError(f"no BSDF for {material!r}")
