"""Progressive pass order (renderer/pass_plan) and pass-ordered accumulation (film.PassFilm)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.renderer.film import Film, PassFilm
from realistic.renderer.pass_plan import plan_passes, progressive_order
from realistic.renderer.passes import render_passes
from realistic.scene.staging import default_setup


@given(st.integers(1, 5000), st.integers(1, 700))
def test_plan_covers_every_sample_id_once(total, pass_samples):
    plan = plan_passes(total, pass_samples)
    covered = np.zeros(total, np.int64)
    for first, count in plan:
        assert 1 <= count <= pass_samples
        covered[first:first + count] += 1
    assert np.all(covered == 1)


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


def _random_sums(rng, plan, spp):
    out = []
    for first, count in plan:
        first_pixel = first // spp
        pixels = (first + count - 1) // spp - first_pixel + 1
        out.append((first_pixel, rng.standard_normal((pixels, 3)) * 10.0 ** rng.integers(-8, 8, (pixels, 1))))
    return out


@given(st.integers(1, 6), st.integers(1, 12), st.integers(1, 40), st.randoms())
def test_pass_film_is_bit_identical_in_any_arrival_order(pixels, spp, pass_samples, shuffle):
    """Pass sums whose float64 additions do not commute (magnitudes 1e-8 to 1e8, pixels split over
    several passes) give the same film bits whatever order they arrive in, duplicates included."""
    plan = plan_passes(pixels * spp, pass_samples)
    sums = _random_sums(np.random.default_rng(pixels * 1000 + spp * 10 + pass_samples), plan, spp)
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
    plan = plan_passes(8, 2)  # 4 pixels, 2 spp, one pixel a pass
    film = PassFilm(Film(4, 1, 2), plan)
    film.add(2, plan[2][0] // 2, np.full((1, 3), 4.0))  # pass 2 arrives before 0 and 1
    assert film.next_pass == 0 and film.film.samples.sum() == 0
    image = film.image().reshape(-1, 3)
    assert np.all(image[plan[2][0] // 2] == 2.0) and image.sum() == 6.0


@pytest.fixture(scope="module")
def tiny():
    setup = default_setup()
    return setup.scene, LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 32, 32, 4)


def test_an_interrupted_render_holds_exactly_the_first_passes_of_the_plan(tiny):
    scene, camera = tiny
    calls = []

    def interrupt(result):
        calls.append(result.samples_done)
        if len(calls) == 2:
            raise KeyboardInterrupt

    result = render_passes(scene, camera, "numpy", pass_samples=256, threads=2, on_pass=interrupt)
    assert result.interrupted and 2 <= result.passes_done < result.passes_total == 16
    plan = plan_passes(camera.sample_count, 256)
    expected = np.zeros(32 * 32, bool)
    for first, count in plan[:result.passes_done]:
        expected[first // 4:(first + count) // 4] = True
    lit = np.any(result.image.reshape(-1, 3) != 0, axis=1)
    assert not np.any(lit & ~expected)  # nothing outside the passes done
    rows = np.flatnonzero(expected.reshape(32, 32).any(axis=1))
    assert rows.min() < 8 and rows.max() >= 16  # not the top rows only: spread over the frame


def test_threads_and_pass_order_do_not_change_the_image(tiny):
    scene, camera = tiny
    one = render_passes(scene, camera, "numpy", pass_samples=96, threads=1).image
    three = render_passes(scene, camera, "numpy", pass_samples=96, threads=3).image
    assert np.array_equal(one, three) and one.max() > 0


def test_previews_are_whole_images_while_rendering(tiny):
    scene, camera = tiny
    previews = []
    result = render_passes(scene, camera, "numpy", pass_samples=256, threads=1, preview=previews.append,
                           preview_every=1e-9)
    assert len(previews) >= 2 and all(p.shape == (32, 32, 3) for p in previews)
    assert np.array_equal(previews[-1], result.image)
    done = [np.count_nonzero(np.any(p != 0, axis=2)) for p in previews]
    assert done == sorted(done)  # pixels only gain samples
