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
number of texels per point is expanded into one flat array of (point, texel) taps, each point's
summed in its taps' order. EWA computes in float32 as pbrt-v3's ``Float`` does (the axes' lengths,
clamp and level in float64: ``_ewa_axes``; the ellipse arranged so that no step cancels:
``_ewa_ellipse``), in the same operations and order as the kernel. They are the references of
``realistic.scene.ewa_kernel`` (``kernels/ewa.cl``), their versions on the device for the "opencl"
backend. A map is plain data (it pickles): a backend keeps its texels on a device.
"""

from __future__ import annotations

import math

import numpy as np

_LUT_SIZE = 128
#: pbrt's EWA weights: a Gaussian exp(-alpha r^2) with alpha = 2, shifted to be 0 at r = 1 (float32,
#: as pbrt-v3's ``Float`` table; the last entry is exactly 0).
EWA_WEIGHTS = (np.exp(-2.0 * np.arange(_LUT_SIZE) / (_LUT_SIZE - 1)) - np.exp(-2.0)).astype(np.float32)
#: The smallest normal float32: the floor of EWA's weights' sum (0 where no texel is inside).
_TINY = np.finfo(np.float32).tiny
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


def _ewa_axes(axis0: np.ndarray, axis1: np.ndarray, max_anisotropy: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (major, minor) float32 axes (N, 2) EWA filters over and the minor one's length (N,)
    (float64): the longer of the float32 ``axis0``, ``axis1`` first, the minor one stretched so that
    the eccentricity is at most ``max_anisotropy`` (pbrt-v3 ``MIPMap::Lookup``), in float64 (no square
    of a float32 overflows or underflows a float64, so no footprint's length is lost) and rounded back."""
    axis0, axis1 = axis0.astype(np.float64), axis1.astype(np.float64)
    swap = axis0[:, 0] * axis0[:, 0] + axis0[:, 1] * axis0[:, 1] < axis1[:, 0] * axis1[:, 0] + axis1[:, 1] * axis1[:, 1]
    major = np.where(swap[:, None], axis1, axis0)
    minor = np.where(swap[:, None], axis0, axis1)
    major_len = np.sqrt(major[:, 0] * major[:, 0] + major[:, 1] * major[:, 1])
    minor_len = np.sqrt(minor[:, 0] * minor[:, 0] + minor[:, 1] * minor[:, 1])
    clamp = (minor_len * max_anisotropy < major_len) & (minor_len > 0)
    stretch = major_len / np.maximum(minor_len * max_anisotropy, 1e-300)
    return (major.astype(np.float32), np.where(clamp[:, None], minor * stretch[:, None], minor).astype(np.float32),
            np.where(clamp, minor_len * stretch, minor_len))


def _ewa_ellipse(a0s: np.ndarray, a0t: np.ndarray, a1s: np.ndarray, a1t: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """pbrt-v3's EWA ellipse of the float32 axes (a0s, a0t), (a1s, a1t) in texels, widened by a texel
    (``MIPMap::EWA``: A s^2 + B s t + C t^2 < F, A = a0t^2 + a1t^2 + 1, B = -2 (a0s a0t + a1s a1t),
    C = a0s^2 + a1s^2 + 1, F = A C - B^2 / 4), arranged so that no step cancels in float32: F summed
    from its positive terms, (a0s a1t - a0t a1s)^2 + A + C - 1 (at least 1), and r^2, the left side
    over F, as a (s - mid)^2 + t^2 / A with a = A / F and a row's centre mid = s - t B / (2 A)
    (pbrt's products cancel to nothing at the eccentricities ``max_anisotropy`` allows). Returns a,
    1 / a, B / (2 A), 1 / A and the half-height sqrt(A), as ``kernels/ewa.cl``'s ``ewa_ellipse``."""
    big_a = a0t * a0t + a1t * a1t + 1
    big_b = -2 * (a0s * a0t + a1s * a1t)
    big_c = a0s * a0s + a1s * a1s + 1
    cross = a0s * a1t - a0t * a1s
    f = cross * cross + (big_a + big_c - 1)
    inv_big_a = 1 / big_a
    return big_a / f, f * inv_big_a, np.float32(0.5) * big_b * inv_big_a, inv_big_a, np.sqrt(big_a)


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
        """Elliptically weighted average (N, 3) float32 over the ellipse with axes ``axis0``, ``axis1``
        (N, 2) around ``st`` (N, 2), all rounded to float32 (``scene.ewa_kernel.EwaKernel`` computes the
        same on the device, in the same float32 operations): none (0) where one of them is not finite
        in float32, level 0 bilinear (in float64) where the minor axis is 0."""
        out = np.zeros((len(st), 3), np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # non-finite lookups give 0, as the kernel's
            st32, axis0, axis1 = (np.asarray(v).astype(np.float32) for v in (st, axis0, axis1))
            finite = np.isfinite(st32).all(axis=1) & np.isfinite(axis0).all(axis=1) & np.isfinite(axis1).all(axis=1)
            major, minor, minor_len = _ewa_axes(axis0, axis1, self.max_anisotropy)
        flat = np.flatnonzero(finite & (minor_len == 0))
        out[flat] = self.bilinear(st32[flat].astype(np.float64), 0)
        rows = np.flatnonzero(finite & (minor_len != 0))
        length = np.maximum(minor_len[rows], 1e-8)
        # lod is 0 where the minor axis is at most a texel of the finest level along its longer side: log2
        # is skipped there, as the kernel skips it
        magnified = length <= 1.0 / (1 << (self.level_count - 1))
        lod = np.zeros(len(rows))
        lod[~magnified] = np.maximum(0.0, self._level_of(length[~magnified]))
        lower = np.floor(lod).astype(np.int64)
        delta = (lod - lower).astype(np.float32)[:, None]
        args = st32[rows], major[rows], minor[rows]
        out[rows] = self._ewa_level(lower, *args)
        # where lod is clamped to 0 (a magnified lookup) the next level has weight 0: skipped, as the kernel does
        blend = np.flatnonzero(delta[:, 0] > 0)
        out[rows[blend]] = (out[rows[blend]] * (1 - delta[blend])
                            + self._ewa_level(lower[blend] + 1, *(arg[blend] for arg in args)) * delta[blend])
        return out

    def _ewa_level(self, level: np.ndarray, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
        """Gaussian-weighted texel average (N, 3) float32 at per-point ``level`` of float32 ``st`` and
        axes (the coarsest level's texel beyond it)."""
        out = np.empty((len(st), 3), np.float32)
        beyond = level >= self.level_count
        out[beyond] = self._texels[-1]
        rows = np.flatnonzero(~beyond)
        level = level[rows]
        w, h = self._width[level].astype(np.float32), self._height[level].astype(np.float32)
        s, t = st[rows, 0] * w - np.float32(0.5), st[rows, 1] * h - np.float32(0.5)
        ellipse = _ewa_ellipse(axis0[rows, 0] * w, axis0[rows, 1] * h, axis1[rows, 0] * w, axis1[rows, 1] * h)
        half_t, inv_a = ellipse[4], ellipse[1]
        t0, t1 = np.ceil(t - half_t).astype(np.int64), np.floor(t + half_t).astype(np.int64)
        nt = np.maximum(t1 - t0 + 1, 0)
        taps = nt * np.floor(2 * np.sqrt(inv_a) + 2).astype(np.int64)  # a bound on the ellipse's texels
        sums = np.zeros((len(rows), 4), np.float32)  # red, green, blue, weight
        ends = np.cumsum(taps)
        start = 0
        while start < len(rows):
            stop = max(start + 1, int(np.searchsorted(ends, ends[start] - taps[start] + _TAPS_PER_CHUNK, "right")))
            self._ewa_taps(np.arange(start, stop), nt, t0, s, ellipse, t, level, sums)
            start = stop
        out[rows] = sums[:, :3] / np.maximum(sums[:, 3:], _TINY)
        return out

    def _ewa_taps(self, points: np.ndarray, nt: np.ndarray, t0: np.ndarray, s: np.ndarray,
                  ellipse: tuple[np.ndarray, ...], t: np.ndarray, level: np.ndarray, sums: np.ndarray) -> None:
        """Add the weighted texels inside ``points``' ellipses (``_ewa_ellipse``) and their weights into
        ``sums`` (red, green, blue, weight), each point's in the kernel's order (rows up, then texels to
        the right), in float32.

        Row by row of each ellipse's box, only the texels between the ellipse's two crossings of
        the row are visited (pbrt visits the whole box and rejects those outside).
        """
        a, inv_a, shift, inv_big_a, _ = ellipse
        rows_per_point = nt[points]
        owner = np.repeat(points, rows_per_point)
        y = t0[owner] + np.arange(int(rows_per_point.sum())) - np.repeat(np.cumsum(rows_per_point) - rows_per_point,
                                                                          rows_per_point)
        dt = y.astype(np.float32) - t[owner]
        row_r2 = dt * dt * inv_big_a[owner]
        mid = s[owner] - shift[owner] * dt
        half_w = np.sqrt(np.maximum(1 - row_r2, np.float32(0)) * inv_a[owner])
        x0 = np.ceil(mid - half_w).astype(np.int64)
        count = np.maximum(np.floor(mid + half_w).astype(np.int64) - x0 + 1, 0)
        row = np.repeat(np.arange(len(owner)), count)
        x = x0[row] + np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        u = x.astype(np.float32) - mid[row]
        r2 = a[owner[row]] * u * u + row_r2[row]
        keep = r2 < 1
        owner, x, y = owner[row][keep], x[keep], y[row][keep]
        weight = EWA_WEIGHTS[(r2[keep] * _LUT_SIZE).astype(np.int64)]  # r2 < 1: r2 * 128 < 128 exactly
        values = np.empty((len(owner), 4), np.float32)
        values[:, :3] = self.texel(level[owner], x, y) * weight[:, None]
        values[:, 3] = weight
        # each point's taps are consecutive: summed in float32 in that order, as the kernel sums them, by
        # adding every point's k-th tap at once (no point twice in one addition), k = 0, 1, ...
        starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
        rank = np.arange(len(owner)) - np.repeat(starts, np.diff(np.r_[starts, len(owner)]))
        order = np.argsort(rank, kind="stable")
        owner, values = owner[order], values[order]
        bounds = np.r_[0, np.cumsum(np.bincount(rank))]
        for first, last in zip(bounds[:-1], bounds[1:]):
            sums[owner[first:last]] += values[first:last]
