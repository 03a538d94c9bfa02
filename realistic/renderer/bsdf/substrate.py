"""pbrt's ``substrate``: Ashikhmin and Shirley's FresnelBlend (2000), a glossy coat over a diffuse base.

pbrt-v3 ``FresnelBlend`` (``src/core/reflection.cpp``):
diffuse = 28 / (23 pi) Rd (1 - Rs) (1 - (1 - |cos_i| / 2)^5) (1 - (1 - |cos_o| / 2)^5),
specular = D(wh) / (4 |wi . wh| max(|cos_i|, |cos_o|)) Schlick(wi . wh, Rs),
sampled half the time by the cosine and half by the GGX visible normals (here ``u_lobe`` picks).
"""

from __future__ import annotations

import numpy as np

from realistic.renderer.bsdf import fresnel
from realistic.renderer.bsdf.base import BSDFSample
from realistic.renderer.bsdf.lambertian import cosine_on_side, cosine_pdf
from realistic.renderer.bsdf.microfacet import GGX, half_vector, upper


class FresnelBlend:
    """Diffuse ``rd`` under a coat of normal reflectance ``rs`` (N, C), GGX widths (N,)."""

    has_specular = False
    only_specular = False

    def __init__(self, rd: np.ndarray, rs: np.ndarray, alpha_x: np.ndarray, alpha_y: np.ndarray):
        self.rd, self.rs = np.asarray(rd, np.float32), np.asarray(rs, np.float32)
        n = len(self.rd)
        self.ggx = GGX(np.broadcast_to(alpha_x, (n,)), np.broadcast_to(alpha_y, (n,)))

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        wo_up, wi_up, same = upper(wo, wi)
        cos_i, cos_o = wi_up[:, 2].astype(np.float64), wo_up[:, 2].astype(np.float64)
        diffuse = (28.0 / (23.0 * np.pi) * (1.0 - (1.0 - 0.5 * cos_i) ** 5) * (1.0 - (1.0 - 0.5 * cos_o) ** 5))
        wh, ok = half_vector(wo_up, wi_up)
        cos_h = np.einsum("ij,ij->i", wi_up.astype(np.float64), wh)
        with np.errstate(divide="ignore", invalid="ignore"):
            shape = self.ggx.d(wh) / (4.0 * np.abs(cos_h) * np.maximum(cos_i, cos_o))
        shape = np.where(ok, np.nan_to_num(shape), 0.0)
        value = (self.rd * (1.0 - self.rs) * diffuse.astype(np.float32)[:, None]
                 + fresnel.schlick(cos_h, self.rs) * shape.astype(np.float32)[:, None])
        return (value * same[:, None]).astype(np.float32)

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        wo_up, wi_up, same = upper(wo, wi)
        wh, ok = half_vector(wo_up, wi_up)
        glossy = np.where(same & ok, np.nan_to_num(self.ggx.reflection_pdf(wo_up, wh)), 0.0)
        return (0.5 * (cosine_pdf(wo, wi) + glossy)).astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        flip = np.where(wo[:, 2] < 0, -1.0, 1.0).astype(np.float32)[:, None]
        wo_up = wo * flip
        wh = self.ggx.sample_visible(wo_up, u)
        glossy = (-wo_up + 2.0 * np.einsum("ij,ij->i", wo_up, wh)[:, None] * wh) * flip
        wi = np.where((u_lobe < 0.5)[:, None], cosine_on_side(wo, u), glossy).astype(np.float32)
        pdf = self.pdf(wo, wi)
        return BSDFSample(wi, self.evaluate(wo, wi), pdf, np.zeros(len(wo), bool), pdf > 0)
