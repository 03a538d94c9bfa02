"""Progressive pass order (renderer/pass_plan) and pass-ordered accumulation (film.PassFilm)."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic import load_lens
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.renderer.film import Film, PassFilm
from realistic.renderer.job import RenderJob, RenderObserver
from realistic.renderer.pass_plan import PASS_RAYS, default_pass_samples, plan_passes, progressive_order, slice_bounds
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.runner import contiguous_rows, gather_rows
from realistic.scene.staging import default_setup


def _coverage(plan, pixels, spp):
    """How many times the plan visits each (pixel, sample) pair."""
    covered = np.zeros((pixels, spp), np.int64)
    for block in plan:
        pixel, sample = block.ids()
        np.add.at(covered, (pixel, sample), 1)
    return covered


@given(st.integers(0, 10**9), st.integers(1, 5000), st.integers(1, 300), st.integers(0, 10**6))
def test_sample_ids_are_each_pairs_sample_within_its_pixel(first, count, samples, first_sample):
    """The tiled sample numbers equal pair t's sample, first_sample + t mod samples (SampleBlock's definition)."""
    block = SampleBlock(first, count, samples, first_sample)
    t = np.arange(first, first + count, dtype=np.int64)
    np.testing.assert_array_equal(block.sample_ids(), first_sample + t % samples)


@given(st.integers(1, 8), st.integers(0, 64))
def test_default_passes_hold_a_fixed_number_of_rays_whatever_the_light_samples(wavelengths, light_samples):
    """Camera rays (one per wavelength) and their shadow rays per pass: the largest whole number of
    samples within PASS_RAYS, so four light samples do not make a pass's memory five times larger."""
    rays_per_sample = wavelengths * (1 + light_samples)
    samples = default_pass_samples(wavelengths, light_samples)
    assert samples * rays_per_sample <= PASS_RAYS < (samples + 1) * rays_per_sample


@given(st.integers(1, 400), st.integers(1, 40), st.integers(1, 700))
def test_plan_covers_every_pixel_sample_pair_once(pixels, spp, pass_samples):
    plan = plan_passes(pixels, spp, pass_samples)
    assert all(1 <= block.count <= pass_samples for block in plan)
    assert np.all(_coverage(plan, pixels, spp) == 1)


@given(st.integers(1, 10**7), st.integers(1, 4096), st.integers(1, 1 << 20))
def test_slices_double_so_each_pixel_is_sent_about_log2_spp_times(pixels, spp, pass_samples):
    """A pass's sums hold every pixel it touches once, so a render sends and adds each pixel's sums
    once per slice: slices grow geometrically (at most log2(spp) + 2 of them while the cap of
    ``pass_samples`` samples does not bind), and the first is a whole frame as soon as one pass can
    hold every pixel."""
    bounds = np.array(slice_bounds(pixels, spp, pass_samples))
    widths = np.diff(bounds)
    assert bounds[0] == 0 and bounds[-1] == spp and np.all(widths >= 1)
    assert widths[0] == min(spp, max(1, pass_samples // pixels))
    assert np.all((widths[1:] == np.minimum(bounds[1:-1], pass_samples)) | (bounds[2:] == spp))
    if spp <= pass_samples:
        assert len(widths) <= np.log2(spp) + 2


@given(st.integers(1, 400), st.integers(1, 40), st.integers(1, 700))
def test_every_pixel_has_the_same_samples_after_each_finished_slice(pixels, spp, pass_samples):
    """Slices outermost: after every prefix of the plan that ends a slice, each pixel has the same
    number of samples, the first k of its own (a whole noisy frame, not finished bands)."""
    plan = plan_passes(pixels, spp, pass_samples)
    film = Film(pixels, 1, spp)
    for index, block in enumerate(plan):
        film.add(block, block.first_pixel, np.zeros((block.pixel_count, 3)))
        if index + 1 == len(plan) or plan[index + 1].first_sample != block.first_sample:
            taken = block.first_sample + block.samples
            assert np.all(film.samples == taken)
            assert np.all(_coverage(plan[:index + 1], pixels, spp)[:, :taken] == 1)


def test_the_default_plan_gives_every_pixel_of_a_large_frame_a_sample_after_one_slice():
    """512x512 at 64 spp: passes of 2^18 pairs, one sample of each pixel per pass, so the first
    slice (one pass) is a whole 1-spp frame."""
    plan = plan_passes(512 * 512, 64)
    assert len(plan) == 64 and all(block.count == 1 << 18 for block in plan)
    assert plan[0].first_sample == 0 and plan[1].first_sample == 1
    assert np.all(_coverage(plan[:1], 512 * 512, 64).sum(axis=1) == 1)


@given(st.integers(1, 3000))
def test_every_power_of_two_prefix_is_spread_over_the_frame(count):
    """The first k = 2^j passes leave no stretch of the frame longer than about 2 n / k ranges unvisited
    (raster order would leave n - k)."""
    order = progressive_order(count)
    assert sorted(order.tolist()) == list(range(count))
    k = 1
    while k <= count:
        visited = np.sort(order[:k])
        gaps = np.diff(np.concatenate([[-1], visited, [count]])) - 1
        assert gaps.max() <= 2 * count / k, (k, gaps.max())
        k *= 2


def _random_sums(rng, plan):
    return [(block.first_pixel, rng.standard_normal((block.pixel_count, 3))
             * 10.0 ** rng.integers(-8, 8, (block.pixel_count, 1))) for block in plan]


@given(st.integers(1, 6), st.integers(1, 12), st.integers(1, 40), st.randoms())
def test_pass_film_is_bit_identical_in_any_arrival_order(pixels, spp, pass_samples, shuffle):
    """Pass sums whose float64 additions do not commute (magnitudes 1e-8 to 1e8, pixels in several
    passes) give the same film bits whatever order they arrive in, duplicates included."""
    plan = plan_passes(pixels, spp, pass_samples)
    sums = _random_sums(np.random.default_rng(pixels * 1000 + spp * 10 + pass_samples), plan)
    in_order = PassFilm(Film(pixels, 1, spp), plan)
    for index, (first_pixel, s) in enumerate(sums):
        in_order.add(index, first_pixel, s)
    arrivals = list(range(len(plan))) + [i for i in range(len(plan)) if i % 3 == 0]  # retries deliver twice
    shuffle.shuffle(arrivals)
    shuffled = PassFilm(Film(pixels, 1, spp), plan)
    for index in arrivals:
        shuffled.add(index, *sums[index])
    assert np.array_equal(in_order.film.sums, shuffled.film.sums)
    assert np.array_equal(in_order.film.samples, shuffled.film.samples)
    assert np.all(shuffled.film.samples == spp) and shuffled.next_pass == len(plan)


def test_waiting_passes_show_in_the_image_but_not_in_the_film():
    plan = plan_passes(4, 2, 1)  # 4 pixels, 2 spp, one pixel's sample a pass
    film = PassFilm(Film(4, 1, 2), plan)
    film.add(2, plan[2].first_pixel, np.full((1, 3), 4.0))  # pass 2 arrives before 0 and 1
    assert film.next_pass == 0 and film.film.samples.sum() == 0
    image = film.image().reshape(-1, 3)
    assert np.all(image[plan[2].first_pixel] == 4.0) and image.sum() == 12.0


@pytest.fixture(scope="module")
def tiny():
    setup = default_setup()
    return setup.scene, LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 32, 32, 4)


def test_an_interrupted_render_is_a_whole_noisy_frame(tiny):
    """32x32 at 4 spp in passes of 256 pairs: each slice is one sample of every pixel, in four
    passes. Interrupted after the first slice, the image is the whole frame at 1 spp: bit for bit
    the render of the same camera at spp 1 (random numbers depend on (pixel, sample) only)."""
    scene, camera = tiny

    def interrupt(result):
        if result.passes_done == 4:
            raise KeyboardInterrupt

    result = render(RenderJob(scene, (camera,), "numpy", pass_samples=256), ThreadPasses(threads=1),
                    RenderObserver(on_pass=interrupt))[0]
    assert result.interrupted and result.passes_done == 4 and result.passes_total == 16
    assert result.samples_done == 32 * 32
    one_spp = render(RenderJob(scene, (dataclasses.replace(camera, spp=1),), "numpy", pass_samples=256),
                     ThreadPasses(threads=1))[0]
    assert np.array_equal(result.image, one_spp.image) and np.count_nonzero(result.image) > 0


def test_threads_and_pass_order_do_not_change_the_image(tiny):
    scene, camera = tiny
    one = render(RenderJob(scene, (camera,), "numpy", pass_samples=96), ThreadPasses(threads=1))[0].image
    three = render(RenderJob(scene, (camera,), "numpy", pass_samples=96), ThreadPasses(threads=3))[0].image
    assert np.array_equal(one, three) and one.max() > 0


def test_previews_are_whole_images_while_rendering(tiny):
    scene, camera = tiny
    previews = []
    result = render(RenderJob(scene, (camera,), "numpy", pass_samples=256), ThreadPasses(threads=1),
                    RenderObserver(preview=previews.append, preview_every=1e-9))[0]
    assert len(previews) >= 2 and all(p.shape == (32, 32, 3) for p in previews)
    assert np.array_equal(previews[-1], result.image)
    done = [np.count_nonzero(np.any(p != 0, axis=2)) for p in previews]
    assert done == sorted(done)  # pixels only gain samples


def test_a_render_without_a_pass_size_sizes_its_passes_by_rays(tiny):
    """128x128 at 8 spp is 131072 samples: one pass at one light sample, but 131072 / 104857 -> 2
    passes at four, whose shadow rays would otherwise make each pass five times the rays."""
    scene, camera = tiny
    camera = dataclasses.replace(camera, width=128, height=128, spp=8)
    one = render(RenderJob(scene, (camera,), "numpy", light_samples=1), ThreadPasses(threads=1))[0]
    four = render(RenderJob(scene, (camera,), "numpy", light_samples=4), ThreadPasses(threads=1))[0]
    assert one.passes_total == len(plan_passes(128 * 128, 8, default_pass_samples(1, 1))) == 1
    assert four.passes_total == len(plan_passes(128 * 128, 8, default_pass_samples(1, 4))) == 2


@given(st.integers(1, 300), st.integers(0, 2**32 - 1), st.sampled_from([np.float32, np.float64]), st.booleans())
def test_gather_rows_is_row_indexing_as_contiguous_float32(count, seed, dtype, transposed):
    """The kernel's (rows, n) output viewed as (n, 3) points, or a plain (n, 3) array: the same rows."""
    rng = np.random.default_rng(seed)
    points = rng.random((3, count)).astype(dtype).T if transposed else rng.random((count, 3)).astype(dtype)
    rows = np.flatnonzero(rng.random(count) < 0.7)
    gathered = gather_rows(points, rows)
    assert gathered.dtype == np.float32 and gathered.flags.c_contiguous and gathered.shape == (len(rows), 3)
    assert np.array_equal(gathered, points[rows].astype(np.float32))


@given(st.integers(0, 300), st.integers(0, 2**32 - 1), st.sampled_from([np.float32, np.float64]), st.booleans())
def test_contiguous_rows_are_every_row_in_order_as_contiguous_float32(count, seed, dtype, transposed):
    """A thin lens's pass copies every ray: the same rows as gathering each by its number."""
    rng = np.random.default_rng(seed)
    points = rng.random((3, count)).astype(dtype).T if transposed else rng.random((count, 3)).astype(dtype)
    copied = contiguous_rows(points)
    assert copied.dtype == np.float32 and copied.flags.c_contiguous and copied.shape == (count, 3)
    assert np.array_equal(copied, gather_rows(points, np.arange(count)))


def test_gather_rows_refuses_a_row_outside_the_points():
    with pytest.raises(IndexError, match="a row outside 0 .. 3"):
        gather_rows(np.zeros((4, 3), np.float32), np.array([0, 4]))
