"""pbrt's ``imagemap`` texture parameters read into an ``ImageTexture``.

Which parameters a version has, and their defaults, are the dialect's (``Dialect.imagemap``). The
file is read as linear (``read_image`` decodes sRGB from integer images, not float ones); an encoding that
differs from that applies to the file's stored values. Every bad value is a one-line ``UserError``
naming the file and line.
"""

from __future__ import annotations

import numpy as np

from realistic.core import validation
from realistic.core.image_files import srgb_decode, srgb_encode
from realistic.errors import UserError
from realistic.scene.model import ImageTexture
from realistic.scene.pbrt.dialect import Dialect
from realistic.scene.pbrt.parser import Params

#: The uv mapping parameters we honour besides the imagemap's own.
_MAPPING = ("uscale", "vscale", "udelta", "vdelta")


def _bool(params: Params, name: str, default: bool, where: str) -> bool:
    p = params.items.get(name)
    if p is None:
        return default
    if len(p.values) != 1 or not isinstance(p.values[0], bool):
        raise UserError(f'{p.where}: imagemap "{name}" must be one bool ("true" or "false")')
    return p.values[0]


def _float(params: Params, name: str, default: float) -> float:
    p = params.items.get(name)
    value = params.get_float(name, default)
    if p is not None and (len(p.values) != 1 or isinstance(p.values[0], bool)):
        raise UserError(f'{p.where}: imagemap "{name}" must be one number')
    return validation.finite(value, f'imagemap "{name}"')


def _filter(params: Params, dialect: Dialect, where: str) -> str:
    conventions = dialect.imagemap
    if conventions.filter_parameter == "filter":
        return validation.texture_filter(params.get_string("filter", conventions.default_filter).lower())
    if params.has("filter"):
        raise UserError(f'{where}: imagemap "filter" is pbrt-v4\'s; pbrt-{dialect.name} uses "bool trilinear"')
    return "trilinear" if _bool(params, "trilinear", False, where) else conventions.default_filter


def _encoded(pixels: np.ndarray, stored_linear: bool, params: Params, dialect: Dialect, filename: str,
             where: str) -> np.ndarray:
    """Texels decoded as the dialect's gamma/encoding parameter says, then scaled (and inverted)."""
    kind = dialect.imagemap.encoding_parameter
    scale = _float(params, "scale", dialect.imagemap.scale)
    raw = pixels if stored_linear else srgb_encode(pixels)
    if kind == "gamma exponent":  # pbrt-v2 imagemap.h convertIn: (scale * texel) ^ gamma
        gamma = _float(params, "gamma", 1.0)
        with np.errstate(all="ignore"):
            texels = np.power(np.maximum(scale * pixels, 0.0), gamma)
        if not np.all(np.isfinite(texels)):
            raise UserError(f'{where}: imagemap "scale" {scale:g} and "gamma" {gamma:g} overflow the texels')
        return texels.astype(np.float32)
    if kind == "gamma sRGB":  # pbrt-v3 imagemap.h convertIn: scale * (gamma ? sRGB-decoded : texel)
        srgb = _bool(params, "gamma", filename.lower().endswith((".png", ".tga")), where)
        return (scale * (srgb_decode(raw) if srgb else raw)).astype(np.float32)
    encoding = params.get_string("encoding", "sRGB" if filename.lower().endswith(".png") else "linear")
    words = encoding.split()
    if encoding == "sRGB":
        texels = srgb_decode(raw)
    elif encoding == "linear":
        texels = raw
    elif len(words) == 2 and words[0] == "gamma":
        try:
            gamma = validation.positive_length(float(words[1]), "encoding gamma")
        except ValueError:
            raise UserError(f'{where}: imagemap encoding "{encoding}" needs a number after "gamma"') from None
        texels = np.power(np.clip(raw, 0.0, 1.0), gamma)
    else:
        raise UserError(f'{where}: imagemap encoding must be "sRGB", "linear" or "gamma <value>", got {encoding!r}')
    texels = scale * texels
    if _bool(params, "invert", False, where):
        texels = np.maximum(0.0, 1.0 - texels)
    return texels.astype(np.float32)


def imagemap_texture(params: Params, pixels: np.ndarray, stored_linear: bool, filename: str, dialect: Dialect,
                     where: str) -> ImageTexture:
    """The ``ImageTexture`` an imagemap's ``params`` (declared at ``where``) describe over ``pixels``
    as read (linear); ``stored_linear``: whether the file held linear floats (EXR, PFM) rather than sRGB."""
    conventions = dialect.imagemap
    try:
        texture_filter = _filter(params, dialect, where)
        mapping = [_float(params, name, 1.0 if name.endswith("scale") else 0.0) for name in _MAPPING]
        texels = _encoded(pixels, stored_linear, params, dialect, filename, where)
        return ImageTexture(texels, (mapping[0], mapping[1]), dialect.texture_v_origin, texture_filter,
                            _float(params, "maxanisotropy", conventions.max_anisotropy),
                            params.get_string("wrap", conventions.wrap), (mapping[2], mapping[3]),
                            conventions.trilinear_blend_from)
    except UserError as err:
        located = str(err).startswith(where.rsplit(":", 1)[0] + ":")
        raise (err if located else UserError(f"{where}: {err}")) from None
