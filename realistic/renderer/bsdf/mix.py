"""A weighted sum of BSDFs: f = sum_k w_k f_k, sampled by picking lobe k with probability c_k.

Used for plastic (diffuse + coat, w = 1, c in proportion to the lobes' colours) and for pbrt's
``mix`` (w = 1 - amount and amount, c their means). The pdf of a non-specular sample is
sum_k c_k pdf_k and its value the whole sum (pbrt's ``BSDF::Sample_f`` does the same over its
BxDFs); a specular sample keeps its lobe's value times w_k and pdf times c_k.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from realistic.renderer.bsdf.base import BSDF, BSDFSample


class WeightedSum:
    """``parts`` with weights (N, C) each and lobe probabilities (N,) each (normalised per hit;
    equal where they are all 0). ``chances`` may instead be a function of wo giving them, for lobes
    whose share depends on the viewing angle (a coat's Fresnel reflectance)."""

    def __init__(self, parts: list[BSDF], weights: list[np.ndarray],
                 chances: list[np.ndarray] | Callable[[np.ndarray], list[np.ndarray]]):
        self.parts = parts
        self.weights = [np.asarray(w, np.float32) for w in weights]
        self._chances = chances
        self.has_specular = any(p.has_specular for p in parts)
        self.only_specular = all(p.only_specular for p in parts)

    def chances(self, wo: np.ndarray) -> np.ndarray:
        """Lobe probabilities (N, parts) for outgoing directions wo."""
        chances = self._chances(wo) if callable(self._chances) else self._chances
        c = np.stack([np.asarray(x, np.float64) for x in chances], axis=1)
        total = c.sum(axis=1, keepdims=True)
        return np.where(total > 0, c / np.where(total > 0, total, 1.0), 1.0 / len(self.parts)).astype(np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return sum(w * p.evaluate(wo, wi) for w, p in zip(self.weights, self.parts)).astype(np.float32)

    def pdf(self, wo: np.ndarray, wi: np.ndarray, chances: np.ndarray | None = None) -> np.ndarray:
        c = self.chances(wo) if chances is None else chances
        return sum(c[:, k] * p.pdf(wo, wi) for k, p in enumerate(self.parts)).astype(np.float32)

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        chances = self.chances(wo)
        cumulative = np.cumsum(chances, axis=1)
        lobe = np.minimum((u_lobe[:, None] >= cumulative).sum(axis=1), len(self.parts) - 1)
        start = np.take_along_axis(cumulative - chances, lobe[:, None], axis=1)[:, 0]
        chance = np.take_along_axis(chances, lobe[:, None], axis=1)[:, 0]
        u_rest = np.clip((u_lobe - start) / np.maximum(chance, 1e-12), 0.0, 1.0 - 1e-7).astype(np.float32)
        samples = [p.sample(wo, u, u_rest) for p in self.parts]
        pick = lobe[:, None]
        wi = np.choose(pick, [s.wi for s in samples]).astype(np.float32)
        specular = np.choose(lobe, [s.specular for s in samples])
        valid = np.choose(lobe, [s.valid for s in samples])
        value, pdf = self.evaluate(wo, wi), self.pdf(wo, wi, chances)
        if specular.any():
            lobe_value = np.choose(pick, [w * s.value for w, s in zip(self.weights, samples)])
            lobe_pdf = chance * np.choose(lobe, [s.pdf for s in samples])
            value = np.where(specular[:, None], lobe_value, value).astype(np.float32)
            pdf = np.where(specular, lobe_pdf, pdf).astype(np.float32)
        return BSDFSample(wi, value, pdf, specular, valid & (pdf > 0))
