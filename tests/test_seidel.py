r"""Third-order spherical aberration of one refracting surface against Seidel's formula.

Derivation (one surface, vertex at the origin, curvature c = 1/R > 0, index n in front and n'
behind, a ray parallel to the axis at height h). The normal at the hit point passes through the
centre of curvature C, so the angle of incidence has sin i = h/R and Snell gives
sin i' = (n/n') sin i. In the triangle C, hit point P, axis crossing F the angle at C is i, at P
is i' and at F is i - i', so by the law of sines CF = R sin i' / sin(i - i'), and the crossing lies
L' = R + CF behind the vertex. With s = h/R and mu = n/n':

    sin(i - i') = s sqrt(1 - mu^2 s^2) - mu s sqrt(1 - s^2) = s (1 - mu) (1 + mu s^2 / 2) + O(s^5)
    CF = R mu / (1 - mu) * (1 - mu s^2 / 2) + O(s^4)

so the paraxial focus is L0 = R n' / (n' - n) and the longitudinal aberration of the marginal ray

    L' - L0 = -n^2 h^2 / (2 n' (n' - n) R) + O(h^4),

which is Seidel's -S_I / (2 n' u'^2) with S_I = n^2 c^3 h^4 (n' - n) / n'^2 and u' = -h (n' - n) c / n'.
An even asphere adds to the sag the fourth-order term (k c^3 / 8 + A4) r^4 beyond the sphere's,
hence to S_I the term 8 (k c^3 / 8 + A4) (n' - n) h^4, and the aberration becomes

    L' - L0 = -h^2 n' / (2 (n' - n)) * (c (n^2 / n'^2 + k) + 8 A4 / c^2) + O(h^4).

(k = -n^2/n'^2 cancels it: the classic aplanatic conic.) The tracer is exact, so the relative
difference must fall as h^2: it is the fifth-order term.
"""

from __future__ import annotations

import numpy as np
import pytest

from realistic.optics.tracer import intersect_asphere, intersect_surface, refract

N_BEFORE, N_AFTER, R = 1.0, 1.5, 50.0
FRACTIONS = np.array([0.005, 0.01, 0.02, 0.04])  # h / R


def traced_aberration(conic: float, a4: float) -> np.ndarray:
    """L' - L0 of rays parallel to the axis at heights FRACTIONS * R, coming from the scene (+z)."""
    h = FRACTIONS * R
    o = (h, np.zeros_like(h), np.full_like(h, 10.0))
    d = (np.zeros_like(h), np.zeros_like(h), -np.ones_like(h))
    if conic == 0 and a4 == 0:
        hit, normal, miss = intersect_surface(o, d, 0.0, R)
    else:
        coefficients = np.zeros(9)
        coefficients[0] = a4
        hit, normal, miss = intersect_asphere(o, d, 0.0, R, conic, coefficients)
    assert not miss.any()
    t, tir = refract(d, normal, N_BEFORE / N_AFTER)
    assert not tir.any()
    crossing_z = hit[2] - hit[0] / t[0] * t[2]
    return -crossing_z - N_AFTER * R / (N_AFTER - N_BEFORE)


def seidel_aberration(conic: float, a4: float) -> np.ndarray:
    c, h = 1 / R, FRACTIONS * R
    return -h**2 * N_AFTER / (2 * (N_AFTER - N_BEFORE)) * (c * (N_BEFORE**2 / N_AFTER**2 + conic) + 8 * a4 / c**2)


@pytest.mark.parametrize("conic, a4", [(0.0, 0.0), (0.7, 0.0), (-1.5, 0.0), (0.0, 2e-7), (-0.3, -1e-7)])
def test_single_surface_spherical_aberration_matches_seidel(conic, a4):
    relative = traced_aberration(conic, a4) / seidel_aberration(conic, a4) - 1
    # the fifth-order remainder: relative error proportional to (h/R)^2, with a coefficient of order 1
    assert np.all(np.abs(relative) < 3 * FRACTIONS**2)
    ratios = relative[1:] / relative[:-1]  # doubling h quadruples the relative error
    np.testing.assert_allclose(ratios, 4.0, rtol=0.01)


def test_the_aplanatic_conic_cancels_third_order_aberration():
    """k = -n^2/n'^2: the traced aberration is of fifth order, far below the sphere's third-order one."""
    aplanatic = traced_aberration(-(N_BEFORE / N_AFTER) ** 2, 0.0)
    sphere = seidel_aberration(0.0, 0.0)
    assert np.all(np.abs(aplanatic) < np.abs(sphere) * FRACTIONS**2)
