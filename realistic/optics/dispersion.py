"""Refractive index against wavelength: a catalogue glass's own formula, or Cauchy from n_d and V_d.

A medium given only by n_d and the Abbe number V_d gets the two-term Cauchy form
n(lambda) = A + B / lambda^2 with lambda in micrometres, chosen so that n(d) = n_d and
(n_d - 1) / (n_F - n_C) = V_d. V = 0 (or air) means a constant index.

A catalogue glass (``realistic.optics.glass``) carries its maker's dispersion formula instead,
``GlassFormula``, with lambda in micrometres and L = lambda^2:

* ``sellmeier`` (Schott, Ohara): n^2 = 1 + B1 L / (L - C1) + B2 L / (L - C2) + B3 L / (L - C3),
  coefficients (B1, B2, B3, C1, C2, C3);
* ``schott`` (the older Schott power series, as Hoya and CDGM publish it):
  n^2 = A0 + A1 L + A2 / L + A3 / L^2 + A4 / L^3 + A5 / L^4, coefficients (A0 .. A5).

Both are written in il2 = 1 / L so that the OpenCL kernel evaluates the same expression
(``realistic.camera.opencl_host``): B L / (L - C) = B / (1 - C il2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

LAMBDA_F_UM = 0.4861327
LAMBDA_D_UM = 0.5875618
LAMBDA_C_UM = 0.6562725
D_LINE_NM = LAMBDA_D_UM * 1000.0

#: The dispersion formulas a catalogue may use, by the name its data file gives.
FORMULAS = ("sellmeier", "schott")


@dataclass(frozen=True)
class GlassFormula:
    """A catalogue glass: its name, its catalogue, and its maker's dispersion formula (module docstring)."""

    name: str
    catalogue: str
    formula: str
    coefficients: tuple[float, float, float, float, float, float]

    def index(self, wavelength_um: float | np.ndarray) -> np.ndarray:
        """n at each wavelength in micrometres."""
        il2 = 1.0 / np.asarray(wavelength_um, dtype=np.float64) ** 2
        c = self.coefficients
        if self.formula == "sellmeier":
            n2 = 1.0 + c[0] / (1.0 - c[3] * il2) + c[1] / (1.0 - c[4] * il2) + c[2] / (1.0 - c[5] * il2)
        else:
            n2 = c[0] + c[1] / il2 + il2 * (c[2] + il2 * (c[3] + il2 * (c[4] + il2 * c[5])))
        return np.sqrt(n2)

    @property
    def n_d(self) -> float:
        return float(self.index(LAMBDA_D_UM))

    @property
    def abbe_v(self) -> float:
        """V_d = (n_d - 1) / (n_F - n_C) of the formula."""
        return (self.n_d - 1.0) / float(self.index(LAMBDA_F_UM) - self.index(LAMBDA_C_UM))

    @property
    def label(self) -> str:
        """``N-BK7 (Schott)``: how reports name the glass."""
        return f"{self.name} ({self.catalogue})"


def cauchy_coefficients(n_d: np.ndarray, abbe_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cauchy (A, B) per medium; B = 0 where V is 0 (no dispersion)."""
    n_d = np.asarray(n_d, dtype=np.float64)
    abbe_v = np.asarray(abbe_v, dtype=np.float64)
    scale = LAMBDA_F_UM**2 * LAMBDA_C_UM**2 / (LAMBDA_C_UM**2 - LAMBDA_F_UM**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(abbe_v > 0, (n_d - 1.0) / abbe_v * scale, 0.0)
    return n_d - b / LAMBDA_D_UM**2, b


def refractive_index(n_d: np.ndarray, abbe_v: np.ndarray, wavelength_nm: float | np.ndarray,
                     glasses: Sequence[GlassFormula | None] = ()) -> np.ndarray:
    """Index of each medium at ``wavelength_nm``: shape (media,) for a scalar wavelength,
    (media, N) for an array of N wavelengths (one per ray). ``glasses`` (per medium, or empty)
    gives a catalogue glass's formula, used instead of Cauchy where it is not None."""
    a, b = cauchy_coefficients(n_d, abbe_v)
    lam_um = np.asarray(wavelength_nm, dtype=np.float64) / 1000.0
    extra = (1,) * lam_um.ndim
    index = a.reshape(a.shape + extra) + b.reshape(b.shape + extra) / lam_um**2
    for i, glass in enumerate(glasses):
        if glass is not None:
            index[i] = glass.index(lam_um)
    return index
