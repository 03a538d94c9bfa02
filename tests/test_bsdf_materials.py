"""Every material's BSDF: white-furnace energy, reciprocity, pdfs that integrate to what sampling
covers and match a histogram of ``sample``, samples consistent with evaluate and pdf."""

import numpy as np
import pytest

from bsdf_helpers import ConstantHits, albedo_by_integration, albedo_by_sampling, direction, uniform_sphere
from realistic.renderer.bsdf import Lambertian, bsdf_for
from realistic.renderer.bsdf.oren_nayar import OrenNayar
from realistic.scene.materials import (
    CoatedDiffuse,
    Conductor,
    Dielectric,
    DiffuseTransmission,
    Mirror,
    Mix,
    Plastic,
    Substrate,
)
from realistic.scene.model import Material

N = 120_000
WHITE = (1.0, 1.0, 1.0)

#: Glossy and diffuse materials (no specular lobe): name -> material.
SMOOTH_FREE = {
    "lambertian": Material(WHITE),
    "oren-nayar": Material(WHITE, sigma=25.0),
    "plastic": Plastic((0.5,) * 3, (0.5,) * 3, 0.3),
    "coated diffuse": CoatedDiffuse(WHITE, 0.25),
    "conductor": Conductor(roughness_u=0.3, roughness_v=0.1),
    "white conductor": Conductor((1.0,) * 3, (1e4,) * 3, 0.2, 0.2),
    "substrate": Substrate(WHITE, (0.04,) * 3, 0.2, 0.2),
    "diffuse transmission": DiffuseTransmission((0.3,) * 3, (0.7,) * 3),
    "mix": Mix(Material(WHITE), Plastic((0.5,) * 3, (0.5,) * 3, 0.2), 0.4),
}
REFLECTIVE = ["lambertian", "oren-nayar", "plastic", "coated diffuse", "conductor", "white conductor", "substrate",
              "mix"]


def _bsdf(material, n=N):
    return bsdf_for(material, ConstantHits(n))


@pytest.mark.parametrize("name", sorted(SMOOTH_FREE))
@pytest.mark.parametrize("theta", [5.0, 50.0, 80.0])
def test_white_furnace_albedo_at_most_one_and_sampling_agrees_with_integration(name, theta):
    rng = np.random.default_rng(int(theta) * 7 + len(name))
    bsdf = _bsdf(SMOOTH_FREE[name])
    wo = direction(theta, 20.0, N)
    by_sampling = albedo_by_sampling(bsdf, wo, rng)
    by_integration = albedo_by_integration(bsdf, wo, rng)
    assert np.all(by_integration <= 1.0 + 0.02)
    assert np.allclose(by_sampling, by_integration, rtol=0.03, atol=0.01)


@pytest.mark.parametrize("material", [Material(WHITE), DiffuseTransmission((0.4,) * 3, (0.6,) * 3),
                                      Mirror(WHITE), Dielectric(1.5), Dielectric(1.33, thin=True),
                                      Mix(Mirror(WHITE), Dielectric(1.7), 0.5), CoatedDiffuse(WHITE, 0.0, eta=1.6)])
@pytest.mark.parametrize("theta", [0.0, 45.0, 89.0])
def test_lossless_materials_keep_all_energy(material, theta):
    """White Lambertian, R + T = 1 diffuse transmission, mirror, glass (R + T = 1 from outside and
    from inside, total internal reflection included), a thin slab, a mix of them, and a white base
    under a smooth coat (diffuse albedo 1 - F(cos_o) plus the coat's F(cos_o)): albedo 1."""
    rng = np.random.default_rng(5)
    bsdf = _bsdf(material)
    for side in (1.0, -1.0):
        wo = direction(theta, 0.0, N) * np.float32([1, 1, side])
        assert np.allclose(albedo_by_sampling(bsdf, wo, rng), 1.0, atol=0.004)


def test_glass_picks_reflection_with_the_fresnel_probability_and_refracts_by_snell():
    bsdf = _bsdf(Dielectric(1.5), 200_000)
    wo = direction(60.0, 0.0, 200_000)
    s = bsdf.sample(wo, np.zeros((200_000, 2), np.float32), np.random.default_rng(2).random(200_000))
    reflected = s.wi[:, 2] > 0
    cos_i, n = 0.5, 1.5
    cos_t = np.sqrt(1 - (1 - cos_i ** 2) / n ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)) ** 2
    assert reflected.mean() == pytest.approx((rs + rp) / 2, abs=0.004)
    sin_t = np.hypot(s.wi[~reflected, 0], s.wi[~reflected, 1])
    assert np.allclose(sin_t, np.sin(np.radians(60.0)) / 1.5, atol=1e-5)
    assert s.specular.all()


@pytest.mark.parametrize("name", REFLECTIVE)
def test_reciprocity(name):
    rng = np.random.default_rng(11)
    bsdf = _bsdf(SMOOTH_FREE[name], 50_000)
    a, b = uniform_sphere(rng, 50_000), uniform_sphere(rng, 50_000)
    b[:, 2] = np.abs(b[:, 2]) * np.sign(a[:, 2])  # same side: reflection
    fab, fba = bsdf.evaluate(a, b), bsdf.evaluate(b, a)
    assert np.allclose(fab, fba, rtol=2e-3, atol=1e-6)
    assert fab.max() > 0


@pytest.mark.parametrize("name", sorted(SMOOTH_FREE))
def test_pdf_integrates_to_the_share_of_valid_samples_and_matches_their_histogram(name):
    """The pdf integrates over the sphere to the fraction of samples ``sample`` produces (1 for the
    cosine lobes; below 1 where visible-normal sampling reflects below the horizon), and a
    histogram of the samples over (cos theta, phi) cells matches the pdf integrated over each cell."""
    rng = np.random.default_rng(21)
    bsdf = _bsdf(SMOOTH_FREE[name], 400_000)
    wo = direction(40.0, 10.0, 400_000)
    z, phi = np.meshgrid((np.arange(800) + 0.5) / 800 * 2 - 1, (np.arange(500) + 0.5) / 500 * 2 * np.pi - np.pi)
    r = np.sqrt(1 - z.ravel() ** 2)  # midpoints of equal-area cells: a quadrature of the sphere
    probe = np.column_stack([r * np.cos(phi.ravel()), r * np.sin(phi.ravel()), z.ravel()]).astype(np.float32)
    mass = bsdf.pdf(wo, probe) * 4 * np.pi
    s = bsdf.sample(wo, rng.random((400_000, 2)).astype(np.float32), rng.random(400_000).astype(np.float32))
    assert mass.mean() == pytest.approx(s.valid.mean(), abs=0.01)

    def cell(w):
        z = np.clip(((w[:, 2] + 1) / 2 * 8).astype(int), 0, 7)
        phi = np.clip(((np.arctan2(w[:, 1], w[:, 0]) + np.pi) / (2 * np.pi) * 8).astype(int), 0, 7)
        return z * 8 + phi

    expected = np.bincount(cell(probe), weights=mass, minlength=64) / len(probe)
    observed = np.bincount(cell(s.wi[s.valid]), minlength=64) / len(s.wi)
    assert np.abs(observed - expected).max() < 0.006


@pytest.mark.parametrize("name", sorted(SMOOTH_FREE))
def test_sample_value_and_pdf_equal_evaluate_and_pdf(name):
    rng = np.random.default_rng(31)
    bsdf = _bsdf(SMOOTH_FREE[name], 20_000)
    wo = uniform_sphere(rng, 20_000)
    s = bsdf.sample(wo, rng.random((20_000, 2)).astype(np.float32), rng.random(20_000).astype(np.float32))
    v = s.valid
    assert v.mean() > 0.5 and not s.specular.any()
    assert np.allclose(s.value[v], bsdf.evaluate(wo, s.wi)[v], rtol=1e-3, atol=1e-6)
    assert np.allclose(s.pdf[v], bsdf.pdf(wo, s.wi)[v], rtol=1e-3, atol=1e-6)


def test_mix_with_a_mirror_has_pdf_mass_of_its_diffuse_share_and_flags_specular_samples():
    rng = np.random.default_rng(41)
    bsdf = _bsdf(Mix(Material(WHITE), Mirror(WHITE), 0.3), 200_000)
    wo = direction(30.0, 0.0, 200_000)
    assert (bsdf.pdf(wo, uniform_sphere(rng, 200_000)) * 4 * np.pi).mean() == pytest.approx(0.7, abs=0.01)
    s = bsdf.sample(wo, rng.random((200_000, 2)).astype(np.float32), rng.random(200_000).astype(np.float32))
    assert s.specular.mean() == pytest.approx(0.3, abs=0.005)
    assert np.allclose(s.wi[s.specular], [-np.sin(np.radians(30)), 0, np.cos(np.radians(30))], atol=1e-6)


def test_oren_nayar_with_sigma_zero_is_lambertian():
    rng = np.random.default_rng(51)
    albedo = rng.random((10_000, 3)).astype(np.float32)
    wo, wi = uniform_sphere(rng, 10_000), uniform_sphere(rng, 10_000)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])
    up = wo[:, 2] > 0
    assert np.allclose(OrenNayar(albedo, 0.0).evaluate(wo, wi)[up], Lambertian(albedo).evaluate(wo, wi)[up],
                       rtol=1e-6)
    assert isinstance(bsdf_for(Material(WHITE, sigma=0.0), ConstantHits(3)), Lambertian)


def test_oren_nayar_against_its_formula_at_hand_picked_angles():
    """sigma 20 degrees: A = 1 - s / (2 (s + 0.33)), B = 0.45 s / (s + 0.09), s = sigma^2 (rad^2);
    theta_i 60, theta_o 30, phi 0 apart: f = (A + B sin 60 tan 30) / pi."""
    s = np.radians(20.0) ** 2
    a, b = 1 - s / (2 * (s + 0.33)), 0.45 * s / (s + 0.09)
    f = OrenNayar(np.ones((1, 1), np.float32), 20.0).evaluate(direction(30.0), direction(60.0))
    assert f[0, 0] == pytest.approx((a + b * np.sin(np.radians(60)) * np.tan(np.radians(30))) / np.pi, rel=1e-5)
    # opposite azimuths: the cos(phi_i - phi_o) term is clamped to 0
    f = OrenNayar(np.ones((1, 1), np.float32), 20.0).evaluate(direction(30.0), direction(60.0, 180.0))
    assert f[0, 0] == pytest.approx(a / np.pi, rel=1e-5)


@pytest.mark.parametrize("material, has, only", [
    (Material(WHITE), False, False), (Material(WHITE, sigma=10.0), False, False), (Plastic(), False, False),
    (Plastic(roughness=0.0), True, False), (Conductor(roughness_u=0.0, roughness_v=0.0), True, True),
    (Mirror(), True, True), (Dielectric(), True, True), (Substrate(), False, False),
    (DiffuseTransmission(), False, False), (Mix(Mirror(), Dielectric()), True, True),
    (CoatedDiffuse(), True, False), (CoatedDiffuse(roughness=0.2), False, False),
    (Mix(Mirror(), Material()), True, False)])
def test_specular_flags(material, has, only):
    bsdf = _bsdf(material, 4)
    assert (bsdf.has_specular, bsdf.only_specular) == (has, only)
    s = bsdf.sample(direction(30.0, 0.0, 4), np.full((4, 2), 0.3, np.float32), np.float32([0.1, 0.4, 0.6, 0.9]))
    assert s.specular.any() <= has and (not only or s.specular.all())


@pytest.mark.parametrize("name", sorted(SMOOTH_FREE))
def test_spectral_rays_get_one_channel_and_the_same_white_furnace(name):
    """With one wavelength per ray a white material's BSDF is the same at every wavelength (the RGB
    basis sums to 1), so its one channel matches the RGB result."""
    from bsdf_helpers import SpectralHits

    rng = np.random.default_rng(61)
    n = 50_000
    hits = SpectralHits(rng.uniform(380, 780, n).astype(np.float32))
    material = SMOOTH_FREE[name]
    bsdf, rgb = bsdf_for(material, hits), _bsdf(material, n)
    wo, wi = direction(35.0, 10.0, n), uniform_sphere(rng, n)
    f, f_rgb = bsdf.evaluate(wo, wi), rgb.evaluate(wo, wi)
    assert f.shape == (n, 1)
    white = np.allclose(f_rgb, f_rgb[:, :1], rtol=1e-6)
    if white:
        assert np.allclose(f[:, 0], f_rgb[:, 0], rtol=1e-4, atol=1e-7)
    s = bsdf.sample(wo, rng.random((n, 2)).astype(np.float32), rng.random(n).astype(np.float32))
    assert s.value.shape == (n, 1) and np.all(np.isfinite(s.value))


def test_coat_internal_diffuse_reflectance_agrees_with_pbrt_v2s_fit():
    """The coat's internal diffuse reflectance 1 - (1 - F_ext) / eta^2 (F_ext integrated here)
    against pbrt-v2's polynomial fit ``Fdr`` (src/core/reflection.h, Egan and Hilgeman 1973), which
    it should match to the fit's accuracy (a few thousandths); eta = 1 reflects nothing."""
    from realistic.renderer.bsdf.coated_diffuse import hemispherical_reflectance

    for eta in (1.2, 1.33, 1.5, 2.0, 2.5):
        internal = 1 - (1 - hemispherical_reflectance(eta)) / eta ** 2
        fit = -1.4399 / eta ** 2 + 0.7099 / eta + 0.6681 + 0.0636 * eta
        assert internal == pytest.approx(fit, abs=0.006)
    assert hemispherical_reflectance(1.0) == pytest.approx(0.0, abs=1e-12)
