"""Measured BRDFs (pbrt-v2 ``IrregIsotropicBRDF`` and ``RegularHalfangleBRDF``, ``src/core/reflection.cpp``),
evaluated in RGB and sampled by the cosine, as pbrt-v2's default ``BxDF::Sample_f``.

Irregular samples: the query pair maps to m = BRDFRemap(wo, wi); pbrt-v2 gathers the samples
strictly within squared distance r2 of m, starting at r2 = 0.001 and doubling until more than two
are found or r2 exceeds 1.5 (so at most 2.048), and returns max(sum w v, 0) / sum w with
w = exp(-100 d^2). ``irregular_lookup`` computes that with a scipy kd-tree giving each query's
nearest samples, sorted by distance: the third nearest decides r2 in closed form, and the weighted
sum runs over the neighbours inside it (more neighbours are fetched for the queries whose radius
holds all that were fetched). It is the reference, and what the table is built from.

The table (``irregular_table``): that average depends on the pair only through m, which lies in the
unit cube (m_x = sin theta_i sin theta_o, m_y = delta phi / pi, m_z = cos theta_i cos theta_o for a
pair on one side). The table holds ``irregular_lookup`` at the nodes (i, j, k) / (n - 1) of a regular
grid of n = ``TABLE_NODES`` per axis, RGB float32, and a pair's value is the trilinear interpolation
of its cell's eight nodes (``table_lookup``, a numba loop from the directions themselves). Nodes with
i + k > n + 1 are never read (m_x + m_z = cos(theta_i - theta_o) <= 1) and hold 0. Built once per
file and kept in the verified disk cache (``realistic.core.disk_cache``), keyed by the samples'
bytes, the grid and the lookup's constants. The interpolant is a weighted mean of the nodes, each a
weighted mean of the samples gathered there, so it lies between the least and greatest sample value
gathered at the nodes within one cell of m (``tests/test_measured_table.py`` holds it to that).

MERL tables: the half vector wh (the pair mirrored so wh.z >= 0) and wi in wh's frame give
theta_h, theta_d and phi_d (phi_d folded into [0, pi)); indices are floor(sqrt(theta_h / (pi / 2))
* 90), floor(theta_d / (pi / 2) * 90) and floor(phi_d / pi * 180), each clamped to the table.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from functools import lru_cache
from typing import Protocol

import numpy as np

from realistic.core.disk_cache import cache_key, load_arrays, store_arrays
from realistic.core.jit import compiled
from realistic.renderer.bsdf.lambertian import CosineSampled
from realistic.scene.measured import HalfangleTable, IrregularSamples

FIRST_RADIUS2 = 0.001
LAST_LEVEL = 11  # 0.001 * 2^11 = 2.048 is the first radius^2 above 1.5
NEIGHBOURS = 8
CHUNK = 65_536
#: Nodes per axis of the irregular samples' table (module notes): cells 1/127 wide.
TABLE_NODES = 128
#: Part of the table's disk-cache key: change it when what the table holds changes.
TABLE_KEY = b"irregular-table-1"
#: Nodes of a cached table recomputed before it is used (``_trusted_table``), a small part of a build.
CHECKED_NODES = 64


class _NearestNeighbours(Protocol):
    """What ``irregular_lookup`` asks of scipy's ``cKDTree``: distances and indices (N, k) of each point's
    k nearest samples, nearest first (``workers`` -1: on every core)."""

    def query(self, x: np.ndarray, k: int, workers: int) -> tuple[np.ndarray, np.ndarray]: ...


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
            d, index = tree.query(points[rows], k=k, workers=-1)
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


def table_nodes(nodes: int) -> np.ndarray:
    """The (i, j, k) indices (M, 3) of the nodes a lookup can read: i + k <= nodes + 1 (module notes)."""
    i, j, k = np.meshgrid(*(np.arange(nodes),) * 3, indexing="ij")
    used = i + k <= nodes + 1
    return np.column_stack([i[used], j[used], k[used]])


def build_irregular_table(samples: IrregularSamples, nodes: int = TABLE_NODES) -> np.ndarray:
    """``irregular_lookup`` at the grid's nodes: (nodes, nodes, nodes, 3) float32, 0 at unread nodes."""
    index = table_nodes(nodes)
    table = np.zeros((nodes, nodes, nodes, 3), np.float32)
    table[index[:, 0], index[:, 1], index[:, 2]] = irregular_lookup(samples, index / (nodes - 1.0))
    return table


def _table_key(samples: IrregularSamples, nodes: int) -> str:
    """The disk-cache key of a table: the samples' bytes, the grid and the lookup's constants."""
    points, rgb = (np.ascontiguousarray(a, np.float64) for a in (samples.points, samples.rgb))
    return cache_key("measured-table", TABLE_KEY, nodes, FIRST_RADIUS2, LAST_LEVEL, points.shape,
                     points.tobytes(), rgb.tobytes())


def _trusted_table(stored: dict[str, np.ndarray], samples: IrregularSamples, nodes: int) -> np.ndarray | None:
    """The table a cache entry holds when it is one ``build_irregular_table`` could have made from
    these samples, else None: float32 of the grid's shape, every value between 0 and the samples'
    greatest (the lookup is a clamped weighted mean of them), 0 at the nodes never read, and
    exactly ``irregular_lookup`` at ``CHECKED_NODES`` of the read ones (so a table of other samples, which
    would pass the bounds, is not taken for this one's)."""
    table = stored.get("table")
    if set(stored) != {"table"} or table is None or table.dtype != np.float32 or table.shape != (nodes,) * 3 + (3,):
        return None
    top = np.maximum(samples.rgb.max(axis=0), 0.0).astype(np.float32)
    if not (np.all(np.isfinite(table)) and np.all(table >= 0) and np.all(table <= top)):
        return None
    axis = np.arange(nodes)
    read_i, read_k = np.nonzero(axis[:, None] + axis[None, :] <= nodes + 1)  # ``table_nodes``' rule, any j
    unread_i, unread_k = np.nonzero(axis[:, None] + axis[None, :] > nodes + 1)
    if np.any(table[unread_i, :, unread_k] != 0):
        return None
    rng = np.random.default_rng(0)
    pick = rng.choice(len(read_i), min(CHECKED_NODES, len(read_i)), replace=False)
    checked = np.column_stack([read_i[pick], rng.integers(0, nodes, len(pick)), read_k[pick]])
    expected = irregular_lookup(samples, checked / (nodes - 1.0)).astype(np.float32)
    if not np.array_equal(table[checked[:, 0], checked[:, 1], checked[:, 2]], expected):
        return None  # the lookup is per node, so a build gives these bits (a numpy whose sums differ: a rebuild)
    return table


_table_lock = threading.Lock()


def irregular_table(samples: IrregularSamples) -> np.ndarray:
    """The samples' table (module notes): from memory, else the disk cache, else built (once per
    process even when several render threads ask at once)."""
    with _table_lock:
        return _irregular_table(samples)


@lru_cache(maxsize=16)
def _irregular_table(samples: IrregularSamples) -> np.ndarray:
    key = _table_key(samples, TABLE_NODES)
    stored = load_arrays(key)
    table = _trusted_table(stored, samples, TABLE_NODES) if stored is not None else None
    if table is None:
        table = build_irregular_table(samples, TABLE_NODES)
        store_arrays(key, {"table": table})
    return table


def _table_loop(table: np.ndarray, wo: np.ndarray, wi: np.ndarray, out: np.ndarray) -> None:
    """The table's RGB at each local pair (wo, wi) into ``out`` (N, 3): BRDFRemap (float64; delta phi
    as the angle between the two azimuths, one atan2, which is ``realistic.scene.measured.brdf_remap``'s
    folded difference of two), then trilinear interpolation; 0 where the two are not on one side."""
    last = table.shape[0] - 1
    for r in range(wo.shape[0]):
        cos_o, cos_i = float(wo[r, 2]), float(wi[r, 2])
        if cos_o * cos_i <= 0.0:
            out[r, 0] = out[r, 1] = out[r, 2] = 0.0
            continue
        sin_o = math.sqrt(max(0.0, 1.0 - cos_o * cos_o))
        sin_i = math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
        ox, oy, ix, iy = float(wo[r, 0]), float(wo[r, 1]), float(wi[r, 0]), float(wi[r, 1])
        if (ox != 0.0 or oy != 0.0) and (ix != 0.0 or iy != 0.0):  # the angle between the azimuths
            dphi = math.atan2(abs(ox * iy - oy * ix), ox * ix + oy * iy)
        else:  # along the normal: pbrt's azimuth atan2(0, 0) = 0
            dphi = (math.atan2(iy, ix) - math.atan2(oy, ox)) % (2 * math.pi)
            if dphi > math.pi:
                dphi = 2 * math.pi - dphi
        gx = min(max(sin_i * sin_o * last, 0.0), float(last))
        gy = min(max(dphi / math.pi * last, 0.0), float(last))
        gz = min(max(cos_i * cos_o * last, 0.0), float(last))
        ix, iy, iz = min(int(gx), last - 1), min(int(gy), last - 1), min(int(gz), last - 1)
        fx, fy, fz = gx - ix, gy - iy, gz - iz
        for c in range(3):
            c00 = table[ix, iy, iz, c] * (1 - fx) + table[ix + 1, iy, iz, c] * fx
            c01 = table[ix, iy, iz + 1, c] * (1 - fx) + table[ix + 1, iy, iz + 1, c] * fx
            c10 = table[ix, iy + 1, iz, c] * (1 - fx) + table[ix + 1, iy + 1, iz, c] * fx
            c11 = table[ix, iy + 1, iz + 1, c] * (1 - fx) + table[ix + 1, iy + 1, iz + 1, c] * fx
            out[r, c] = (c00 * (1 - fy) + c10 * fy) * (1 - fz) + (c01 * (1 - fy) + c11 * fy) * fz


def table_lookup(table: np.ndarray, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """The table's RGB (N, 3) float64 for local pairs (wo, wi) (N, 3) (module notes)."""
    out = np.empty((len(wo), 3), np.float64)
    compiled(_table_loop)(table, np.ascontiguousarray(wo), np.ascontiguousarray(wi), out)
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
        self._rgb: Callable[[np.ndarray, np.ndarray], np.ndarray]
        if isinstance(data, IrregularSamples):
            table = irregular_table(data)
            self._rgb = lambda wo, wi: table_lookup(table, wo, wi)
        else:
            self._rgb = lambda wo, wi: _halfangle_rgb(data, wo, wi)

    def evaluate(self, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return np.einsum("ncj,nj->nc", self.to_channels, self._rgb(wo, wi).astype(np.float32))


def _halfangle_rgb(table: HalfangleTable, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """``halfangle_lookup`` where the pair is on one side, else 0: RGB (N, 3)."""
    rgb = np.zeros((len(wo), 3), np.float64)
    rows = np.flatnonzero(wo[:, 2] * wi[:, 2] > 0)
    if len(rows):
        rgb[rows] = halfangle_lookup(table, wo[rows], wi[rows])
    return rgb
