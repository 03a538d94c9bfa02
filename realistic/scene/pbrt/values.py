"""pbrt parameter values read as our types (spectral light values as the RGB pbrt records for them),
the renderer's coordinate limit, and errors located at the directive they came from; shared by the
camera, film, shape, light and scene-assembly modules."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from realistic.core.pbrt_spectra import CIE_NM, blackbody, named_illuminant, recorded_rgb, sampled, xyz_rgb
from realistic.errors import LensFileError, UserError
from realistic.scene.measured import float_file_numbers
from realistic.scene.model import RGB
from realistic.scene.pbrt.lexer import PbrtSyntaxError
from realistic.scene.pbrt.parser import Param, Params

GREY: RGB = (0.5, 0.5, 0.5)
#: Farthest a shape or the camera may reach from the world origin: the renderer intersects in single
#: precision, where products of larger coordinates overflow (float32 holds up to 3.4e38).
MAX_WORLD_COORDINATE = 1e18
#: Parameter types that give a light's emission as a spectrum (or XYZ) rather than RGB.
SPECTRAL_TYPES = ("spectrum", "blackbody", "xyz")


def rgb(params: Params, name: str, default: RGB | None) -> RGB | None:
    """An RGB triple (one value: grey); None for what we cannot read as RGB (spectra, other counts)."""
    p = params.items.get(name)
    if p is None:
        return default
    if p.type in SPECTRAL_TYPES or len(p.values) not in (1, 3):
        return None
    values = params.get_floats(name, [])  # a syntax error naming the parameter when they are not numbers
    return (values[0], values[0], values[0]) if len(values) == 1 else (values[0], values[1], values[2])


def whole_number(params: Params, name: str, default: float, where: str) -> int:
    """An integer parameter, which must hold a whole number."""
    value = params.get_float(name, default)
    if value != int(value):
        raise UserError(f'{where}: "{name}" must be a whole number, got {value:g}')
    return int(value)


#: A message that starts with a file and line number ("scene.pbrt:12: ...").
_LOCATED = re.compile(r"^[^\n]+?:\d+: ")


@contextmanager
def located(where: str) -> Iterator[None]:
    """Prefix ``where`` (a scene file:line) to a UserError that does not already name a file and line
    (its own, or another's: a texture's line where a material uses it)."""
    try:
        yield
    except (LensFileError, PbrtSyntaxError):
        raise
    except UserError as err:
        message = str(err)
        if message.startswith(f"{where}:") or _LOCATED.match(message):
            raise
        raise UserError(f"{where}: {message}") from None


def spectral_rgb(param: Param, spectra: str, find: Callable[[str, Path, str, str], Path],
                 warn: Callable[[str, str], None]) -> RGB:
    """The RGB that pbrt version ``spectra`` ("v2", "v3" or "v4": ``Dialect.spectra``) records for a
    light's ``blackbody``, ``spectrum`` or ``xyz`` parameter, relative to an RGB light recording its
    own RGB (``realistic.core.pbrt_spectra``). pbrt-v4 reads ``blackbody [T]`` and named illuminants or
    tabulated pairs, in increasing wavelength; pbrt-v2/v3 ``blackbody [T scale]``, pairs (sorted, as
    their ``FromSampled`` sorts them) and ``xyz``; both read pairs from a file named in the spectrum.
    Components below 0 (colours outside sRGB) are clipped to 0 with a warning: lights emit none."""
    where, kind, name = param.where, param.type, param.name
    label = f'"{kind} {name}"'
    with located(where):
        if kind == "blackbody":
            numbers = _numbers(param, label)
            if spectra == "v4" and len(numbers) != 1:
                raise UserError(f"{label} takes one temperature in pbrt-v4 (got {len(numbers)} numbers; pbrt-v3's "
                                f'[temperature scale] is written "blackbody {name}" [T] "float scale" [scale])')
            if spectra != "v4" and len(numbers) != 2:
                raise UserError(f"{label} takes [temperature scale] in pbrt-{spectra} (got {len(numbers)} numbers)")
            if spectra != "v4" and numbers[1] < 0:
                raise UserError(f"{label} scale must not be negative, got {numbers[1]:g}")
            values = blackbody(CIE_NM, numbers[0], spectra) * (numbers[1] if spectra != "v4" else 1.0)
        elif kind == "xyz":
            if spectra == "v4":
                raise UserError(f"{label}: pbrt-v4 has no xyz parameters (use rgb, blackbody or spectrum)")
            numbers = _numbers(param, label)
            if len(numbers) != 3:
                raise UserError(f"{label} takes 3 numbers, got {len(numbers)}")
            return _emitted(xyz_rgb(np.array(numbers)), label, where, warn)
        else:
            values = _spectrum_values(param, label, spectra, find)
        try:
            return _emitted(recorded_rgb(values, spectra), label, where, warn)
        except UserError as err:
            raise UserError(f"{label}: {err}") from None


def _numbers(param: Param, label: str) -> list[float]:
    """The parameter's values, all finite numbers."""
    numbers = [v for v in param.values if isinstance(v, float)]
    if len(numbers) != len(param.values) or not numbers:
        raise UserError(f"{label} expects numbers")
    if not all(math.isfinite(v) for v in numbers):
        raise UserError(f"{label} must be finite numbers, got {' '.join(f'{v:g}' for v in numbers)}")
    return numbers


def _spectrum_values(param: Param, label: str, spectra: str,
                     find: Callable[[str, Path, str, str], Path]) -> np.ndarray:
    """A ``spectrum`` parameter at ``CIE_NM``: a named illuminant (pbrt-v4), a file of pairs, or pairs."""
    texts = [v for v in param.values if isinstance(v, str)]
    if texts:
        if len(texts) != 1 or len(param.values) != 1:
            raise UserError(f"{label} takes one spectrum name or file")
        named = named_illuminant(texts[0]) if spectra == "v4" else None
        if named is not None:
            return named
        path = find(texts[0], Path(param.where.rsplit(":", 1)[0]).parent, param.where, "spectrum file")
        try:
            numbers = [float(v) for v in float_file_numbers(path.read_bytes())]
        except (OSError, ValueError) as err:
            raise UserError(f"{label}: spectrum file {path}: {err}") from None
        label = f"{label} (file {path})"
    else:
        numbers = _numbers(param, label)
    if len(numbers) < 2 or len(numbers) % 2:
        raise UserError(f"{label} needs (wavelength, value) pairs, got {len(numbers)} numbers")
    pairs = np.asarray(numbers, np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(pairs)):
        raise UserError(f"{label} must be finite numbers")
    if np.any(pairs[:, 1] < 0):
        raise UserError(f"{label} has a negative value ({pairs[:, 1].min():g}); a light cannot emit less than none")
    if np.any(pairs[:, 0] <= 0):
        raise UserError(f"{label} has a wavelength that is not positive ({pairs[:, 0].min():g} nm)")
    if spectra != "v4":  # pbrt-v2/v3 FromSampled sorts the samples (SortSpectrumSamples)
        pairs = pairs[np.argsort(pairs[:, 0], kind="stable")]
    steps = np.diff(pairs[:, 0])
    if np.any(steps <= 0):
        at = int(np.argmax(steps <= 0))
        raise UserError(f"{label} wavelengths must increase ({pairs[at, 0]:g} nm, then {pairs[at + 1, 0]:g} nm)")
    return sampled(pairs[:, 0], pairs[:, 1], spectra)


def _emitted(rgb: np.ndarray, label: str, where: str, warn: Callable[[str, str], None]) -> RGB:
    """``rgb`` as an emission, negative components (outside sRGB) clipped to 0 with a warning."""
    if np.any(rgb < 0):
        warn(where, f"{label} is outside sRGB (RGB {rgb[0]:.4g} {rgb[1]:.4g} {rgb[2]:.4g}; negative components "
                    f"rendered as 0)")
        rgb = np.maximum(rgb, 0.0)
    return float(rgb[0]), float(rgb[1]), float(rgb[2])
