"""Refractive index against wavelength from n_d and the Abbe number (two-term Cauchy form).

n(lambda) = A + B / lambda^2 with lambda in micrometres, chosen so that n(d) = n_d and
(n_d - 1) / (n_F - n_C) = V_d. V = 0 (or air) means a constant index.
"""

from __future__ import annotations

import numpy as np

LAMBDA_F_UM = 0.4861327
LAMBDA_D_UM = 0.5875618
LAMBDA_C_UM = 0.6562725
D_LINE_NM = LAMBDA_D_UM * 1000.0


def cauchy_coefficients(n_d: np.ndarray, abbe_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cauchy (A, B) per medium; B = 0 where V is 0 (no dispersion)."""
    n_d = np.asarray(n_d, dtype=np.float64)
    abbe_v = np.asarray(abbe_v, dtype=np.float64)
    scale = LAMBDA_F_UM**2 * LAMBDA_C_UM**2 / (LAMBDA_C_UM**2 - LAMBDA_F_UM**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(abbe_v > 0, (n_d - 1.0) / abbe_v * scale, 0.0)
    return n_d - b / LAMBDA_D_UM**2, b


def refractive_index(n_d: np.ndarray, abbe_v: np.ndarray, wavelength_nm: float | np.ndarray) -> np.ndarray:
    """Index of each medium at ``wavelength_nm``: shape (media,) for a scalar wavelength,
    (media, N) for an array of N wavelengths (one per ray)."""
    a, b = cauchy_coefficients(n_d, abbe_v)
    lam_um = np.asarray(wavelength_nm, dtype=np.float64) / 1000.0
    extra = (1,) * lam_um.ndim
    return a.reshape(a.shape + extra) + b.reshape(b.shape + extra) / lam_um**2
