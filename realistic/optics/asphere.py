"""Even-asphere surface shape: the sag and its slope, shared by the tracer, samplers and validation.

The sag (axial depth of the surface behind its vertex, + toward the film, at radial distance r) is

    z(r) = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2)) + A4 r^4 + A6 r^6 + ... + A20 r^20

with c = 1/R the base curvature and k the conic constant (0 sphere, -1 paraboloid, < -1
hyperboloid, between -1 and 0 prolate ellipsoid, > 0 oblate ellipsoid). Written as a function of
rho = r^2, the conic term's derivative is c / (2 sqrt(1 - (1 + k) c^2 rho)), which holds for
every k (the paraboloid included), so one formula serves the Newton iteration and the normal.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

#: A squared radius: one float (a lens file's check) or an array of them (a tracer's rays).
Rho2 = TypeVar("Rho2", float, np.ndarray)

#: The even powers of r that carry a polynomial coefficient (CODE V's A..J, Zemax's PARM 2..9 and beyond).
COEFFICIENT_POWERS = tuple(range(4, 22, 2))
COEFFICIENT_COUNT = len(COEFFICIENT_POWERS)


def conic_radicand(rho2: Rho2, curvature: float, conic: float) -> Rho2:
    """1 - (1 + k) c^2 r^2: the sag is defined where it is >= 0."""
    return 1.0 - (1.0 + conic) * curvature * curvature * rho2


def sag_mm(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray) -> np.ndarray:
    """The sag at squared radius ``rho2`` (mm^2); NaN where the conic is undefined. ``coefficients``
    are A4, A6, ... (all of them, or up to the highest nonzero one: ``significant``)."""
    return sag_and_slope(rho2, curvature, conic, coefficients)[0]


def sag_slope(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray) -> np.ndarray:
    """d sag / d(r^2): the surface normal is (2 x s', 2 y s', 1) up to sign and length."""
    return sag_and_slope(rho2, curvature, conic, coefficients)[1]


def sag_and_slope(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The sag and its slope at once, with one square root: Newton's method needs both at every step,
    and the float64 tracer's cost there is numpy's per-call overhead."""
    rho2 = np.asarray(rho2, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):  # NaN outside the conic's domain
        root = np.sqrt(conic_radicand(rho2, curvature, conic))
        sag = curvature * rho2 / (1.0 + root) + _horner(rho2, coefficients) * rho2 * rho2
        # d/d(rho) of A_m rho^m is m A_m rho^(m-1), with m = 2 for A4
        slope = curvature / (2.0 * root) + _horner(rho2, np.arange(2, len(coefficients) + 2) * coefficients) * rho2
    return sag, slope


def _horner(rho2: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """c0 + c1 rho + c2 rho^2 + ... by Horner's rule from the last coefficient, starting from 0
    (0 * rho + c_last: NaN where rho is not finite, even when the polynomial is constant)."""
    poly = np.asarray(rho2, dtype=np.float64) * 0.0
    for c in coefficients[::-1]:
        poly = poly * rho2 + c
    return poly


def significant(coefficients: np.ndarray) -> np.ndarray:
    """The coefficients A4 .. up to the highest nonzero one, for ``sag_mm`` and ``sag_slope``, which
    take the first as A4 and the last as the highest. Horner's steps over the zeros above it only
    multiply 0 by rho and add 0, so starting at the highest nonzero one gives the same values bit for
    bit (0 * rho either way, NaN where rho is not finite)."""
    nonzero = np.flatnonzero(coefficients)
    return coefficients[:nonzero[-1] + 1] if len(nonzero) else coefficients[:0]
