"""Measured BRDFs on the direct-lighting fast path: ``kernels/shade.cl``'s MEASURED variant against
``DirectLighting``'s numpy reference of the same estimator (pbrt-v2 ``directlighting``'s light
sample plus cosine-weighted BSDF sample per light sample, power heuristic), with the same random
numbers: per shadow-ray row (same live rows, bit-identical origins, contributions and vectors to
float32 rounding and the kernel's polynomial atan2), per image, in a furnace (a constant BRDF under a
disk light: the closed-form radiance), and against the MIS path integrator's images within their
own noise. The measured files are written here (pbrt-v2's ``.brdf`` format), so nothing needs
../shared. Skips only when no OpenCL platform exists.
"""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import vectoriser_remarks
from lane_helpers import point_major
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import rng
from realistic.core.transforms import look_at, rotate, translate
from realistic.renderer.bsdf.measured import irregular_table
from realistic.renderer.direct_lighting import DirectLighting, bfloat16
from realistic.renderer.integrators import make_integrator
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.path import PathIntegrator
from realistic.renderer.shade_kernel import table_records
from realistic.scene.intersect import Intersector
from realistic.scene.materials import Measured
from realistic.scene.measured import load_measured
from realistic.scene.model import AreaLight, Material, Scene
from realistic.scene.packet_loop import PACKET
from realistic.scene.shapes import quad, sphere
from test_shade_kernel import SEED, busy_scene, rays_of

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

F32 = np.float32


def write_brdf(path: Path, values, count: int = 300, seed: int = 1) -> Path:
    """A pbrt-v2 irregular isotropic ``.brdf`` file: 3 wavelengths, ``count`` records at random
    angles, each record's values ``values(theta_i, phi_i, theta_o, phi_o)`` (3 per record)."""
    generator = np.random.default_rng(seed)
    theta_i, theta_o = generator.uniform(0, np.pi / 2, count), generator.uniform(0, np.pi / 2, count)
    phi_i, phi_o = generator.uniform(0, 2 * np.pi, count), generator.uniform(0, 2 * np.pi, count)
    rows = np.column_stack([theta_i, phi_i, theta_o, phi_o, values(theta_i, phi_i, theta_o, phi_o)])
    path.write_text("3 450 550 650\n" + "\n".join(" ".join(f"{v:.7f}" for v in row) for row in rows) + "\n")
    return path


def _glossy(theta_i, phi_i, theta_o, phi_o):
    """Values that vary with every BRDFRemap coordinate, differently per wavelength."""
    return np.column_stack([0.05 + 0.3 * np.cos(theta_i) * np.cos(theta_o),
                            0.1 + 0.08 * np.cos(phi_i - phi_o) * np.sin(theta_i) * np.sin(theta_o),
                            0.2 + 0.1 * np.cos(theta_i - theta_o) ** 8])


@pytest.fixture(scope="module")
def glossy(tmp_path_factory) -> Measured:
    path = write_brdf(tmp_path_factory.mktemp("brdf") / "glossy.brdf", _glossy)
    return Measured(str(path))


@pytest.fixture(scope="module")
def flat(tmp_path_factory) -> Measured:
    """A constant measured BRDF: every sample's spectrum flat at 0.2."""
    path = write_brdf(tmp_path_factory.mktemp("brdf") / "flat.brdf", lambda *a: np.full((len(a[0]), 3), 0.2),
                      count=40)
    return Measured(str(path))


def with_materials(scene: Scene, materials: dict[int, object]) -> Scene:
    """``scene`` with the instances ``materials`` names given those materials."""
    instances = [dataclasses.replace(inst, material=materials.get(i, inst.material))
                 for i, inst in enumerate(scene.instances)]
    return dataclasses.replace(scene, instances=instances, lights=list(scene.lights))


@pytest.fixture(scope="module")
def measured_rays(glossy):
    """The shade kernel tests' busy scene with a sphere, the cone and the quad measured, and its rays."""
    scene, eye, target = busy_scene()
    scene = with_materials(scene, {1: glossy, 3: glossy, 4: glossy})
    return scene, rays_of(scene, eye, target)


@pytest.mark.parametrize("light_samples", [1, 3])
def test_per_row_samples_match_the_numpy_path(measured_rays, light_samples):
    """Every light sample's row and its BSDF sample's row (the next row) against the numpy
    reference's ``_light_sample`` and ``_bsdf_sample``."""
    scene, (origin, direction, pixel, sample, spread) = measured_rays
    intersector = Intersector(scene)
    numpy_path = DirectLighting(scene, intersector, light_samples, SEED, spread)
    kernel_path = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl")
    assert kernel_path._measured_kernel.rows_per_sample == 2 and kernel_path._kernel.rows_per_sample == 1
    hits = intersector.closest(origin, direction)
    surface = np.flatnonzero((hits.geom >= 0) & (hits.geom < len(scene.instances)))
    point, shadow_origin, shading, ng, rho = numpy_path._surface_points(origin, direction, hits, surface)
    measured = numpy_path._measured_hits(direction, hits, surface, shading)
    albedo = kernel_path._host_albedo(origin, direction, hits)
    batch = kernel_path._measured_kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom,
                                               hits.normal, pixel, sample, albedo, light_samples, SEED)
    assert batch.length.shape == (batch.stride // PACKET, 2 * light_samples, PACKET)
    length, origin_rows, vector_rows, contribution_rows = (
        point_major(a) for a in (batch.length, batch.origin, batch.vector, batch.contribution))
    live_rows, bsdf_live = [], 0
    for k in range(light_samples):
        light = numpy_path._light_sample(point, shadow_origin, shading, ng, rho, pixel[surface], sample[surface], k,
                                         None, measured)
        paired = numpy_path._bsdf_sample(point, shadow_origin, ng, measured, pixel[surface], sample[surface], k)
        bsdf_live += len(paired[2])
        for row, (contribution, vector, live) in ((2 * k, light), (2 * k + 1, paired)):
            rows = surface[live] * (2 * light_samples) + row  # point-major: a ray's rows adjacent
            live_rows.append(rows)
            assert np.all(length[rows] == F32(1.0 - 1e-4))
            np.testing.assert_array_equal(origin_rows[rows], shadow_origin[live])
            np.testing.assert_allclose(vector_rows[rows], vector, rtol=1e-4, atol=1e-5 * np.abs(vector).max())
            np.testing.assert_allclose(contribution_rows[rows], contribution, rtol=2e-4,
                                       atol=2e-5 * np.abs(contribution).max())
    dead = np.setdiff1d(np.arange(len(length)), np.concatenate(live_rows))
    assert np.all(length[dead] == -1.0) and np.all(contribution_rows[dead] == 0.0)
    assert bsdf_live >= 5  # BSDF samples that meet a light (the lights are small)


@pytest.mark.parametrize("light_samples", [1, 6])
def test_radiance_matches_the_numpy_path(measured_rays, light_samples, monkeypatch):
    """The whole ``radiance`` (6 light samples: two launches of up to 4), and the shadow-ray count."""
    scene, (origin, direction, pixel, sample, spread) = measured_rays
    intersector = Intersector(scene)
    expected, expected_rays = DirectLighting(scene, intersector, light_samples, SEED, spread).radiance(
        origin, direction, pixel, sample)
    got, shadow_rays = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl").radiance(
        origin, direction, pixel, sample)
    assert shadow_rays == expected_rays > 0
    np.testing.assert_allclose(got, expected, rtol=2e-4, atol=2e-5 * np.abs(expected).max())


def test_the_kernels_table_is_bfloat16_in_records_of_two_nodes():
    """``bfloat16`` rounds to nearest (relative error at most 2^-8) onto floats whose low 16 bits
    are 0, and ``table_records`` holds node (x, y, z)'s RGB and node (x + 1, y, z)'s in the upper
    halves of its words as ``shade.cl`` unpacks them."""
    values = np.random.default_rng(3).random((4, 3, 2, 3)).astype(F32) * 10
    rounded = bfloat16(values)
    assert np.all(rounded.view(np.uint32) & 0xFFFF == 0)
    assert np.all(np.abs(rounded - values) <= values * 2.0**-8)
    records = table_records(rounded)
    low, high = (records << 16).view(F32), (records & 0xFFFF0000).view(F32)
    here = np.stack([low[..., 0], high[..., 0], low[..., 1]], axis=-1)
    there = np.stack([high[..., 1], low[..., 2], high[..., 2]], axis=-1)
    np.testing.assert_array_equal(here, rounded)
    np.testing.assert_array_equal(there[:-1], rounded[1:])
    assert np.all(there[-1] == 0)


def test_bsdf_numbers_are_a_stratified_net_independent_of_the_light_points():
    """``rng.light_bsdf_uniforms``: a pixel's 64 BSDF numbers put one point in each of 8 x 8 cells
    (a (0, 6, 2)-net, as the light points), and they are not the light points."""
    points = np.concatenate([np.column_stack(rng.light_bsdf_uniforms(np.full(1, 77), np.full(1, s), k, 4, SEED))
                             for s in range(16) for k in range(4)])
    cells = (np.floor(points[:, 0] * 8) * 8 + np.floor(points[:, 1] * 8)).astype(int)
    assert len(set(cells.tolist())) == 64
    light = np.concatenate([np.column_stack(rng.light_uniforms(np.full(1, 77), np.full(1, s), k, 4, SEED)[1:])
                            for s in range(16) for k in range(4)])
    assert not np.any(np.all(np.abs(light - points) < 1e-6, axis=1))


def test_a_constant_brdf_under_a_disk_light_gives_the_closed_form(flat):
    """Furnace: a floor of constant f under a one-sided disk light of radius R at height h reflects,
    at the point below the disk's centre, f L pi R^2 / (R^2 + h^2) (the disk's projected solid
    angle): the MIS estimate's mean over many camera samples matches it within 3 standard errors,
    and so do the light samples' and the BSDF samples' shares of it taken alone (each weighted)."""
    radius, height, radiance = 1.5, 2.0, 3.0
    scene = Scene(background=(0.0, 0.0, 0.0))
    scene.add(quad(50.0, 50.0), rotate(-90, (1, 0, 0)), flat)
    scene.lights.append(AreaLight("disk", (radius, radius), (radiance,) * 3,
                                  translate(0.0, height, 0.0) @ rotate(90, (1, 0, 0))))
    n = 4000
    origin = np.tile(np.array([[0.0, 1.0, 0.0]], F32), (n, 1))
    direction = np.tile(np.array([[0.0, -1.0, 0.0]], F32), (n, 1))
    pixel, sample = np.arange(n) % 97, np.arange(n) // 97
    integrator = DirectLighting(scene, Intersector(scene), 4, SEED, backend="opencl")
    out, _ = integrator.radiance(origin, direction, pixel, sample)
    f = bfloat16(irregular_table(load_measured(flat.path)))[0, 0, 127]  # every read node: the constant's RGB
    assert np.ptp(f) > 0.01  # pbrt-v2's spectrum-to-RGB of a flat spectrum is not grey
    expected = f * radiance * np.pi * radius**2 / (radius**2 + height**2)
    error = out.std(axis=0) / np.sqrt(n)
    np.testing.assert_array_less(np.abs(out.mean(axis=0) - expected), 3 * error + 1e-4 * expected)


def test_a_measured_materials_albedo_aov_is_its_directional_albedo(flat):
    """``first_hits`` (the albedo AOV) on the fast path: a constant f reflects f pi of a uniform sky,
    whatever the view."""
    scene = Scene(background=(0.0, 0.0, 0.0))
    scene.add(quad(50.0, 50.0), rotate(-90, (1, 0, 0)), flat)
    scene.lights.append(AreaLight("disk", (1.0, 1.0), (1.0,) * 3, translate(0.0, 2.0, 0.0) @ rotate(90, (1, 0, 0))))
    direction = np.array([[0.0, -1.0, 0.0], [0.6, -0.8, 0.0], [0.0, -0.6, 0.8]], F32)
    origin = np.zeros_like(direction) + F32(1.0)
    integrator = DirectLighting(scene, Intersector(scene), 1, SEED, backend="opencl")
    first = integrator.first_hits(origin, direction, integrator.intersector.closest(origin, direction))
    f = bfloat16(irregular_table(load_measured(flat.path)))[0, 0, 127]
    np.testing.assert_allclose(first.albedo, np.broadcast_to(f * np.pi, (3, 3)), rtol=1e-5)


def test_the_measured_variant_vectorises(tmp_path, glossy):
    """PoCL's work-group vectoriser widens the MEASURED variant of ``shade`` (no SLP-packed pairs), 8
    work items at a time (its outputs in lanes: vector stores)."""
    script = (
        "import sys, dataclasses\n"
        "import numpy as np\n"
        "from realistic.renderer.direct_lighting import DirectLighting\n"
        "from realistic.scene.intersect import Intersector\n"
        "from realistic.scene.materials import Measured\n"
        "from test_shade_kernel import busy_scene\n"
        "scene = busy_scene()[0]\n"
        "scene.instances[1] = dataclasses.replace(scene.instances[1], material=Measured(sys.argv[1]))\n"
        "integrator = DirectLighting(scene, Intersector(scene), 2, backend='opencl')\n"
        "assert integrator._measured_kernel.rows_per_sample == 2\n"
        "ray = np.array([[0.0, 1.0, 4.0]], np.float32)\n"
        "direction = np.array([[0.0, -0.2, -1.0]], np.float32) / np.float32(1.0198039)\n"
        "integrator.radiance(ray, direction, np.zeros(1, np.int32), np.zeros(1, np.int64))\n")
    remarks = vectoriser_remarks(script, glossy.path, pocl_cache=tmp_path)
    assert "loop not vectorized" not in remarks and "vectorized loop" in remarks
    widths = re.findall(r"vectorized loop \(vectorization width: (\d+)", remarks)  # 4 with (N, 3) rows
    assert widths and min(int(w) for w in widths) >= 8, widths


def _measured_scene(glossy: Measured) -> tuple[Scene, np.ndarray, np.ndarray]:
    scene = Scene(background=(0.0, 0.0, 0.0))
    scene.add(quad(8.0, 8.0), rotate(-90, (1, 0, 0)), Material((0.5, 0.5, 0.5)))
    scene.add(sphere(0.6, 32), translate(0.0, 0.6, 0.0), glossy)
    scene.lights.append(AreaLight("disk", (1.0, 1.0), (6.0, 6.0, 6.0),
                                  translate(0.5, 3.0, 0.5) @ rotate(90, (1, 0, 0))))
    scene.lights.append(AreaLight("quad", (1.0, 0.6), (2.0, 3.0, 4.0),
                                  translate(-2.0, 1.5, 0.0) @ rotate(-70, (0, 1, 0)), two_sided=True))
    return scene, np.array([0.0, 1.2, 3.5]), np.array([0.0, 0.5, 0.0])


def test_routing(glossy, tmp_path):
    """directlighting + area lights + Lambertian or irregular measured materials + the opencl
    backend + RGB rays: the fast path; the numpy backend, spectral rays, a MERL table or the path
    integrator: ``PathIntegrator``, as before."""
    scene, _, _ = _measured_scene(glossy)
    intersector = Intersector(scene)
    assert type(make_integrator(scene, intersector, 2, backend="opencl")) is DirectLighting
    assert type(make_integrator(scene, intersector, 2, backend="numpy")) is PathIntegrator
    assert type(make_integrator(scene, intersector, 2, backend="opencl", spectral=True)) is PathIntegrator
    assert type(make_integrator(dataclasses.replace(scene, integrator="path"), intersector, 2,
                                backend="opencl")) is PathIntegrator
    merl = tmp_path / "grey.binary"
    dims = np.array([90, 90, 180], "<i4").tobytes()
    merl.write_bytes(dims + np.full(3 * 90 * 90 * 180, 0.1, "<f8").tobytes())
    merl_scene = with_materials(scene, {1: Measured(str(merl))})
    assert type(make_integrator(merl_scene, Intersector(merl_scene), 2, backend="opencl")) is PathIntegrator


def test_images_agree_with_the_path_integrator_within_its_noise(glossy):
    """The fast path's image against the MIS path integrator's ("direct", the route measured
    materials took before), which is not the code under test: the fast path's difference from the
    path integrator's seed-1 image is no larger than that of the path integrator's seed-2 image from
    it (per-pixel RMS, with a 30 % margin), and the image means agree within 4 standard errors of
    that noise."""
    scene, eye, target = _measured_scene(glossy)
    camera = ThinLensCamera(40.0, 0.0, 3.5, 32, 24, 16, look_at(eye, target))

    def image(backend: str, seed: int) -> np.ndarray:
        job = RenderJob(scene, (camera,), backend, seed, light_samples=8)
        return render(job, ThreadPasses(threads=2))[0].image

    fast = image("opencl", 1)  # measured + opencl: the kernel's MIS
    old_a, old_b = image("numpy", 1), image("numpy", 2)  # PathIntegrator, "direct"
    noise = np.sqrt(np.mean((old_a - old_b) ** 2))
    assert noise > 0 and np.sqrt(np.mean((fast - old_a) ** 2)) < 1.3 * noise
    pixels = fast.shape[0] * fast.shape[1]
    assert np.abs(fast.mean() - old_a.mean()) < 4 * noise / np.sqrt(pixels)
