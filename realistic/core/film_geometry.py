"""Film sizes: a film is the resolution's aspect ratio with a given diagonal (mm)."""

from __future__ import annotations

import math

import numpy as np

#: Diagonal of a 36 x 24 mm ("full frame") film, the default for meshes and lens analysis.
FULL_FRAME_DIAGONAL_MM = 43.27


def pixel_pitch_mm(diagonal_mm: float, width: int, height: int) -> float:
    """Side in mm of a (square) pixel of a ``width`` x ``height`` film with the given diagonal."""
    return diagonal_mm / math.hypot(width, height)


def film_size_mm(diagonal_mm: float, width: int, height: int) -> tuple[float, float]:
    """(width, height) in mm of a ``width`` x ``height`` pixel film with the given diagonal."""
    pixel_mm = pixel_pitch_mm(diagonal_mm, width, height)
    return width * pixel_mm, height * pixel_mm


#: A frame with more than this fraction of its area outside the lens's image circle gets a warning
#: (and, where the user gave no film, a film sized to the lens).
MOSTLY_OUTSIDE = 0.5
#: Grid points per side on which ``fraction_outside_circle`` tests the frame.
_COVERAGE_GRID = 200


def fraction_outside_circle(diagonal_mm: float, width: int, height: int, circle_diameter_mm: float) -> float:
    """Fraction of a ``width`` x ``height`` film's area (the given diagonal, centred) lying outside a
    centred circle of ``circle_diameter_mm``: the share of the frame a lens with that image circle
    leaves dark. Measured on a grid of pixel-like cells (to 1 / ``_COVERAGE_GRID`` per side)."""
    w_mm, h_mm = film_size_mm(diagonal_mm, width, height)
    cells = (np.arange(_COVERAGE_GRID) + 0.5) / _COVERAGE_GRID - 0.5
    radius = np.hypot(cells[None, :] * w_mm, cells[:, None] * h_mm)
    return float(np.mean(radius > circle_diameter_mm / 2))
