"""Textures: evaluating materials' albedo at surface points, batched."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from realistic.scene.mipmap import MipMap
from realistic.scene.model import CheckerTexture, GridTexture, ImageTexture, Material, Texture

#: A pixel's footprint around N texture points: two ellipse axes, each (N, 2) in uv units.
Footprint = tuple[np.ndarray, np.ndarray]
#: ``(mipmap, texture_filter, st, axes) -> (N, 3)``: an image texture's lookups at (s, t) (N, 2) with
#: its filter (``validation.TEXTURE_FILTERS``) over footprints ``axes`` in (s, t) units, or at level 0
#: bilinear where ``axes`` is None (no footprint), as ``numpy_lookup``, the reference, makes them; a
#: render backend's (``realistic.renderer.backends``) runs them on the OpenCL device.
ImageLookup = Callable[[MipMap, str, np.ndarray, Footprint | None], np.ndarray]


def filter_width(axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
    """pbrt's filter width (N,) for the isotropic filters (point, bilinear, trilinear): twice the
    largest component of either axis (N, 2) (``kernels/ewa.cl``'s ``filter_width`` mirrors it)."""
    return 2 * np.maximum(np.abs(axis0).max(axis=1), np.abs(axis1).max(axis=1))


def numpy_lookup(mipmap: MipMap, texture_filter: str, st: np.ndarray, axes: Footprint | None) -> np.ndarray:
    """The numpy reference ``ImageLookup``: ``MipMap.bilinear`` (level 0) without a footprint, else
    ``MipMap.ewa`` over the axes, or the isotropic filter at their ``filter_width``."""
    if axes is None:
        return mipmap.bilinear(st)
    axis0, axis1 = axes
    if texture_filter == "ewa":
        return mipmap.ewa(st, axis0, axis1)
    lookup = {"point": mipmap.point, "bilinear": mipmap.bilinear_at_width, "trilinear": mipmap.trilinear}
    return lookup[texture_filter](st, filter_width(axis0, axis1))


def evaluate(texture: Texture, uv: np.ndarray, footprint: Footprint | None = None,
             lookup: ImageLookup = numpy_lookup) -> np.ndarray:
    """Texture colour (N, 3) float32 at texture coordinates uv (N, 2).

    ``footprint``: two axes (N, 2) each, in uv units, of the ellipse a pixel covers around each point
    (one pixel step, as pbrt's ray differentials); image textures filter over it, the procedural
    ones point-sample. ``lookup`` filters image textures (a backend's runs it on the device: ``scene.ewa_kernel``).
    """
    if isinstance(texture, GridTexture):
        f = (uv * texture.cells) % 1.0
        half = texture.line_width / 2
        on_line = np.any((f < half) | (f > 1 - half), axis=1)
        return np.where(on_line[:, None], np.asarray(texture.line, np.float32),
                        np.asarray(texture.base, np.float32)).astype(np.float32)
    if isinstance(texture, CheckerTexture):
        parity = (np.floor(uv[:, 0] * texture.cells) + np.floor(uv[:, 1] * texture.cells)) % 2
        return np.where(parity[:, None] == 0, np.asarray(texture.even, np.float32),
                        np.asarray(texture.odd, np.float32)).astype(np.float32)
    if isinstance(texture, ImageTexture):
        return _image(texture, uv, footprint, lookup)
    raise TypeError(f"unknown texture {texture!r}")


def st_mapping(texture: ImageTexture) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(repeats, offset, flip, shift), each (2,) float64: st = (uv * repeats + offset) * flip + shift,
    with t down the image's rows, so a bottom-origin image flips v (footprint axes scale by repeats * flip)."""
    bottom = texture.v_origin == "bottom"
    return (np.asarray(texture.scale, np.float64), np.asarray(texture.offset, np.float64),
            np.array([1.0, -1.0 if bottom else 1.0]), np.array([0.0, 1.0 if bottom else 0.0]))


def _image(texture: ImageTexture, uv: np.ndarray, footprint: Footprint | None, lookup: ImageLookup) -> np.ndarray:
    """``lookup``'s MIP-map lookup at ``st_mapping``'s (s, t), over the footprint mapped to (s, t)."""
    repeats, offset, flip, shift = st_mapping(texture)
    st = (np.asarray(uv, np.float64) * repeats + offset) * flip + shift
    axes = None if footprint is None else \
        (np.asarray(footprint[0], np.float64) * repeats * flip, np.asarray(footprint[1], np.float64) * repeats * flip)
    return lookup(texture.mipmap, texture.filter, st, axes).astype(np.float32)


def albedo(material: Material, uv: np.ndarray | None, count: int, footprint: Footprint | None = None,
           lookup: ImageLookup = numpy_lookup) -> np.ndarray:
    """Diffuse reflectance (N, 3) of ``count`` points of one material (uv needed with a texture)."""
    colour = np.broadcast_to(np.asarray(material.diffuse, dtype=np.float32), (count, 3))
    if material.texture is None or uv is None:
        return colour
    return colour * evaluate(material.texture, uv, footprint, lookup)
