"""Textures: evaluating materials' albedo at surface points, batched."""

from __future__ import annotations

import numpy as np

from realistic.scene.model import CheckerTexture, GridTexture, ImageTexture, Material, Texture


def evaluate(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """Texture colour (N, 3) float32 at texture coordinates uv (N, 2)."""
    if isinstance(texture, GridTexture):
        f = (uv * texture.cells) % 1.0
        half = texture.line_width / 2
        on_line = np.any((f < half) | (f > 1 - half), axis=1)
        return np.where(on_line[:, None], np.float32(texture.line), np.float32(texture.base)).astype(np.float32)
    if isinstance(texture, CheckerTexture):
        parity = (np.floor(uv[:, 0] * texture.cells) + np.floor(uv[:, 1] * texture.cells)) % 2
        return np.where(parity[:, None] == 0, np.float32(texture.even), np.float32(texture.odd)).astype(np.float32)
    if isinstance(texture, ImageTexture):
        return _bilinear(texture, uv)
    raise TypeError(f"unknown texture {texture!r}")


def _bilinear(texture: ImageTexture, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup with wrap-around; u to the right, v = 0 at the row ``texture.v_origin`` names."""
    height, width = texture.pixels.shape[:2]
    x = (uv[:, 0] * texture.scale[0]) % 1.0 * width - 0.5
    v = (uv[:, 1] * texture.scale[1]) % 1.0
    y = (v if texture.v_origin == "top" else 1.0 - v) * height - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64) % width, y0.astype(np.int64) % height
    x1, y1 = (x0 + 1) % width, (y0 + 1) % height
    p = texture.pixels
    top = p[y0, x0] * (1 - fx) + p[y0, x1] * fx
    bottom = p[y1, x0] * (1 - fx) + p[y1, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def albedo(material: Material, uv: np.ndarray | None, count: int) -> np.ndarray:
    """Diffuse reflectance (N, 3) of ``count`` points of one material (uv needed with a texture)."""
    colour = np.broadcast_to(np.asarray(material.diffuse, dtype=np.float32), (count, 3))
    if material.texture is None or uv is None:
        return colour
    return colour * evaluate(material.texture, uv)
