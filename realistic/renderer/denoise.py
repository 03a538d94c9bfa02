"""Open Image Denoise (Intel's OIDN) on a render's image, guided by its albedo and normal AOVs.

Optional: the ``pyoidn`` binding (the ``denoise`` extra, ``pip install 'realistic[denoise]'``) is
imported only here, when a denoised image is asked for. OIDN's "RT" filter takes the HDR colour
(``hdr``: film irradiance is not bounded by 1) with the albedo and the normals of the first hits
(``renderer.aov``: in [0, 1] and unit length, as OIDN asks) as auxiliary images; they are
averages over each pixel's samples, so they are not noise-free under depth of field or motion,
and OIDN prefilters them (``clean_aux`` False).

The denoised image replaces ``RenderResult.image`` and the film's own estimate is kept as
``RenderResult.noisy`` (written as the EXR's "Noisy" layer by ``output.save``): what a viewer and
the PNG show is what was asked for, and the unbiased estimate stays in the file for measurement.
"""

from __future__ import annotations

import dataclasses
import importlib.util

import numpy as np

from realistic.errors import UserError
from realistic.renderer.job import RenderResult

#: The AOVs OIDN takes as guides; a render to be denoised computes them.
GUIDE_AOVS = ("albedo", "normal")
MISSING = "denoising needs Open Image Denoise's Python binding: pip install 'realistic[denoise]' (pyoidn)"


def check_available() -> None:
    """UserError (one line, naming the extra) unless the binding is installed: checked before a
    render that will be denoised starts, not after it."""
    if importlib.util.find_spec("pyoidn") is None:
        raise UserError(MISSING)


def _rgb(aovs: dict[str, np.ndarray], names: tuple[str, str, str]) -> np.ndarray | None:
    if not all(name in aovs for name in names):
        return None
    return np.ascontiguousarray(np.stack([aovs[name] for name in names], axis=-1), np.float32)


def denoise_image(image: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None
                  ) -> np.ndarray:
    """``image`` (H, W, 3) denoised by OIDN's RT filter in HDR mode, guided by ``albedo`` and
    ``normal`` (H, W, 3) where given (OIDN takes a normal only with an albedo)."""
    try:
        import pyoidn
    except ImportError:
        raise UserError(MISSING) from None
    colour = np.ascontiguousarray(image, np.float32)
    if normal is not None and albedo is None:
        raise ValueError("OIDN takes normals only together with an albedo")
    return np.asarray(pyoidn.denoise(colour, albedo, normal, hdr=True, quality="high"), np.float32)


def denoised(result: RenderResult) -> RenderResult:
    """``result`` with its image denoised (``denoise_image``, guided by its albedo and normal AOVs
    when it has them) and the film's image kept as ``noisy``."""
    if not result.image.size:
        return result
    albedo = _rgb(result.aovs, ("Albedo.R", "Albedo.G", "Albedo.B"))
    normal = _rgb(result.aovs, ("N.X", "N.Y", "N.Z")) if albedo is not None else None
    return dataclasses.replace(result, image=denoise_image(result.image, albedo, normal), noisy=result.image)
