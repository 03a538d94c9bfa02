"""The BSDF protocol, the record a BSDF sample returns, and the local shading frame."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from realistic.core.vectors import dot, normalise


@dataclass(frozen=True)
class BSDFSample:
    """Sampled incident directions for N hits.

    ``value`` is f(wo, wi) (N, C); ``pdf`` its solid-angle density (N,). For a specular sample
    (``specular`` True) f and pdf are both relative to the delta: value * |cos(wi)| / pdf is the
    throughput, as in pbrt. ``valid`` is False where no direction was produced (pdf 0).
    """

    wi: np.ndarray  # (N, 3) float32, local frame
    value: np.ndarray  # (N, C) float32
    pdf: np.ndarray  # (N,) float32
    specular: np.ndarray  # (N,) bool
    valid: np.ndarray  # (N,) bool


class BSDF(Protocol):
    """Scattering at N hits of one material (see the package docstring for the conventions).

    ``has_specular``: some hits may return specular samples (mirror, glass, smooth metal, a mix
    holding one); ``only_specular``: every sample is specular and ``evaluate`` is zero everywhere,
    so light sampling there is wasted work.
    """

    has_specular: bool
    only_specular: bool

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        """f(wo, wi), (N, C); zero for the specular lobes."""

    def pdf(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        """Solid-angle density (N,) with which ``sample`` picks wi given wo; zero for specular lobes."""

    def sample(self, wo: np.ndarray, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        """One wi per hit from uniform numbers ``u`` (N, 2) and ``u_lobe`` (N,) (lobe choice)."""


class HitParameters(Protocol):
    """Material parameters looked up at a batch of hits (textures at their uv and footprint)."""

    def colour(self, value: object) -> np.ndarray:
        """An RGB constant or a texture at the hits, (N, C) float32 (C = 1 for spectral rays)."""

    def scalar(self, value: object) -> np.ndarray:
        """A float constant or a texture's mean channel at the hits, (N,) float32."""


class ShadingFrame:
    """Orthonormal frames (s, t, n) per hit built from unit normals n (N, 3)."""

    def __init__(self, normal: np.ndarray):
        n = np.asarray(normal, np.float32)
        # Duff et al. 2017, "Building an Orthonormal Basis, Revisited": continuous except at z = -1.
        sign = np.where(n[:, 2] >= 0, 1.0, -1.0).astype(np.float32)
        a = -1.0 / (sign + n[:, 2])
        b = n[:, 0] * n[:, 1] * a
        s = np.column_stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]])
        t = np.column_stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]])
        self.s, self.t, self.n = normalise(s.astype(np.float32)), normalise(t.astype(np.float32)), n

    def to_local(self, w: np.ndarray) -> np.ndarray:
        """World directions (N, 3) in the local frame."""
        return np.column_stack([dot(w, self.s), dot(w, self.t), dot(w, self.n)]).astype(np.float32)

    def to_world(self, w: np.ndarray) -> np.ndarray:
        """Local directions (N, 3) in world space."""
        return (self.s * w[:, :1] + self.t * w[:, 1:2] + self.n * w[:, 2:]).astype(np.float32)
