"""The shape of the aperture stop: a circle, N blades (straight or curved), or an image mask.

Lens frame coordinates on the stop plane, in mm, scaled by the stop's diameter D:

* ``blades`` N >= 3: the opening is the regular N-gon whose vertices lie on the circle of
  diameter D, turned by ``rotation_deg`` (0: a vertex on +x). ``curvature`` c in [0, 1] bows each
  side outward into a circular arc whose sagitta is c times the gap between the side and the circle
  (0: straight blades, 1: the full circle).
* ``mask``: a greyscale image (PNG, EXR, ...) spanning the square of side D centred on the axis,
  first row at +y; a pixel of level 0.5 or more is open.

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

    def key(self) -> tuple:
        """Hashable identity (for caches)."""
        mask = b"" if self.mask is None else self.mask.tobytes() + bytes(str(self.mask.shape), "ascii")
        return (self.blades, self.rotation_deg, self.curvature, mask)

    def describe(self) -> str:
        if self.mask is not None:
            return f"mask {self.source}"
        bend = f", curvature {self.curvature:g}" if self.curvature else ""
        return f"{self.blades} blades, rotated {self.rotation_deg:g} deg{bend}"

    def edges(self, diameter_mm: float) -> list[tuple[float, float, float, float]]:
        """Per side of a bladed stop: (nx, ny, a, rho), outward unit normal n, and either the
        apothem a of a straight side (rho = 0) or, for an arc, the arc circle's centre at
        distance a along n and its radius rho (the opening is inside every arc's circle)."""
        radius = diameter_mm / 2
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
            return diameter_mm / 2
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


def bladed_stop(blades: int, rotation_deg: float = 0.0, curvature: float = 0.0) -> StopShape:
    """N straight or curved blades (``realistic.core.validation`` bounds N), turned by ``rotation_deg``."""
    blades = validation.blades(blades)
    rotation_deg = validation.finite(rotation_deg, "blade rotation (degrees)")
    if not 0 <= curvature <= 1:
        raise UserError(f"blade curvature must be between 0 (straight) and 1 (round), got {curvature:g}")
    return StopShape(blades=blades, rotation_deg=rotation_deg, curvature=curvature)


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
