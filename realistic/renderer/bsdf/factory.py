"""The BSDF of a scene material at a batch of hits."""

from __future__ import annotations

from realistic.renderer.bsdf.base import BSDF, HitParameters
from realistic.renderer.bsdf.lambertian import Lambertian
from realistic.scene.model import Material


def bsdf_for(material: Material, hits: HitParameters) -> BSDF:
    """``material``'s BSDF with its parameters (constants or textures) looked up at ``hits``."""
    albedo = hits.colour(material.diffuse)
    if material.texture is not None:
        albedo = albedo * hits.colour(material.texture)
    return Lambertian(albedo)
