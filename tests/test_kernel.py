"""The OpenCL lens kernel (kernels/lens.cl on PoCL) against the float64 numpy reference.

Skips only when no OpenCL platform exists; CI installs PoCL through the package's dependencies.
"""

import dataclasses
from functools import lru_cache

import numpy as np
import pytest

from realistic import load_lens, rng
from realistic.camera import Camera, build_camera, film_points, generate_rays
from realistic.errors import UserError
from realistic.paraxial import film_distance_for_focus
from realistic.prescription import LensSystem
from realistic.raygen import ray_generator
from realistic.reference import trace_from_film
from realistic.sampling import rear_element_sampler

opencl_host = pytest.importorskip("realistic.opencl_host")

LENSES = ["dgauss", "wide", "fisheye", "telephoto", "dgauss100"]
SAMPLINGS = ["pupil", "rear"]
EDGE_MM = 1e-4


@pytest.fixture(scope="module", autouse=True)
def opencl_platform():
    try:
        opencl_host.context()
    except UserError as err:
        pytest.skip(f"no OpenCL platform: {err}")


def _world_from_camera() -> np.ndarray:
    """A rigid transform (rotation about a skew axis, translation in mm), so tolerances stay mm."""
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = 0.7
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    m[:3, 3] = [120.0, -35.0, 410.0]
    return m


@lru_cache(maxsize=None)
def _camera(name: str, sampling: str) -> Camera:
    """64 x 48 pixels x 33 samples (101,376) over a 43.27 mm film: centre to corners."""
    if sampling != "pupil":
        return dataclasses.replace(_camera(name, "pupil"), lens_sampling=sampling)
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    return build_camera(lens, film, 43.27, 64, 48, spp=33, world_from_camera=_world_from_camera(),
                        camera_origin_mm=film + lens.track_length_mm)


def _apertures_grown(lens: LensSystem, delta_mm: float) -> LensSystem:
    return dataclasses.replace(lens, aperture_mm=lens.aperture_mm + 2 * delta_mm)


def _edge_rays(camera: Camera, count: int, seed: int) -> np.ndarray:
    """Rays whose verdict changes when every clear aperture grows or shrinks by EDGE_MM (radius),
    and, for pupil sampling, rays whose film point lies within EDGE_MM of a radial interval edge
    (float32 and float64 may pick neighbouring exit-pupil boxes there)."""
    ids = np.arange(count)
    pixel, sample = ids // camera.spp, ids % camera.spp
    u_x, u_y, u_lens, v_lens = rng.stratified4(pixel, sample, seed)
    film_xy = film_points(camera, pixel, u_x, u_y)
    film = np.column_stack([film_xy, np.zeros(count)])
    if camera.lens_sampling == "pupil":
        sampler = camera.pupil
        radius = np.hypot(film_xy[:, 0], film_xy[:, 1])
        step = camera.pupil.film_radius_mm / len(camera.pupil.bounds)
        near_interval_edge = np.abs(radius / step - np.round(radius / step)) * step < EDGE_MM
    else:
        sampler = rear_element_sampler(camera.lens, camera.film_distance_mm)
        near_interval_edge = np.zeros(count, dtype=bool)
    targets, _ = sampler.sample(film_xy, u_lens.astype(np.float64), v_lens.astype(np.float64))
    verdicts = [trace_from_film(_apertures_grown(camera.lens, d), camera.film_distance_mm, film,
                                targets - film).passed for d in (-EDGE_MM, EDGE_MM)]
    return (verdicts[0] != verdicts[1]) | near_interval_edge


@pytest.mark.parametrize("sampling", SAMPLINGS)
@pytest.mark.parametrize("name", LENSES)
def test_kernel_matches_reference(name, sampling):
    _check_against_reference(_camera(name, sampling))


def _cross_mask(tmp_path) -> str:
    """A PNG stop mask: a plus sign, with a hole, to exercise the mask's lookup."""
    from PIL import Image

    pixels = np.zeros((64, 64), np.uint8)
    pixels[24:40, :] = pixels[:, 24:40] = 255
    pixels[30:34, 30:34] = 0
    path = tmp_path / "cross.png"
    Image.fromarray(pixels).save(path)
    return str(path)


@pytest.mark.parametrize("shape", ["hexagon", "curved", "mask"])
def test_kernel_matches_reference_with_shaped_stops(shape, tmp_path):
    from realistic.aperture import bladed_stop, mask_stop

    stops = {"hexagon": lambda: bladed_stop(6, 10.0), "curved": lambda: bladed_stop(7, 25.0, 0.4),
             "mask": lambda: mask_stop(_cross_mask(tmp_path))}
    base = _camera("dgauss", "pupil")
    lens = base.lens.with_stop_shape(stops[shape]())
    camera = build_camera(lens, base.film_distance_mm, 43.27, 64, 48, spp=33, world_from_camera=_world_from_camera(),
                          camera_origin_mm=base.film_distance_mm + lens.track_length_mm)
    _check_against_reference(camera)


def _check_against_reference(camera: Camera) -> None:
    count, seed = camera.sample_count, 11
    assert count >= 100_000
    kernel = ray_generator(camera, "opencl", seed)(0, count)
    ref = generate_rays(camera, 0, count, seed)
    np.testing.assert_array_equal(kernel.pixel, ref.pixel)

    k_pass = np.any(kernel.direction != 0, axis=1)
    r_pass = np.any(ref.direction != 0, axis=1)
    edge = _edge_rays(camera, count, seed)
    assert edge.mean() < 0.01, "the edge allowance must stay a small minority of the rays"
    disagree = (k_pass != r_pass) & ~edge
    assert not disagree.any(), f"{disagree.sum()} rays get a different pass/blocked verdict, e.g. ids " \
                               f"{np.flatnonzero(disagree)[:5]}"
    assert 0.02 < r_pass.mean(), "too few rays pass for the comparison to mean anything"

    blocked = ~k_pass
    assert np.all(kernel.weight[blocked] == 0) and np.all(kernel.origin[blocked] == 0)
    both = k_pass & r_pass
    np.testing.assert_allclose(kernel.direction[both], ref.direction[both], rtol=0, atol=1e-5)
    np.testing.assert_allclose(kernel.origin[both], ref.origin[both], rtol=0, atol=1e-3)
    weighted = both & (ref.weight > 0)
    np.testing.assert_allclose(kernel.weight[weighted], ref.weight[weighted], rtol=1e-4, atol=0)
    np.testing.assert_array_equal(kernel.weight[both & (ref.weight == 0)], 0)


@pytest.mark.parametrize("sampling", SAMPLINGS)
def test_batch_size_does_not_change_rays(sampling):
    camera = _camera("dgauss", sampling)
    kernel = opencl_host.LensKernel(camera)
    first, total = 1234, 70_000  # first is not a multiple of spp: launches start mid-pixel
    whole = kernel.generate(first, total, seed=5)
    sizes = [1, 255, 256, 257, 9_999, 31]
    sizes.append(total - sum(sizes))
    starts = first + np.concatenate([[0], np.cumsum(sizes)[:-1]])
    parts = [kernel.generate(int(s), n, seed=5) for s, n in zip(starts, sizes)]
    for field in ("origin", "direction", "weight", "pixel"):
        joined = np.concatenate([getattr(p, field) for p in parts])
        assert np.array_equal(getattr(whole, field), joined), field


def test_concurrent_launches_from_two_threads_keep_their_own_rays():
    from concurrent.futures import ThreadPoolExecutor

    kernel = opencl_host.LensKernel(_camera("dgauss", "pupil"))
    starts = [i * 20_000 for i in range(12)]
    serial = [kernel.generate(s, 20_000, seed=2) for s in starts]
    with ThreadPoolExecutor(max_workers=2) as pool:
        parallel = list(pool.map(lambda s: kernel.generate(s, 20_000, seed=2), starts))
    for a, b in zip(serial, parallel):
        assert np.array_equal(a.origin, b.origin) and np.array_equal(a.pixel, b.pixel)


def test_kernel_random_numbers_equal_numpy_bit_for_bit():
    camera = dataclasses.replace(_camera("dgauss", "pupil"), spp=7)
    kernel = opencl_host.LensKernel(camera)
    for first, seed in ((0, 0), ((2**31 - 5_000) * 7 + 3, 0xFFFFFFFF), (123_457, 2**32 + 99)):
        count = 20_000
        bits = kernel.sample_bits(first, count, seed)
        ids = np.arange(first, first + count, dtype=np.int64)
        pixel, sample = ids // 7, ids % 7
        with np.errstate(over="ignore"):
            expected = [sample.astype(np.uint32) * np.uint32(step)
                        + rng.hash_key(pixel, np.uint32(0xFFFFFFFF), dim, seed & 0xFFFFFFFF)
                        for dim, step in enumerate(rng.KRONECKER_R4)]
        np.testing.assert_array_equal(bits, np.stack(expected))
        floats = rng.stratified4(pixel, sample, seed & 0xFFFFFFFF)
        np.testing.assert_array_equal(rng.to_unit_float(bits), np.stack(floats))


def test_no_platform_is_one_clear_line(monkeypatch):
    monkeypatch.setattr(opencl_host.cl, "get_platforms", lambda: [])
    with pytest.raises(UserError) as err:
        opencl_host.context("no such device anywhere")
    message = str(err.value)
    assert "\n" not in message
    assert 'pip install "pyopencl[pocl]"' in message and "--backend numpy" in message


def test_device_choice_by_index_name_and_environment(monkeypatch):
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    default = opencl_host.context().devices[0]
    assert opencl_host.context("0:0").devices[0].int_ptr == opencl_host.context("0").devices[0].int_ptr
    assert opencl_host.context(default.name.strip()[:6]).devices[0].name == default.name
    with pytest.raises(UserError, match="--cl-device"):
        opencl_host.context("no such device anywhere")
    monkeypatch.setenv("PYOPENCL_CTX", "no such device anywhere")
    with pytest.raises(UserError, match="PYOPENCL_CTX"):
        opencl_host.context()


def test_program_is_built_once_per_camera_configuration():
    camera = _camera("wide", "pupil")
    first = opencl_host.LensKernel(camera)
    again = opencl_host.LensKernel(camera)
    assert again.program is first.program
    other = opencl_host.LensKernel(_camera("wide", "rear"))
    assert other.program is not first.program
