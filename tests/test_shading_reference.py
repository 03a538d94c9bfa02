"""The integrator against a plain, slow reference of its shading maths (one ray at a time, float64).

The reference is written from the formulas in ``realistic.renderer.direct_lighting``'s docstring, not
from its code: barycentric interpolation of normals and uvs, the light picked by power, the
area-sampling estimator, the pixel footprint solved as a least-squares 2 x 2 system, and pbrt's EWA
filter transcribed scalar (``test_textures._ewa_reference``). Only the shadow rays and the texture
coordinates are built in float32 exactly as the integrator documents them (hit point o + t d, offset
along the geometric normal; uvs interpolated from float32 corners): shadow rays are geometry that
embree tests in float32, and pbrt's EWA weights are a table lookup that rounding can move by a step,
so a visibility or table bin flipped by rounding is not a shading error. Everything is compared to
1e-5 of the image's scale, per ray and per pixel.
"""

import math

import numpy as np
import pytest

from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.core.transforms import rotate, translate
from realistic.core.warp import concentric_disk
from realistic.optics.formats import load_lens
from realistic.renderer.backends import backend_for
from realistic.renderer.direct_lighting import SHADOW_OFFSET, DirectLighting
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, CheckerTexture, GridTexture, ImageTexture, Material, Scene
from realistic.scene.shapes import cone, quad, sphere
from realistic.scene.staging import default_setup
from test_textures import _ewa_reference

SEED, SPP, LIGHT_SAMPLES = 7, 2, 2
F32 = np.float32


def textured_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """An EWA-filtered image floor seen at a grazing angle, a checkered smooth sphere, a gridded cone,
    a plain cube-ish quad, a one-sided disk light and a two-sided quad light; (scene, eye, target)."""
    image = np.random.default_rng(5).random((32, 64, 3)).astype(np.float32)
    scene = Scene(background=(0.1, 0.2, 0.3))
    floor = ImageTexture(image, scale=(6.0, 4.0), v_origin="top", filter="ewa", max_anisotropy=8.0,
                         offset=(0.25, 0.5))
    scene.add(quad(20.0, 20.0), rotate(-90, (1, 0, 0)), Material((0.9, 0.8, 0.7), floor))
    scene.add(sphere(0.6, 24), translate(-0.8, 0.6, 0.0), Material((0.7, 0.7, 0.7), CheckerTexture(cells=6.0)))
    scene.add(cone(0.5, 1.2, 24), translate(0.9, 0.0, -0.3) @ rotate(-90, (1, 0, 0)),
              Material((1.0, 1.0, 1.0), GridTexture(cells=5.0, line_width=0.2)))
    scene.add(quad(0.8, 0.8), translate(0.1, 0.5, -1.2) @ rotate(20, (0, 1, 0)), Material((0.3, 0.6, 0.9)))
    scene.lights.append(AreaLight("disk", (0.8, 0.8), (30.0, 28.0, 25.0),
                                  translate(0.3, 3.0, 0.5) @ rotate(90, (1, 0, 0))))
    scene.lights.append(AreaLight("quad", (1.0, 0.5), (5.0, 6.0, 9.0),
                                  translate(-2.0, 1.5, -1.0) @ rotate(60, (0, 1, 0)), two_sided=True))
    return scene, np.array([0.0, 1.0, 4.0]), np.array([0.0, 0.4, 0.0])


def _texture(texture, uv: np.ndarray, footprint: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """One point's texture colour, from each texture's definition."""
    if isinstance(texture, GridTexture):
        f = (uv * texture.cells) % 1.0
        on_line = np.any((f < texture.line_width / 2) | (f > 1 - texture.line_width / 2))
        return np.array(texture.line if on_line else texture.base)
    if isinstance(texture, CheckerTexture):
        parity = (math.floor(uv[0] * texture.cells) + math.floor(uv[1] * texture.cells)) % 2
        return np.array(texture.even if parity == 0 else texture.odd)
    assert isinstance(texture, ImageTexture) and texture.wrap == "repeat" and texture.filter == "ewa"
    repeats = np.array(texture.scale)
    flip = np.array([1.0, -1.0]) if texture.v_origin == "bottom" else np.array([1.0, 1.0])
    st = (uv * repeats + texture.offset) * flip + (0.0, 1.0 if texture.v_origin == "bottom" else 0.0)
    axes = [axis * repeats * flip for axis in footprint]
    return _ewa_reference(texture.mipmap.levels, st, axes[0], axes[1], texture.max_anisotropy)


def _footprint(d: np.ndarray, n: np.ndarray, distance: float, spread: float, edges: np.ndarray,
               duv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """uv axes of one hit's pixel cone: across the ray and along its projection (stretched by 1/cos)."""
    cosine = d @ n
    along = d - cosine * n
    if along @ along < 1e-20:
        helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        along = np.cross(n, helper)
    along /= np.linalg.norm(along)
    across = np.cross(n, along)
    width = distance * spread
    axes = []
    for w in (across * width, along * width / max(abs(cosine), 1e-3)):
        coefficients = np.linalg.lstsq(edges.T, w, rcond=None)[0]  # w = alpha e1 + beta e2
        axes.append(coefficients @ duv)
    return axes[0], axes[1]


def reference_radiance(scene: Scene, intersector: Intersector, origin: np.ndarray, direction: np.ndarray,
                       pixel: np.ndarray, sample: np.ndarray, spread: float) -> np.ndarray:
    """RGB radiance (N, 3) float64 along float32 rays, one ray at a time."""
    hits = intersector.closest(origin, direction)
    frames = [light.frame() for light in scene.lights]
    power = np.array([light.area() * (2 if light.two_sided else 1) * np.mean(light.radiance) for light in scene.lights])
    cdf = np.cumsum(power / power.sum())
    u = [rng.light_uniforms(pixel, sample, k, LIGHT_SAMPLES, SEED) for k in range(LIGHT_SAMPLES)]  # pick, u1, u2
    out = np.zeros((len(origin), 3))
    shadow = []  # (ray, shadow origin, shadow vector, contribution if unoccluded)
    for i in range(len(origin)):
        geom, d = int(hits.geom[i]), direction[i].astype(np.float64)
        if geom < 0:
            out[i] = scene.background
            continue
        if geom >= len(scene.instances):
            light = scene.lights[geom - len(scene.instances)]
            normal = frames[geom - len(scene.instances)][3]
            out[i] = light.radiance if (d @ normal < 0 or light.two_sided) else 0.0
            continue
        instance = scene.instances[geom]
        mesh = scene.meshes[instance.mesh]
        face = mesh.faces[hits.prim[i]]
        bary = np.array([1.0 - hits.u[i] - hits.v[i], hits.u[i], hits.v[i]], np.float64)
        # float32 geometry, as embree and the integrator's shadow rays
        point = origin[i] + hits.t[i] * direction[i]
        ng = hits.normal[i].astype(F32)
        ng = ng / np.sqrt(ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2])
        if ng @ direction[i] > 0:
            ng = -ng
        eps = F32(SHADOW_OFFSET) * (np.abs(point).max() + F32(1e-2 * intersector.extent))
        shadow_origin = point + ng * eps
        # float64 shading
        linear = instance.transform[:3, :3]
        ng64 = ng.astype(np.float64)
        normal = ng64
        if mesh.normals is not None and np.ptp(mesh.normals, axis=0).max() > 1e-6:
            n = np.linalg.inv(linear).T @ (bary @ mesh.normals[face])
            n /= np.linalg.norm(n)
            n = n if n @ ng64 >= 0 else -n
            normal = n
        material = instance.material
        rho = np.array(material.diffuse, np.float64)
        if material.texture is not None:
            # float32 texture coordinates, as the integrator stores them: EWA's weights come from a
            # 128-entry table, so rounding that moves a texel across a bin moves its weight by a step
            corner_uv = mesh.uv[face].astype(F32)
            b = np.array([F32(1.0) - hits.u[i] - hits.v[i], hits.u[i], hits.v[i]], F32)
            uv = (corner_uv[0] * b[0] + corner_uv[1] * b[1] + corner_uv[2] * b[2]).astype(np.float64)
            footprint = None
            if isinstance(material.texture, ImageTexture):
                corners = mesh.vertices[face] @ linear.T
                edges = np.array([corners[1] - corners[0], corners[2] - corners[0]])
                duv = np.array([mesh.uv[face[1]] - mesh.uv[face[0]], mesh.uv[face[2]] - mesh.uv[face[0]]])
                footprint = _footprint(d, ng64, float(hits.t[i]), spread, edges, duv)
            rho = rho * _texture(material.texture, uv, footprint)
        for k in range(LIGHT_SAMPLES):
            j = min(int(np.searchsorted(cdf, u[k][0][i], side="right")), len(cdf) - 1)
            light, (centre, a, b, light_normal) = scene.lights[j], frames[j]
            u1, u2 = u[k][1][i], u[k][2][i]
            if light.shape == "disk":
                x, y = (float(v[0]) for v in concentric_disk(np.array([u1]), np.array([u2])))
            else:
                x, y = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
            q = centre.astype(F32) + a.astype(F32) * F32(x) + b.astype(F32) * F32(y)
            to_light = q.astype(np.float64) - point.astype(np.float64)
            dist2 = to_light @ to_light
            wi = to_light / math.sqrt(dist2)
            cos_p, cos_q = wi @ normal, -(wi @ light_normal)
            cos_q = abs(cos_q) if light.two_sided else cos_q
            if cos_p > 0 and cos_q > 0 and wi @ ng64 > 0:
                value = (rho / math.pi * np.array(light.radiance) * cos_p * cos_q / dist2
                         * light.area() / (power[j] / power.sum()))
                shadow.append((i, shadow_origin, q - shadow_origin, value / LIGHT_SAMPLES))
    if shadow:
        rows = np.array([s[0] for s in shadow])
        blocked = intersector.occluded(np.array([s[1] for s in shadow], F32), np.array([s[2] for s in shadow], F32),
                                    np.full(len(shadow), 1.0 - 1e-4, F32))
        values = np.array([s[3] for s in shadow])
        np.add.at(out, rows[~blocked], values[~blocked])
    return out


def camera_for(name: str) -> tuple[Scene, LensCamera]:
    lens = load_lens("dgauss")
    if name == "default":
        setup = default_setup()
        return setup.scene, LensCamera.looking_at(lens, setup.eye, setup.target, None, FULL_FRAME_DIAGONAL_MM,
                                                  24, 16, SPP)
    scene, eye, target = textured_scene()
    return scene, LensCamera.looking_at(lens, eye, target, None, FULL_FRAME_DIAGONAL_MM, 24, 16, SPP)


@pytest.fixture(scope="module", params=[(scene, backend) for scene in ("default", "textured")
                                        for backend in ("numpy", "opencl")], ids=lambda p: "-".join(p))
def case(request):
    """(name, scene, camera, backend, rays, live rows, reference radiance of the live rays, reference image)."""
    name, backend = request.param
    scene, camera = camera_for(name)
    rays = backend_for(backend).ray_generator(camera, SEED)(SampleBlock(0, camera.sample_count, camera.spp))
    assert rays.wavelength_nm is None  # an RGB render: the reference has no spectral path
    alive = np.flatnonzero(rays.weight != 0)
    origin, direction = rays.origin[alive].astype(F32), rays.direction[alive].astype(F32)
    # a render filters textures over 1/sqrt(spp) of a pixel, at least pbrt-v4's 1/8 (the runner's footprint)
    spread = camera.pixel_spread_radians() * max(scene.differential_floor, 1 / math.sqrt(camera.spp))
    expected = reference_radiance(scene, Intersector(scene), origin, direction, rays.pixel[alive], alive % SPP, spread)
    image = np.zeros((camera.width * camera.height, 3))
    np.add.at(image, rays.pixel[alive], expected * rays.weight[alive, None])
    return name, scene, camera, backend, rays, alive, expected, image.reshape(camera.height, camera.width, 3) / SPP


def test_the_scenes_exercise_every_branch(case):
    name, scene, _, _, rays, alive, expected, _ = case
    hits = Intersector(scene).closest(rays.origin[alive].astype(F32), rays.direction[alive].astype(F32))
    assert np.any(hits.geom < 0)  # the sky
    assert name == "default" or np.any(hits.geom >= len(scene.instances))  # the textured scene sees its lights
    surfaces = hits.geom[(hits.geom >= 0) & (hits.geom < len(scene.instances))]
    lit = expected.max(axis=1) > 2 * max(scene.background)
    assert len(np.unique(surfaces)) >= 2 and np.count_nonzero(lit) > len(alive) // 4, np.count_nonzero(lit)


def test_radiance_per_ray_matches_the_reference(case):
    _, scene, camera, _, rays, alive, expected, _ = case
    spread = camera.pixel_spread_radians() * max(scene.differential_floor, 1 / math.sqrt(camera.spp))
    integrator = DirectLighting(scene, Intersector(scene), LIGHT_SAMPLES, SEED, spread)
    got, shadow_rays = integrator.radiance(rays.origin[alive].astype(F32), rays.direction[alive].astype(F32),
                                           rays.pixel[alive], alive % SPP)
    assert got.dtype == np.float32 and shadow_rays > 0
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


@pytest.mark.parametrize("morton", [False, True])
def test_rendered_image_matches_the_reference(case, morton):
    _, scene, camera, backend, _, _, _, image = case
    job = RenderJob(scene, (camera,), backend, SEED, light_samples=LIGHT_SAMPLES, pass_samples=200, morton=morton)
    got = render(job, ThreadPasses(threads=2))[0].image
    np.testing.assert_allclose(got, image, rtol=1e-5, atol=1e-5 * np.abs(image).max())

