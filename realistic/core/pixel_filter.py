"""Pixel reconstruction filters as pbrt defines them, and the film offsets that sample them.

Every pbrt filter is separable, f(x, y) = f_x(x) f_y(y) (x, y in pixels from the pixel centre,
zero beyond the radius), so each axis is sampled on its own:

- ``box``: f = 1 (pbrt-v2/v3 ``src/filters/box.cpp``, pbrt-v4 ``src/pbrt/filters.cpp``).
- ``triangle``: f = max(0, r - |x|) (pbrt-v2/v3 ``src/filters/triangle.cpp``).
- ``gaussian``: f = max(0, exp(-alpha x^2) - exp(-alpha r^2)) (pbrt-v2/v3
  ``src/filters/gaussian.h``); pbrt-v4's sigma is alpha = 1 / (2 sigma^2) (its ``filters.cpp``:
  "sigma 0.5 equivalent to old alpha = 2").
- ``mitchell``: Mitchell-Netravali with B, C, of t = 2|x| / r in [0, 2] (pbrt-v2
  ``src/filters/mitchell.h``, pbrt-v3 the same, pbrt-v4 ``Mitchell1D(2 x / radius)``).
- ``sinc`` (Lanczos windowed sinc): f = sinc(a x) sinc(b x), sinc(t) = sin(pi t) / (pi t).
  pbrt-v2 ``src/filters/sinc.h`` scales by the radius (a = tau / r, b = 1 / r); pbrt-v3
  ``src/filters/sinc.h`` and pbrt-v4 ``WindowedSinc`` use pixels (a = 1, b = 1 / tau). The
  dialect picks a and b (``realistic.scene.pbrt.dialect``).

How the filter reaches the image: filter importance sampling (pbrt-v4's approach), not weighted
splatting. Each sample's film offset from its pixel's centre is drawn from |f| and the sample's
weight is multiplied by sign(f) * integral|f| / integral(f), so the film stays sum / samples per
pixel and a sample still belongs to exactly one pixel: no pass spills into neighbouring rows and
accumulation costs the same for every radius (splatting a radius-2 filter would touch ~16 pixels
per sample, and shading already dominates the render). The estimate of pixel p is unbiased for
(f * L)(p) / integral(f).

Box and triangle are sampled exactly (inverse CDF in closed form, weight 1). Gaussian, Mitchell and
sinc are sampled from a table of ``TABLE_BINS`` bins per axis holding each bin's *average* of f
(Gauss-Legendre): the filter applied is that piecewise-constant f_tab, which has the same integral
over every bin as f, and the sampling is exact for it (as pbrt-v4's ``FilterSampler`` tabulates f,
at 32 values per pixel of radius). The bin search compares float32 u with the float32 CDF, as the
kernel does, so both pick the same bin.

The 0.5-radius box maps u to the offset u - 1/2 exactly, so its film points are bit-identical to
plain jittering within the pixel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from realistic.core import validation
from realistic.errors import UserError

FILTER_NAMES = ("box", "triangle", "gaussian", "mitchell", "sinc")
#: Other names accepted for a filter (pbrt calls the Lanczos windowed sinc "sinc").
FILTER_ALIASES = {"lanczos": "sinc"}
#: Bins per axis of a tabulated filter: a power of two, for the kernel's branch-free bin search.
TABLE_BINS = 256
_GAUSS_POINTS = 8
#: The net integral of a sign-changing filter must be at least this fraction of integral|f|.
MIN_NET_FRACTION = 1e-3


def filter_name(name: str) -> str:
    """The filter's name in ``FILTER_NAMES`` for ``name`` or an alias; the one check of a filter
    name (CLI, Python API and pbrt importer); UserError naming the choices otherwise."""
    name = FILTER_ALIASES.get(name, name)
    if name not in FILTER_NAMES:
        raise UserError(f"unknown pixel filter {name!r} (choose {', '.join(FILTER_NAMES + tuple(FILTER_ALIASES))})")
    return name


def _sinc(t: np.ndarray) -> np.ndarray:
    return np.sinc(t)  # numpy's sinc is sin(pi t) / (pi t)


def _mitchell(t: np.ndarray, b: float, c: float) -> np.ndarray:
    """Mitchell-Netravali of |t| in [0, 2] (0 beyond)."""
    t = np.abs(t)
    near = ((12 - 9 * b - 6 * c) * t**3 + (-18 + 12 * b + 6 * c) * t**2 + (6 - 2 * b)) / 6
    far = ((-b - 6 * c) * t**3 + (6 * b + 30 * c) * t**2 + (-12 * b - 48 * c) * t + (8 * b + 24 * c)) / 6
    return np.where(t <= 1, near, np.where(t <= 2, far, 0.0))


@dataclass(frozen=True)
class AxisTable:
    """One axis of a tabulated filter: bin edges' CDF of |f_tab| (float32, as the kernel holds it),
    each bin's sign, and the weight factor integral|f_tab| / integral(f_tab)."""

    radius: float
    cdf: np.ndarray  # (TABLE_BINS + 1,) float32, 0 .. 1
    sign: np.ndarray  # (TABLE_BINS,) float64, +1 or -1
    ratio: float

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Offsets (pixels) and signs for uniform float32 ``u`` in [0, 1)."""
        u32 = np.asarray(u, np.float32)
        k = np.clip(np.searchsorted(self.cdf, u32, side="right") - 1, 0, TABLE_BINS - 1)
        lo, hi = self.cdf[k].astype(np.float64), self.cdf[k + 1].astype(np.float64)
        t = (u32.astype(np.float64) - lo) / (hi - lo)
        return -self.radius + (k + t) * (2 * self.radius / TABLE_BINS), self.sign[k]


@dataclass(frozen=True)
class PixelFilter:
    """A pbrt pixel filter: ``name`` in ``FILTER_NAMES``, radii in pixels, and its parameters
    (``alpha`` for gaussian, ``b``/``c`` for mitchell, ``sinc_scale``/``window_scale`` for sinc:
    f = sinc(sinc_scale x) sinc(window_scale x)). Validated on construction."""

    name: str = "box"
    radius_x: float = 0.5
    radius_y: float = 0.5
    alpha: float = 2.0
    b: float = 1.0 / 3.0
    c: float = 1.0 / 3.0
    sinc_scale: float = 1.0
    window_scale: float = 1.0 / 3.0

    def __post_init__(self) -> None:
        if self.name not in FILTER_NAMES:
            filter_name(self.name)  # raises, naming the choices
        validation.filter_radius(self.radius_x, "filter x radius (pixels)")
        validation.filter_radius(self.radius_y, "filter y radius (pixels)")
        validation.positive_length(self.alpha, "gaussian filter alpha")
        validation.finite(self.b, "mitchell filter B")
        validation.finite(self.c, "mitchell filter C")
        validation.positive_length(self.sinc_scale, "sinc filter frequency")
        validation.positive_length(self.window_scale, "sinc filter window frequency")
        if self.tabulated:  # build the tables now: a filter that integrates to about zero is refused here
            _ = (self.x_table, self.y_table)

    @property
    def tabulated(self) -> bool:
        """True when the offsets come from a table (gaussian, mitchell, sinc)."""
        return self.name in ("gaussian", "mitchell", "sinc")

    def evaluate_1d(self, x: np.ndarray, radius: float) -> np.ndarray:
        """f along one axis at offsets ``x`` (pixels) for that axis's ``radius``."""
        x = np.asarray(x, np.float64)
        inside = np.abs(x) <= radius
        if self.name == "box":
            value = np.ones_like(x)
        elif self.name == "triangle":
            value = radius - np.abs(x)
        elif self.name == "gaussian":
            value = np.maximum(np.exp(-self.alpha * x * x) - math.exp(-self.alpha * radius * radius), 0.0)
        elif self.name == "mitchell":
            value = _mitchell(2 * x / radius, self.b, self.c)
        else:
            value = _sinc(self.sinc_scale * x) * _sinc(self.window_scale * x)
        return np.where(inside, value, 0.0)

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """f(x, y) for offsets in pixels from the pixel centre."""
        return self.evaluate_1d(x, self.radius_x) * self.evaluate_1d(y, self.radius_y)

    def integral_1d(self, radius: float) -> float:
        """The integral of f along one axis over [-radius, radius]."""
        if self.name == "box":
            return 2 * radius
        if self.name == "triangle":
            return radius * radius
        if self.name == "gaussian":
            a = self.alpha
            return math.sqrt(math.pi / a) * math.erf(math.sqrt(a) * radius) - 2 * radius * math.exp(-a * radius**2)
        if self.name == "mitchell":
            # the family sums to one over integer shifts for every B, C, so it integrates to 1 over
            # t in [-2, 2]; x = t r / 2
            return radius / 2
        return float(self._bin_integrals(radius).sum())  # sinc: no elementary antiderivative

    def integral(self) -> float:
        """The integral of f over its support (pixel^2)."""
        return self.integral_1d(self.radius_x) * self.integral_1d(self.radius_y)

    def _bin_integrals(self, radius: float) -> np.ndarray:
        """The integral of f over each of ``TABLE_BINS`` equal bins of [-radius, radius]
        (Gauss-Legendre; sign changes of Mitchell and sinc are resolved by the fine bins)."""
        nodes, weights = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
        edges = np.linspace(-radius, radius, TABLE_BINS + 1)
        half = (edges[1:] - edges[:-1])[:, None] / 2
        x = (edges[:-1, None] + edges[1:, None]) / 2 + half * nodes[None, :]
        return (self.evaluate_1d(x, radius) * weights[None, :] * half).sum(axis=1)

    def _table(self, radius: float) -> AxisTable:
        area = self._bin_integrals(radius)
        magnitude = np.abs(area)
        cdf = np.concatenate([[0.0], np.cumsum(magnitude)]) / magnitude.sum()
        cdf[-1] = 1.0
        net = area.sum()
        if not net > MIN_NET_FRACTION * magnitude.sum():
            raise UserError(f"{self.describe()} integrates to about zero along an axis: it cannot normalise a pixel")
        return AxisTable(radius, cdf.astype(np.float32), np.where(area < 0, -1.0, 1.0), float(magnitude.sum() / net))

    @cached_property
    def x_table(self) -> AxisTable:
        return self._table(self.radius_x)

    @cached_property
    def y_table(self) -> AxisTable:
        return self._table(self.radius_y)

    def _offsets_1d(self, u: np.ndarray, along_x: bool) -> tuple[np.ndarray, np.ndarray]:
        """Offsets from the pixel centre (pixels, float64) and per-sample weights along x (``along_x``) or y."""
        u = np.asarray(u, np.float32).astype(np.float64)
        radius = self.radius_x if along_x else self.radius_y
        if self.name == "box":
            return (u - 0.5) * (2 * radius), np.ones_like(u)
        if self.name == "triangle":
            left = u < 0.5
            root = np.sqrt(np.where(left, 2 * u, 2 - 2 * u))
            return radius * np.where(left, root - 1, 1 - root), np.ones_like(u)
        table = self.x_table if along_x else self.y_table
        offset, sign = table.sample(u)
        return offset, sign * table.ratio

    def offsets(self, u_x: np.ndarray, u_y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Film offsets (dx, dy) in pixels from the pixel centre, drawn from |f| with uniform
        float32 ``u_x``, ``u_y``, and each sample's weight sign(f) integral|f| / integral(f)."""
        dx, wx = self._offsets_1d(u_x, along_x=True)
        dy, wy = self._offsets_1d(u_y, along_x=False)
        return dx, dy, wx * wy

    def describe(self) -> str:
        """One line for logs and image headers: the name, radii and parameters."""
        text = f"{self.name} radius {self.radius_x:g}x{self.radius_y:g}"
        extra = {"gaussian": f" alpha {self.alpha:g}", "mitchell": f" B {self.b:g} C {self.c:g}",
                 "sinc": f" sinc(x*{self.sinc_scale:g}) window sinc(x*{self.window_scale:g})"}
        return text + extra.get(self.name, "")


#: Today's film: every sample lands uniformly in its own pixel (the mesh scenes' and API's default).
PIXEL_BOX = PixelFilter()
