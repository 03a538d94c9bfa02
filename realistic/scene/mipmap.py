"""MIP maps of RGB images and filtered lookups batched over points (point, bilinear, trilinear, EWA).

Texture space here is (s, t) in [0, 1) per image repeat, s to the right and t down the rows of the
(H, W, 3) array (the caller flips t for a bottom-origin image). A texel (x, y) covers
[x, x + 1) x [y, y + 1) in texel units, so its centre is at (x + 0.5) / W.

The pyramid follows pbrt-v3 ``src/core/mipmap.h``: level 0 is the image at power-of-two size,
each next level halves each side (down to 1) by averaging 2 x 2 texels, 1 + log2(max(W, H))
levels. Where pbrt resamples a non-power-of-two image with a Lanczos filter, this resamples by
exact area averaging (each new texel is the old image's mean over its span): no ringing, no
negative lobes, and every level keeps the image mean exactly.

Lookups follow the same file: trilinear blends bilinear lookups at the two levels around
``L - 1 + log2(width)``; pbrt-v4 ``src/pbrt/util/mipmap.cpp`` (``MIPMap::Filter``: ``if (iLevel == 0)
return Bilerp<T>(0, st)``) reads level 0 alone wherever the floor of that is 0, blending only from
level 1 up, the one place the versions differ: ``trilinear_blend_from`` (0 as v3, 1 as v4) says which;
EWA clamps the ellipse's eccentricity to ``max_anisotropy``, picks the level from the minor axis and
blends two levels of a Gaussian-weighted sum over the texels inside the ellipse (weights from pbrt's
128-entry table of exp(-2 r^2) - exp(-2)); where the level is clamped to 0 (a magnified lookup) the
second level's weight is 0 and its sum is skipped. ``point`` and ``bilinear`` follow pbrt-v4
``src/pbrt/util/mipmap.cpp`` (MIPMap::Filter): one lookup at the level floor(L - 1 + log2(width)),
the point filter's texel index rounded half away from zero (``std::round``). Where L - 1 + log2(width)
reaches the coarsest level, point, bilinear and trilinear return its one texel as it is, unwrapped
(both versions: ``Texel(Levels() - 1, 0, 0)``). All lookups are numpy over the points; EWA's varying
number of texels per point is expanded into one flat array of (point, texel) taps and summed with
``np.bincount``; they are the references of ``realistic.scene.ewa_kernel`` (``kernels/ewa.cl``), their
versions on the device for the "opencl" backend. A map is plain data (it pickles): a backend keeps its
texels on a device.
"""

from __future__ import annotations

import math

import numpy as np

_LUT_SIZE = 128
#: pbrt's EWA weights: a Gaussian exp(-alpha r^2) with alpha = 2, shifted to be 0 at r = 1.
EWA_WEIGHTS = np.exp(-2.0 * np.arange(_LUT_SIZE) / (_LUT_SIZE - 1)) - np.exp(-2.0)
#: Most (point, texel) EWA taps expanded at once, to bound memory.
_TAPS_PER_CHUNK = 1 << 21


def _area_resample_matrix(old: int, new: int) -> np.ndarray:
    """(new, old) weights: new texel i = mean of the old samples over [i, i + 1) * old / new."""
    edges = np.arange(new + 1) * (old / new)
    lo, hi = edges[:-1, None], edges[1:, None]
    j = np.arange(old)[None, :]
    overlap = np.clip(np.minimum(hi, j + 1) - np.maximum(lo, j), 0.0, None)
    return overlap / (old / new)


def _next_power_of_two(n: int) -> int:
    return 1 << (n - 1).bit_length()


def _round_half_away(x: np.ndarray) -> np.ndarray:
    """``x`` rounded to the nearest integer (int64), halves away from zero (C's ``round``; numpy's
    rounds them to even), exactly: x - trunc(x) is exact."""
    whole = np.trunc(x)
    return (whole + np.where(np.abs(x - whole) >= 0.5, np.sign(x), 0.0)).astype(np.int64)


def _halve(level: np.ndarray) -> np.ndarray:
    """The next coarser level: 2 x 2 averages (2 x 1 or 1 x 2 once a side is down to 1)."""
    if level.shape[0] > 1:
        level = 0.5 * (level[0::2] + level[1::2])
    if level.shape[1] > 1:
        level = 0.5 * (level[:, 0::2] + level[:, 1::2])
    return level


class MipMap:
    """A pyramid of an (H, W, 3) linear image, stored as one flat texel array, and its lookups."""

    def __init__(self, pixels: np.ndarray, wrap: str = "repeat", max_anisotropy: float = 8.0,
                 trilinear_blend_from: int = 0):
        """``trilinear_blend_from``: the level from which ``trilinear`` blends two levels, reading level 0
        alone below it (0: pbrt-v1 to v3; 1: pbrt-v4; ``validation.TRILINEAR_BLEND_STARTS``)."""
        image = np.asarray(pixels, dtype=np.float64)
        height, width = image.shape[:2]
        size_y, size_x = _next_power_of_two(height), _next_power_of_two(width)
        if (size_y, size_x) != (height, width):
            image = np.einsum("yi,ijc,xj->yxc", _area_resample_matrix(height, size_y), image,
                              _area_resample_matrix(width, size_x))
        shapes = [(size_y, size_x)]
        for _ in range(int(math.log2(max(size_x, size_y)))):
            shapes.append((max(1, shapes[-1][0] // 2), max(1, shapes[-1][1] // 2)))
        self.wrap, self.max_anisotropy = wrap, float(max_anisotropy)
        self.trilinear_blend_from = int(trilinear_blend_from)
        self._height = np.array([h for h, _ in shapes], np.int64)
        self._width = np.array([w for _, w in shapes], np.int64)
        self._base = np.concatenate([[0], np.cumsum(self._width * self._height)[:-1]])
        # averaged in float64, stored in float32 level by level: one float64 level is alive at a time
        self._texels = np.empty((int(np.sum(self._width * self._height)), 3), np.float32)
        level = image
        for index in range(len(shapes)):
            if index:
                level = _halve(level)
            self._texels[self._base[index]:self._base[index] + level.shape[0] * level.shape[1]] = level.reshape(-1, 3)

    @property
    def level_count(self) -> int:
        return len(self._width)

    @property
    def levels(self) -> list[np.ndarray]:
        """Each level as an (h, w, 3) float32 view of ``texels`` (only the float32 pyramid is kept:
        a float64 copy of the homework's 1024 x 1024 texture would hold 32 MiB for nothing)."""
        return [self._texels[base:base + w * h].reshape(h, w, 3)
                for base, w, h in zip(self._base, self._width, self._height)]

    @property
    def texels(self) -> np.ndarray:
        """Every level's texels (M, 3) float32, level after level, rows top to bottom."""
        return self._texels

    @property
    def level_base(self) -> np.ndarray:
        """Index in ``texels`` of each level's first texel."""
        return self._base

    @property
    def level_width(self) -> np.ndarray:
        return self._width

    @property
    def level_height(self) -> np.ndarray:
        return self._height

    def texel(self, level: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Texels (N, 3) at integer (x, y) of per-point ``level``s, outside the image as ``wrap`` says."""
        w, h = self._width[level], self._height[level]
        inside = None
        if self.wrap == "repeat":
            x, y = np.mod(x, w), np.mod(y, h)
        elif self.wrap == "clamp":
            x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
        else:
            inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
        values = np.take(self._texels, self._base[level] + y * w + x, axis=0)
        return values if inside is None else values * inside[:, None]

    def bilinear(self, st: np.ndarray, level: np.ndarray | int = 0) -> np.ndarray:
        """Bilinear interpolation (N, 3) of texel centres at (s, t) (N, 2) on per-point ``level``s."""
        level = np.broadcast_to(np.asarray(level, np.int64), (len(st),))
        x = st[:, 0] * self._width[level] - 0.5
        y = st[:, 1] * self._height[level] - 0.5
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
        top = self.texel(level, x0, y0) * (1 - fx) + self.texel(level, x0 + 1, y0) * fx
        bottom = self.texel(level, x0, y0 + 1) * (1 - fx) + self.texel(level, x0 + 1, y0 + 1) * fx
        return top * (1 - fy) + bottom * fy

    def _level_of(self, width: np.ndarray) -> np.ndarray:
        """Continuous level L - 1 + log2(width) of a filter ``width`` in (s, t) units."""
        return self.level_count - 1 + np.log2(np.maximum(width, 1e-8))

    def _coarsest_where_wide(self, level: np.ndarray, values: np.ndarray) -> np.ndarray:
        """``values`` with the rows whose continuous ``level`` reaches the coarsest level replaced by
        its one texel, unwrapped (pbrt-v3 ``MIPMap::Lookup``, pbrt-v4 ``MIPMap::Filter``)."""
        wide = level >= self.level_count - 1
        values[wide] = self._texels[-1]
        return values

    def point(self, st: np.ndarray, width: np.ndarray) -> np.ndarray:
        """The nearest texel at level floor(L - 1 + log2(width)) (pbrt-v4's point filter): the texel
        index is st * size - 0.5 rounded half away from zero, as ``std::round`` does."""
        continuous = self._level_of(width)
        level = np.clip(np.floor(continuous), 0, self.level_count - 1).astype(np.int64)
        x = _round_half_away(st[:, 0] * self._width[level] - 0.5)
        y = _round_half_away(st[:, 1] * self._height[level] - 0.5)
        return self._coarsest_where_wide(continuous, self.texel(level, x, y))

    def bilinear_at_width(self, st: np.ndarray, width: np.ndarray) -> np.ndarray:
        """Bilinear at level floor(L - 1 + log2(width)) (pbrt-v4's bilinear filter)."""
        continuous = self._level_of(width)
        level = np.clip(np.floor(continuous), 0, self.level_count - 1).astype(np.int64)
        return self._coarsest_where_wide(continuous, self.bilinear(st, level))

    def trilinear(self, st: np.ndarray, width: np.ndarray) -> np.ndarray:
        """Blend of bilinear lookups on the two levels around L - 1 + log2(width) (N, 3); where that
        level's floor (clamped to 0) is under ``trilinear_blend_from``, level 0's lookup alone (pbrt-v3
        ``src/core/mipmap.h`` ``MIPMap::Lookup`` blends from level 0, pbrt-v4 ``src/pbrt/util/mipmap.cpp``
        ``MIPMap::Filter`` from level 1)."""
        continuous = self._level_of(width)
        level = np.clip(continuous, 0.0, self.level_count - 1)
        lower = np.floor(level).astype(np.int64)
        upper = np.minimum(lower + 1, self.level_count - 1)
        delta = (level - lower)[:, None]
        below = self.bilinear(st, lower)
        blend = below * (1 - delta) + self.bilinear(st, upper) * delta
        alone = (lower < self.trilinear_blend_from)[:, None]
        return self._coarsest_where_wide(continuous, np.where(alone, below, blend))

    def ewa(self, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
        """Elliptically weighted average (N, 3) over the ellipse with axes ``axis0``, ``axis1`` (N, 2)
        (``scene.ewa_kernel.EwaKernel`` computes the same on the device, to float32 rounding)."""
        swap = (axis0 * axis0).sum(axis=1) < (axis1 * axis1).sum(axis=1)
        major = np.where(swap[:, None], axis1, axis0).astype(np.float64)
        minor = np.where(swap[:, None], axis0, axis1).astype(np.float64)
        major_len, minor_len = np.linalg.norm(major, axis=1), np.linalg.norm(minor, axis=1)
        clamp = (minor_len * self.max_anisotropy < major_len) & (minor_len > 0)
        stretch = np.where(clamp, major_len / np.maximum(minor_len * self.max_anisotropy, 1e-300), 1.0)
        minor, minor_len = minor * stretch[:, None], minor_len * stretch
        out = np.empty((len(st), 3))
        flat = minor_len == 0
        out[flat] = self.bilinear(st[flat], 0)
        rows = np.flatnonzero(~flat)
        lod = np.maximum(0.0, self._level_of(minor_len[rows]))
        lower = np.floor(lod).astype(np.int64)
        delta = (lod - lower)[:, None]
        args = st[rows], major[rows], minor[rows]
        out[rows] = self._ewa_level(lower, *args)
        # where lod is clamped to 0 (a magnified lookup) the next level has weight 0: skipped, as the kernel does
        blend = np.flatnonzero(delta[:, 0] > 0)
        out[rows[blend]] = (out[rows[blend]] * (1 - delta[blend])
                            + self._ewa_level(lower[blend] + 1, *(arg[blend] for arg in args)) * delta[blend])
        return out

    def _ewa_level(self, level: np.ndarray, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
        """Gaussian-weighted texel sum at per-point ``level`` (the coarsest level's texel beyond it)."""
        out = np.empty((len(st), 3))
        beyond = level >= self.level_count
        out[beyond] = self._texels[-1]
        rows = np.flatnonzero(~beyond)
        level = level[rows]
        w, h = self._width[level].astype(np.float64), self._height[level].astype(np.float64)
        s, t = st[rows, 0] * w - 0.5, st[rows, 1] * h - 0.5
        a0s, a0t, a1s, a1t = axis0[rows, 0] * w, axis0[rows, 1] * h, axis1[rows, 0] * w, axis1[rows, 1] * h
        a = a0t * a0t + a1t * a1t + 1
        b = -2 * (a0s * a0t + a1s * a1t)
        c = a0s * a0s + a1s * a1s + 1
        inv_f = 1 / (a * c - b * b * 0.25)
        a, b, c = a * inv_f, b * inv_f, c * inv_f
        det = 4 * a * c - b * b
        half_s, half_t = 2 * np.sqrt(det * c) / det, 2 * np.sqrt(a * det) / det
        t0, t1 = np.ceil(t - half_t).astype(np.int64), np.floor(t + half_t).astype(np.int64)
        nt = np.maximum(t1 - t0 + 1, 0)
        taps = nt * np.floor(2 * half_s + 1).astype(np.int64)  # the box's texels: a bound on the ellipse's
        sums, weights = np.zeros((len(rows), 3)), np.zeros(len(rows))
        ends = np.cumsum(taps)
        start = 0
        while start < len(rows):
            stop = max(start + 1, int(np.searchsorted(ends, ends[start] - taps[start] + _TAPS_PER_CHUNK, "right")))
            self._ewa_taps(np.arange(start, stop), nt, t0, s, t, a, b, c, level, sums, weights)
            start = stop
        out[rows] = sums / np.maximum(weights, 1e-300)[:, None]
        return out

    def _ewa_taps(self, points: np.ndarray, nt: np.ndarray, t0: np.ndarray, s: np.ndarray, t: np.ndarray,
                  a: np.ndarray, b: np.ndarray, c: np.ndarray, level: np.ndarray, sums: np.ndarray,
                  weights: np.ndarray) -> None:
        """Add the weighted texels inside ``points``' ellipses into ``sums`` and ``weights``.

        Row by row of each ellipse's box, only the texels between the ellipse's two crossings of
        the row are visited (pbrt visits the whole box and rejects those outside).
        """
        rows_per_point = nt[points]
        owner = np.repeat(points, rows_per_point)
        y = t0[owner] + np.arange(int(rows_per_point.sum())) - np.repeat(np.cumsum(rows_per_point) - rows_per_point,
                                                                          rows_per_point)
        dt = y - t[owner]
        aa, bb = a[owner], b[owner] * dt
        root = np.sqrt(np.maximum(bb * bb - 4 * aa * (c[owner] * dt * dt - 1), 0.0))
        x0 = np.ceil(s[owner] + (-bb - root) / (2 * aa)).astype(np.int64)
        count = np.maximum(np.floor(s[owner] + (-bb + root) / (2 * aa)).astype(np.int64) - x0 + 1, 0)
        row = np.repeat(np.arange(len(owner)), count)
        x = x0[row] + np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        owner, y = owner[row], y[row]
        ds, dt = x - s[owner], y - t[owner]
        r2 = a[owner] * ds * ds + b[owner] * ds * dt + c[owner] * dt * dt
        keep = r2 < 1
        owner, x, y = owner[keep], x[keep], y[keep]
        weight = EWA_WEIGHTS[np.minimum((r2[keep] * _LUT_SIZE).astype(np.int64), _LUT_SIZE - 1)]
        texels = self.texel(level[owner], x, y) * weight[:, None]
        n = len(sums)
        for channel in range(3):
            sums[:, channel] += np.bincount(owner, texels[:, channel], minlength=n)
        weights += np.bincount(owner, weight, minlength=n)
