"""pbrt-v2's two measured-BRDF file formats, read into arrays (cached per file).

Both as pbrt-v2 ``src/materials/measured.cpp`` (``MeasuredMaterial``) reads them:

- **Irregular isotropic samples** (``.brdf``, the files of pbrt's ``scenes/brdfs``): numbers read by
  ``ReadFloatFile`` (``src/core/floatfile.cpp``: ``#`` starts a comment to the end of the line; a
  number is a run of digits, ``.``, ``e``, ``+``, ``-``; anything else is skipped with a warning).
  The first number is the count of wavelengths, then the wavelengths in nm, then records of
  theta_i, phi_i, theta_o, phi_o (radians) and one value per wavelength. Each record becomes the
  point ``brdf_remap(wo, wi)`` = (sin theta_i sin theta_o, delta phi / pi, cos theta_i cos theta_o)
  (``BRDFRemap`` in ``src/core/reflection.cpp``) and its spectrum's RGB.
- **MERL half-angle tables** (any other suffix; Matusik et al. 2003): three little-endian int32
  dimensions whose product must be 90 * 90 * 180, then that many float64 values per channel, all
  red, then green, then blue, scaled by 1/1500, 1.15/1500, 1.66/1500 and clamped at 0. Index order:
  phi_d fastest, then theta_d, then theta_h.

Spectra to RGB as pbrt-v2 turns them (``RGBSpectrum::FromSampled``, ``src/core/spectrum.h``;
``realistic.core.pbrt_spectra.sampled_rgb``): the samples interpolated linearly (constant beyond
the ends), summed against its 1 nm CIE tables over the sum of y bar, and ``XYZToRGB``'s sRGB matrix
applied to that unadapted XYZ, so that a flat 1 gives about (1.205, 0.948, 0.909), as in pbrt-v2
(a white-balanced conversion to (1, 1, 1) shifted the measured dragons' hue by about 10 %, issue 34).
``spectrum_to_rgb`` is the project's own white-balanced conversion, for pbrt-v4's tabulated spectra.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from realistic.core.pbrt_spectra import sampled_rgb
from realistic.core.spectrum import LAMBDA_MAX_NM, LAMBDA_MIN_NM, RGB_FROM_XYZ, cie_xyz
from realistic.errors import UserError

MERL_SHAPE = (90, 90, 180)  # theta_h, theta_d, phi_d bins
MERL_SCALE = (1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0)
#: Largest measured-file record count we read (the pbrt files hold about 1,500; MERL tables 1.5 M).
MAX_IRREGULAR_SAMPLES = 10_000_000
_NUMBER = re.compile(rb"[0-9.+\-][0-9.eE+\-]*")  # ReadFloatFile's number characters ('e' inside only)


@dataclass(frozen=True, eq=False)
class IrregularSamples:
    """Measured samples at BRDFRemap points (M, 3) with their RGB values (M, 3)."""

    points: np.ndarray
    rgb: np.ndarray


@dataclass(frozen=True, eq=False)
class HalfangleTable:
    """A MERL table of RGB values, shape (90, 90, 180, 3): theta_h, theta_d, phi_d, channel."""

    rgb: np.ndarray


def brdf_remap(wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """pbrt-v2's BRDFRemap of direction pairs (N, 3) in the local frame: (N, 3) float64 points."""
    wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
    cos_i, cos_o = wi[:, 2], wo[:, 2]
    sin_i = np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i))
    sin_o = np.sqrt(np.maximum(0.0, 1.0 - cos_o * cos_o))
    dphi = np.mod(_phi(wi) - _phi(wo), 2 * np.pi)
    dphi = np.where(dphi > np.pi, 2 * np.pi - dphi, dphi)
    return np.column_stack([sin_i * sin_o, dphi / np.pi, cos_i * cos_o])


def _phi(w: np.ndarray) -> np.ndarray:
    """pbrt's SphericalPhi: atan2(y, x) in [0, 2 pi)."""
    return np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi)


def spectrum_to_rgb(wavelengths_nm: np.ndarray, values: np.ndarray) -> np.ndarray:
    """RGB (M, 3) of sampled spectra ``values`` (M, W) at increasing ``wavelengths_nm`` (W,), white
    balanced: a flat spectrum 1 is (1, 1, 1) (``realistic.core.spectrum.RGB_FROM_XYZ``)."""
    grid = np.arange(LAMBDA_MIN_NM, LAMBDA_MAX_NM + 0.5, 1.0)
    weights = np.zeros((len(wavelengths_nm), len(grid)))  # linear interpolation as a matrix
    for j in range(len(wavelengths_nm)):
        unit = np.zeros(len(wavelengths_nm))
        unit[j] = 1.0
        weights[j] = np.interp(grid, wavelengths_nm, unit)
    xyz = values @ (weights @ cie_xyz(grid))  # 1 nm rectangle rule
    return xyz @ RGB_FROM_XYZ.T


def float_file_numbers(data: bytes) -> np.ndarray:
    """ReadFloatFile's numbers: comments dropped, number-character runs parsed (bad runs are errors)."""
    text = re.sub(rb"#[^\n]*", b" ", data)
    tokens = _NUMBER.findall(text)
    try:
        return np.array([float(t) for t in tokens], dtype=np.float64)
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise ValueError(f"{bad.decode('ascii')!r} is not a number") from None


def _is_float(token: bytes) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def read_irregular(path: Path) -> IrregularSamples:
    """A ``.brdf`` file of irregular isotropic samples (module docstring), or a one-line UserError."""
    try:
        values = float_file_numbers(path.read_bytes())
    except OSError as err:
        raise UserError(f"{path}: cannot read the measured BRDF ({err.strerror})") from None
    except ValueError as err:
        raise UserError(f"{path}: measured BRDF: {err}") from None
    if len(values) == 0 or not 1 <= values[0] <= 10_000 or values[0] != int(values[0]):
        shown = f"{values[0]:g}" if len(values) else "nothing"
        raise UserError(f"{path}: measured BRDF must start with its number of wavelengths (1 to 10000), "
                        f"got {shown}")
    count = int(values[0])
    record = 4 + count
    body = values[1 + count:]
    if len(values) < 1 + count or len(body) == 0 or len(body) % record:
        raise UserError(f"{path}: measured BRDF with {count} wavelengths needs {count} wavelengths and then "
                        f"records of {record} numbers (theta_i, phi_i, theta_o, phi_o and one value per "
                        f"wavelength); {len(values) - 1} numbers follow the count")
    if len(body) // record > MAX_IRREGULAR_SAMPLES:
        raise UserError(f"{path}: measured BRDF with more than {MAX_IRREGULAR_SAMPLES} samples")
    wavelengths = values[1:1 + count]
    if not np.all(np.isfinite(body)) or not np.all(np.isfinite(wavelengths)) or np.any(np.diff(wavelengths) <= 0):
        raise UserError(f"{path}: measured BRDF wavelengths must increase and every value must be finite")
    rows = body.reshape(-1, record)
    theta_i, phi_i, theta_o, phi_o = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]
    wi = np.column_stack([np.sin(theta_i) * np.cos(phi_i), np.sin(theta_i) * np.sin(phi_i), np.cos(theta_i)])
    wo = np.column_stack([np.sin(theta_o) * np.cos(phi_o), np.sin(theta_o) * np.sin(phi_o), np.cos(theta_o)])
    return IrregularSamples(brdf_remap(wo, wi), sampled_rgb(wavelengths, rows[:, 4:], "v2"))


def read_halfangle(path: Path) -> HalfangleTable:
    """A MERL binary table (module docstring), or a one-line UserError."""
    try:
        data = path.read_bytes()
    except OSError as err:
        raise UserError(f"{path}: cannot read the measured BRDF ({err.strerror})") from None
    if len(data) < 12:
        raise UserError(f"{path}: MERL BRDF table shorter than its 12-byte header ({len(data)} bytes)")
    dims = np.frombuffer(data[:12], "<i4").astype(np.int64)
    n = int(np.prod(MERL_SHAPE))
    if int(np.prod(dims)) != n:
        raise UserError(f"{path}: MERL BRDF table of {' x '.join(str(d) for d in dims)} values; pbrt-v2 reads "
                        f"only 90 x 90 x 180 tables")
    if len(data) != 12 + 3 * n * 8:
        raise UserError(f"{path}: MERL BRDF table of {len(data)} bytes; a 90 x 90 x 180 RGB table of doubles "
                        f"has {12 + 3 * n * 8}")
    channels = np.frombuffer(data, "<f8", count=3 * n, offset=12).reshape(3, n)
    with np.errstate(invalid="ignore"):
        rgb = np.nan_to_num(channels.T * np.asarray(MERL_SCALE), nan=0.0, posinf=0.0, neginf=0.0)
    return HalfangleTable(np.maximum(rgb, 0.0).astype(np.float32).reshape(*MERL_SHAPE, 3))


@lru_cache(maxsize=16)
def load_measured(path: str) -> IrregularSamples | HalfangleTable:
    """The measured BRDF at ``path``, read once per path: ``.brdf`` (any case) as irregular samples,
    anything else as a MERL table (pbrt-v2 decides by the suffix the same way)."""
    file = Path(path)
    return read_irregular(file) if file.suffix.lower() == ".brdf" else read_halfangle(file)
