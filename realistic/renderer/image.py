"""The image the Python API returns, and showing it: a notebook displays it tone-mapped.

``Image`` is the (H, W, 3) float32 film irradiance as an ``np.ndarray`` subclass, so every caller
that uses the array goes on using it; it adds ``_repr_png_`` (what IPython and Jupyter display:
the PNG preview's pixels, sRGB-encoded at the preview's exposure, ``output.preview_stops``) and a
one-line ``__repr__``. What a computation makes that is no longer an image (a mean, a sum over the
channels) is a plain ndarray; a slice stays a view that prints and displays as the array it is.
``show`` draws an image or a ``RenderResult`` with matplotlib, encoded the same way, where
``plt.imshow`` of the linear values would look too dark.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from realistic.core.image_files import png_bytes, preview_pixels
from realistic.errors import UserError
from realistic.renderer.job import RenderResult
from realistic.renderer.output import preview_stops

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def _is_image(array: np.ndarray) -> bool:
    return array.ndim == 3 and array.shape[2] == 3


class Image(np.ndarray):
    """Film irradiance (H, W, 3) float32 that displays itself (see the module docstring)."""

    @classmethod
    def of(cls, pixels: np.ndarray) -> Image:
        """``pixels`` (H, W, 3) viewed as an ``Image`` (no copy)."""
        array = np.asarray(pixels)
        if not _is_image(array):
            raise UserError(f"an image is (height, width, 3) RGB, got an array of shape {array.shape}")
        return array.view(cls)

    def __array_wrap__(self, array: np.ndarray, context: Any = None, return_scalar: bool = False) -> Any:
        """Results that are still (H, W, 3) stay images; others (a mean, one channel) are plain arrays."""
        if _is_image(array) and not return_scalar:
            return array.view(type(self))
        plain = array.view(np.ndarray)
        return plain[()] if return_scalar or plain.ndim == 0 else plain  # (numpy 1 has no return_scalar)

    def __repr__(self) -> str:
        if not _is_image(self):  # a slice of pixels
            return repr(self.view(np.ndarray))
        plain = self.view(np.ndarray)
        finite = plain[np.isfinite(plain)]
        values = (f"mean {float(finite.mean()):.4g}, max {float(finite.max()):.4g}" if finite.size
                  else "no finite values")
        bad = plain.size - finite.size
        return f"Image({self.shape[1]}x{self.shape[0]} {self.dtype}, {values}{f', {bad} not finite' if bad else ''})"

    def _repr_png_(self) -> bytes | None:
        """The PNG preview's file (sRGB at the preview's exposure), for IPython; None for a slice."""
        if not _is_image(self) or self.size == 0:
            return None
        plain = self.view(np.ndarray)
        return png_bytes(plain, preview_stops(plain, None, None))


def show(image: np.ndarray | RenderResult, exposure: float | None = None, ax: Axes | None = None) -> None:
    """Draw ``image`` (an image array or a ``RenderResult``) on ``ax`` (None: a new matplotlib
    figure sized to it), sRGB-encoded at ``exposure`` stops (None: the PNG preview's exposure).
    In a notebook the figure shows below the cell; in a script call ``matplotlib.pyplot.show()``."""
    import matplotlib.pyplot as plt

    pixels = np.asarray(image.image if isinstance(image, RenderResult) else image)
    if not _is_image(pixels) or pixels.size == 0:
        raise UserError(f"show takes a (height, width, 3) image or a RenderResult, got one of shape {pixels.shape}")
    encoded = preview_pixels(pixels, preview_stops(pixels, None, exposure))
    if ax is None:
        height, width = pixels.shape[:2]
        inches = 6.0 / max(width, height, 1)
        _, ax = plt.subplots(figsize=(max(width * inches, 1.0), max(height * inches, 1.0)))
    ax.imshow(encoded, interpolation="nearest")
    ax.set_axis_off()
