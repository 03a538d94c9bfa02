"""Textures: evaluating materials' albedo at surface points, batched."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from realistic.scene.mipmap import MipMap
from realistic.scene.model import CheckerTexture, GridTexture, ImageTexture, Material, Texture

#: A pixel's footprint around N texture points: two ellipse axes, each (N, 2) in uv units.
Footprint = tuple[np.ndarray, np.ndarray]
#: ``(mipmap, st, axis0, axis1) -> (N, 3)``: an EWA lookup as ``MipMap.ewa`` makes it; a render
#: backend's (``realistic.renderer.backends``) runs it on the OpenCL device.
EwaLookup = Callable[[MipMap, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def numpy_ewa(mipmap: MipMap, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
    """``MipMap.ewa``, the numpy reference, as an ``EwaLookup``."""
    return mipmap.ewa(st, axis0, axis1)


def evaluate(texture: Texture, uv: np.ndarray, footprint: Footprint | None = None, ewa: EwaLookup = numpy_ewa
             ) -> np.ndarray:
    """Texture colour (N, 3) float32 at texture coordinates uv (N, 2).

    ``footprint``: two axes (N, 2) each, in uv units, of the ellipse a pixel covers around each point
    (one pixel step, as pbrt's ray differentials); image textures filter over it, the procedural
    ones point-sample. ``ewa`` makes EWA lookups (a backend's runs them on the device: ``scene.ewa_kernel``).
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
        return _image(texture, uv, footprint, ewa)
    raise TypeError(f"unknown texture {texture!r}")


def st_mapping(texture: ImageTexture) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(repeats, offset, flip, shift), each (2,) float64: st = (uv * repeats + offset) * flip + shift,
    with t down the image's rows, so a bottom-origin image flips v (footprint axes scale by repeats * flip)."""
    bottom = texture.v_origin == "bottom"
    return (np.asarray(texture.scale, np.float64), np.asarray(texture.offset, np.float64),
            np.array([1.0, -1.0 if bottom else 1.0]), np.array([0.0, 1.0 if bottom else 0.0]))


def _image(texture: ImageTexture, uv: np.ndarray, footprint: Footprint | None, ewa: EwaLookup) -> np.ndarray:
    """A MIP-map lookup at ``st_mapping``'s (s, t)."""
    repeats, offset, flip, shift = st_mapping(texture)
    st = (np.asarray(uv, np.float64) * repeats + offset) * flip + shift
    mipmap = texture.mipmap
    if footprint is None:
        return mipmap.bilinear(st).astype(np.float32)
    axis0, axis1 = (np.asarray(axis, np.float64) * repeats * flip for axis in footprint)
    if texture.filter == "ewa":
        return ewa(mipmap, st, axis0, axis1).astype(np.float32)
    # pbrt's filter width for the isotropic filters: twice the largest component of either axis
    width = 2 * np.maximum(np.abs(axis0).max(axis=1), np.abs(axis1).max(axis=1))
    lookup = {"point": mipmap.point, "bilinear": mipmap.bilinear_at_width, "trilinear": mipmap.trilinear}
    return lookup[texture.filter](st, width).astype(np.float32)


def albedo(material: Material, uv: np.ndarray | None, count: int, footprint: Footprint | None = None,
           ewa: EwaLookup = numpy_ewa) -> np.ndarray:
    """Diffuse reflectance (N, 3) of ``count`` points of one material (uv needed with a texture)."""
    colour = np.broadcast_to(np.asarray(material.diffuse, dtype=np.float32), (count, 3))
    if material.texture is None or uv is None:
        return colour
    return colour * evaluate(material.texture, uv, footprint, ewa)
