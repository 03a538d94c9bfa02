"""The OpenCL shading kernel (kernels/shade.cl on PoCL) against DirectLighting's numpy path.

Per hit and light sample: the same live samples, bit-identical shadow-ray origins, and contributions
and shadow-ray vectors equal to float32 rounding (1e-5 relative); its random numbers are
``realistic.core.rng.light_uniforms``'s bit for bit. Per image: renders with backend "numpy" and "opencl"
through a thin lens (whose rays are the same for both backends) agree to 1e-5 relative. The
independent float64 reference (tests/test_shading_reference.py) checks the kernel's images too,
through its "opencl" cases. Skips only when no OpenCL platform exists.
"""

import dataclasses
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import vectoriser_remarks
from lane_helpers import in_lanes, point_major
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import jit, rng
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.core.jit import compiled
from realistic.core.spectrum import rgb_basis, rgb_response, wavelengths_nm
from realistic.core.transforms import look_at, rotate, scale, translate
from realistic.core.warp import concentric_disk
from realistic.optics.formats import load_lens
from realistic.renderer.backends import backend_for
from realistic.renderer.direct_lighting import DirectLighting, _visible_sums, visible_sums
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.intersect import Intersector
from realistic.scene.model import AreaLight, CheckerTexture, GridTexture, Material, Scene
from realistic.scene.packet_loop import PACKET
from realistic.scene.shapes import cone, sphere
from realistic.scene.staging import default_setup
from test_shading_reference import textured_scene

pytest.importorskip("realistic.camera.opencl_host")
pytestmark = pytest.mark.usefixtures("opencl_platform")

SEED = 11
F32 = np.float32


def busy_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """The shading reference's textured scene (an EWA image floor, a checkered smooth sphere, a gridded
    smooth cone, a plain quad; a one-sided disk and a two-sided quad light) plus a smooth sphere under
    a non-uniform scale (its normal matrix is not a rotation), a mirrored smooth cone, a two-sided
    disk light, a one-sided quad light and a dozen small bright quad lights (a longer light CDF to search)."""
    scene, eye, target = textured_scene()
    scene.add(sphere(0.5, 20), translate(0.6, 0.9, 0.8) @ scale(1.6, 0.7, 1.0) @ rotate(30, (0, 0, 1)),
              Material((0.6, 0.9, 0.4), CheckerTexture((0.9, 0.1, 0.2), (0.1, 0.8, 0.3), cells=9.0)))
    scene.add(cone(0.3, 0.8, 16), translate(-1.6, 0.0, 0.6) @ scale(-1.0, 1.0, 1.0) @ rotate(-90, (1, 0, 0)),
              Material((0.8, 0.5, 0.2), GridTexture((0.9, 0.9, 0.2), (0.1, 0.1, 0.5), cells=3.0, line_width=0.1)))
    scene.lights.append(AreaLight("disk", (0.4, 0.4), (8.0, 4.0, 2.0),
                                  translate(1.5, 1.8, 1.0) @ rotate(120, (1, 0, 0)), two_sided=True))
    scene.lights.append(AreaLight("quad", (0.6, 0.3), (2.0, 9.0, 3.0),
                                  translate(0.0, 2.5, 2.0) @ rotate(150, (1, 0, 0))))
    for i in range(12):
        scene.lights.append(AreaLight("quad", (0.1, 0.1), (100.0 + 40.0 * i,) * 3,
                                      translate(-2.5 + 0.4 * i, 2.2, -2.0) @ rotate(90 + 5 * i, (1, 0, 0)),
                                      two_sided=bool(i % 2)))
    return scene, eye, target


def rays_of(scene: Scene, eye: np.ndarray, target: np.ndarray, width: int = 40, height: int = 30, spp: int = 2):
    """A lens camera's camera rays (numpy reference) over the whole image: (origin, direction, pixel, sample)."""
    camera = LensCamera.looking_at(load_lens("dgauss"), eye, target, None, FULL_FRAME_DIAGONAL_MM, width, height, spp)
    rays = backend_for("numpy").ray_generator(camera, SEED)(SampleBlock(0, camera.sample_count, spp))
    alive = np.flatnonzero(rays.weight != 0)
    return (rays.origin[alive].astype(F32), rays.direction[alive].astype(F32), rays.pixel[alive],
            alive % spp, camera.pixel_spread_radians())


@pytest.fixture(scope="module", params=["default", "busy"])
def scene_rays(request):
    if request.param == "default":
        setup = default_setup()
        return setup.scene, rays_of(setup.scene, setup.eye, setup.target)
    scene, eye, target = busy_scene()
    return scene, rays_of(scene, eye, target)


@pytest.mark.parametrize("light_samples", [1, 3])
def test_per_hit_samples_match_the_numpy_path(scene_rays, light_samples):
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    numpy_path = DirectLighting(scene, intersector, light_samples, SEED, spread)
    kernel_path = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl")
    hits = intersector.closest(origin, direction)
    surface = np.flatnonzero((hits.geom >= 0) & (hits.geom < len(scene.instances)))
    point, shadow_origin, shading, ng, rho = numpy_path._surface_points(origin, direction, hits, surface)
    albedo = kernel_path._host_albedo(origin, direction, hits) if kernel_path._kernel.host_albedo.any() else None
    batch = kernel_path._kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal,
                                      pixel, sample, albedo, light_samples, SEED)
    assert batch.length.shape == (batch.stride // PACKET, light_samples, PACKET)
    assert batch.origin.shape == batch.vector.shape == batch.contribution.shape == batch.length.shape[:2] + (3, PACKET)
    length, origin, vector, contribution_rows = (point_major(a) for a in (batch.length, batch.origin, batch.vector,
                                                                         batch.contribution))
    live_rows = []
    for k in range(light_samples):
        contribution, to_light, live = numpy_path._light_sample(point, shadow_origin, shading, ng, rho,
                                                                pixel[surface], sample[surface], k, None)
        rows = surface[live] * light_samples + k  # point-major: a ray's light samples adjacent
        live_rows.append(rows)
        assert np.all(length[rows] == F32(1.0 - 1e-4))
        np.testing.assert_array_equal(origin[rows], shadow_origin[live])  # exactly: embree's geometry
        np.testing.assert_allclose(vector[rows], to_light, rtol=1e-5, atol=1e-6 * np.abs(to_light).max())
        np.testing.assert_allclose(contribution_rows[rows], contribution, rtol=1e-5,
                                   atol=1e-6 * np.abs(contribution).max())
    dead = np.setdiff1d(np.arange(len(length)), np.concatenate(live_rows))
    assert len(dead) and np.all(length[dead] == -1.0) and np.all(contribution_rows[dead] == 0.0)
    if scene.lights[0].shape == "disk" and len(scene.lights) > 2:  # the busy scene: every light is picked
        picked = set()
        for k in range(light_samples):
            u = rng.light_uniforms(pixel[surface], sample[surface], k, light_samples, SEED)[0]
            picked |= set(np.searchsorted(numpy_path._light_cdf, u, side="right").tolist())
        assert picked >= set(range(len(scene.lights)))


@pytest.mark.parametrize("light_samples", [1, 2])
def test_radiance_matches_the_numpy_path(scene_rays, light_samples):
    """The whole ``radiance``: emitters, misses and surfaces, shadow rays traced; the same ray count."""
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    expected, expected_rays = DirectLighting(scene, intersector, light_samples, SEED, spread).radiance(
        origin, direction, pixel, sample)
    got, shadow_rays = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl").radiance(
        origin, direction, pixel, sample)
    assert got.dtype == np.float32 and shadow_rays == expected_rays > 0
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


@pytest.mark.parametrize("spectral", [False, True])
def test_radiance_sums_the_point_major_rows_to_the_bit(scene_rays, spectral):
    """The kernel path's surface radiance is, bit for bit, a launch's shadow rays as point-major rows
    (hit i's k-th at row i per + k) traced by ``occluded`` and each ray's unblocked contributions
    added in k's order in float32, over the light samples: the lanes, their packet loop and
    ``visible_sums`` change no bit of it."""
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    light_samples = 3  # one launch
    integrator = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl")
    wavelength = wavelengths_of(len(origin)) if spectral else None
    got, shadow_rays = integrator.radiance(origin, direction, pixel, sample, wavelength_nm=wavelength)
    hits = intersector.closest(origin, direction)
    albedo = integrator._host_albedo(origin, direction, hits) if integrator._kernel.host_albedo.any() else None
    batch = integrator._kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal,
                                     pixel, sample, albedo, light_samples, SEED, wavelength_nm=wavelength)
    length, contribution = point_major(batch.length), point_major(batch.contribution)
    blocked = intersector.occluded(point_major(batch.origin), point_major(batch.vector), length)
    products = np.where(((length > 0) & ~blocked)[:, None], contribution, F32(0)).reshape(-1, light_samples,
                                                                                         contribution.shape[1])
    expected = products[:, 0].copy()
    for k in range(1, light_samples):
        expected += products[:, k]
    expected = expected[:len(origin)] / F32(light_samples)
    if spectral:
        expected = expected * batch.response[:len(origin)]
    surface = (hits.geom >= 0) & (hits.geom < len(scene.instances))
    assert shadow_rays == np.count_nonzero(length > 0) and np.any(expected[surface] > 0)
    assert np.array_equal(got[surface].view(np.uint32), expected[surface].view(np.uint32))


@pytest.mark.parametrize("light_samples, budget", [(3, 1), (6, None)])
def test_light_samples_in_several_launches_match(scene_rays, monkeypatch, light_samples, budget):
    """A pass whose light samples exceed a launch's shadow-ray budget (one row: one light sample
    per launch) or its unrolled count (MAX_LAUNCH_SAMPLES: 6 = 4 + 2, two program variants) runs
    them in groups."""
    from realistic.renderer import shade_kernel

    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    expected, expected_rays = DirectLighting(scene, intersector, light_samples, SEED, spread).radiance(
        origin, direction, pixel, sample)
    if budget is not None:
        monkeypatch.setattr(shade_kernel, "MAX_SHADOW_ROWS", budget)
    assert budget is not None or light_samples > shade_kernel.MAX_LAUNCH_SAMPLES  # so it runs in groups
    got, shadow_rays = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl").radiance(
        origin, direction, pixel, sample)
    assert shadow_rays == expected_rays
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


@pytest.mark.parametrize("per_ray, channels, fresh", [(1, 3, True), (4, 3, True), (2, 1, False), (8, 3, False)])
def test_visible_sums_add_each_rays_rows_in_order_to_the_bit(per_ray, channels, fresh):
    """``_visible_sums`` gives exactly numpy's sums of the old sample-major layout, each light
    sample's row times 1 or 0 added in order in float32 (``np.add.reduce`` over the samples from
    the first product, or added to earlier launches' sums), and counts the rows traced."""
    rng_ = np.random.default_rng(per_ray)
    n, stride = 37, 48
    contribution = (rng_.random((stride * per_ray, channels)) * 10.0 ** rng_.integers(-3, 4, (stride * per_ray, 1))
                    ).astype(np.float32)
    blocked = rng_.random(stride * per_ray) < 0.4
    length = np.where(rng_.random(stride * per_ray) < 0.7, F32(1 - 1e-4), F32(-1))
    length[n * per_ray:] = -1  # padding rows are dead, as the kernel writes them
    dead = length < 0  # as the kernel writes them (contribution 0) and embree answers them (blocked)
    contribution[dead], blocked[dead] = 0, True
    earlier = rng_.random((n, channels)).astype(np.float32)
    sample_major = contribution.reshape(stride, per_ray, channels).transpose(1, 0, 2)[:, :n]
    visible = np.logical_not(blocked).astype(np.float32).reshape(stride, per_ray).T[:, :n, None]
    products = sample_major * visible
    expected = np.add.reduce(products, axis=0) if fresh else earlier.copy()
    if not fresh:
        for row in products:
            expected += row
    out = np.full((n, channels), np.nan, np.float32) if fresh else earlier.copy()
    traced = compiled(_visible_sums)(in_lanes(contribution, per_ray), in_lanes(blocked, per_ray),
                                     in_lanes(length, per_ray), n, fresh, out)
    assert np.array_equal(out.view(np.uint32), expected.view(np.uint32))
    assert traced == np.count_nonzero(length > 0)


@pytest.mark.parametrize("channels", [3, 1])
def test_visible_sums_read_nothing_of_dead_rows(channels, monkeypatch):
    """A dead row (length -1) adds 0 whatever its contribution and embree's answer hold: the sums
    equal those of the rows as the kernel writes them (contribution 0, blocked), where NaN there
    would otherwise reach the sums; both forms (compiled and numpy) agree."""
    rng_ = np.random.default_rng(channels)
    n, per_ray = 29, 4
    contribution = rng_.random((n * per_ray, channels)).astype(np.float32)
    blocked = rng_.random(n * per_ray) < 0.4
    length = np.where(rng_.random(n * per_ray) < 0.5, F32(1 - 1e-4), F32(-1))
    length[:per_ray] = -1  # a ray with every row dead
    dead = length < 0
    as_written = contribution.copy(), blocked.copy()
    as_written[0][dead], as_written[1][dead] = 0, True
    contribution[dead], blocked[dead] = np.nan, False
    expected = np.empty((n, channels), np.float32)
    assert compiled(_visible_sums)(in_lanes(as_written[0], per_ray), in_lanes(as_written[1], per_ray),
                                   in_lanes(length, per_ray), n, True, expected) == np.count_nonzero(~dead)
    assert np.all(np.isfinite(expected)) and np.all(expected[0] == 0)
    for numba_loops in (True, False):
        monkeypatch.setattr(jit, "_use_compiled", [numba_loops])
        got = np.full((n, channels), np.nan, np.float32)
        assert visible_sums(in_lanes(contribution, per_ray), in_lanes(blocked, per_ray), in_lanes(length, per_ray), n,
                            True, got) == np.count_nonzero(~dead)
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))


#: Contributions drawn from these (signed zeros, negatives, a tiny and a huge value): ``_visible_sums``
#: must keep each product's sign of zero and the order of its additions for the bits to agree.
CONTRIBUTIONS = np.array([0.0, -0.0, 1.0, -1.0, 0.1, -2.5, 3e-39, 1e30, 7.25, 0.3], np.float32)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1), groups=st.integers(1, 4), per=st.integers(1, 8),
       channels=st.sampled_from([1, 3]), fresh=st.booleans(), live=st.sampled_from(["some", "none", "all"]),
       shadowed=st.sampled_from(["some", "none", "all"]), short=st.integers(0, PACKET - 1))
def test_visible_sums_compiled_equal_numpys_to_the_bit(seed, groups, per, channels, fresh, live, shadowed, short,
                                                       monkeypatch):
    """The compiled loop (vectorised over lanes) gives numpy's form's sums and count bit for bit over
    drawn launches: dead rays (length -1, 0 or NaN, their contribution and answer anything: NaN
    here), every ray or none dead or blocked, n not a multiple of 16 (the padding lanes' lengths
    live or NaN, their contributions NaN), 1 to 8 rays per hit, RGB and one channel, fresh sums and
    sums added to earlier ones (signed zeros among them)."""
    rng_ = np.random.default_rng(seed)
    n = max(1, groups * PACKET - short)
    lanes = (groups, per, PACKET)
    length = np.where(rng_.random(lanes) < 0.5, F32(1 - 1e-4), F32(-1)) if live == "some" else np.full(
        lanes, F32(1 - 1e-4) if live == "all" else F32(-1))
    dead = length < 0
    length[dead] = rng_.choice(np.array([-1, 0, np.nan], np.float32), np.count_nonzero(dead))
    blocked = rng_.random(lanes) < 0.5 if shadowed == "some" else np.full(lanes, shadowed == "all")
    contribution = rng_.choice(CONTRIBUTIONS, (groups, per, channels, PACKET))
    contribution[np.broadcast_to(dead[:, :, None], contribution.shape)] = np.nan
    padding = np.zeros(groups * PACKET, bool)
    padding[n:] = True
    padding = padding.reshape(groups, 1, PACKET)
    length[np.broadcast_to(padding, lanes)] = np.where(rng_.random(lanes) < 0.5, F32(1 - 1e-4), F32(np.nan))[
        np.broadcast_to(padding, lanes)]
    contribution[np.broadcast_to(padding[:, :, None], contribution.shape)] = np.nan
    earlier = rng_.choice(CONTRIBUTIONS, (n, channels))
    sums = []
    for numba_loops in (True, False):
        monkeypatch.setattr(jit, "_use_compiled", [numba_loops])
        out = np.full((n, channels), np.nan, np.float32) if fresh else earlier.copy()
        sums.append((visible_sums(contribution, blocked, length, n, fresh, out), out))
    (traced, got), (expected_traced, expected) = sums
    assert traced == expected_traced == np.count_nonzero(length.transpose(0, 2, 1).reshape(-1, per)[:n] > 0)
    assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))


def test_visible_sums_vectorise():
    """The loop, compiled for the types a launch passes it (``compile_shading_loops``'s), adds and
    multiplies packed rows of lanes (AVX's ymm or zmm registers), not one float at a time. Compiled
    here uncached: numba shows no assembly of a loop loaded from its cache."""
    numba = pytest.importorskip("numba")
    llvmlite = pytest.importorskip("llvmlite.binding")
    if not llvmlite.get_host_cpu_features().get("avx", False):
        pytest.skip("this CPU has no AVX")
    loop = numba.njit(nogil=True)(_visible_sums)
    loop(np.empty((0, 1, 3, PACKET), np.float32), np.empty((0, 1, PACKET), np.bool_),
         np.empty((0, 1, PACKET), np.float32), 0, True, np.empty((0, 3), np.float32))
    assembly = loop.inspect_asm(loop.signatures[0])
    for operation in ("vmulps", "vaddps"):
        assert re.search(rf"\b{operation}\b[^\n]*%[yz]mm", assembly), operation


def test_a_launch_makes_at_most_max_launch_samples(scene_rays):
    from realistic.renderer.shade_kernel import MAX_LAUNCH_SAMPLES

    scene, (origin, direction, pixel, sample, spread) = scene_rays
    integrator = DirectLighting(scene, Intersector(scene), 1, SEED, spread, backend="opencl")
    hits = integrator.intersector.closest(origin, direction)
    with pytest.raises(ValueError, match=f"1 to {MAX_LAUNCH_SAMPLES} light samples"):
        integrator._kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal,
                                 pixel, sample, None, MAX_LAUNCH_SAMPLES + 1, SEED)


def test_outputs_keep_their_values_as_a_threads_block_grows(scene_rays):
    """A thread's outputs share one block (one read per launch): launches that outgrow it (more rays,
    then spectral rays, whose per-ray rows had a placeholder) and a small one after them give the
    arrays of a fresh kernel's first launch, each output in its own memory."""
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    hits = intersector.closest(origin, direction)
    wavelength = wavelengths_of(len(origin))

    def launch(kernel, n: int, spectral: bool) -> list[np.ndarray]:
        albedo = np.full((n, 3), 0.5, F32) if kernel.host_albedo.any() else None
        batch = kernel.shade(origin[:n], direction[:n], hits.t[:n], hits.u[:n], hits.v[:n], hits.prim[:n],
                             hits.geom[:n], hits.normal[:n], pixel[:n], sample[:n], albedo, 2, SEED,
                             wavelength_nm=wavelength[:n] if spectral else None)
        arrays = [batch.origin, batch.vector, batch.length, batch.contribution]
        arrays += [batch.response, batch.basis] if spectral else []
        assert not any(np.shares_memory(a, b) for i, a in enumerate(arrays) for b in arrays[i + 1:])
        return [a.copy() for a in arrays]

    def fresh():
        return DirectLighting(scene, intersector, 2, SEED, spread, backend="opencl")._kernel

    kernel = fresh()
    small = 300
    for n, spectral in ((small, False), (len(origin), False), (len(origin), True), (small, False)):
        for got, expected in zip(launch(kernel, n, spectral), launch(fresh(), n, spectral)):
            np.testing.assert_array_equal(got, expected)


def test_no_rays():
    setup = default_setup()
    integrator = DirectLighting(setup.scene, Intersector(setup.scene), 2, backend="opencl")
    empty = np.zeros((0, 3), F32)
    got, shadow_rays = integrator.radiance(empty, empty, np.zeros(0, np.int32), np.zeros(0, np.int64))
    assert got.shape == (0, 3) and shadow_rays == 0


def wavelengths_of(count: int) -> np.ndarray:
    """Spectral rays' wavelengths: the density's inverse CDF at scattered numbers, and both ends."""
    u = np.random.default_rng(5).random(count)
    u[:2] = (0.0, 1.0 - 2**-24)
    return wavelengths_nm(u)


@pytest.mark.parametrize("light_samples", [1, 3])
def test_spectral_per_hit_samples_match_the_numpy_path(scene_rays, light_samples):
    """Spectral rays (one wavelength each): the same live samples and shadow rays as RGB rays,
    contributions equal to the numpy path's spectral values (albedo and radiance through
    ``spectral_value`` at each ray's ``rgb_basis`` row), and each ray's film weight and basis row
    equal to ``rgb_response`` and ``rgb_basis`` (the kernel's come from its interpolated SPECTRUM table)."""
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    intersector = Intersector(scene)
    numpy_path = DirectLighting(scene, intersector, light_samples, SEED, spread)
    kernel_path = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl")
    wavelength = wavelengths_of(len(origin))
    basis = rgb_basis(wavelength)
    hits = intersector.closest(origin, direction)
    surface = np.flatnonzero((hits.geom >= 0) & (hits.geom < len(scene.instances)))
    point, shadow_origin, shading, ng, rho = numpy_path._surface_points(origin, direction, hits, surface, basis)
    albedo = kernel_path._host_albedo(origin, direction, hits) if kernel_path._kernel.host_albedo.any() else None
    batch = kernel_path._kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal,
                                      pixel, sample, albedo, light_samples, SEED, wavelength_nm=wavelength)
    for k in range(light_samples):
        contribution, to_light, live = numpy_path._light_sample(point, shadow_origin, shading, ng, rho,
                                                                pixel[surface], sample[surface], k, basis[surface])
        rows = surface[live] * light_samples + k  # point-major: a ray's light samples adjacent
        assert np.all(point_major(batch.length)[rows] == F32(1.0 - 1e-4))
        np.testing.assert_array_equal(point_major(batch.origin)[rows], shadow_origin[live])
        assert contribution.shape == point_major(batch.contribution)[rows].shape == (len(live), 1)
        np.testing.assert_allclose(point_major(batch.contribution)[rows], contribution, rtol=1e-5,
                                   atol=1e-6 * np.abs(contribution).max())
    expected = rgb_response(wavelength)
    # within the table's interpolation error (5e-6 of the largest weight) and float32 rounding
    np.testing.assert_allclose(batch.response[:len(origin)], expected, rtol=1e-5, atol=6e-6 * np.abs(expected).max())
    np.testing.assert_allclose(batch.basis[:len(origin)], basis, rtol=0, atol=1e-6)  # the table's 3e-7, and rounding


@pytest.mark.parametrize("light_samples", [1, 2])
def test_spectral_radiance_matches_the_numpy_path(scene_rays, light_samples):
    """The whole spectral ``radiance`` (emitters, a coloured background, surfaces): the kernel's
    against the numpy path's, and the same shadow rays traced."""
    scene, (origin, direction, pixel, sample, spread) = scene_rays
    scene = dataclasses.replace(scene, background=(0.3, 0.1, 0.05))
    wavelength = wavelengths_of(len(origin))
    intersector = Intersector(scene)
    expected, expected_rays = DirectLighting(scene, intersector, light_samples, SEED, spread).radiance(
        origin, direction, pixel, sample, wavelength_nm=wavelength)
    integrator = DirectLighting(scene, intersector, light_samples, SEED, spread, backend="opencl")
    assert integrator._kernel is not None
    got, shadow_rays = integrator.radiance(origin, direction, pixel, sample, wavelength_nm=wavelength)
    assert got.dtype == np.float32 and shadow_rays == expected_rays > 0
    hits = intersector.closest(origin, direction)
    assert (hits.geom < 0).any()  # misses see the background
    assert len(scene.lights) < 3 or (hits.geom >= len(scene.instances)).any()  # the busy scene's emitters
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


def test_spectral_renders_match_the_numpy_shading(monkeypatch):
    """A dispersive lens camera's render (three wavelengths a sample, two light samples) shaded by the
    kernel and by numpy (the kernel left unbuilt), both with the lens kernel's camera rays: the
    images differ by the shading alone."""
    setup = default_setup()
    camera = dataclasses.replace(
        LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, FULL_FRAME_DIAGONAL_MM, 40, 30, 4),
        spectral=True, wavelengths_per_sample=3)
    job = RenderJob(setup.scene, (camera,), "opencl", SEED, light_samples=2, pass_samples=700)
    kernel_image = render(job, ThreadPasses(threads=2))[0].image
    monkeypatch.setattr(DirectLighting, "_build_kernel", lambda self: None)
    numpy_image = render(job, ThreadPasses(threads=2))[0].image
    assert numpy_image.max() > 0 and np.ptp(numpy_image[..., 0] - numpy_image[..., 2]) > 0  # colour, not grey
    np.testing.assert_allclose(kernel_image, numpy_image, rtol=1e-5, atol=1e-5 * numpy_image.max())


def test_random_numbers_are_rng_light_uniforms_bit_for_bit():
    setup = default_setup()
    kernel = DirectLighting(setup.scene, Intersector(setup.scene), backend="opencl")._kernel
    generator = np.random.default_rng(3)
    pixel = np.concatenate([generator.integers(0, 2**31 - 1, 5000), [0, 1, 2**31 - 1]]).astype(np.int32)
    sample = np.concatenate([generator.integers(0, 2**32 - 1, 5000), [0, 2**32 - 1, 7]]).astype(np.int64)
    for seed, light_samples in ((0, 3), (5, 1), (2**32 - 1, 4)):
        got = kernel.light_uniforms(pixel, sample, light_samples, seed)
        for k in range(light_samples):
            expected = rng.light_uniforms(pixel, sample, k, light_samples, seed)
            for j in range(3):
                np.testing.assert_array_equal(got[3 * k + j], expected[j])


def test_disk_points_match_the_concentric_map():
    setup = default_setup()
    kernel = DirectLighting(setup.scene, Intersector(setup.scene), backend="opencl")._kernel
    grid = (np.arange(257) / 256).astype(F32)
    u1, u2 = (a.ravel() for a in np.meshgrid(np.minimum(grid, F32(1 - 2**-24)), grid))
    x, y = kernel.disk_points(u1, u2)
    ex, ey = concentric_disk(u1, u2)
    np.testing.assert_allclose(x, ex, rtol=0, atol=3e-7)
    np.testing.assert_allclose(y, ey, rtol=0, atol=3e-7)


@pytest.mark.parametrize("name", ["bench", "busy"])
def test_renders_match_between_backends(name):
    """A small bench render (a mesh on the grid floor under the disk light) and the busy scene with
    two light samples: through a thin lens both backends trace the same camera rays, so the images
    differ by the shading alone."""
    if name == "bench":
        setup = default_setup()
        scene, eye, target, light_samples = setup.scene, setup.eye, setup.target, 1
    else:
        (scene, eye, target), light_samples = busy_scene(), 2
    distance = float(np.linalg.norm(np.asarray(target) - np.asarray(eye)))
    camera = ThinLensCamera(40.0, 0.02, distance, 48, 32, 4, look_at(eye, target))
    jobs = {backend: RenderJob(scene, (camera,), backend, SEED, light_samples=light_samples, pass_samples=1500)
            for backend in ("numpy", "opencl")}
    images = {backend: render(job, ThreadPasses(threads=2))[0].image for backend, job in jobs.items()}
    assert images["numpy"].max() > 0
    np.testing.assert_allclose(images["opencl"], images["numpy"], rtol=1e-5, atol=1e-5 * images["numpy"].max())


def test_the_kernel_vectorises(tmp_path):
    """PoCL's work-group vectoriser widens ``shade``, RGB and spectral (every table read would
    otherwise be scalar: about 4x slower). Its remarks need a fresh build, so this runs in a process of its own."""

    script = (
        "import numpy as np\n"
        "from realistic.renderer.direct_lighting import DirectLighting\n"
        "from realistic.scene.intersect import Intersector\n"
        "from test_shade_kernel import busy_scene\n"
        "scene = busy_scene()[0]\n"
        "integrator = DirectLighting(scene, Intersector(scene), 2, backend='opencl')\n"
        "ray = np.array([[0.0, 1.0, 4.0]], np.float32)\n"
        "direction = np.array([[0.0, -0.2, -1.0]], np.float32) / np.float32(1.0198039)\n"
        "for wavelength in (None, np.array([550.0], np.float32)):  # the RGB and the spectral variant\n"
        "    integrator.radiance(ray, direction, np.zeros(1, np.int32), np.zeros(1, np.int64),\n"
        "                        wavelength_nm=wavelength)\n")
    remarks = vectoriser_remarks(script, pocl_cache=tmp_path)
    assert "loop not vectorized" not in remarks and "vectorized loop" in remarks
    # 8 work items at a time: its outputs in lanes make every store a vector store, where rows of
    # (N, 3) made them scatters and it took 4
    widths = re.findall(r"vectorized loop \(vectorization width: (\d+)", remarks)
    assert widths and min(int(w) for w in widths) >= 8, widths
