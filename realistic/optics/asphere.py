"""Even-asphere surface shape: the sag and its slope, shared by the tracer, samplers and validation.

The sag (axial depth of the surface behind its vertex, + toward the film, at radial distance r) is

    z(r) = c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2)) + A4 r^4 + A6 r^6 + ... + A20 r^20

with c = 1/R the base curvature and k the conic constant (0 sphere, -1 paraboloid, < -1
hyperboloid, between -1 and 0 prolate ellipsoid, > 0 oblate ellipsoid). Written as a function of
rho = r^2, the conic term's derivative is c / (2 sqrt(1 - (1 + k) c^2 rho)), which holds for
every k (the paraboloid included), so one formula serves the Newton iteration and the normal.
"""

from __future__ import annotations

import numpy as np

#: The even powers of r that carry a polynomial coefficient (CODE V's A..J, Zemax's PARM 2..9 and beyond).
COEFFICIENT_POWERS = tuple(range(4, 22, 2))
COEFFICIENT_COUNT = len(COEFFICIENT_POWERS)


def conic_radicand(rho2: np.ndarray, curvature: float, conic: float) -> np.ndarray:
    """1 - (1 + k) c^2 r^2: the sag is defined where it is >= 0."""
    return 1.0 - (1.0 + conic) * curvature * curvature * rho2


def sag_mm(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray) -> np.ndarray:
    """The sag at squared radius ``rho2`` (mm^2); NaN where the conic is undefined. ``coefficients``
    are A4, A6, ... (all of them, or up to the highest nonzero one: ``significant``)."""
    return _sag(rho2, curvature, coefficients, _root(rho2, curvature, conic))


def sag_slope(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray) -> np.ndarray:
    """d sag / d(r^2): the surface normal is (2 x s', 2 y s', 1) up to sign and length."""
    return _slope(rho2, curvature, coefficients, _root(rho2, curvature, conic))


def sag_and_slope(rho2: np.ndarray, curvature: float, conic: float, coefficients: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``sag_mm`` and ``sag_slope`` at once, bit for bit, with one square root (Newton's method
    needs both at every step)."""
    root = _root(rho2, curvature, conic)
    return _sag(rho2, curvature, coefficients, root), _slope(rho2, curvature, coefficients, root)


def _root(rho2: np.ndarray, curvature: float, conic: float) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.sqrt(conic_radicand(rho2, curvature, conic))


def _sag(rho2: np.ndarray, curvature: float, coefficients: np.ndarray, root: np.ndarray) -> np.ndarray:
    poly = np.zeros_like(np.asarray(rho2, dtype=np.float64))
    for a in coefficients[::-1]:  # Horner in rho from the highest A down to A4, then times rho^2
        poly = poly * rho2 + a
    return curvature * rho2 / (1.0 + root) + poly * rho2 * rho2


def _slope(rho2: np.ndarray, curvature: float, coefficients: np.ndarray, root: np.ndarray) -> np.ndarray:
    poly = np.zeros_like(np.asarray(rho2, dtype=np.float64))
    for m, a in zip(range(len(coefficients) + 1, 1, -1), coefficients[::-1]):  # sum m A_m rho^(m-1)
        poly = poly * rho2 + m * a
    with np.errstate(divide="ignore"):
        return curvature / (2.0 * root) + poly * rho2


def significant(coefficients: np.ndarray) -> np.ndarray:
    """The coefficients A4 .. up to the highest nonzero one, for ``sag_mm`` and ``sag_slope``, which
    take the first as A4 and the last as the highest. Horner's steps over the zeros above it only
    multiply 0 by rho and add 0, so starting at the highest nonzero one gives the same values bit for
    bit (0 * rho either way, NaN where rho is not finite)."""
    nonzero = np.flatnonzero(coefficients)
    return coefficients[:nonzero[-1] + 1] if len(nonzero) else coefficients[:0]
