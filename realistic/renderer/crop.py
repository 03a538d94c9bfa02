"""The part of the image a render takes: pbrt-v4's film pixel bounds (``--pixelbounds``, or a
``--cropwindow`` in NDC turned into pixels as pbrt-v4's ``film.cpp`` does).

A cropped render takes, for each pixel of its bounds, the very sample ids the whole image would
(``pass_plan.plan_passes`` keeps the whole image's slices), so those pixels are bit-identical to
the same pixels of an uncropped render with the same seed. Its image holds the bounds only; the EXR
says where they lie: data window = the bounds, display window = the full resolution, as pbrt-v4's
``Image::Write`` sets them from ``ImageMetadata::pixelBounds`` and ``fullResolution``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from realistic.core import validation
from realistic.errors import UserError


@dataclass(frozen=True)
class PixelBounds:
    """Pixels x0 .. x1 - 1 by y0 .. y1 - 1 of an image (pbrt-v4's ``Bounds2i`` pixelBounds: half open)."""

    x0: int
    x1: int
    y0: int
    y1: int

    @classmethod
    def whole(cls, width: int, height: int) -> PixelBounds:
        return cls(0, width, 0, height)

    @classmethod
    def of_crop_window(cls, crop: tuple[float, float, float, float], width: int, height: int) -> PixelBounds:
        """The pixels of NDC crop window (x0, x1, y0, y1) in a ``width`` x ``height`` image: pbrt-v4's
        ``ceil(resolution * crop)`` at each end, so a pixel is in when its left (top) edge is."""
        x0, x1, y0, y1 = validation.crop_window(*crop)
        bounds = cls(math.ceil(width * x0), math.ceil(width * x1), math.ceil(height * y0), math.ceil(height * y1))
        if bounds.x0 >= bounds.x1 or bounds.y0 >= bounds.y1:
            raise UserError(f"crop window {x0:g} {x1:g} {y0:g} {y1:g} covers no pixel of the {width}x{height} image")
        return bounds

    def within(self, width: int, height: int) -> PixelBounds:
        """These bounds after checking they lie in a ``width`` x ``height`` image (one-line UserError)."""
        validation.pixel_bounds(self.x0, self.x1, self.y0, self.y1, width, height)
        return self

    @property
    def width(self) -> int:
        return self.x1 - self.x0

    @property
    def height(self) -> int:
        return self.y1 - self.y0

    def spans(self, image_width: int) -> list[tuple[int, int]]:
        """(first pixel, pixel count) of each run of consecutive pixel indices (``y * image_width + x``)
        in the bounds: one per row, or one in all when the rows are whole."""
        if self.x0 == 0 and self.x1 == image_width:
            return [(self.y0 * image_width, self.height * image_width)]
        return [(y * image_width + self.x0, self.width) for y in range(self.y0, self.y1)]

    def __str__(self) -> str:
        return f"{self.x0} {self.x1} {self.y0} {self.y1}"
