"""Texture footprints of camera rays: the ellipse a pixel's cone covers on a surface, in uv units.

A pixel subtends ``spread`` radians seen from the scene, so at hit distance d its cone is d * spread
across. On a surface seen at angle theta to the normal the cone's cross-section stretches by
1 / |cos theta| along the ray's projection and keeps its width across it: two axes in the tangent
plane. The triangle's uv Jacobian carries them into uv: a tangent vector w = alpha e1 + beta e2
(e1, e2 the triangle's world edges) moves uv by alpha g1 + beta g2 (g1, g2 its uv edges). The axes
are one pixel step long, as pbrt's ray differentials are, so the texture filters treat them alike.
"""

from __future__ import annotations

import math

import numpy as np

from realistic.core.vectors import dot, normalise

#: Grazing hits: the along-ray axis is stretched by at most 1 / this (pbrt's EWA clamps it anyway).
MIN_COSINE = 1e-3


def differential_scale(spp: int, floor: float) -> float:
    """The fraction of a pixel a camera ray's footprint spans at ``spp`` samples per pixel: pbrt
    shrinks each camera ray's differentials by 1/sqrt(spp), since spp samples already cover the
    pixel (pbrt-v2 src/renderers/samplerrenderer.cpp and pbrt-v3 src/core/integrator.cpp:
    ``ScaleDifferentials(1 / sqrt(samplesPerPixel))``), and pbrt-v4 keeps at least 1/8 of a pixel
    (src/pbrt/cpu/integrators.cpp: ``max(.125, 1 / sqrt(SamplesPerPixel()))``): ``floor``."""
    return max(floor, 1.0 / math.sqrt(spp))


def tangent_axes(direction: np.ndarray, normal: np.ndarray, width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-space axes (N, 3) of a cone of ``width`` (N,) cut by the plane of unit ``normal``
    (N, 3) along unit ``direction`` (N, 3): (across the ray, along the ray's projection)."""
    cosine = dot(direction, normal)
    along = normalise(direction - cosine[:, None] * normal)
    fallback = normalise(np.cross(normal, np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])))
    along = np.where(dot(along, along)[:, None] > 0.5, along, fallback)
    across = np.cross(normal, along)
    stretch = 1.0 / np.maximum(np.abs(cosine), MIN_COSINE)
    return across * width[:, None], along * (width * stretch)[:, None]


def to_uv(vectors: np.ndarray, edge1: np.ndarray, edge2: np.ndarray, duv1: np.ndarray, duv2: np.ndarray
          ) -> np.ndarray:
    """uv offsets (N, 2) of tangent ``vectors`` (N, 3) on triangles with world edges ``edge1``,
    ``edge2`` (N, 3) and uv edges ``duv1``, ``duv2`` (N, 2); zero on degenerate triangles."""
    g11, g12, g22 = dot(edge1, edge1), dot(edge1, edge2), dot(edge2, edge2)
    r1, r2 = dot(edge1, vectors), dot(edge2, vectors)
    det = g11 * g22 - g12 * g12
    good = det > 1e-12 * g11 * g22
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=good)
    alpha, beta = (g22 * r1 - g12 * r2) * inv, (g11 * r2 - g12 * r1) * inv
    return alpha[:, None] * duv1 + beta[:, None] * duv2


def uv_footprint(direction: np.ndarray, normal: np.ndarray, distance: np.ndarray, spread_radians: float,
                 edge1: np.ndarray, edge2: np.ndarray, duv1: np.ndarray, duv2: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The two uv axes (N, 2) of each hit's pixel footprint (see the module docstring)."""
    across, along = tangent_axes(direction, normal, distance * spread_radians)
    return to_uv(across, edge1, edge2, duv1, duv2), to_uv(along, edge1, edge2, duv1, duv2)


def triangle_footprint(vertices: np.ndarray, uv: np.ndarray, face: np.ndarray, linear: np.ndarray,
                       direction: np.ndarray, normal: np.ndarray, distance: np.ndarray, spread_radians: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``uv_footprint`` of hits on triangles ``face`` (N, 3) (rows of a mesh's ``vertices`` and
    ``uv``, the uv as float32 as the filters read them) placed in the world by ``linear`` ((N, 3, 3)
    or one (3, 3)): the footprint of instances' and of area lights' triangles alike."""
    corner = [np.take(vertices, face[:, k], axis=0) for k in range(3)]
    corner_uv = [np.take(uv, face[:, k], axis=0).astype(np.float32).astype(np.float64) for k in range(3)]
    linear = np.broadcast_to(np.asarray(linear, np.float64), (len(face), 3, 3))
    return uv_footprint(direction.astype(np.float64), normal.astype(np.float64), distance.astype(np.float64),
                        spread_radians, np.einsum("nij,nj->ni", linear, corner[1] - corner[0]),
                        np.einsum("nij,nj->ni", linear, corner[2] - corner[0]), corner_uv[1] - corner_uv[0],
                        corner_uv[2] - corner_uv[0])
