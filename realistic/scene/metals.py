"""Complex refractive indices (eta, k) of pbrt's named metals as RGB, from pbrt's tabulated spectra.

Copper: pbrt-v3 ``src/materials/metal.cpp`` (``CopperWavelengths``, ``CopperN``, ``CopperK``: 56
samples from 298.8 to 885.6 nm), the default of pbrt-v2/v3 ``metal`` and of pbrt-v4 ``conductor``.
Silver, aluminium, gold (on the same 56 wavelengths), magnesium oxide and titanium dioxide: pbrt-v4
``src/pbrt/util/spectrum.cpp`` (``Ag_eta``, ``Ag_k``, ``Al_eta``, ``Al_k``, ``Au_eta``, ``Au_k``,
``MgO_eta``, ``MgO_k``, ``TiO2_eta``, ``TiO2_k``), the named spectra "metal-<name>-eta" and
"metal-<name>-k" of pbrt-v4 ``conductor``. pbrt-v4's brass ("metal-CuZn-...") is not tabulated
here. Every table is turned into RGB by the same integral as every pbrt-v4 sampled spectrum here
(``realistic.scene.measured.spectrum_to_rgb``); pbrt-v1/v2/v3 files convert copper as those
versions do (``realistic.scene.pbrt.materials``).

pbrt-v4 does not convert eta and k: ``ConductorMaterial`` (``src/pbrt/materials.h``) samples both
spectra at the ray's wavelengths, ``ConductorBxDF`` (``src/pbrt/bxdfs.h``) evaluates ``FrComplex``
(``src/pbrt/util/scattering.h``) per wavelength, and the RGB film integrates the result. Fresnel
of the RGB-converted indices differs from that (gold's red -4.6 %, green +3.9 % at normal
incidence), so ``reflectance_table`` tabulates, per pair of named spectra, the RGB that pbrt-v4's
film records for the spectral Fresnel reflectance against cos(theta): the reflectance under the
white of an RGB light (``rgb L [1 1 1]`` emits the sRGB illuminant D65, ``RGBIlluminantSpectrum``
in ``src/pbrt/util/spectrum.h``) through the default ``cie1931`` sensor (``src/pbrt/film.h``
``PixelSensor``: x bar, y bar, z bar, no white balance) and sRGB's ``RGBFromXYZ``
(``src/pbrt/util/colorspace.cpp``): RGB = RGBFromXYZ int F D65 (x, y, z bar) / int D65 y bar over
360-830 nm (``realistic.core.pbrt_spectra``), so a reflectance of 1 records (1, 1, 1). Gold lies
outside sRGB's gamut: its red records 1.022 at normal incidence, as in pbrt-v4.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from realistic.core.pbrt_spectra import CIE_NM, CMF, PBRT4_RGB_FROM_XYZ, named_illuminant
from realistic.scene.measured import spectrum_to_rgb

COPPER_NM = (
    298.7570554, 302.4004341, 306.1337728, 309.960445, 313.8839949, 317.9081487, 322.036826, 326.2741526,
    330.6244747, 335.092373, 339.6826795, 344.4004944, 349.2512056, 354.2405086, 359.374429, 364.6593471,
    370.1020239, 375.7096303, 381.4897785, 387.4505563, 393.6005651, 399.9489613, 406.5055016, 413.2805933,
    420.2853492, 427.5316483, 435.0322035, 442.8006357, 450.8515564, 459.2006593, 467.8648226, 476.8622231,
    486.2124627, 495.936712, 506.0578694, 516.6007417, 527.5922468, 539.0616435, 551.0407911, 563.5644455,
    576.6705953, 590.4008476, 604.8008683, 619.92089, 635.8162974, 652.5483053, 670.1847459, 688.8009889,
    708.4810171, 729.3186941, 751.4192606, 774.9011125, 799.8979226, 826.5611867, 855.0632966, 885.6012714)
COPPER_N = (
    1.400313, 1.38, 1.358438, 1.34, 1.329063, 1.325, 1.3325, 1.34, 1.334375, 1.325, 1.317812, 1.31, 1.300313,
    1.29, 1.281563, 1.27, 1.249062, 1.225, 1.2, 1.18, 1.174375, 1.175, 1.1775, 1.18, 1.178125, 1.175, 1.172812,
    1.17, 1.165312, 1.16, 1.155312, 1.15, 1.142812, 1.135, 1.131562, 1.12, 1.092437, 1.04, 0.950375, 0.826,
    0.645875, 0.468, 0.35125, 0.272, 0.230813, 0.214, 0.20925, 0.213, 0.21625, 0.223, 0.2365, 0.25, 0.254188,
    0.26, 0.28, 0.3)
COPPER_K = (
    1.662125, 1.687, 1.703313, 1.72, 1.744563, 1.77, 1.791625, 1.81, 1.822125, 1.834, 1.85175, 1.872, 1.89425,
    1.916, 1.931688, 1.95, 1.972438, 2.015, 2.121562, 2.21, 2.177188, 2.13, 2.160063, 2.21, 2.249938, 2.289,
    2.326, 2.362, 2.397625, 2.433, 2.469187, 2.504, 2.535875, 2.564, 2.589625, 2.605, 2.595562, 2.583, 2.5765,
    2.599, 2.678062, 2.809, 3.01075, 3.24, 3.458187, 3.67, 3.863125, 4.05, 4.239563, 4.43, 4.619563, 4.817,
    5.034125, 5.26, 5.485625, 5.717)

#: pbrt-v4 tabulates silver, aluminium and gold at copper's wavelengths (``COPPER_NM``).
AG_N = (
    1.519, 1.496, 1.4325, 1.323, 1.142062, 0.932, 0.719062, 0.526, 0.388125, 0.294, 0.253313, 0.238, 0.221438,
    0.209, 0.194813, 0.186, 0.192063, 0.2, 0.198063, 0.192, 0.182, 0.173, 0.172625, 0.173, 0.166688, 0.16, 0.1585,
    0.157, 0.151063, 0.144, 0.137313, 0.132, 0.13025, 0.13, 0.129938, 0.13, 0.130063, 0.129, 0.124375, 0.12,
    0.119313, 0.121, 0.1255, 0.131, 0.136125, 0.14, 0.140063, 0.14, 0.144313, 0.148, 0.145875, 0.143, 0.142563,
    0.145, 0.151938, 0.163)
AG_K = (
    1.08, 0.882, 0.761063, 0.647, 0.550875, 0.504, 0.554375, 0.663, 0.818563, 0.986, 1.120687, 1.24, 1.34525, 1.44,
    1.53375, 1.61, 1.641875, 1.67, 1.735, 1.81, 1.87875, 1.95, 2.029375, 2.11, 2.18625, 2.26, 2.329375, 2.4,
    2.47875, 2.56, 2.64, 2.72, 2.798125, 2.88, 2.97375, 3.07, 3.159375, 3.25, 3.348125, 3.45, 3.55375, 3.66,
    3.76625, 3.88, 4.010625, 4.15, 4.293125, 4.44, 4.58625, 4.74, 4.908125, 5.09, 5.28875, 5.5, 5.720624, 5.95)
AL_N = (
    0.273375, 0.28, 0.286813, 0.294, 0.301875, 0.31, 0.317875, 0.326, 0.33475, 0.344, 0.353813, 0.364, 0.374375,
    0.385, 0.39575, 0.407, 0.419125, 0.432, 0.445688, 0.46, 0.474688, 0.49, 0.506188, 0.523, 0.540063, 0.558,
    0.577313, 0.598, 0.620313, 0.644, 0.668625, 0.695, 0.72375, 0.755, 0.789, 0.826, 0.867, 0.912, 0.963, 1.02,
    1.08, 1.15, 1.22, 1.3, 1.39, 1.49, 1.6, 1.74, 1.91, 2.14, 2.41, 2.63, 2.8, 2.74, 2.58, 2.24)
AL_K = (
    3.59375, 3.64, 3.689375, 3.74, 3.789375, 3.84, 3.894375, 3.95, 4.005, 4.06, 4.11375, 4.17, 4.23375, 4.3, 4.365,
    4.43, 4.49375, 4.56, 4.63375, 4.71, 4.784375, 4.86, 4.938125, 5.02, 5.10875, 5.2, 5.29, 5.38, 5.48, 5.58, 5.69,
    5.8, 5.915, 6.03, 6.15, 6.28, 6.42, 6.55, 6.7, 6.85, 7.0, 7.15, 7.31, 7.48, 7.65, 7.82, 8.01, 8.21, 8.39, 8.57,
    8.62, 8.6, 8.45, 8.31, 8.21, 8.21)
AU_N = (
    1.795, 1.812, 1.822625, 1.83, 1.837125, 1.84, 1.83425, 1.824, 1.812, 1.798, 1.782, 1.766, 1.7525, 1.74,
    1.727625, 1.716, 1.705875, 1.696, 1.68475, 1.674, 1.666, 1.658, 1.64725, 1.636, 1.628, 1.616, 1.59625, 1.562,
    1.502125, 1.426, 1.345875, 1.242, 1.08675, 0.916, 0.7545, 0.608, 0.49175, 0.402, 0.3455, 0.306, 0.267625, 0.236,
    0.212375, 0.194, 0.17775, 0.166, 0.161, 0.16, 0.160875, 0.164, 0.1695, 0.176, 0.181375, 0.188, 0.198125, 0.21)
AU_K = (
    1.920375, 1.92, 1.918875, 1.916, 1.911375, 1.904, 1.891375, 1.878, 1.86825, 1.86, 1.85175, 1.846, 1.84525,
    1.848, 1.852375, 1.862, 1.883, 1.906, 1.9225, 1.936, 1.94775, 1.956, 1.959375, 1.958, 1.951375, 1.94, 1.9245,
    1.904, 1.875875, 1.846, 1.814625, 1.796, 1.797375, 1.84, 1.9565, 2.12, 2.32625, 2.54, 2.730625, 2.88, 2.940625,
    2.97, 3.015, 3.06, 3.07, 3.15, 3.445812, 3.8, 4.087687, 4.357, 4.610188, 4.86, 5.125813, 5.39, 5.63125, 5.88)
MGO_NM = (
    309.950012, 330.613007, 351.118988, 355.549011, 360.932007, 361.141998, 364.968994, 382.065002, 386.712006,
    393.337982, 404.634003, 430.935028, 435.781982, 457.82901, 477.949036, 486.004974, 487.91803, 499.919006,
    502.350006, 508.531982, 514.440002, 546.166992, 589.258972, 632.874023, 643.718018, 656.325989, 667.635986,
    690.695984, 706.439026, 767.677979)
MGO_N = (
    1.798, 1.785, 1.7768, 1.7755, 1.7732, 1.77318, 1.77186, 1.7668, 1.7655, 1.7638, 1.76104, 1.7557, 1.75471,
    1.7512, 1.7483, 1.74711, 1.7469, 1.7454, 1.7453, 1.74446, 1.7439, 1.74077, 1.73737, 1.7346, 1.734, 1.73335,
    1.73277, 1.73191, 1.73101, 1.72872)
MGO_K = (
    0.0, 0.0, 0.0, 1e-06, 1e-06, 1e-06, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
TIO2_NM = (
    305.972015, 317.979004, 334.990997, 344.007019, 359.988007, 388.044006, 399.935028, 412.031006, 419.985992,
    439.957001, 460.037018, 479.985016, 499.919006, 520.049988, 539.044006, 539.983032, 559.981995, 579.888,
    600.097046, 619.900024, 640.062012, 659.819031, 680.088013, 700.05603, 719.97699, 740.179016, 760.147034,
    779.747986, 799.871033, 819.97406, 839.973083, 859.778015, 879.915039, 899.709961)
TIO2_N = (
    3.84, 5.38, 4.22, 4.36, 3.87, 3.49, 3.4, 3.24, 3.29, 3.2, 3.13, 3.08, 3.03, 3.0, 2.95, 2.97, 2.94, 2.92, 2.9,
    2.88, 2.87, 2.85, 2.84, 2.83, 2.82, 2.81, 2.81, 2.8, 2.79, 2.79, 2.78, 2.78, 2.77, 2.77)
TIO2_K = (
    1.95, 2.18, 0.788, 0.0, 0.251, 0.0, 0.0, 0.022, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

#: Name in pbrt-v4's "metal-<name>-eta" -> (wavelengths nm, n, k).
TABLES = {
    "Cu": (COPPER_NM, COPPER_N, COPPER_K),
    "Ag": (COPPER_NM, AG_N, AG_K),
    "Al": (COPPER_NM, AL_N, AL_K),
    "Au": (COPPER_NM, AU_N, AU_K),
    "MgO": (MGO_NM, MGO_N, MGO_K),
    "TiO2": (TIO2_NM, TIO2_N, TIO2_K),
}
#: The cosines, evenly spaced over [0, 1], at which ``reflectance_table`` samples the reflectance
#: (linear interpolation between them is within 5e-5 of the integral for every metal here).
TABLE_COSINES = np.linspace(0.0, 1.0, 513)
RGBPair = tuple[tuple[float, float, float], tuple[float, float, float]]


@cache
def named_metal(name: str) -> RGBPair:
    """The metal ``name`` of ``TABLES`` ("Au", ...): its (eta, k) as RGB triples.

    The projection to RGB can dip just below zero where a spectrum is zero over most of the visible
    (TiO2's k, -8e-5 in green); k is clamped at 0, as an absorption coefficient cannot be negative.
    """
    nm, n, k = TABLES[name]
    eta, kappa = spectrum_to_rgb(np.asarray(nm), np.array([n, k]))
    kappa = np.maximum(kappa, 0.0)
    return (float(eta[0]), float(eta[1]), float(eta[2])), (float(kappa[0]), float(kappa[1]), float(kappa[2]))


def copper() -> RGBPair:
    """Copper's (eta, k) as RGB triples."""
    return named_metal("Cu")


def fr_complex(cos_i: np.ndarray, eta: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex index ``eta`` + i ``k`` seen from a
    medium of index 1 at cosines ``cos_i`` in [0, 1] (broadcast against ``eta`` and ``k``): pbrt-v4
    ``FrComplex`` (``src/pbrt/util/scattering.h``), in complex float64."""
    cos_i = np.asarray(cos_i, np.float64)
    index = np.asarray(eta, np.float64) + 1j * np.asarray(k, np.float64)
    sin2_t = (1.0 - cos_i * cos_i) / (index * index)
    cos_t = np.sqrt(1.0 - sin2_t)
    r_parl = (index * cos_i - cos_t) / (index * cos_i + cos_t)
    r_perp = (cos_i - index * cos_t) / (cos_i + index * cos_t)
    return (np.abs(r_parl) ** 2 + np.abs(r_perp) ** 2) / 2.0


@cache
def film_weights() -> np.ndarray:
    """(471, 3) weights at ``CIE_NM`` (1 nm apart) turning a spectral reflectance into the linear
    sRGB pbrt-v4's film records for it under a white RGB light (module docstring); each column sums to 1."""
    d65 = named_illuminant("stdillum-D65")
    if d65 is None:
        raise LookupError("stdillum-D65 is missing from realistic.core.cie_data")
    return (d65[:, None] * CMF) @ PBRT4_RGB_FROM_XYZ.T / float(d65 @ CMF[:, 1])


@cache
def reflectance_table(eta_metal: str, k_metal: str) -> np.ndarray:
    """(len(TABLE_COSINES), 3) float32: the RGB pbrt-v4's film records for the Fresnel reflectance of
    the spectra "metal-<eta_metal>-eta" and "metal-<k_metal>-k" (``TABLES``) at each of
    ``TABLE_COSINES``. Each table is linear between its samples; beyond its ends it holds its end
    values (pbrt-v4 reads 0 there; only MgO ends inside 360-830 nm, at 768 nm, where an index of 0
    would leave Fresnel undefined)."""
    eta_nm, eta, _ = TABLES[eta_metal]
    k_nm, _, k = TABLES[k_metal]
    eta_cie, k_cie = np.interp(CIE_NM, eta_nm, eta), np.interp(CIE_NM, k_nm, k)
    reflectance = fr_complex(TABLE_COSINES[:, None], eta_cie[None, :], k_cie[None, :])
    return (reflectance @ film_weights()).astype(np.float32)
