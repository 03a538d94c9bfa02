"""Rough glass: pbrt-v4's ``DielectricBxDF`` with a Trowbridge-Reitz (GGX) distribution
(``src/pbrt/bxdfs.h``, ``src/pbrt/bxdfs.cpp``; Walter et al. 2007, "Microfacet Models for
Refraction through Rough Surfaces").

wo with z > 0 is outside (index 1), z < 0 inside (index ``eta``): the integrator hands the outward
normal (``renderer.bsdf``). A pair on one side reflects, f = D G F / |4 cos_i cos_o|; a pair on
opposite sides transmits through the microfacet of the generalised half vector
wm = normalise(eta' wi + wo) (eta' the index ratio across, turned to +z), with
f = D G (1 - F) |(wi.wm)(wo.wm)| / (|cos_i cos_o| (wi.wm + wo.wm / eta')^2); F is the dielectric
Fresnel reflectance at wo.wm. Microfacets that face away from either direction contribute nothing.
Sampling (``sample``) picks a visible normal wm (Heitz 2018) and reflects with probability F or
refracts with 1 - F, so each sample's weight f |cos_i| / pdf is G / G1(wo) (at most 1: the
single-scattering model loses the light that would scatter again among the microfacets).

Kr and Kt tint the reflected and transmitted lobes (pbrt-v3's rough ``glass``; pbrt-v4's
``dielectric`` has none, i.e. 1). Radiance is not divided by eta'^2 on crossing (pbrt-v4 does in
radiance mode), as smooth glass (``dielectric``) does here: the factors cancel for a ray that
enters and leaves a closed object, and a white glass in a white furnace reads 1 inside and out.

Hits whose alpha is below ``SMOOTH_ALPHA`` in both directions, or whose index is 1, are smooth glass
(pbrt-v4 ``EffectivelySmooth``): specular samples from ``dielectric.Dielectric``.
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf import fresnel
from realistic.renderer.bsdf.base import BSDFSample
from realistic.renderer.bsdf.dielectric import Dielectric
from realistic.renderer.bsdf.microfacet import GGX, SMOOTH_ALPHA


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


class RoughDielectric:
    """Glass of index ``eta`` (N,), tints ``kr``, ``kt`` (N, C) and GGX widths ``alpha_x``, ``alpha_y`` (N,)."""

    def __init__(self, eta: np.ndarray | float, kr: np.ndarray, kt: np.ndarray, alpha_x: np.ndarray,
                 alpha_y: np.ndarray):
        self.kr, self.kt = np.asarray(kr, np.float32), np.asarray(kt, np.float32)
        n = len(self.kr)
        self.eta = np.broadcast_to(np.asarray(eta, np.float64), (n,))
        ax = np.broadcast_to(np.asarray(alpha_x, np.float64), (n,))
        ay = np.broadcast_to(np.asarray(alpha_y, np.float64), (n,))
        self.smooth = (np.maximum(ax, ay) < SMOOTH_ALPHA) | (self.eta == 1.0)
        self.ggx = GGX(ax, ay)
        self.has_specular = bool(self.smooth.any())
        self.only_specular = bool(self.smooth.all()) and n > 0

    def _lobes(self, wo: np.ndarray, wi: np.ndarray, wm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """f (N, C) and the density (N,) of ``sample`` for the pairs wo, wi about microfacet normals wm
        (+z side); zero where wm faces away from either direction and on smooth rows."""
        wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
        cos_o, cos_i = wo[:, 2], wi[:, 2]
        reflect = cos_o * cos_i > 0
        etap = np.where(reflect, 1.0, np.where(cos_o > 0, self.eta, 1.0 / self.eta))
        o_m, i_m = _dot(wo, wm), _dot(wi, wm)
        ok = (cos_o != 0) & (cos_i != 0) & (i_m * cos_i > 0) & (o_m * cos_o > 0) & ~self.smooth
        f_r = fresnel.dielectric(o_m, self.eta).astype(np.float64)
        d = self.ggx.d(wm)
        g = self.ggx.g(wo, wi)
        with np.errstate(divide="ignore", invalid="ignore"):
            visible = self.ggx.g1(wo) / np.abs(cos_o) * d * np.abs(o_m)  # pbrt-v4 TrowbridgeReitz PDF(wo, wm)
            denom = (i_m + o_m / etap) ** 2
            f_reflect = d * g * f_r / np.abs(4.0 * cos_i * cos_o)
            f_transmit = d * g * (1.0 - f_r) * np.abs(i_m * o_m / (cos_i * cos_o * denom))
            pdf_reflect = visible / (4.0 * np.abs(o_m)) * f_r
            pdf_transmit = visible * np.abs(i_m) / denom * (1.0 - f_r)
        f = np.where(reflect, f_reflect, f_transmit)
        pdf = np.where(reflect, pdf_reflect, pdf_transmit)
        good = ok & np.isfinite(f) & np.isfinite(pdf)
        value = np.where(reflect[:, None], self.kr, self.kt) * np.where(good, f, 0.0)[:, None]
        return value.astype(np.float32), np.where(good, pdf, 0.0).astype(np.float32)

    def _half_vector(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        """The generalised half vectors (N, 3), turned to +z (zero where undefined)."""
        wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
        reflect = wo[:, 2] * wi[:, 2] > 0
        etap = np.where(reflect, 1.0, np.where(wo[:, 2] > 0, self.eta, 1.0 / self.eta))
        wm = wi * etap[:, None] + wo
        length = np.sqrt(_dot(wm, wm))
        wm = np.divide(wm, length[:, None], out=np.zeros_like(wm), where=length[:, None] > 0)
        return wm * np.where(wm[:, 2] < 0, -1.0, 1.0)[:, None]

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return self._lobes(wo, wi, self._half_vector(wo, wi))[0]

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return self._lobes(wo, wi, self._half_vector(wo, wi))[1]

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        wo64 = np.asarray(wo, np.float64)
        side = np.where(wo64[:, 2] < 0, -1.0, 1.0)
        wm = self.ggx.sample_visible(wo64 * side[:, None], u)  # pbrt-v4 Sample_wm: wo turned up
        o_m = _dot(wo64, wm)
        f_r = fresnel.dielectric(o_m, self.eta).astype(np.float64)
        reflect = u_lobe < f_r
        reflected = -wo64 + 2.0 * o_m[:, None] * wm
        # pbrt-v4 Refract about wm: from wo's side of the microfacet into the other
        inside = o_m < 0
        ratio = np.where(inside, self.eta, 1.0 / self.eta)  # eta_i / eta_t
        normal = np.where(inside[:, None], -wm, wm)
        cos_i = np.abs(o_m)
        sin2_t = ratio * ratio * np.maximum(0.0, 1.0 - cos_i * cos_i)
        cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
        refracted = -ratio[:, None] * wo64 + (ratio * cos_i - cos_t)[:, None] * normal
        wi = np.where(reflect[:, None], reflected, refracted)
        same = wi[:, 2] * wo64[:, 2] > 0
        valid = np.where(reflect, same, ~same & (wi[:, 2] != 0) & (sin2_t < 1.0))
        wi32 = wi.astype(np.float32)
        value, pdf = self._lobes(wo64, wi, wm)
        valid &= pdf > 0
        specular = self.smooth.copy()
        if specular.any():
            rows = np.flatnonzero(specular)
            s = Dielectric(self.eta[rows], self.kr[rows], self.kt[rows]).sample(wo[rows], u[rows], u_lobe[rows])
            wi32[rows], value[rows], pdf[rows], valid[rows] = s.wi, s.value, s.pdf, s.valid
        return BSDFSample(wi32, value, pdf, specular, valid)
