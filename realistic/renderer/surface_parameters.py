"""BSDF parameters at surface hits, and the directional albedo the albedo AOV reports.

Both integrators build their hits' BSDFs through ``SurfaceParameters`` (constants, and textures at
the hits' uv, image textures filtered over their footprints) and estimate a first hit's albedo with
``directional_albedo``: ``PathIntegrator`` at every surface, ``DirectLighting`` at area lights that
carry a material.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property

import numpy as np

from realistic.renderer.bsdf import BSDF
from realistic.renderer.light_sampler import colour
from realistic.scene.model import ImageTexture, Texture
from realistic.scene.textures import Footprint, ImageLookup, evaluate, numpy_lookup

#: Samples of a first hit's albedo estimate, as pbrt-v4's ``nRhoSamples`` (cpu/integrators.cpp): the
#: centres of a 4 x 4 grid of (u0, u1), the same at every hit so the estimate is exact for a
#: Lambertian BSDF and noise-free across a surface (``renderer.path`` samples its BSDFs with them).
RHO_SAMPLES = 16
RHO_U = np.array([((k % 4 + 0.5) / 4, (k // 4 + 0.5) / 4) for k in range(RHO_SAMPLES)], np.float32)
#: Each of the albedo estimate's BSDF samples (``RHO_U``) with its own lobe choice.
_RHO_LOBE = np.array([((7 * k) % RHO_SAMPLES + 0.5) / RHO_SAMPLES for k in range(RHO_SAMPLES)], np.float32)


def directional_albedo(bsdf: BSDF, wo: np.ndarray) -> np.ndarray:
    """A BSDF's directional albedo (n, 3) at local directions ``wo`` (n, 3): rho(wo) = E[f |cos wi|
    / pdf] over the ``RHO_SAMPLES`` fixed samples (pbrt-v4 ``BSDF::rho``, which its integrators
    fill a ``VisibleSurface`` with); exact for a Lambertian BSDF."""
    total = np.zeros((len(wo), 3), np.float64)
    for k in range(RHO_SAMPLES):
        s = bsdf.sample(wo, np.broadcast_to(RHO_U[k], (len(wo), 2)), np.full(len(wo), _RHO_LOBE[k], np.float32))
        ok = s.valid & (s.pdf > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            total += np.where(ok[:, None], s.value * (np.abs(s.wi[:, 2]) / np.where(ok, s.pdf, 1.0))[:, None], 0.0)
    return (total / RHO_SAMPLES).astype(np.float32)


class SurfaceParameters:
    """``HitParameters`` over ``count`` hits: constants, and textures at their uv (image textures
    filtered over their footprints). ``uv`` and ``footprint`` are functions called on the first
    texture lookup that needs them (``footprint`` may return None: point-sampled), so untextured
    materials cost neither. ``lookup`` filters the image textures (``textures.ImageLookup``: the numpy
    reference, or a render backend's ``image_lookup`` on its device)."""

    def __init__(self, count: int, uv: Callable[[], np.ndarray], footprint: Callable[[], Footprint | None],
                 basis: np.ndarray | None, lookup: ImageLookup = numpy_lookup):
        self.count, self.basis = count, basis
        self._uv_of, self._footprint_of, self._lookup = uv, footprint, lookup

    @cached_property
    def _uv(self) -> np.ndarray:
        return self._uv_of()

    @cached_property
    def _footprint(self) -> Footprint | None:
        return self._footprint_of()

    def colour(self, value: object) -> np.ndarray:
        if isinstance(value, tuple | list | np.ndarray | float | int):
            rgb = np.broadcast_to(np.asarray(value, np.float32), (self.count, 3))
        elif isinstance(value, Texture):
            rgb = evaluate(value, self._uv, self._footprint if isinstance(value, ImageTexture) else None, self._lookup)
        else:
            raise TypeError(f"unknown texture {value!r}")
        return colour(rgb, self.basis)

    def scalar(self, value: object) -> np.ndarray:
        if isinstance(value, float | int):
            return np.full(self.count, value, np.float32)
        if not isinstance(value, Texture):
            raise TypeError(f"unknown texture {value!r}")
        return evaluate(value, self._uv, None, self._lookup).mean(axis=1).astype(np.float32)
