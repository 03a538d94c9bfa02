"""The matte material and the textures any material may carry: plain data that
``realistic.scene.materials`` (the other materials) and ``realistic.scene.model`` (the scene that
holds them) both build on, so that the scene can name every material without an import cycle."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.scene.mipmap import MipMap

RGB = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class ImageTexture:
    """An RGB image (linear, rows top to bottom) repeated over uv, looked up through a MIP map.

    ``v_origin`` says which row v = 0 is: "bottom" (pbrt-v3 and v4 flip images on load) or "top"
    (pbrt-v1 and v2 look up the file's first row at v = 0); the pbrt dialect decides. ``filter``
    ("point", "bilinear", "trilinear", "ewa"), ``max_anisotropy`` and ``wrap`` ("repeat", "black",
    "clamp") are pbrt's imagemap parameters; the defaults are pbrt-v3's. ``trilinear_blend_from`` is
    the level from which the "trilinear" filter blends two levels, reading level 0 alone below it:
    0 as pbrt-v1 to v3, 1 as pbrt-v4 (``MipMap.trilinear``); the pbrt dialect decides. A lookup without
    a footprint reads level 0 bilinearly whatever the filter.
    """

    pixels: np.ndarray  # (H, W, 3) float32, linear
    scale: tuple[float, float] = (1.0, 1.0)  # repetitions of the image per unit of u, v
    v_origin: str = "bottom"
    filter: str = "ewa"
    max_anisotropy: float = 8.0
    wrap: str = "repeat"
    offset: tuple[float, float] = (0.0, 0.0)  # pbrt's udelta, vdelta: added to the scaled u, v
    trilinear_blend_from: int = 0

    def __post_init__(self) -> None:
        validation.texture_filter(self.filter)
        validation.texture_wrap(self.wrap)
        validation.max_anisotropy(self.max_anisotropy)
        validation.trilinear_blend_from(self.trilinear_blend_from)
        for name, value in zip(("uscale", "vscale", "udelta", "vdelta"), (*self.scale, *self.offset)):
            validation.finite(value, f"image texture {name}")

    @cached_property
    def mipmap(self) -> MipMap:
        """The MIP map of ``pixels``, built on first use and kept."""
        return MipMap(self.pixels, self.wrap, self.max_anisotropy, self.trilinear_blend_from)


@dataclass(frozen=True)
class GridTexture:
    """Thin lines of ``line`` colour on ``base`` colour, ``cells`` cells per unit of u and v."""

    base: RGB = (0.8, 0.8, 0.8)
    line: RGB = (0.1, 0.1, 0.1)
    cells: float = 10.0
    line_width: float = 0.04  # fraction of a cell


@dataclass(frozen=True)
class CheckerTexture:
    """Alternating squares, ``cells`` per unit of u and v."""

    even: RGB = (0.8, 0.8, 0.8)
    odd: RGB = (0.2, 0.2, 0.2)
    cells: float = 10.0


Texture = ImageTexture | GridTexture | CheckerTexture


@dataclass(frozen=True)
class Material:
    """Matte reflector: albedo = ``diffuse`` times the texture's colour when there is one.

    ``sigma`` is the Oren-Nayar roughness in degrees (the standard deviation of the facet slope
    angle, pbrt's ``matte`` sigma); 0 is Lambertian. Other materials: ``realistic.scene.materials``.
    """

    diffuse: RGB = (0.5, 0.5, 0.5)
    texture: Texture | None = None
    sigma: float = 0.0

    def __post_init__(self) -> None:
        if self.texture is None:  # an albedo; with a texture, a factor on the texture's colour
            validation.reflectance(self.diffuse, "matte Kd")
        elif not all(validation.finite(c, "matte Kd") >= 0 for c in self.diffuse):
            raise UserError(f"matte Kd must not be negative, got {self.diffuse}")
        if not 0.0 <= validation.finite(self.sigma, "matte sigma (degrees)") <= 90.0:
            raise UserError(f"matte sigma (degrees) must be between 0 and 90, got {self.sigma:g}")
