"""Film sizes: a film is the resolution's aspect ratio with a given diagonal (mm)."""

from __future__ import annotations

import math

#: Diagonal of a 36 x 24 mm ("full frame") film, the default for meshes and lens analysis.
FULL_FRAME_DIAGONAL_MM = 43.27


def pixel_pitch_mm(diagonal_mm: float, width: int, height: int) -> float:
    """Side in mm of a (square) pixel of a ``width`` x ``height`` film with the given diagonal."""
    return diagonal_mm / math.hypot(width, height)


def film_size_mm(diagonal_mm: float, width: int, height: int) -> tuple[float, float]:
    """(width, height) in mm of a ``width`` x ``height`` pixel film with the given diagonal."""
    pixel_mm = pixel_pitch_mm(diagonal_mm, width, height)
    return width * pixel_mm, height * pixel_mm
