"""The OpenCL lens kernel (kernels/lens.cl on PoCL) against the float64 numpy reference.

Skips only when no OpenCL platform exists; CI installs PoCL through the package's dependencies.
"""

import dataclasses

import numpy as np
import pytest

from kernel_reference import assert_kernel_matches, camera_for_lens, reference_camera
from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng
from realistic.core.pixel_filter import PixelFilter
from realistic.errors import UserError
from realistic.optics.paraxial import film_distance_for_focus
from realistic.renderer.backends import backend_for

opencl_host = pytest.importorskip("realistic.camera.opencl_host")
opencl = pytest.importorskip("realistic.device.opencl")
Device = opencl.Device

LENSES = ["dgauss", "wide", "fisheye", "telephoto", "dgauss100"]
SAMPLINGS = ["pupil", "rear"]

pytestmark = pytest.mark.usefixtures("opencl_platform")


@pytest.mark.parametrize("sampling", SAMPLINGS)
@pytest.mark.parametrize("name", LENSES)
def test_kernel_matches_reference(name, sampling):
    _check_against_reference(reference_camera(name, sampling))


@pytest.mark.parametrize("pixel_filter", [PixelFilter("triangle", 2.0, 1.5), PixelFilter("gaussian", 1.5, 1.5, 2.0),
                                          PixelFilter("mitchell", 2.0, 2.0), PixelFilter("sinc", 3.0, 4.0)],
                         ids=lambda f: f.name)
def test_kernel_matches_reference_with_pixel_filters(pixel_filter):
    """The film offsets drawn from a filter (exact tent, tables with signed weights) agree."""
    camera = dataclasses.replace(reference_camera("dgauss", "pupil"), pixel_filter=pixel_filter)
    _check_against_reference(camera)


def test_default_box_film_points_are_plain_jitter_bit_for_bit():
    """The 0.5-pixel box maps u to the in-pixel offset u exactly: today's film points, unchanged."""
    camera = reference_camera("dgauss", "pupil")
    pixel = np.arange(50_000) // camera.spp
    u_x, u_y, _, _ = rng.stratified4(pixel, np.arange(50_000) % camera.spp, 3)
    film_xy, weight = camera.filtered_film_points(pixel, u_x, u_y)
    assert np.array_equal(film_xy, camera.film_points(pixel, u_x, u_y)) and np.all(weight == 1.0)


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
    from realistic.optics.stop_shape import bladed_stop, mask_stop

    stops = {"hexagon": lambda: bladed_stop(6, 10.0), "curved": lambda: bladed_stop(7, 25.0, 0.4),
             "mask": lambda: mask_stop(_cross_mask(tmp_path))}
    _check_against_reference(camera_for_lens(load_lens("dgauss").with_stop_shape(stops[shape]())))


def _check_against_reference(camera: LensCamera) -> None:
    count, seed = camera.sample_count, 11
    assert count >= 100_000
    kernel = backend_for("opencl").ray_generator(camera, seed)(SampleBlock(0, count, camera.spp))
    assert_kernel_matches(kernel, camera.generate_rays(SampleBlock(0, count, camera.spp), seed), camera, seed)


@pytest.mark.parametrize("sampling", SAMPLINGS)
def test_batch_size_does_not_change_rays(sampling):
    camera = reference_camera("dgauss", sampling)
    kernel = opencl_host.LensKernel(camera)
    first, total = 1234, 70_000  # first is not a multiple of spp: launches start mid-pixel
    whole = kernel.generate(SampleBlock(first, total, camera.spp), seed=5)
    sizes = [1, 255, 256, 257, 9_999, 31]
    sizes.append(total - sum(sizes))
    starts = first + np.concatenate([[0], np.cumsum(sizes)[:-1]])
    parts = [kernel.generate(SampleBlock(int(s), n, camera.spp), seed=5) for s, n in zip(starts, sizes)]
    for field in ("origin", "direction", "weight", "pixel"):
        joined = np.concatenate([getattr(p, field) for p in parts])
        assert np.array_equal(getattr(whole, field), joined), field


def test_concurrent_launches_from_two_threads_keep_their_own_rays():
    from concurrent.futures import ThreadPoolExecutor

    kernel = opencl_host.LensKernel(reference_camera("dgauss", "pupil"))
    starts = [i * 20_000 for i in range(12)]
    serial = [kernel.generate(SampleBlock(s, 20_000, kernel.camera.spp), seed=2) for s in starts]
    with ThreadPoolExecutor(max_workers=2) as pool:
        parallel = list(pool.map(lambda s: kernel.generate(SampleBlock(s, 20_000, kernel.camera.spp), seed=2), starts))
    for a, b in zip(serial, parallel):
        assert np.array_equal(a.origin, b.origin) and np.array_equal(a.pixel, b.pixel)


@pytest.mark.parametrize("sampling", SAMPLINGS)
def test_sliced_launches_match_the_reference_and_the_whole_pixel_launch(sampling):
    """A pass of the progressive plan is a slice of each pixel's samples: the kernel's rays of
    samples [3, 8) of a run of pixels (and a launch starting mid-run) match the reference, and are
    bit for bit those of the same (pixel, sample) pairs in a launch of whole pixels."""
    camera = reference_camera("dgauss", sampling)
    assert camera.spp >= 8
    kernel = opencl_host.LensKernel(camera)
    first_pixel, pixels = 777, 20_000
    whole = kernel.generate(SampleBlock.of_pixels(first_pixel, pixels, 0, camera.spp), seed=4)
    for block in (SampleBlock.of_pixels(first_pixel, pixels, 3, 5),
                  SampleBlock(first_pixel * 5 + 2, pixels * 5 - 9, 5, 3)):
        rays = kernel.generate(block, seed=4)
        assert_kernel_matches(rays, camera.generate_rays(block, 4), camera, 4, block=block)
        pixel, sample = block.ids()
        assert np.array_equal(rays.pixel, pixel)
        at = (pixel - first_pixel) * camera.spp + sample  # the same pairs in the whole-pixel launch
        for field in ("origin", "direction", "weight"):
            assert np.array_equal(getattr(rays, field), getattr(whole, field)[at]), field


def test_kernel_refuses_blocks_past_its_32_bit_indices():
    kernel = opencl_host.LensKernel(reference_camera("dgauss", "pupil"))
    with pytest.raises(ValueError, match="32-bit"):
        kernel.generate(SampleBlock.of_pixels(2**31 - 10, 64, 0, 1))
    with pytest.raises(ValueError, match="32-bit"):
        kernel.generate(SampleBlock(0, 64, 4, 2**32 - 2))


def test_kernel_random_numbers_equal_numpy_bit_for_bit():
    camera = dataclasses.replace(reference_camera("dgauss", "pupil"), spp=7)
    kernel = opencl_host.LensKernel(camera)
    for first, seed in ((0, 0), ((2**31 - 5_000) * 7 + 3, 0xFFFFFFFF), (123_457, 2**32 + 99)):
        count = 20_000
        bits = kernel.sample_bits(SampleBlock(first, count, camera.spp), seed)
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
    monkeypatch.setattr(opencl.cl, "get_platforms", lambda: [])
    with pytest.raises(UserError) as err:
        Device.for_spec("no such device anywhere")
    message = str(err.value)
    assert "\n" not in message
    assert 'pip install "pyopencl[pocl]"' in message and "--backend numpy" in message


def test_device_choice_by_index_name_and_environment(monkeypatch):
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    default = Device.for_spec().devices[0]
    assert Device.for_spec("0:0").devices[0].int_ptr == Device.for_spec("0").devices[0].int_ptr
    assert Device.for_spec(default.name.strip()[:6]).devices[0].name == default.name
    assert Device.for_spec("0:0") is Device.for_spec("0:0")  # one per process and spec
    with pytest.raises(UserError, match="--cl-device"):
        Device.for_spec("no such device anywhere")
    monkeypatch.setenv("PYOPENCL_CTX", "no such device anywhere")
    with pytest.raises(UserError, match="PYOPENCL_CTX"):
        Device.for_spec()


def test_program_is_built_once_per_camera_configuration():
    camera = reference_camera("wide", "pupil")
    first = opencl_host.LensKernel(camera)
    again = opencl_host.LensKernel(camera)
    assert again.program is first.program
    other = opencl_host.LensKernel(reference_camera("wide", "rear"))
    assert other.program is not first.program


def _telephoto_rays():
    camera = reference_camera("telephoto", "pupil")
    opencl.build_program.cache_clear()  # the in-process cache would hand back the same program
    kernel = opencl_host.LensKernel(camera, None, opencl_host.RAYS_PER_ITEM)  # given: no timing builds another program
    return kernel.generate(SampleBlock(0, 30_000, camera.spp), seed=3)


def _assert_same_rays(a, b):
    for field in ("origin", "direction", "weight", "pixel"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_a_program_from_cached_binaries_makes_the_rays_a_source_build_makes(monkeypatch, tmp_path):
    """A program's first build leaves a mark in the disk cache, its second stores the binaries as
    the process exits, and the third loads them: the rays are bit for bit those of a build from
    source with the cache off."""
    from realistic.core import disk_cache

    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))
    first = _telephoto_rays()
    (entry,) = tmp_path.glob("opencl-program-*.npz")
    assert list(disk_cache.load_arrays(entry.stem)) == ["built"]
    second = _telephoto_rays()
    assert list(disk_cache.load_arrays(entry.stem)) == ["built"]  # not yet: at exit
    opencl.store_built_binaries()
    assert list(disk_cache.load_arrays(entry.stem)) == ["device0"]
    loaded = _telephoto_rays()
    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    uncached = _telephoto_rays()
    opencl.build_program.cache_clear()
    for rays in (second, loaded, uncached):
        _assert_same_rays(rays, first)


BUILD = ("import glob, os\n"
         "from realistic.device.opencl import Device\n"
         "from realistic.core import disk_cache\n"
         "source = '__kernel void twice(__global float *a) { a[get_global_id(0)] *= 2.0f; }'\n"
         "Device.for_spec().build_program(source, 'twice.cl')\n"
         "(entry,) = glob.glob(os.path.join(os.environ['REALISTIC_CACHE_DIR'], 'opencl-program-*.npz'))\n"
         "print(sorted(disk_cache.load_arrays(os.path.basename(entry)[:-4])))\n")


def test_a_second_build_stores_its_binaries_as_the_process_exits(tmp_path):
    """A program's first build from source leaves a mark; the second, in another process, stores
    the binaries when that process exits (``store_built_binaries``), not while it runs."""
    from conftest import run_fresh
    from realistic.core import disk_cache

    def build() -> str:
        return run_fresh(BUILD, timeout=300, REALISTIC_CACHE_DIR=str(tmp_path)).stdout.strip()

    assert build() == "['built']"
    assert build() == "['built']"  # during the second process
    (entry,) = tmp_path.glob("opencl-program-*.npz")
    with np.load(entry) as stored:
        assert sorted(stored.files) == sorted(["device0", disk_cache.KEY_FIELD, disk_cache.DIGEST_FIELD])  # after it


def test_a_corrupt_or_foreign_cache_entry_is_rebuilt_from_source(monkeypatch, tmp_path):
    from realistic.core import disk_cache

    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))
    built = _telephoto_rays()
    (entry,) = tmp_path.glob("opencl-program-*.npz")
    for bad in ({"device0": np.frombuffer(b"not a program", np.uint8)}, {"elsewhere": np.zeros(4, np.uint8)}):
        disk_cache.store_arrays(entry.stem, bad)
        _assert_same_rays(_telephoto_rays(), built)
        opencl.store_built_binaries()
        assert list(disk_cache.load_arrays(entry.stem)) == ["device0"]  # replaced by the real binaries
    entry.write_bytes(b"truncated")
    _assert_same_rays(_telephoto_rays(), built)
    opencl.build_program.cache_clear()


def test_a_kernel_that_does_not_compile_names_its_file_and_the_compiler_message():
    with pytest.raises(RuntimeError, match=r"building broken\.cl failed:(.|\n)*undeclared_name"):
        source = "__kernel void k(__global float *a) { a[0] = undeclared_name; }"
        Device.for_spec().build_program(source, "broken.cl")


def test_a_new_resolution_or_sample_count_reuses_the_program_and_matches_the_reference():
    """Resolution, film size and spp are kernel arguments, not compiled in: a camera that differs only
    in them shares the built program (no recompile for a new --res or --spp), and its rays still
    match the reference."""
    camera = reference_camera("dgauss", "pupil")
    first = opencl_host.LensKernel(camera)
    for changed in (dataclasses.replace(camera, spp=camera.spp + 3),
                    dataclasses.replace(camera, width=2 * camera.width, height=2 * camera.height),
                    dataclasses.replace(camera, width=camera.width + 5)):  # another aspect: another film size
        again = opencl_host.LensKernel(changed)
        assert again.program is first.program
        _check_against_reference(changed)


@pytest.mark.parametrize("sampling", SAMPLINGS)
def test_a_new_focus_reuses_the_program_and_matches_the_reference(sampling):
    """What depends on the film distance (sampling plane, vertices, exit-pupil boxes) is the kernel's
    ``settings`` argument: refocusing shares the built program, and each focus's rays match its own
    reference (so the argument is read, not the first camera's values)."""
    camera = reference_camera("dgauss", sampling)
    first = opencl_host.LensKernel(camera)
    for metres in (0.8, 40.0):
        refocused = dataclasses.replace(camera, film_distance_mm=film_distance_for_focus(camera.lens, 1000 * metres))
        assert not np.array_equal(opencl_host.setting_values(refocused), opencl_host.setting_values(camera))
        assert opencl_host.LensKernel(refocused).program is first.program
        _check_against_reference(refocused)


def test_a_new_round_stop_reuses_the_program_and_matches_the_reference():
    """A round stop's diameter (an f-stop) is a setting too; a bladed stop's outline is compiled in."""
    camera = reference_camera("dgauss", "pupil")
    first = opencl_host.LensKernel(camera)
    diameter = float(camera.lens.aperture_mm[camera.lens.stop])
    for scale in (0.4, 0.75):
        stopped = dataclasses.replace(camera, lens=camera.lens.with_stop_diameter(scale * diameter))
        assert opencl_host.LensKernel(stopped).program is first.program
        _check_against_reference(stopped)
    from realistic.optics.stop_shape import bladed_stop

    bladed = dataclasses.replace(camera, lens=camera.lens.with_stop_shape(bladed_stop(6, 10.0)))
    assert opencl_host.LensKernel(bladed).program is not first.program


def test_pixels_of_a_huge_film_map_to_their_rows_and_columns_exactly():
    """The kernel finds a pixel's row by a double multiply, not a division: near the end of a
    16411 x 16417 film (pixel ids past 2^28) every column and row still matches the reference."""
    camera = dataclasses.replace(reference_camera("dgauss", "pupil"), width=16411, height=16417, spp=2)
    block = SampleBlock(camera.sample_count - 40_000, 40_000, camera.spp)
    kernel = backend_for("opencl").ray_generator(camera, 3)(block)
    reference = camera.generate_rays(block, 3)
    assert kernel.pixel.min() > 2**28
    assert_kernel_matches(kernel, reference, camera, 3, block=block)


def test_another_lens_binary_under_dgauss_key_is_rebuilt_not_run(monkeypatch, tmp_path):
    """The reported bug: telephoto's program binary copied under dgauss's cache key ran and gave
    dgauss wrong rays (exit 0). Each entry carries its key, so the copy is refused and dgauss's
    program is built from source: its rays are those of a build with the cache off."""
    import shutil

    from realistic.core import disk_cache

    per_item = opencl_host.RAYS_PER_ITEM  # given, so no timed choice builds other programs

    device = Device.for_spec()
    telephoto, dgauss = reference_camera("telephoto", "pupil"), reference_camera("dgauss", "pupil")
    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    opencl.build_program.cache_clear()
    block = SampleBlock(0, 20_000, dgauss.spp)
    uncached = opencl_host.LensKernel(dgauss, device, per_item).generate(block, seed=3)
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path))

    def key(camera: LensCamera) -> str:
        source, _ = opencl_host.lens_program(camera, per_item)
        return disk_cache.cache_key(opencl.CACHE_KIND, device.identity(), source.encode(), ())

    for _ in range(2):  # a mark, then the binaries at "exit"
        opencl.build_program.cache_clear()
        opencl_host.LensKernel(telephoto, device, per_item)
    opencl.store_built_binaries()
    assert list(disk_cache.load_arrays(key(telephoto))) == ["device0"]
    shutil.copy(tmp_path / f"{key(telephoto)}.npz", tmp_path / f"{key(dgauss)}.npz")
    assert disk_cache.load_arrays(key(dgauss)) is None
    opencl.build_program.cache_clear()
    _assert_same_rays(opencl_host.LensKernel(dgauss, device, per_item).generate(block, seed=3), uncached)
    opencl.build_program.cache_clear()


@pytest.mark.parametrize(("name", "sampling", "spectral"), [("dgauss", "pupil", False), ("wide", "rear", False),
                                                            ("dgauss100", "rear", True),
                                                            ("phone-us10101561", "pupil", False)])
def test_rays_per_work_item_leave_every_ray_bit_identical(name, sampling, spectral):
    """A work item tracing 2 or 4 rays side by side computes each as one ray per work item does."""
    camera = reference_camera(name, sampling, spectral=spectral)
    block = SampleBlock(777, 50_000, camera.spp)
    one = opencl_host.LensKernel(camera, rays_per_item=1).generate(block, seed=4)
    for per_item in (2, 4):
        several = opencl_host.LensKernel(camera, rays_per_item=per_item).generate(block, seed=4)
        _assert_same_rays(several, one)
        assert np.array_equal(several.wavelength_nm, one.wavelength_nm) if spectral else several.wavelength_nm is None


@pytest.mark.parametrize(("name", "sampling", "wavelengths"), [("dgauss100", "rear", 2), ("dgauss100", "pupil", 3),
                                                                ("wide", "rear", 3), ("phone-us10101561", "pupil", 2)])
def test_a_work_item_per_spectral_sample_leaves_every_ray_bit_identical(name, sampling, wavelengths):
    """A work item tracing one spectral sample's K rays, whose film and lens point it makes once
    (``shares_samples``), computes each ray as one ray per work item does, in the same order; the
    layout is what a spectral camera of K = 2 or 3 chooses between, and K = 4 is left to the launch's
    rays i, i + n, ... (SLP packs four consecutive rays)."""
    camera = dataclasses.replace(reference_camera(name, sampling, spectral=True), wavelengths_per_sample=wavelengths)
    assert opencl_host.rays_per_item_choices(camera) == (wavelengths, 1)
    assert opencl_host.shares_samples(camera, wavelengths) and not opencl_host.shares_samples(camera, 1)
    block = SampleBlock(777, 50_000, camera.spp)
    one = opencl_host.LensKernel(camera, rays_per_item=1).generate(block, seed=4)
    shared = opencl_host.LensKernel(camera, rays_per_item=wavelengths).generate(block, seed=4)
    _assert_same_rays(shared, one)
    assert np.array_equal(shared.wavelength_nm, one.wavelength_nm)
    four = dataclasses.replace(camera, wavelengths_per_sample=4)
    assert not opencl_host.shares_samples(four, opencl_host.rays_per_item_choices(four)[0])


def test_rays_per_work_item_are_chosen_among_the_choices_and_kept():
    camera = reference_camera("telephoto", "rear")
    first = opencl_host.LensKernel(camera)
    assert first.rays_per_item in opencl_host.rays_per_item_choices(camera)
    assert opencl_host.LensKernel(camera).program is first.program


@pytest.mark.parametrize("coating", ["none", "mgf2"])
@pytest.mark.parametrize(("name", "spectral"), [("dgauss", False), ("dgauss", True), ("wide", True)])
def test_kernel_weight_matches_reference_with_each_coating(name, spectral, coating):
    """Each surface's Fresnel transmittance (bare, or through the MgF2 layer at the ray's wavelength)
    enters the kernel's weight as it enters the float64 reference's, to float32 precision."""
    camera = camera_for_lens(load_lens(name).with_coating(coating), spectral=spectral)
    _check_against_reference(camera)
    kernel = backend_for("opencl").ray_generator(camera, 5)(SampleBlock(0, 20_000, camera.spp))
    ideal = dataclasses.replace(camera, lens=load_lens(name))
    plain = backend_for("opencl").ray_generator(ideal, 5)(SampleBlock(0, 20_000, camera.spp))
    lit = plain.weight > 0
    loss = 1 - kernel.weight[lit] / plain.weight[lit]  # the same rays, less the light the surfaces reflect
    assert np.all(loss > 0) and np.all(loss < 1)


def test_ideal_coating_leaves_the_kernel_source_and_rays_unchanged():
    """``ideal`` (the default) writes no transmission call and COATED 0, so the kernel computes what it
    computed before coatings existed: a lens's rays equal, bit for bit, those of the lens made ideal
    from another coating."""
    lens = load_lens("dgauss")
    header = opencl_host.camera_header(camera_for_lens(lens))
    assert "transmit_" not in header and "#define COATED 0" in header
    again = camera_for_lens(lens.with_coating("mgf2").with_coating("ideal"))
    assert opencl_host.camera_header(again) == header
    block = SampleBlock(0, 30_000, again.spp)
    a = backend_for("opencl").ray_generator(camera_for_lens(lens), 2)(block)
    b = backend_for("opencl").ray_generator(again, 2)(block)
    assert np.array_equal(a.weight, b.weight) and np.array_equal(a.direction, b.direction)
