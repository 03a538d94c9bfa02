"""MIS direct lighting against light sampling alone: the same mean, on diffuse and glossy surfaces,
and specular paths through a mirror reach the lights."""

import math

import numpy as np
import pytest

from realistic.core.spectrum import rgb_response
from realistic.core.transforms import rotate, translate
from realistic.renderer.bsdf import BSDFSample, Lambertian, bsdf_for
from realistic.renderer.direct_lighting import DirectLighting
from realistic.renderer.integrators import make_integrator
from realistic.renderer.path import PathIntegrator
from realistic.scene.intersect import Intersector
from realistic.scene.lights import InfiniteLight, PointLight
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.shapes import quad

N = 60000


class Phong:
    """A normalised Phong lobe about the mirror direction, f = (e + 2) / 2 pi cos^e(alpha), sampled
    exactly (its pdf integrates to 1; directions below the surface are dropped)."""

    def __init__(self, exponent: float, count: int, channels: int):
        self.e, self.channels = exponent, channels

    def _cos_alpha(self, wo, wi):
        mirror = wo * np.float32([-1, -1, 1])
        return np.maximum(0.0, (mirror * wi).sum(axis=1))

    def evaluate(self, wo, wi):
        value = (self.e + 2) / (2 * math.pi) * self._cos_alpha(wo, wi) ** self.e * ((wi[:, 2] > 0) & (wo[:, 2] > 0))
        return np.repeat(value.astype(np.float32)[:, None], self.channels, axis=1)

    def pdf(self, wo, wi):
        return ((self.e + 1) / (2 * math.pi) * self._cos_alpha(wo, wi) ** self.e * (wi[:, 2] > 0)).astype(np.float32)

    def sample(self, wo, u, u_lobe):
        cos = u[:, 0] ** (1 / (self.e + 1))
        sin = np.sqrt(1 - cos * cos)
        phi = 2 * math.pi * u[:, 1]
        local = np.column_stack([sin * np.cos(phi), sin * np.sin(phi), cos])
        mirror = (wo * np.float32([-1, -1, 1])).astype(np.float64)
        # a frame about the mirror direction
        a = np.where(np.abs(mirror[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        s = np.cross(mirror, a)
        s /= np.linalg.norm(s, axis=1, keepdims=True)
        t = np.cross(mirror, s)
        wi = (s * local[:, :1] + t * local[:, 1:2] + mirror * local[:, 2:]).astype(np.float32)
        return BSDFSample(wi, self.evaluate(wo, wi), self.pdf(wo, wi), np.zeros(len(wi), bool), wi[:, 2] > 0)


class Mirror:
    """A perfect mirror of reflectance r: a specular sample only."""

    def __init__(self, r: float, count: int, channels: int):
        self.r, self.count, self.channels = r, count, channels

    def evaluate(self, wo, wi):
        return np.zeros((len(wo), self.channels), np.float32)

    def pdf(self, wo, wi):
        return np.zeros(len(wo), np.float32)

    def sample(self, wo, u, u_lobe):
        wi = (wo * np.float32([-1, -1, 1])).astype(np.float32)
        value = np.full((len(wo), self.channels), self.r, np.float32) / np.maximum(np.abs(wi[:, 2:]), 1e-8)
        return BSDFSample(wi, value, np.ones(len(wo), np.float32), np.ones(len(wo), bool), wo[:, 2] > 0)


def _factory(kind):
    def make(material, hits):
        channels = hits.colour((1.0, 1.0, 1.0)).shape[1]
        count = len(hits.colour((1.0, 1.0, 1.0)))
        return kind(count, channels)
    return make


def _lit_floor(light_radius: float) -> Scene:
    scene = Scene()
    scene.add(quad(20.0, 20.0), np.eye(4), Material((0.8, 0.8, 0.8)))
    scene.lights.append(AreaLight("disk", (light_radius, light_radius), (4.0, 4.0, 4.0),
                                  translate(0.5, 0.0, 1.5) @ rotate(180, (1, 0, 0))))
    return scene


def _camera_rays(n: int):
    rng = np.random.default_rng(8)
    target = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n), np.zeros(n)])
    origin = np.tile([-2.0, 0.0, 2.0], (n, 1))
    d = target - origin
    return origin.astype(np.float32), (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def _mean(integrator, spectral: bool = False):
    origin, direction = _camera_rays(N)
    wavelength = np.random.default_rng(9).uniform(400, 700, N) if spectral else None
    radiance, _ = integrator.radiance(origin, direction, np.arange(N), np.zeros(N, int), None, wavelength)
    value = radiance[:, 0]
    if spectral:  # radiance times the film's weight: the spectral value is their quotient (the largest weight's)
        response = rgb_response(wavelength)
        column = np.abs(response).argmax(axis=1)
        value = radiance[np.arange(N), column] / response[np.arange(N), column]
    return value.mean(), value.std() / math.sqrt(N)


@pytest.mark.parametrize("radius", [0.05, 1.0])
def test_mis_direct_agrees_with_light_sampling_on_diffuse_surfaces(radius):
    scene = _lit_floor(radius)
    light_only, e1 = _mean(DirectLighting(scene, Intersector(scene), 1, 1))
    mis, e2 = _mean(PathIntegrator(scene, Intersector(scene), 1, 2, 0.0, 5, "direct"))
    assert abs(light_only - mis) < 4 * math.hypot(e1, e2)


@pytest.mark.parametrize("exponent", [5.0, 200.0])
def test_mis_direct_agrees_with_light_sampling_on_glossy_surfaces(exponent):
    """Same mean; and on the sharp lobe MIS has the lower variance (the point of MIS)."""
    scene = _lit_floor(0.3)
    make = _factory(lambda n, c: Phong(exponent, n, c))
    light_only, e1 = _mean(PathIntegrator(scene, Intersector(scene), 1, 3, 0.0, 5, "direct", mis=False,
                                          bsdf_factory=make))
    mis, e2 = _mean(PathIntegrator(scene, Intersector(scene), 1, 4, 0.0, 5, "direct", bsdf_factory=make))
    assert abs(light_only - mis) < 4 * math.hypot(e1, e2)
    if exponent > 100:
        assert e2 < e1


def test_spectral_rays_agree_with_rgb_for_grey_scenes():
    scene = _lit_floor(0.5)
    rgb, e1 = _mean(PathIntegrator(scene, Intersector(scene), 1, 5, 0.0, 5, "direct"))
    spectral, e2 = _mean(PathIntegrator(scene, Intersector(scene), 1, 5, 0.0, 5, "direct"), spectral=True)
    assert abs(rgb - spectral) < 4 * math.hypot(e1, e2)


def test_mirror_paths_reach_a_point_light_never_and_the_sky_exactly():
    """A mirror of reflectance r under a constant sky of radiance 1 reads r (the specular path is
    followed); a point light is a delta no mirror path can hit, so it adds nothing there."""
    scene = Scene()
    scene.add(quad(20.0, 20.0), np.eye(4), Material())
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0)))
    scene.lights.append(PointLight((50.0, 50.0, 50.0), np.array([0.0, 0.0, 1.0])))
    integrator = PathIntegrator(scene, Intersector(scene), 1, 6, 0.0, 5, "direct",
                                bsdf_factory=_factory(lambda n, c: Mirror(0.9, n, c)))
    origin, direction = _camera_rays(2000)
    radiance, _ = integrator.radiance(origin, direction, np.arange(2000), np.zeros(2000, int))
    np.testing.assert_allclose(radiance, 0.9, rtol=1e-5)


def test_lambertian_area_lit_scenes_keep_the_direct_lighting_fast_path():
    scene = _lit_floor(0.5)
    assert type(make_integrator(scene, Intersector(scene))) is DirectLighting
    assert isinstance(bsdf_for(Material(), _NoHitsProbe()), Lambertian)
    scene.integrator = "path"
    assert isinstance(make_integrator(scene, Intersector(scene)), PathIntegrator)
    scene.integrator = "directlighting"
    scene.lights.append(PointLight((1.0, 1.0, 1.0), np.zeros(3)))
    assert isinstance(make_integrator(scene, Intersector(scene)), PathIntegrator)


class _NoHitsProbe:
    def colour(self, value):
        return np.zeros((0, 3), np.float32)

    def scalar(self, value):
        return np.zeros(0, np.float32)


@pytest.mark.parametrize("depth,expected", [(0, 0.0), (1, 0.0), (2, 0.9)])
def test_directlighting_maxdepth_limits_specular_bounces_as_pbrt(depth, expected):
    """pbrt-v3's DirectLightingIntegrator follows a specular bounce while depth + 1 < maxdepth, and
    lights the first hit whatever maxdepth is (a point light over a Lambertian floor at depth 0)."""
    scene = Scene()
    scene.add(quad(20.0, 20.0), np.eye(4), Material())
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0)))
    mirror = PathIntegrator(scene, Intersector(scene), 1, 6, 0.0, depth, "direct",
                            bsdf_factory=_factory(lambda n, c: Mirror(0.9, n, c)))
    origin, direction = _camera_rays(100)
    radiance, _ = mirror.radiance(origin, direction, np.arange(100), np.zeros(100, int))
    np.testing.assert_allclose(radiance, expected, rtol=1e-5)
    lit = Scene()
    lit.add(quad(20.0, 20.0), np.eye(4), Material((1.0, 1.0, 1.0)))
    lit.lights.append(PointLight((1.0, 1.0, 1.0), np.array([0.0, 0.0, 1.0])))
    floor = PathIntegrator(lit, Intersector(lit), 1, 6, 0.0, depth, "direct")
    radiance, _ = floor.radiance(np.float32([[0, 0, 2]]), np.float32([[0, 0, -1]]), np.zeros(1, int), np.zeros(1, int))
    np.testing.assert_allclose(radiance, 1 / math.pi, rtol=1e-5)
