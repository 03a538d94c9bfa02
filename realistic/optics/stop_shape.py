"""The shape of the aperture stop: a circle, N blades (straight or curved), or an image mask.

Lens frame coordinates on the stop plane, in mm, scaled by the stop's diameter D:

* ``blades`` N >= 3: the opening is the regular N-gon whose vertices lie on the circle of
  diameter ``extent`` x D (``extent`` 1 unless a shape says otherwise), turned by ``rotation_deg``
  (0: a vertex on +x). ``curvature`` c in [0, 1] bows each side outward into a circular arc whose
  sagitta is c times the gap between the side and that circle (0: straight blades, 1: the full circle).
* ``mask``: a binary image spanning the square of side D centred on the axis, first row at +y. From
  an image file (``mask_stop``) a pixel of level 0.5 or more is open; a polygon (``polygon_stop``)
  opens the pixels whose centres it holds; a transmission profile (``transmission_stop``) is
  dithered, so the fraction of open pixels in any small block follows the profile.

Exposure follows the open area, as it does in a real camera: a circle and a mask of the same open
area give the same brightness, a hexagon inscribed in the circle about 83 % of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.core import validation
from realistic.errors import UserError

MASK_MAX_SIDE = 128  # larger masks are resampled (the kernel holds the mask as a constant table)


@dataclass(frozen=True, eq=False)
class StopShape:
    blades: int = 0
    rotation_deg: float = 0.0
    curvature: float = 0.0
    mask: np.ndarray | None = field(default=None, repr=False)  # (H, W) bool, row 0 at +y
    source: str = ""
    extent: float = 1.0  # blades: the vertices' circle as a fraction of the stop's diameter

    def key(self) -> tuple[int, float, float, bytes, float]:
        """Hashable identity (for caches)."""
        mask = b"" if self.mask is None else self.mask.tobytes() + bytes(str(self.mask.shape), "ascii")
        return (self.blades, self.rotation_deg, self.curvature, mask, self.extent)

    def describe(self) -> str:
        if self.mask is not None:
            return f"mask {self.source}"
        bend = f", curvature {self.curvature:g}" if self.curvature else ""
        size = f", {self.extent:g} of the stop's diameter" if self.extent != 1 else ""
        return f"{self.blades} blades, rotated {self.rotation_deg:g} deg{bend}{size}"

    def edges(self, diameter_mm: float) -> list[tuple[float, float, float, float]]:
        """Per side of a bladed stop: (nx, ny, a, rho), outward unit normal n, and either the
        apothem a of a straight side (rho = 0) or, for an arc, the arc circle's centre at
        distance a along n and its radius rho (the opening is inside every arc's circle)."""
        radius = self.extent * diameter_mm / 2
        half = math.pi / self.blades
        apothem = radius * math.cos(half)
        sides = []
        for k in range(self.blades):
            theta = math.radians(self.rotation_deg) + (2 * k + 1) * half
            nx, ny = math.cos(theta), math.sin(theta)
            sagitta = self.curvature * (radius - apothem)
            if sagitta <= 0:
                sides.append((nx, ny, apothem, 0.0))
                continue
            chord_half = radius * math.sin(half)
            rho = (chord_half**2 + sagitta**2) / (2 * sagitta)
            sides.append((nx, ny, apothem + sagitta - rho, rho))
        return sides

    def inside(self, x: np.ndarray, y: np.ndarray, diameter_mm: float) -> np.ndarray:
        """Whether stop-plane points (mm) lie in the opening."""
        if self.mask is not None:
            rows, cols = self.mask.shape
            col = np.floor((x / diameter_mm + 0.5) * cols)
            row = np.floor((0.5 - y / diameter_mm) * rows)
            valid = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
            flat = np.clip(row, 0, rows - 1).astype(np.int64) * cols + np.clip(col, 0, cols - 1).astype(np.int64)
            return valid & self.mask.ravel()[flat]
        ok = np.ones(np.shape(x), dtype=bool)
        for nx, ny, a, rho in self.edges(diameter_mm):
            if rho == 0:
                ok &= x * nx + y * ny <= a
            else:
                dx, dy = x - a * nx, y - a * ny
                ok &= dx * dx + dy * dy <= rho * rho
        return ok

    def reach_mm(self, diameter_mm: float) -> float:
        """Largest distance from the axis of any open point (blades stay inside the stop's circle)."""
        if self.mask is None:
            return self.extent * diameter_mm / 2
        rows, cols = self.mask.shape
        r, c = np.nonzero(self.mask)
        corner_x = np.maximum(np.abs(c / cols - 0.5), np.abs((c + 1) / cols - 0.5))
        corner_y = np.maximum(np.abs(r / rows - 0.5), np.abs((r + 1) / rows - 0.5))
        return float(np.hypot(corner_x, corner_y).max()) * diameter_mm

    def open_area_mm2(self, diameter_mm: float, samples: int = 1 << 20) -> float:
        """Open area of the stop (mm^2), by a fine grid over its square."""
        side = int(math.sqrt(samples))
        g = (np.arange(side) + 0.5) / side - 0.5
        x, y = np.meshgrid(g * diameter_mm, g * diameter_mm)
        return float(self.inside(x, y, diameter_mm).mean()) * diameter_mm**2


def bladed_stop(blades: int, rotation_deg: float = 0.0, curvature: float = 0.0, extent: float = 1.0) -> StopShape:
    """N straight or curved blades (``realistic.core.validation`` bounds N), turned by ``rotation_deg``,
    their vertices on the circle of ``extent`` (0 to 1) times the stop's diameter."""
    blades = validation.blades(blades)
    rotation_deg = validation.finite(rotation_deg, "blade rotation (degrees)")
    if not 0 <= curvature <= 1:
        raise UserError(f"blade curvature must be between 0 (straight) and 1 (round), got {curvature:g}")
    if not 0 < extent <= 1:
        raise UserError(f"blade extent must be above 0 and at most 1 (the stop's circle), got {extent:g}")
    return StopShape(blades=blades, rotation_deg=rotation_deg, curvature=curvature, extent=extent)


def _mask_centres(side: int) -> tuple[np.ndarray, np.ndarray]:
    """x and y (in units of the stop's radius) of the pixel centres of a side x side mask, row 0 at +y."""
    g = (np.arange(side) + 0.5) / side * 2 - 1
    return np.meshgrid(g, -g)


def polygon_stop(vertices: np.ndarray, source: str, side: int = MASK_MAX_SIDE) -> StopShape:
    """A stop opened inside a simple polygon (``vertices`` (N, 2) in units of the stop's radius, any
    winding, convex or not): the pixels of a ``side`` x ``side`` mask whose centres it holds (even-odd rule)."""
    x, y = _mask_centres(side)
    inside = np.zeros(x.shape, dtype=bool)
    for (x0, y0), (x1, y1) in zip(vertices, np.roll(vertices, -1, axis=0)):
        crosses = (y0 > y) != (y1 > y)  # the edge spans the pixel centre's row
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < x_at)
    if not inside.any():
        raise UserError(f"{source}: the aperture polygon opens no pixel of the stop's mask")
    return StopShape(mask=inside, source=source)


def _bayer(order: int = 3) -> np.ndarray:
    """The 2^order square Bayer matrix (0 .. 4^order - 1): each 2 x 2 step spreads its thresholds evenly."""
    m = np.zeros((1, 1))
    for _ in range(order):
        m = np.block([[4 * m, 4 * m + 2], [4 * m + 3, 4 * m + 1]])
    return m


def transmission_stop(levels: np.ndarray, source: str) -> StopShape:
    """A stop whose transmission follows ``levels`` ((H, W), row 0 at +y, spanning the stop's square;
    scaled so its largest value is fully open): block-averaged to at most ``MASK_MAX_SIDE`` pixels a side,
    then ordered-dithered to the binary mask the tracer and kernel hold, so each 8 x 8 block opens the
    fraction of its pixels that its mean level asks for."""
    levels = np.nan_to_num(np.asarray(levels, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0).clip(0, None)
    peak = levels.max() if levels.size else 0.0
    if not peak > 0:
        raise UserError(f"{source}: the aperture's transmission is zero everywhere")
    rows, cols = levels.shape
    step = max(1, math.ceil(max(rows, cols) / MASK_MAX_SIDE))
    rows, cols = rows // step, cols // step
    blocks = levels[:rows * step, :cols * step].reshape(rows, step, cols, step).mean(axis=(1, 3)) / peak
    threshold = (np.tile(_bayer(), (rows // 8 + 1, cols // 8 + 1))[:rows, :cols] + 0.5) / 64
    mask = blocks > threshold
    if not mask.any():
        raise UserError(f"{source}: the aperture's transmission is too faint to open any pixel of the stop's mask")
    return StopShape(mask=mask, source=source)


def mask_stop(path: str | Path) -> StopShape:
    """A stop shaped by an image (read like a texture); open where its level is 0.5 or more."""
    from realistic.core.image_files import read_linear_rgb

    pixels = read_linear_rgb(Path(path)).mean(axis=2)
    rows, cols = pixels.shape
    step = max(1, math.ceil(max(rows, cols) / MASK_MAX_SIDE))
    mask = pixels[step // 2::step, step // 2::step] >= 0.5
    if not mask.any():
        raise UserError(f"{path}: the aperture mask has no open pixel (level >= 0.5)")
    return StopShape(mask=np.ascontiguousarray(mask), source=str(path))
