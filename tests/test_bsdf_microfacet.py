"""GGX and Fresnel against closed forms derived here, and the roughness rules of each pbrt version."""

import numpy as np
import pytest

from bsdf_helpers import ConstantHits, direction
from realistic.renderer.bsdf import bsdf_for, fresnel
from realistic.renderer.bsdf.microfacet import GGX, alpha
from realistic.scene.materials import Conductor


def test_ggx_distribution_and_masking_at_hand_picked_angles():
    """Isotropic GGX: D(theta) = a^2 / (pi cos^4 (a^2 + tan^2)^2), so D(0) = 1 / (pi a^2);
    Lambda(theta) = (sqrt(1 + a^2 tan^2) - 1) / 2."""
    a = 0.3
    ggx = GGX(np.float32([a, a]), np.float32([a, a]))
    wh = np.vstack([direction(0.0), direction(35.0, 70.0)])
    t2 = np.tan(np.radians(35.0)) ** 2
    expected = [1 / (np.pi * a * a), a * a / (np.pi * np.cos(np.radians(35.0)) ** 4 * (a * a + t2) ** 2)]
    assert np.allclose(ggx.d(wh), expected, rtol=1e-5)
    assert np.allclose(ggx.lambda_(wh), [0.0, (np.sqrt(1 + a * a * t2) - 1) / 2], atol=1e-7, rtol=1e-5)


def test_ggx_anisotropic_distribution_is_normalised_over_projected_area():
    """The integral of D(wh) cos(theta_h) over the hemisphere is 1 (midpoint rule in (cos, phi))."""
    z, phi = np.meshgrid((np.arange(2000) + 0.5) / 2000, (np.arange(400) + 0.5) / 400 * 2 * np.pi)
    r = np.sqrt(1 - z.ravel() ** 2)
    wh = np.column_stack([r * np.cos(phi.ravel()), r * np.sin(phi.ravel()), z.ravel()])
    ggx = GGX(np.full(len(wh), 0.4), np.full(len(wh), 0.15))
    assert (ggx.d(wh) * wh[:, 2]).mean() * 2 * np.pi == pytest.approx(1.0, abs=0.01)


def test_rough_conductor_at_the_specular_direction_equals_the_torrance_sparrow_closed_form():
    """wo and wi at 45 degrees either side of the normal: wh = n, so f = F(cos 45) D(0) G / (4 cos^2 45)
    with D(0) = 1 / (pi a^2), G = 1 / (1 + 2 Lambda(45)), Lambda(45) = (sqrt(1 + a^2) - 1) / 2, and F the
    conductor reflectance at 45 degrees from its closed form for k = 0 (the dielectric one)."""
    a, n = 0.2, 1.8
    material = Conductor((n,) * 3, (0.0,) * 3, a, a)
    f = bsdf_for(material, ConstantHits(1)).evaluate(direction(45.0, 0.0), direction(45.0, 180.0))
    c = np.cos(np.radians(45.0))
    ct = np.sqrt(1 - (1 - c * c) / n ** 2)
    fr = (((c - n * ct) / (c + n * ct)) ** 2 + ((n * c - ct) / (n * c + ct)) ** 2) / 2
    g = 1 / (1 + 2 * (np.sqrt(1 + a * a) - 1) / 2)
    assert f[0, 0] == pytest.approx(fr * g / (np.pi * a * a) / (4 * c * c), rel=1e-4)


def test_fresnel_closed_forms():
    n = 1.5
    assert fresnel.dielectric(np.float32([1.0]), n)[0] == pytest.approx(((n - 1) / (n + 1)) ** 2, rel=1e-6)
    assert fresnel.dielectric(np.float32([-1.0]), n)[0] == pytest.approx(((n - 1) / (n + 1)) ** 2, rel=1e-6)
    critical = np.degrees(np.arcsin(1 / n))
    inside = -np.cos(np.radians([critical + 0.5, 60.0, 89.0]))
    assert np.all(fresnel.dielectric(inside, n) == 1.0)  # total internal reflection
    brewster = np.arctan(n)  # p-polarised reflectance vanishes: R = Rs / 2
    c, ct = np.cos(brewster), np.sin(brewster)  # theta_t = 90 deg - theta_B
    rs = ((c - n * ct) / (c + n * ct)) ** 2
    assert fresnel.dielectric(np.float32([c]), n)[0] == pytest.approx(rs / 2, rel=1e-5)
    eta, k = np.float32([[0.2, 1.1, 2.0]]), np.float32([[3.9, 2.4, 0.0]])
    normal = ((eta - 1) ** 2 + k ** 2) / ((eta + 1) ** 2 + k ** 2)
    assert np.allclose(fresnel.conductor(np.float32([1.0]), eta, k), normal, rtol=1e-5)
    cos = np.float32(np.cos(np.radians([10, 40, 70, 85])))
    assert np.allclose(fresnel.conductor(cos, np.full((4, 1), 1.7), np.zeros((4, 1)))[:, 0],
                       fresnel.dielectric(cos, 1.7), rtol=1e-5)


def test_refraction_obeys_snell_and_reverses():
    wo = direction(50.0, 30.0)
    wi, ok = fresnel.refract_z(wo, 1.33)
    assert ok.all() and wi[0, 2] < 0
    assert np.hypot(wi[0, 0], wi[0, 1]) == pytest.approx(np.sin(np.radians(50.0)) / 1.33, rel=1e-6)
    back, ok = fresnel.refract_z(wi, 1.33)  # from inside along wi: out along wo
    assert ok.all() and np.allclose(back, wo, atol=1e-6)


def test_roughness_rules():
    r = np.float32([0.01, 0.25, 1.0])
    assert np.allclose(alpha(r, "alpha"), r)
    assert np.allclose(alpha(r, "sqrt"), np.sqrt(r))
    x = np.log(r.astype(np.float64))
    poly = 1.62142 + 0.819955 * x + 0.1734 * x ** 2 + 0.0171201 * x ** 3 + 0.000640711 * x ** 4
    assert np.allclose(alpha(r, "pbrt-v3"), poly, rtol=1e-6)
    assert alpha(np.float32([1.0]), "pbrt-v3")[0] == pytest.approx(1.62142)
    # pbrt-v2 Blinn exponent e = 1 / r as the Beckmann width sqrt(2 / (e + 2))
    assert np.allclose(alpha(r, "blinn"), np.sqrt(2 / (1 / r + 2)), rtol=1e-6)
    assert alpha(np.float32([0.0]), "blinn")[0] == 0.0
