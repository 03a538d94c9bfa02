"""Measured BRDFs (pbrt-v2 ``IrregIsotropicBRDF`` and ``RegularHalfangleBRDF``, ``src/core/reflection.cpp``),
evaluated in RGB and sampled by the cosine, as pbrt-v2's default ``BxDF::Sample_f``.

Irregular samples: the query pair maps to m = BRDFRemap(wo, wi); pbrt-v2 gathers the samples
strictly within squared distance r2 of m, starting at r2 = 0.001 and doubling until more than two
are found or r2 exceeds 1.5 (so at most 2.048), and returns max(sum w v, 0) / sum w with
w = exp(-100 d^2). Here a scipy kd-tree gives each query's nearest samples, sorted by distance: the
third nearest decides r2 in closed form, and the weighted sum runs over the neighbours inside it
(more neighbours are fetched for the queries whose radius holds all that were fetched).

MERL tables: the half vector wh (the pair mirrored so wh.z >= 0) and wi in wh's frame give
theta_h, theta_d and phi_d (phi_d folded into [0, pi)); indices are floor(sqrt(theta_h / (pi / 2))
* 90), floor(theta_d / (pi / 2) * 90) and floor(phi_d / pi * 180), each clamped to the table.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Protocol

import numpy as np

from realistic.renderer.bsdf.lambertian import CosineSampled
from realistic.scene.measured import HalfangleTable, IrregularSamples, brdf_remap

FIRST_RADIUS2 = 0.001
LAST_LEVEL = 11  # 0.001 * 2^11 = 2.048 is the first radius^2 above 1.5
NEIGHBOURS = 8
CHUNK = 65_536


class _NearestNeighbours(Protocol):
    """What ``irregular_lookup`` asks of scipy's ``cKDTree``: distances and indices (N, k) of each point's
    k nearest samples, nearest first."""

    def query(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]: ...


@lru_cache(maxsize=16)
def _tree(samples: IrregularSamples) -> _NearestNeighbours:
    """The samples' kd-tree, built once per file (scipy is imported here, when a scene needs it)."""
    from scipy.spatial import cKDTree

    return cKDTree(samples.points)


def irregular_lookup(samples: IrregularSamples, points: np.ndarray) -> np.ndarray:
    """pbrt-v2's kd-tree average (N, 3) of the samples around BRDFRemap ``points`` (N, 3)."""
    out = np.zeros((len(points), 3), np.float64)
    tree, total = _tree(samples), len(samples.points)
    for start in range(0, len(points), CHUNK):
        rows = np.arange(start, min(start + CHUNK, len(points)))
        k = min(NEIGHBOURS, total)
        while len(rows):
            d, index = tree.query(points[rows], k=k)
            d, index = d.reshape(len(rows), -1), index.reshape(len(rows), -1)
            d2 = d * d
            if total >= 3:
                level = np.floor(np.log2(np.maximum(d2[:, 2], 1e-300) / FIRST_RADIUS2)) + 1
                level = np.clip(level, 0, LAST_LEVEL)
            else:
                level = np.full(len(rows), LAST_LEVEL, np.float64)
            radius2 = FIRST_RADIUS2 * 2.0 ** level
            inside = d2 < radius2[:, None]
            w = np.exp(-100.0 * d2) * inside
            value = np.einsum("nk,nkc->nc", w, samples.rgb[index])
            weight = w.sum(axis=1)
            good = weight > 0
            out[rows[good]] = np.maximum(value[good], 0.0) / weight[good, None]
            truncated = inside[:, -1] & (k < total)
            rows, k = rows[truncated], min(4 * k, total)
    return out


def halfangle_lookup(table: HalfangleTable, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """pbrt-v2 ``RegularHalfangleBRDF::f``: the table's RGB (N, 3) for local pairs (wo, wi)."""
    wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
    wh = wo + wi
    flip = np.where(wh[:, 2] < 0, -1.0, 1.0)[:, None]
    wi, wh = wi * flip, wh * flip
    length = np.linalg.norm(wh, axis=1)
    ok = length > 0
    wh = wh / np.where(ok, length, 1.0)[:, None]
    cos_h = np.clip(wh[:, 2], -1.0, 1.0)
    sin_h = np.sqrt(np.maximum(0.0, 1.0 - cos_h * cos_h))
    safe = np.where(sin_h > 0, sin_h, 1.0)
    cos_phi = np.where(sin_h > 0, np.clip(wh[:, 0] / safe, -1, 1), 1.0)
    sin_phi = np.where(sin_h > 0, np.clip(wh[:, 1] / safe, -1, 1), 0.0)
    x = np.column_stack([cos_phi * cos_h, sin_phi * cos_h, -sin_h])
    y = np.column_stack([-sin_phi, cos_phi, np.zeros(len(wh))])
    wd = np.column_stack([np.einsum("ij,ij->i", wi, x), np.einsum("ij,ij->i", wi, y), np.einsum("ij,ij->i", wi, wh)])
    theta_h = np.arccos(cos_h)
    theta_d = np.arccos(np.clip(wd[:, 2], -1.0, 1.0))
    phi_d = np.mod(np.arctan2(wd[:, 1], wd[:, 0]), 2 * np.pi)
    phi_d = np.where(phi_d > np.pi, phi_d - np.pi, phi_d)
    n_h, n_d, n_phi = table.rgb.shape[:3]

    def remap(v: np.ndarray, top: float, count: int) -> np.ndarray:
        return np.clip((v / top * count).astype(np.int64), 0, count - 1)

    i_h = remap(np.sqrt(np.maximum(0.0, theta_h / (np.pi / 2))), 1.0, n_h)
    i_d = remap(theta_d, np.pi / 2, n_d)
    i_phi = remap(phi_d, np.pi, n_phi)
    return np.where(ok[:, None], table.rgb[i_h, i_d, i_phi], 0.0)


class MeasuredBRDF(CosineSampled):
    """A measured BRDF; ``to_channels`` (N, C, 3) turns its RGB into the rays' C channels."""


    def __init__(self, data: IrregularSamples | HalfangleTable, to_channels: np.ndarray):
        self.data, self.to_channels = data, np.asarray(to_channels, np.float32)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        same = wo[:, 2] * wi[:, 2] > 0
        rgb = np.zeros((len(wo), 3), np.float64)
        rows = np.flatnonzero(same)
        if len(rows):
            if isinstance(self.data, HalfangleTable):
                rgb[rows] = halfangle_lookup(self.data, wo[rows], wi[rows])
            else:
                rgb[rows] = irregular_lookup(self.data, brdf_remap(wo[rows], wi[rows]))
        return np.einsum("ncj,nj->nc", self.to_channels, rgb.astype(np.float32))
