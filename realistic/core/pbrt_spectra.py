"""pbrt's spectra as RGB, per version: a light's emission given as a spectrum (``blackbody`` and
``spectrum`` parameters) as the linear sRGB that each pbrt version's film records for it, on the
scale on which an RGB light records its own RGB (the renderer then treats it as that RGB light);
and pbrt-v2/v3's RGB of any sampled spectrum (``sampled_rgb``: reflectances, indices, measured
BRDFs), as their ``RGBSpectrum::FromSampled`` computes it.

pbrt-v4 (``src/pbrt/lights.cpp``, every ``...Light::Create``: ``scale /= SpectrumToPhotometric(L)``)
divides a light's spectrum by its luminance, the inner product with y bar over 360-830 nm
(``src/pbrt/util/spectrum.cpp``: ``SpectrumToPhotometric``, ``InnerProduct``); for an RGB value it
takes only the colour space's illuminant (D65, luminance ``CIE_Y_integral``), so RGB (r, g, b) emits
(r, g, b) x D65 / ``CIE_Y_integral`` (the sigmoid spectrum times the illuminant,
``RGBIlluminantSpectrum``), which the default ``cie1931`` sensor (``src/pbrt/film.h``:
``ToSensorRGB``, x bar, y bar, z bar with no white balance) records as XYZ of luminance y =
0.2126 r + 0.7152 g + 0.0722 b and the RGB film turns back into (r, g, b) (``RGBFromXYZ`` of sRGB,
whose white is D65's). A spectral light therefore records ``RGBFromXYZ`` x XYZ(s) / Y(s) times its
scale: the same luminance as RGB (1, 1, 1) at the same scale, with the spectrum's chromaticity.

pbrt-v2 and pbrt-v3 do not normalise: ``RGBSpectrum::FromSampled`` (``src/core/spectrum.h``)
integrates the samples, linearly interpolated and constant beyond their ends, against the CIE
tables and converts XYZ with ``XYZToRGB`` (the sRGB matrix, no white balance: a flat spectrum 1
is (1.205, 0.948, 0.909)); pbrt-v2 divides the sums by the sum of y bar, pbrt-v3 multiplies them
by 470 / (``CIE_Y_integral`` x 471). Blackbodies: pbrt-v3 and v4 ``BlackbodyNormalized`` /
``BlackbodySpectrum``, Planck's law with pbrt's h, c and k_B divided by its value at Wien's peak
2.8977721e-3 / T m; pbrt-v2 ``Blackbody`` (``src/core/spectrum.cpp``) divides by its value at
555 nm, with c2 = 1.4388e7 nm K. Planck's law is evaluated in logarithms so that no temperature
overflows.
"""

from __future__ import annotations

import math

import numpy as np

from realistic.core.cie_data import (
    CIE_LAMBDA_MAX_NM,
    CIE_LAMBDA_MIN_NM,
    CIE_X,
    CIE_Y,
    CIE_Z,
    ILLUMINANT_STEP_NM,
    NAMED_ILLUMINANTS,
)
from realistic.errors import UserError

#: Whose spectrum-to-RGB conversion each pbrt dialect follows (pbrt-v1 reads spectra as pbrt-v2).
CONVERSION_OF_DIALECT = {"v1": "v2", "v2": "v2", "v3": "v3", "v4": "v4"}
#: The CIE tables' wavelengths (nm) and matching functions (471, 3).
CIE_NM = np.arange(CIE_LAMBDA_MIN_NM, CIE_LAMBDA_MAX_NM + 1, dtype=np.float64)
CMF = np.column_stack([CIE_X, CIE_Y, CIE_Z])
#: pbrt's ``CIE_Y_integral`` (every version's ``spectrum.h``).
CIE_Y_INTEGRAL = 106.856895
#: Planck's constant, the speed of light and Boltzmann's constant as pbrt-v3 and pbrt-v4 write them.
PLANCK_H, LIGHT_C, BOLTZMANN_K = 6.62606957e-34, 299792458.0, 1.3806488e-23
#: Second radiation constant h c / k_B in nm K: pbrt-v3/v4's, and pbrt-v2's ``C2``.
C2_NM_K = PLANCK_H * LIGHT_C / BOLTZMANN_K * 1e9
C2_V2_NM_K = 1.4388e7
#: Wien's displacement constant (m K), pbrt-v3/v4's blackbody normalisation.
WIEN_M_K = 2.8977721e-3
#: pbrt-v2/v3 ``XYZToRGB`` (``src/core/spectrum.h``).
PBRT3_RGB_FROM_XYZ = np.array([[3.240479, -1.537150, -0.498535],
                               [-0.969256, 1.875991, 0.041556],
                               [0.055648, -0.204043, 1.057311]])
#: sRGB primaries (x, y) of pbrt-v4's ``RGBColorSpace::sRGB`` (``src/pbrt/util/colorspace.cpp``).
SRGB_PRIMARIES = ((0.64, 0.33), (0.3, 0.6), (0.15, 0.06))


def _log_planck(nm: np.ndarray, temperature: float, c2: float) -> np.ndarray:
    """log of Planck's law at ``nm`` up to an additive constant: -5 log(lambda) - log(exp(x) - 1) with
    x = c2 / (lambda T), taken from log x so that neither a large nor a tiny x overflows or vanishes:
    x + log(1 - exp(-x)) above 1, log x + log(expm1(x) / x) (about x / 2 when tiny) below."""
    log_x = math.log(c2) - np.log(nm) - math.log(temperature)
    with np.errstate(all="ignore"):  # np.where computes both branches; each is used only where it is sound
        x = np.exp(np.minimum(log_x, 700.0))
        small = np.where(x > 1e-8, np.log(np.expm1(np.minimum(x, 1.0)) / np.maximum(x, 1e-8)), x / 2)
        return -5.0 * np.log(nm) - np.where(log_x > 0.0, np.exp(log_x) + np.log1p(-np.exp(-x)), log_x + small)


def blackbody(nm: np.ndarray, temperature: float, version: str) -> np.ndarray:
    """pbrt's normalised blackbody at ``nm``: peak 1 (pbrt-v3/v4) or 1 at 555 nm (pbrt-v2); a
    temperature that is not positive and finite is an error (pbrt would emit nothing or NaN)."""
    if not (math.isfinite(temperature) and temperature > 0):
        raise UserError(f"blackbody temperature must be a positive number of kelvin, got {temperature:g}")
    nm = np.asarray(nm, np.float64)
    c2, at = (C2_V2_NM_K, 555.0) if version == "v2" else (C2_NM_K, WIEN_M_K / temperature * 1e9)
    with np.errstate(over="ignore", invalid="ignore"):
        values = np.exp(_log_planck(nm, temperature, c2) - _log_planck(np.array(at), temperature, c2))
    if not np.all(np.isfinite(values)):
        at_what = "at 555 nm" if version == "v2" else "at its peak"
        raise UserError(f"blackbody temperature {temperature:g} K is too low for pbrt-{version}'s normalisation "
                        f"{at_what} (its spectrum overflows)")
    return values


def sampled(wavelengths_nm: np.ndarray, values: np.ndarray, version: str) -> np.ndarray:
    """A tabulated spectrum at ``CIE_NM``: linear between its samples, and beyond its ends constant
    (pbrt-v2/v3 ``InterpolateSpectrumSamples``) or 0 (pbrt-v4 ``PiecewiseLinearSpectrum``)."""
    outside = 0.0 if version == "v4" else None
    return np.interp(CIE_NM, wavelengths_nm, values, left=outside, right=outside)


def named_illuminant(name: str) -> np.ndarray | None:
    """pbrt-v4's named illuminant ``name`` at ``CIE_NM`` (its table extended by its end values, as
    ``PiecewiseLinearSpectrum::FromInterleaved`` does), or None for a name pbrt-v4 does not define."""
    entry = NAMED_ILLUMINANTS.get(name)
    if entry is None:
        return None
    start, values = entry
    nm = start + ILLUMINANT_STEP_NM * np.arange(len(values))
    return np.interp(CIE_NM, nm, np.asarray(values, np.float64))


def spectrum_xyz(values: np.ndarray) -> np.ndarray:
    """The inner products of a spectrum at ``CIE_NM`` with x bar, y bar, z bar (pbrt's ``InnerProduct``)."""
    return np.asarray(values, np.float64) @ CMF


def _pbrt4_srgb_from_xyz() -> np.ndarray:
    """pbrt-v4's sRGB ``RGBFromXYZ``: primaries scaled so that D65's XYZ (``SpectrumToXYZ`` of
    "stdillum-D65") maps to (1, 1, 1) (``RGBColorSpace::RGBColorSpace``)."""
    d65 = named_illuminant("stdillum-D65")
    assert d65 is not None
    white = spectrum_xyz(d65)
    white = white / white[1]
    primaries = np.array([[x / y, 1.0, (1 - x - y) / y] for x, y in SRGB_PRIMARIES]).T
    return np.linalg.inv(primaries @ np.diag(np.linalg.solve(primaries, white)))


PBRT4_RGB_FROM_XYZ = _pbrt4_srgb_from_xyz()


def recorded_rgb(values: np.ndarray, version: str) -> np.ndarray:
    """The RGB a light of spectrum ``values`` (at ``CIE_NM``) records on ``version``'s film, relative
    to an RGB light recording its RGB. pbrt-v4: luminance normalised (a spectrum with none is an error)."""
    if version == "v4":  # only the ratio counts: scaled to a peak of 1 first, so that no sum overflows
        peak = float(np.max(values))
        xyz = spectrum_xyz(np.asarray(values, np.float64) / peak) if peak > 0 else np.zeros(3)
        if not xyz[1] > 0:
            raise UserError("a spectrum with no luminance (pbrt-v4 divides a light's spectrum by its luminance)")
        return PBRT4_RGB_FROM_XYZ @ (xyz / xyz[1])
    return _pbrt3_rgb(spectrum_xyz(values), version)


def _pbrt3_rgb(sums: np.ndarray, version: str) -> np.ndarray:
    """pbrt-v2/v3 ``RGBSpectrum::FromSampled``'s RGB of the inner products ``sums`` (..., 3) with the
    CIE tables: divided by the sum of y bar (v2) or times 470 / (``CIE_Y_integral`` x 471) (v3)."""
    if version == "v3":
        xyz = sums * (CIE_NM[-1] - CIE_NM[0]) / (CIE_Y_INTEGRAL * len(CIE_NM))
    else:
        xyz = sums / float(np.sum(CMF[:, 1]))
    return xyz @ PBRT3_RGB_FROM_XYZ.T


def sampled_rgb(wavelengths_nm: np.ndarray, values: np.ndarray, version: str) -> np.ndarray:
    """pbrt-v2/v3's RGB (M, 3) of spectra ``values`` (M, W) sampled at increasing ``wavelengths_nm``
    (W,): ``RGBSpectrum::FromSampled``, linear between samples and constant beyond the ends, so that
    a flat spectrum 1 is (1.205, 0.948, 0.909) in pbrt-v2 (0.998 times that in pbrt-v3)."""
    unit = np.eye(len(wavelengths_nm))
    weights = np.array([np.interp(CIE_NM, wavelengths_nm, row) for row in unit])  # (W, 471) interpolation
    return _pbrt3_rgb(np.asarray(values, np.float64) @ (weights @ CMF), version)


def xyz_rgb(xyz: np.ndarray) -> np.ndarray:
    """pbrt-v2/v3's RGB of an ``xyz`` parameter (``RGBSpectrum::FromXYZ``: ``XYZToRGB``)."""
    return PBRT3_RGB_FROM_XYZ @ np.asarray(xyz, np.float64)
