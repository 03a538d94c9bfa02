"""BSDFs for the integrator, batched over hits and evaluated in each hit's local shading frame.

Conventions shared by every BSDF (``base.BSDF``):

- Directions ``wo`` (toward the viewer) and ``wi`` (toward the light) are (N, 3) float32 unit
  vectors in the local frame, where the shading normal is +z; both point away from the surface,
  so ``w[:, 2]`` is the cosine with the normal. ``base.ShadingFrame`` maps world to local and back.
- Colours are (N, C) float32 with C = 3 (RGB rays) or C = 1 (spectral rays, one wavelength each).
- ``evaluate`` gives f(wo, wi) without the cosine; ``pdf`` is per unit solid angle of ``wi``.
  Specular (delta) lobes are zero in both and appear only through ``sample``, which flags them.
- ``bsdf_for(material, hits)`` builds the BSDF of one material for a batch of hits; ``hits`` looks
  textures and constants up at those hits (``base.HitParameters``).

Modules: ``base`` (the protocol, the sample record, the frame), ``lambertian``, ``factory``.
"""

from realistic.renderer.bsdf.base import BSDF, BSDFSample, HitParameters, ShadingFrame
from realistic.renderer.bsdf.factory import bsdf_for
from realistic.renderer.bsdf.lambertian import Lambertian

__all__ = ["BSDF", "BSDFSample", "HitParameters", "Lambertian", "ShadingFrame", "bsdf_for"]
