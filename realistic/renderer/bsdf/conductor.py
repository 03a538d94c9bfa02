"""Glossy and specular reflection off microfacets: metals (conductor Fresnel), the mirror (no
Fresnel), and the coat of plastic (dielectric Fresnel).

f = scale F(wo . wh) D(wh) G(wo, wi) / (4 cos_o cos_i) (Torrance-Sparrow with GGX, as pbrt-v3
``MicrofacetReflection``), sampled through the visible normals. Where alpha is below
``microfacet.SMOOTH_ALPHA`` the lobe is a perfect mirror, f = scale F(cos_o) delta / |cos_i|
(pbrt ``SpecularReflection``): only ``sample`` produces it. Two-sided, like every reflection here.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from realistic.renderer.bsdf.base import BSDFSample
from realistic.renderer.bsdf.fresnel import reflect_z
from realistic.renderer.bsdf.microfacet import GGX, SMOOTH_ALPHA, half_vector, upper

Fresnel = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (cosines (M,), hit rows (M,)) -> reflectance (M, C)


class MicrofacetReflection:
    """Reflection of ``scale`` (N, C) times ``fresnel`` over GGX microfacets of widths ``alpha_x``,
    ``alpha_y`` (N,); smooth hits (alpha below ``SMOOTH_ALPHA``) reflect specularly."""

    def __init__(self, scale: np.ndarray, alpha_x: np.ndarray, alpha_y: np.ndarray, fresnel: Fresnel | None = None):
        self.scale = np.asarray(scale, np.float32)
        n = len(self.scale)
        alpha_x = np.broadcast_to(np.asarray(alpha_x, np.float32), (n,))
        alpha_y = np.broadcast_to(np.asarray(alpha_y, np.float32), (n,))
        self.smooth = np.maximum(alpha_x, alpha_y) < SMOOTH_ALPHA
        self.ggx = GGX(alpha_x, alpha_y)
        self.fresnel = fresnel
        self.has_specular = bool(self.smooth.any())
        self.only_specular = bool(self.smooth.all())

    def _reflected(self, cos: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """scale x Fresnel (M, C) at the hit ``rows`` for the cosines ``cos`` (M,)."""
        scale = np.take(self.scale, rows, axis=0)
        return scale if self.fresnel is None else scale * self.fresnel(cos, rows)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        if self.only_specular:
            return np.zeros_like(self.scale)
        wo_up, wi_up, same = upper(wo, wi)
        wh, ok = half_vector(wo_up, wi_up)
        cos_o, cos_i = wo_up[:, 2].astype(np.float64), wi_up[:, 2].astype(np.float64)
        live = same & ok & ~self.smooth & (cos_o > 0) & (cos_i > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            shape = self.ggx.d(wh) * self.ggx.g(wo_up, wi_up) / (4.0 * cos_o * cos_i)
        rows = np.flatnonzero(live)
        cos_h = np.einsum("ij,ij->i", np.take(wo_up, rows, axis=0).astype(np.float64), np.take(wh, rows, axis=0))
        out = np.zeros_like(self.scale)
        out[rows] = self._reflected(cos_h, rows) * np.nan_to_num(shape[rows]).astype(np.float32)[:, None]
        return out

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        if self.only_specular:
            return np.zeros(len(wo), np.float32)
        wo_up, wi_up, same = upper(wo, wi)
        wh, ok = half_vector(wo_up, wi_up)
        live = same & ok & ~self.smooth & (wo_up[:, 2] > 0)
        return np.where(live, np.nan_to_num(self.ggx.reflection_pdf(wo_up, wh)), 0.0).astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        if self.only_specular:
            wi = reflect_z(wo)
        else:
            flip = np.where(wo[:, 2] < 0, -1.0, 1.0).astype(np.float32)[:, None]
            wo_up = wo * flip
            wh = self.ggx.sample_visible(wo_up, u)
            wi_up = (-wo_up + 2.0 * np.einsum("ij,ij->i", wo_up, wh)[:, None] * wh).astype(np.float32)
            wi = np.where(self.smooth[:, None], reflect_z(wo), wi_up * flip).astype(np.float32)
        value = self.evaluate(wo, wi)
        pdf = self.pdf(wo, wi)
        if self.has_specular:
            rows = np.flatnonzero(self.smooth)
            cos = np.abs(wo[rows, 2]).astype(np.float32)
            with np.errstate(divide="ignore", invalid="ignore"):
                value[rows] = np.nan_to_num(self._reflected(cos, rows) / cos[:, None])
            pdf = np.where(self.smooth, 1.0, pdf).astype(np.float32)
        valid = (pdf > 0) & (wo[:, 2] != 0) & (wi[:, 2] * wo[:, 2] > 0)
        return BSDFSample(wi, value, pdf, self.smooth.copy(), valid)
