"""Spectral colour: wavelengths per camera sample, RGB to spectrum, spectrum to linear sRGB.

Wavelength sampling: importance sampled over [380, 780] nm with a density matched to what reaches
the film: p proportional to |rgb(lambda)| + a floor of 0.1 % of its peak, |rgb| the Euclidean norm
of the linear sRGB response of a unit spectral sample (colour matching functions through
``RGB_FROM_XYZ``, negative lobes included). Among fixed densities, |rgb| minimises the summed
per-sample variance of the three channels' estimators r_c L / p for a flat spectrum (Lagrange: p
proportional to sqrt(sum_c r_c^2)), and that variance multiplies all other noise of a spectral
sample: per-sample variances (R, G, B) of about (4.9, 2.2, 2.8) against (9.6, 4.1, 5.6) for uniform
wavelengths and (7.2, 2.2, 4.9) for pbrt-v4's ``SampleVisibleWavelengths`` (sech^2; pbrt-v4
src/pbrt/util/sampling.h) restricted to 380-780 nm (``estimator_variance``; the floor keeps 1 / p
bounded in the far red). The density is piecewise linear between ``WAVELENGTH_INTERVALS`` + 1 equally
spaced nodes (continuous, so response / pdf stays smooth and stratification keeps paying off), its
CDF piecewise quadratic: the inverse finds the node interval (a fixed 6-step binary search in the
kernel) and solves the quadratic in the form 2v / (p0 + sqrt(p0^2 + 2 s v)), stable when the slope s
is 0. The uniform number comes from the fifth dimension of the pixel's R5 sequence
(``realistic.core.rng``), so a pixel's wavelengths are stratified jointly with its film and lens
positions.

Several wavelengths per camera sample: one wavelength per sample leaves a floor of colour noise
that no density removes (the per-sample variances above: a spectral image had 2.5-2.7x the
relative RMSE of an RGB one at equal spp). A spectral camera therefore traces each sample at K
wavelengths, invCDF((u + j) / K) for j = 0 .. K - 1 (``realistic.core.rng.spectral_rays``):
one per 1/K of this density's probability, all sharing the sample's film, lens and light-sample
numbers, each ray adding 1/K of ``rgb_response``. The mean of the K responses is nearly the
constant (1, 1, 1) (``stratified_response_variance``: per-channel variances of (0.35, 0.24, 0.64)
for K = 2, (0.16, 0.006, 0.05) for K = 3, (0.11, 0.03, 0.10) for K = 4, against (4.9, 2.2, 2.8)
for K = 1), so what noise is left is the luminance noise an RGB render has.
``DEFAULT_WAVELENGTHS_PER_SAMPLE`` is the smallest K that met the issue's target (spectral
relative RMSE at most 1.3x the RGB render's at equal spp) on both of ``bench/spectral_noise.py``'s
scenes at 16 and 64 spp: K = 2 gave 1.29-1.34x, K = 3 1.03-1.04x, K = 4 1.02-1.03x.

RGB to spectrum: s(lambda) = r b_R(lambda) + g b_G(lambda) + b b_B(lambda) with three smooth,
non-negative basis functions that sum to 1 at every wavelength (a partition of unity made of two
logistic steps at 490 and 590 nm, 12 nm wide). So (1, 1, 1) is the constant spectrum 1 exactly,
any grey c is the constant c, and a reflectance in [0, 1]^3 stays within [0, 1] at every
wavelength (energy is conserved). Greys and white round-trip exactly; a saturated colour comes
back within about 5 % per channel (the round-trip matrix of the three basis spectra through the
colour matching functions is the identity to within 0.05).

Spectrum to RGB: the CIE 1931 2-degree colour matching functions in the multi-lobe analytic fit
of Wyman, Sloan and Shirley (JCGT 2013), integrated over [380, 780] nm to XYZ, adapted from the
equal-energy white E to D65 with the Bradford transform, converted to linear sRGB, and scaled per
channel so that the constant spectrum 1 gives exactly (1, 1, 1): a white object stays white.
``rgb_response(lambda)`` folds all of that and the sampling's 1/pdf into one (N, 3) weight, so a
film sample adds weight x L(lambda) x rgb_response(lambda), whose expectation is the CIE integral.
"""

from __future__ import annotations

import math

import numpy as np

LAMBDA_MIN_NM = 380.0
LAMBDA_MAX_NM = 780.0
#: Intervals of the piecewise linear wavelength density (nodes every 6.25 nm; a power of two for the
#: kernel's binary search).
WAVELENGTH_INTERVALS = 64
#: The density's floor, as a fraction of the peak of |rgb|.
DENSITY_FLOOR = 1e-3
#: Wavelengths (rays) per spectral camera sample, by default (measured: ``bench/spectral_noise.py``).
DEFAULT_WAVELENGTHS_PER_SAMPLE = 3

#: (weight, mean nm, sigma below the mean, sigma above) per lobe; Wyman, Sloan, Shirley 2013, eq. 2.
CMF_LOBES = (
    ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),  # x
    ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),  # y
    ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),  # z
)
#: Linear sRGB from CIE XYZ (IEC 61966-2-1, D65 white).
SRGB_FROM_XYZ = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])
#: Bradford cone response matrix (chromatic adaptation).
BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])
D65_XYZ = np.array([0.95047, 1.0, 1.08883])
#: Logistic steps of the RGB basis: blue/green and green/red boundaries and width (nm).
BASIS_STEPS_NM = (490.0, 590.0)
BASIS_WIDTH_NM = 12.0


def cie_xyz(wavelength_nm: np.ndarray) -> np.ndarray:
    """CIE 1931 colour matching functions (N, 3) at ``wavelength_nm`` (analytic multi-lobe fit)."""
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    out = np.zeros(lam.shape + (3,))
    for c, lobes in enumerate(CMF_LOBES):
        for weight, mean, below, above in lobes:
            t = (lam - mean) / np.where(lam < mean, below, above)
            out[..., c] += weight * np.exp(-0.5 * t * t)
    return out


def cie_xyz_integral(lo_nm: float = LAMBDA_MIN_NM, hi_nm: float = LAMBDA_MAX_NM) -> np.ndarray:
    """Exact integral over [lo, hi] nm of each colour matching function (closed form with erf)."""
    def half_gaussian(a: float, b: float, mean: float, sigma: float) -> float:
        scale = sigma * math.sqrt(math.pi / 2)
        return scale * (math.erf((b - mean) / (sigma * math.sqrt(2))) - math.erf((a - mean) / (sigma * math.sqrt(2))))

    total = np.zeros(3)
    for c, lobes in enumerate(CMF_LOBES):
        for weight, mean, below, above in lobes:
            left = half_gaussian(lo_nm, min(hi_nm, mean), mean, below) if lo_nm < mean else 0.0
            right = half_gaussian(max(lo_nm, mean), hi_nm, mean, above) if hi_nm > mean else 0.0
            total[c] += weight * (left + right)
    return total


def _rgb_from_xyz() -> np.ndarray:
    """White-balanced linear sRGB from XYZ: Bradford E -> D65, sRGB, then (1, 1, 1) for the constant 1."""
    white_e = cie_xyz_integral()
    cone_ratio = (BRADFORD @ D65_XYZ) / (BRADFORD @ (white_e / white_e[1]))
    adapt = np.linalg.inv(BRADFORD) @ np.diag(cone_ratio) @ BRADFORD
    m = SRGB_FROM_XYZ @ adapt
    return m / (m @ white_e)[:, None]


RGB_FROM_XYZ = _rgb_from_xyz()


def cie_rgb(wavelength_nm: np.ndarray) -> np.ndarray:
    """Linear sRGB (N, 3) of a unit spectral sample at ``wavelength_nm``; integrates to (1, 1, 1)."""
    return cie_xyz(wavelength_nm) @ RGB_FROM_XYZ.T


def _wavelength_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nodes nm, density per nm at the nodes, CDF at the nodes) of the piecewise linear density."""
    nodes = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, WAVELENGTH_INTERVALS + 1)
    target = np.linalg.norm(cie_rgb(nodes), axis=-1)
    density = target + DENSITY_FLOOR * target.max()
    steps = (density[1:] + density[:-1]) / 2 * np.diff(nodes)
    density /= steps.sum()
    return nodes, density, np.concatenate([[0.0], np.cumsum(steps / steps.sum())])


WAVELENGTH_NODES_NM, WAVELENGTH_DENSITY, WAVELENGTH_CDF = _wavelength_table()


def wavelengths_nm(u: np.ndarray) -> np.ndarray:
    """Wavelengths (float32 nm) from uniform numbers in [0, 1): the density's inverse CDF (float64,
    then rounded; the kernel's float32 version agrees within about 1e-3 nm)."""
    u = np.asarray(u, dtype=np.float64)
    k = np.clip(np.searchsorted(WAVELENGTH_CDF, u, side="right") - 1, 0, WAVELENGTH_INTERVALS - 1)
    p0, p1 = WAVELENGTH_DENSITY[k], WAVELENGTH_DENSITY[k + 1]
    width = WAVELENGTH_NODES_NM[1] - WAVELENGTH_NODES_NM[0]
    v = u - WAVELENGTH_CDF[k]
    t = 2 * v / (p0 + np.sqrt(p0 * p0 + 2 * (p1 - p0) / width * v))
    return (WAVELENGTH_NODES_NM[k] + t).astype(np.float32)


def wavelength_pdf(wavelength_nm: np.ndarray) -> np.ndarray:
    """Density (per nm, float64) of ``wavelengths_nm`` at each wavelength in [380, 780] nm."""
    return np.interp(np.asarray(wavelength_nm, dtype=np.float64), WAVELENGTH_NODES_NM, WAVELENGTH_DENSITY)


def rgb_response(wavelength_nm: np.ndarray) -> np.ndarray:
    """Per-sample film weight (N, 3): ``cie_rgb`` over ``wavelength_pdf``, so its expectation over the
    sampled wavelengths of a spectrum s is the CIE integral of s (a constant 1 gives (1, 1, 1))."""
    return (cie_rgb(wavelength_nm) / wavelength_pdf(wavelength_nm)[..., None]).astype(np.float32)


def estimator_variance(density: np.ndarray, wavelength_nm: np.ndarray) -> np.ndarray:
    """Per-channel variance of one sample's ``cie_rgb / p`` for a flat spectrum 1, with p the
    ``density`` tabulated on the fine grid ``wavelength_nm`` (normalised here; trapezoidal rule)."""
    p = density / np.trapezoid(density, wavelength_nm)
    r = cie_rgb(wavelength_nm)
    return np.trapezoid(r * r / p[:, None], wavelength_nm, axis=0) - np.trapezoid(r, wavelength_nm, axis=0) ** 2


def stratified_response_variance(wavelengths: int, points: int = 1 << 16) -> np.ndarray:
    """Per-channel variance over u of the mean of ``rgb_response`` at the K = ``wavelengths``
    stratified wavelengths invCDF((u + j) / K), j = 0 .. K - 1: the colour noise factor of one
    spectral sample of a flat spectrum 1 (its mean is (1, 1, 1)). K = 1 is ``estimator_variance``
    of this density. Computed with ``points`` equally spaced u (midpoints)."""
    u = (np.arange(points) + 0.5) / points
    mean = np.zeros((points, 3))
    for j in range(wavelengths):
        mean += rgb_response(wavelengths_nm((u + j) / wavelengths)).astype(np.float64)
    return np.var(mean / wavelengths, axis=0)


def rgb_basis(wavelength_nm: np.ndarray) -> np.ndarray:
    """The RGB-to-spectrum basis (N, 3) = (b_R, b_G, b_B) at ``wavelength_nm``; rows sum to 1."""
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    blue_green, green_red = BASIS_STEPS_NM
    s1 = 1.0 / (1.0 + np.exp(-(lam - blue_green) / BASIS_WIDTH_NM))
    s2 = 1.0 / (1.0 + np.exp(-(lam - green_red) / BASIS_WIDTH_NM))
    return np.stack([s2, s1 - s2, 1.0 - s1], axis=-1).astype(np.float32)


def spectral_value(rgb: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """The spectrum of each RGB row (N, 3) at its wavelength, given that wavelength's basis row (N, 3)."""
    rgb = np.asarray(rgb, dtype=np.float32)
    return rgb[:, 0] * basis[:, 0] + rgb[:, 1] * basis[:, 1] + rgb[:, 2] * basis[:, 2]
