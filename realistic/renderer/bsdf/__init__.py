"""BSDFs for the integrator, batched over hits and evaluated in each hit's local shading frame.

Conventions shared by every BSDF (``base.BSDF``):

- Directions ``wo`` (toward the viewer) and ``wi`` (toward the light) are (N, 3) float32 unit
  vectors in the local frame, where the shading normal is +z; both point away from the surface,
  so ``w[:, 2]`` is the cosine with the normal. ``base.ShadingFrame`` maps world to local and back.
- Colours are (N, C) float32 with C = 3 (RGB rays) or C = 1 (spectral rays, one wavelength each).
- ``evaluate`` gives f(wo, wi) without the cosine; ``pdf`` is per unit solid angle of ``wi``.
  Specular (delta) lobes are zero in both and appear only through ``sample``, which flags them.
- ``bsdf_for(material, hits)`` builds the BSDF of one material for a batch of hits; ``hits`` looks
  textures and constants up at those hits (``base.HitParameters``). ``hits.colour`` must be linear
  in its RGB argument (no clamping: conductor indices exceed 1), since measured BRDFs turn their
  RGB into the rays' channels through ``hits.colour`` of the three unit colours.
- Reflection lobes are two-sided (pbrt's ``SameHemisphere``): they reflect a pair of directions on
  either side, so flipping the shading normal toward the viewer changes nothing for them. Glass
  (``dielectric``, ``rough_dielectric``) tells inside from outside by the sign of ``wo[:, 2]``, so
  the integrator hands every BSDF the frame of the surface's outward normal, never turned toward
  the viewer (``PathIntegrator._outward_normals``), as pbrt does.
- ``has_specular`` / ``only_specular`` say whether ``sample`` may / always returns specular samples.

Modules: ``base`` (the protocol, the sample record, the frame), ``lambertian`` (and the cosine
sampling the diffuse lobes share), ``oren_nayar``, ``fresnel`` (reflectances, reflection and
refraction), ``microfacet`` (GGX and the roughness rules), ``conductor`` (metals, mirror, the coat
of plastic), ``dielectric`` (glass, thin slabs), ``rough_dielectric`` (pbrt-v4's rough glass),
``substrate`` (FresnelBlend), ``diffuse_transmission``, ``mix`` (weighted sums: plastic and pbrt's
mix), ``measured`` (pbrt-v2's measured BRDFs), ``factory``.
"""

from realistic.renderer.bsdf.base import BSDF, BSDFSample, HitParameters, ShadingFrame
from realistic.renderer.bsdf.factory import bsdf_for
from realistic.renderer.bsdf.lambertian import Lambertian

__all__ = ["BSDF", "BSDFSample", "HitParameters", "Lambertian", "ShadingFrame", "bsdf_for"]
