"""The part of the image a render takes: pbrt-v4's film pixel bounds (``--pixelbounds``, or a
``--cropwindow`` in NDC turned into pixels as pbrt-v4's ``film.cpp`` does).

A cropped render runs the passes of the whole image's plan that hold pixels of its bounds, and
traces and shades the rays of those pixels only (``runner.PassRunner``: the camera makes a pass's
rays in one kernel launch, and those of other pixels are dropped; making a ray costs little beside
tracing and shading it, and far less than a launch per row of the crop would). Each pixel of the
bounds thus takes the very samples, grouped in the very passes, of the whole render: its float64
sums are added in the same order, and it is bit-identical to the same pixel of an uncropped render
with the same seed. Its image holds the bounds only; the EXR says where they lie: data window =
the bounds, display window = the full resolution, as pbrt-v4's ``Image::Write`` sets them from
``ImageMetadata::pixelBounds`` and ``fullResolution``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic.camera.base import SampleBlock
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

    def contains(self, pixel: np.ndarray, image_width: int) -> np.ndarray:
        """Whether each pixel index (``y * image_width + x``) lies in the bounds."""
        y, x = np.divmod(pixel, image_width)
        return (x >= self.x0) & (x < self.x1) & (y >= self.y0) & (y < self.y1)

    def samples_in(self, block: SampleBlock, image_width: int) -> int:
        """How many of ``block``'s samples belong to pixels in the bounds."""
        pixels = np.arange(block.first_pixel, block.first_pixel + block.pixel_count, dtype=np.int64)
        return int(block.samples_per_pixel()[self.contains(pixels, image_width)].sum())

    def passes(self, plan: list[SampleBlock], image_width: int) -> list[SampleBlock]:
        """The passes of the whole image's ``plan`` that hold samples of pixels in the bounds, in
        order: a crop renders those passes, tracing the rays of its own pixels only."""
        return [block for block in plan if self.samples_in(block, image_width)]

    def __str__(self) -> str:
        return f"{self.x0} {self.x1} {self.y0} {self.y1}"
