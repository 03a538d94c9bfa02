"""A 2-D piecewise-constant distribution over [0, 1)^2, batched (pbrt's ``Distribution2D``).

Cells are the (rows, columns) of a non-negative weight array: v (rows) is drawn from the marginal,
then u (columns) from that row's conditional, each by inverting its piecewise-linear CDF, so the
density is weight / mean(weight) inside each cell. Used to importance-sample environment maps.
"""

from __future__ import annotations

import numpy as np


class Distribution2D:
    """Density over [0, 1)^2 proportional to ``weights`` (H, W) per cell; all-zero weights give uniform."""

    def __init__(self, weights: np.ndarray):
        w = np.asarray(weights, np.float64)
        if w.ndim != 2 or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights must be a finite non-negative 2-D array")
        if w.sum() <= 0:
            w = np.ones_like(w)
        self.height, self.width = w.shape
        self.density = w / w.mean()  # per cell, integrates to 1 over the unit square
        row_sums = w.sum(axis=1)
        self._row_cdf = np.concatenate([[0.0], np.cumsum(row_sums)]) / row_sums.sum()
        safe = np.where(row_sums[:, None] > 0, w, 1.0)
        self._col_cdf = np.concatenate([np.zeros((self.height, 1)), np.cumsum(safe, axis=1)], axis=1)
        self._col_cdf /= self._col_cdf[:, -1:]
        # row r's CDF shifted to [r, r + 1]: one searchsorted finds every point's column
        self._flat_cdf = (self._col_cdf + np.arange(self.height)[:, None]).ravel()

    @property
    def cdfs(self) -> tuple[np.ndarray, np.ndarray]:
        """The marginal CDF over rows (H + 1,) and each row's conditional CDF over columns (H, W + 1),
        each from 0 to 1: what ``sample`` inverts (for a kernel that samples as it does)."""
        return self._row_cdf, self._col_cdf

    def sample(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (N, 2) as (u, v) from uniform u1 (columns) and u2 (rows), and their densities (N,)."""
        u1, u2 = np.asarray(u1, np.float64), np.asarray(u2, np.float64)
        row = np.clip(np.searchsorted(self._row_cdf, u2, side="right") - 1, 0, self.height - 1)
        lo, hi = self._row_cdf[row], self._row_cdf[row + 1]
        v = (row + np.clip((u2 - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)) / self.height
        index = np.searchsorted(self._flat_cdf, row + u1, side="right") - 1
        col = np.clip(index - row * (self.width + 1), 0, self.width - 1)
        lo, hi = self._col_cdf[row, col], self._col_cdf[row, col + 1]
        u = (col + np.clip((u1 - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)) / self.width
        uv = np.column_stack([np.minimum(u, np.nextafter(1.0, 0)), np.minimum(v, np.nextafter(1.0, 0))])
        return uv, self.density[row, col]

    def pdf(self, uv: np.ndarray) -> np.ndarray:
        """Density (N,) at points uv (N, 2)."""
        col = np.clip((np.asarray(uv[:, 0]) * self.width).astype(np.int64), 0, self.width - 1)
        row = np.clip((np.asarray(uv[:, 1]) * self.height).astype(np.int64), 0, self.height - 1)
        return self.density[row, col]
