"""pbrt-v4's rough dielectric (``renderer.bsdf.rough_dielectric``) against properties that need no
render: samples consistent with ``evaluate`` and ``pdf``, a density that integrates to the share of
valid samples, a directional albedo of at most 1 that matches an independent quadrature of f,
generalised reciprocity, Snell's direction and total internal reflection in the smooth limit, and
the materials that reach it from pbrt files."""

import numpy as np
import pytest

from bsdf_helpers import ConstantHits, albedo_by_integration, albedo_by_sampling, direction, uniform_sphere
from realistic.errors import UserError
from realistic.renderer.bsdf import bsdf_for
from realistic.renderer.bsdf.dielectric import Dielectric as SmoothDielectric
from realistic.renderer.bsdf.fresnel import refract_z
from realistic.renderer.bsdf.rough_dielectric import RoughDielectric
from realistic.scene.materials import Dielectric
from realistic.scene.surfaces import CheckerTexture

ETA = 1.5
N = 200_000


def _rough(alpha: float, n: int, eta: float = ETA, kr: float = 1.0, kt: float = 1.0) -> RoughDielectric:
    return RoughDielectric(eta, np.full((n, 3), kr, np.float32), np.full((n, 3), kt, np.float32),
                           np.full(n, alpha, np.float32), np.full(n, alpha, np.float32))


def _sample(bsdf: RoughDielectric, wo: np.ndarray, seed: int = 0):
    rng = np.random.default_rng(seed)
    return bsdf.sample(wo, rng.random((len(wo), 2)).astype(np.float32), rng.random(len(wo)).astype(np.float32))


CASES = [(a, t) for a in (0.05, 0.3, 0.6) for t in (10.0, 60.0, 120.0, 170.0)]  # theta > 90: wo inside


@pytest.mark.parametrize("alpha,theta", CASES)
def test_samples_agree_with_evaluate_and_pdf(alpha, theta):
    bsdf = _rough(alpha, 20_000)
    wo = direction(theta, 30.0, 20_000)
    s = _sample(bsdf, wo)
    ok = s.valid
    assert ok.mean() > 0.5 and not s.specular.any()
    np.testing.assert_allclose(s.value[ok], bsdf.evaluate(wo, s.wi)[ok], rtol=2e-3, atol=1e-6)
    np.testing.assert_allclose(s.pdf[ok], bsdf.pdf(wo, s.wi)[ok], rtol=2e-3, atol=1e-6)


@pytest.mark.parametrize("alpha,theta", CASES)
def test_density_integrates_to_the_share_of_valid_samples(alpha, theta):
    rng = np.random.default_rng(1)
    bsdf = _rough(alpha, N)
    wo = direction(theta, 30.0, N)
    wi = uniform_sphere(rng, N)
    integral = bsdf.pdf(wo, wi).astype(np.float64) * 4 * np.pi
    valid = _sample(bsdf, wo).valid.mean()
    assert abs(integral.mean() - valid) < 4 * integral.std() / np.sqrt(N) + 2e-3


@pytest.mark.parametrize("alpha,theta", CASES)
def test_white_rough_glass_conserves_energy(alpha, theta):
    """Every sample's weight f |cos| / pdf is G / G1(wo) <= 1, so the albedo is at most 1; the
    sampled albedo matches an independent quadrature of f over the sphere."""
    rng = np.random.default_rng(2)
    bsdf = _rough(alpha, N)
    wo = direction(theta, 30.0, N)
    s = _sample(bsdf, wo)
    weight = np.where(s.valid, s.value[:, 0] * np.abs(s.wi[:, 2]) / np.where(s.valid, s.pdf, 1.0), 0.0)
    assert weight.max() <= 1.0 + 1e-4
    by_sampling = albedo_by_sampling(bsdf, wo, rng)[0]
    wi = uniform_sphere(rng, N)
    quadrature = bsdf.evaluate(wo, wi)[:, 0].astype(np.float64) * np.abs(wi[:, 2]) * 4 * np.pi
    assert by_sampling <= 1.0 + 1e-4
    assert abs(albedo_by_integration(bsdf, wo, rng)[0] - by_sampling) < 4 * quadrature.std() / np.sqrt(N) + 3e-3


def test_generalised_reciprocity():
    """f(wo, wi) = f(wi, wo) for reflection; f(wo, wi) / n_i^2 = f(wi, wo) / n_o^2 for transmission
    (radiance is not scaled on crossing, see the module docstring)."""
    rng = np.random.default_rng(3)
    n = 20_000
    bsdf = _rough(0.4, n)
    # unit in float64: at grazing angles F depends on the last bits of a float32 direction
    wo, wi = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, n, 3)))
    forward, backward = bsdf.evaluate(wo, wi)[:, 0], bsdf.evaluate(wi, wo)[:, 0]
    n_o = np.where(wo[:, 2] > 0, 1.0, ETA)
    n_i = np.where(wi[:, 2] > 0, 1.0, ETA)
    assert (forward > 0).mean() > 0.5
    np.testing.assert_allclose(forward / n_i ** 2, backward / n_o ** 2, rtol=2e-3, atol=1e-7)


@pytest.mark.parametrize("theta", [20.0, 50.0, 160.0])
def test_nearly_smooth_glass_refracts_along_snells_direction(theta):
    n = 20_000
    bsdf = _rough(0.002, n, kr=0.0)
    wo = direction(theta, 0.0, n)
    s = _sample(bsdf, wo)
    through = s.valid & (s.wi[:, 2] * wo[:, 2] < 0)
    expected, ok = refract_z(wo[:1], ETA)
    assert ok[0] and through.mean() > 0.9
    np.testing.assert_allclose(s.wi[through].mean(axis=0), expected[0], atol=5e-3)
    # the share refracted is 1 - F, as smooth glass
    fresnel = SmoothDielectric(ETA, np.ones((1, 3)), np.ones((1, 3))).reflectance(wo[:1])[0]
    assert abs(through.mean() - (1 - fresnel)) < 4 * np.sqrt(fresnel * (1 - fresnel) / n) + 2e-3


@pytest.mark.parametrize("alpha", [0.01, 0.05])
def test_rough_glass_inside_beyond_the_critical_angle_transmits_only_through_steep_microfacets(alpha):
    """60 degrees from the normal inside n = 1.5 (critical 41.8 degrees): light leaves only through
    microfacets tilted more than 18.2 degrees toward it, which hold a share alpha^2 / (alpha^2 +
    tan^2 18.2) of the surface's projected microfacet area (GGX); the rest reflects."""
    n = 100_000
    s = _sample(_rough(alpha, n), direction(180.0 - 60.0, 0.0, n))
    t2 = np.tan(np.radians(60.0 - np.degrees(np.arcsin(1 / ETA)))) ** 2
    assert s.valid.mean() > 0.99
    assert np.mean(s.valid & (s.wi[:, 2] > 0)) < 2 * alpha ** 2 / (alpha ** 2 + t2)


def test_smooth_hits_and_index_one_are_specular():
    bsdf = RoughDielectric(np.array([1.5, 1.0, 1.5]), np.ones((3, 3)), np.ones((3, 3)), np.array([0.0, 0.5, 0.5]),
                           np.array([0.0, 0.5, 0.5]))
    s = _sample(bsdf, direction(30.0, 0.0, 3))
    assert list(s.specular) == [True, True, False] and bsdf.has_specular and not bsdf.only_specular
    np.testing.assert_allclose(s.wi[1], -direction(30.0)[0], atol=1e-6)  # index 1: straight through


class _TexturedHits(ConstantHits):
    """Two hits where a texture reads 0 and 0.2."""

    def scalar(self, value):
        return np.float32([0.0, 0.2]) if isinstance(value, CheckerTexture) else super().scalar(value)


def test_materials_make_smooth_or_rough_glass():
    hits = ConstantHits(4)
    assert isinstance(bsdf_for(Dielectric(1.5), hits), SmoothDielectric)
    assert isinstance(bsdf_for(Dielectric(1.5, roughness_u=0.1, roughness_v=0.1), hits), RoughDielectric)
    # pbrt-v3 remaps roughness 0 to alpha 0.05, but its glass is specular where both are 0 (glass.cpp)
    texture = CheckerTexture()
    v3 = bsdf_for(Dielectric(1.5, roughness_u=texture, roughness_v=texture, rule="pbrt-v3"), _TexturedHits(2))
    assert list(_sample(v3, direction(30.0, 0.0, 2)).specular) == [True, False]


def test_thin_glass_cannot_be_rough():
    with pytest.raises(UserError, match="thin dielectric"):
        Dielectric(1.5, thin=True, roughness_u=0.1)
