"""Film accumulation, EXR and PNG output, atomic writes."""

import os
from pathlib import Path

import numpy as np
import pytest

from realistic.camera.base import SampleBlock
from realistic.core.atomic_files import check_writable, write_atomically
from realistic.core.image_files import read_exr, srgb_encode, write_exr, write_png
from realistic.errors import UserError
from realistic.renderer.film import Film, pass_sums


def test_film_averages_over_the_samples_taken_including_partial_pixels():
    film = Film(width=3, height=1, spp=4)
    # pass 1: sample ids 0..5 (pixel 0 complete, pixel 1 half done)
    pixel = np.array([0, 0, 0, 1, 1])  # id 2 was vignetted: no row, but it still counts
    value = np.array([[4.0, 0, 0], [4.0, 0, 0], [4.0, 0, 0], [2.0, 0, 0], [2.0, 0, 0]])
    film.add(SampleBlock(0, 6, 4), 0, pass_sums(pixel, value, 0, 2))
    image = film.image()
    assert image[0, 0, 0] == pytest.approx(3.0)  # 12 / 4 samples
    assert image[0, 1, 0] == pytest.approx(2.0)  # 4 / 2 samples so far
    assert image[0, 2, 0] == 0.0  # no samples yet
    film.add(SampleBlock(6, 6, 4), 1, pass_sums(np.array([1, 2]), np.array([[8.0, 0, 0], [4.0, 1, 0]]), 1, 2))
    image = film.image()
    assert image[0, 1, 0] == pytest.approx(3.0)  # 12 / 4
    assert image[0, 2, 0] == pytest.approx(1.0) and image[0, 2, 1] == pytest.approx(0.25)
    np.testing.assert_array_equal(film.samples, [4, 4, 4])


def sequential_sums(pixel: np.ndarray, value: np.ndarray, pixel_count: int) -> np.ndarray:
    """Per-pixel sums as a plain loop makes them: each row added in turn, in float64."""
    sums = np.zeros((pixel_count, 3))
    for p, row in zip(pixel, value.astype(np.float64)):
        sums[p] += row
    return sums


@pytest.mark.parametrize("sort", [True, False])
def test_pass_sums_add_each_pixels_rows_in_order_to_the_bit(sort):
    """Rows in pixel order (runs of up to 700 rows, pixels with none between) and rows in any order
    both give exactly the sums of adding each row in turn in float64, as the farm's and the
    threads' renders assume. (``np.add.reduceat``, 35 % faster on sorted rows, fails this: it
    adds long runs pairwise.)"""
    rng = np.random.default_rng(4)
    pixel = np.repeat(np.arange(0, 60, 3), rng.integers(1, 700, 20)) + 5
    if not sort:
        pixel = rng.permutation(pixel)
    value = (rng.random((len(pixel), 3)) * 10.0 ** rng.integers(-3, 4, (len(pixel), 1))).astype(np.float32)
    sums = pass_sums(pixel, value, 5, 60)
    np.testing.assert_array_equal(sums, sequential_sums(pixel - 5, value, 60))
    assert np.count_nonzero(sums.any(axis=1)) == 20


def test_pass_sums_weight_each_row_in_its_precision_first():
    """With weights, each float32 row times its weight rounded to float32, then added in turn in
    float64: the sums of the weighted (N, 3) array the runner used to make."""
    rng = np.random.default_rng(5)
    pixel = rng.integers(0, 40, 3000) + 7
    value = (rng.random((3000, 3)) * 10.0 ** rng.integers(-3, 4, (3000, 1))).astype(np.float32)
    weight = (rng.random(3000) * 3 - 1).astype(np.float32)
    sums = pass_sums(pixel, value, 7, 40, weight)
    np.testing.assert_array_equal(sums, sequential_sums(pixel - 7, value * weight[:, None], 40))


@pytest.mark.parametrize("compiled_loops", [True, False], ids=["compiled", "numpy"])
def test_pass_sums_of_a_pass_with_no_rows_are_float64_zeros(compiled_loops, monkeypatch):
    """A pass that traces no ray (every one vignetted, or outside a crop) sums to float64 zeros in
    both forms: numpy's np.bincount of no rows gives int64, which the film refuses."""
    from realistic.core import jit

    monkeypatch.setattr(jit, "_use_compiled", [compiled_loops])
    for value in (np.zeros((0, 3), np.float32), np.zeros((0, 3))):
        sums = pass_sums(np.zeros(0, np.int32), value, 4, 5, np.zeros(0, value.dtype))
        assert sums.dtype == np.float64 and sums.shape == (5, 3) and not sums.any()


@pytest.mark.parametrize("pixel", [[3, 4, 2], [3, 9, 4]])
def test_pass_sums_refuse_a_pixel_outside_the_pass(pixel):
    with pytest.raises(ValueError, match="a pixel outside 3 .. 8"):
        pass_sums(np.array(pixel), np.ones((3, 3), np.float32), 3, 6)


def test_film_counts_a_slice_of_each_pixels_samples():
    """Samples [1, 3) of pixels 0..2 give each pixel 2 samples; then sample 0 of all of them, 3."""
    film = Film(width=3, height=1, spp=4)
    film.add(SampleBlock.of_pixels(0, 3, 1, 2), 0, np.array([[6.0, 0, 0], [2.0, 0, 0], [0.0, 0, 0]]))
    np.testing.assert_array_equal(film.samples, [2, 2, 2])
    assert film.image()[0, 0, 0] == pytest.approx(3.0)
    film.add(SampleBlock.of_pixels(0, 3, 0, 1), 0, np.array([[3.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]]))
    np.testing.assert_array_equal(film.samples, [3, 3, 3])
    np.testing.assert_allclose(film.image()[0, :, 0], [3.0, 1.0, 1.0])


def test_exr_round_trip_keeps_pixels_and_metadata(tmp_path):
    rng = np.random.default_rng(0)
    image = rng.random((5, 7, 3)).astype(np.float32) * 100
    meta = {"lens": "dgauss", "fNumber": 2.03, "focusDistanceMm": 1234.5, "spp": 16, "seed": 7,
            "renderSeconds": 1.25}
    path = tmp_path / "out.exr"
    write_exr(path, image, meta)
    pixels, header = read_exr(path)
    np.testing.assert_array_equal(pixels, image)
    for key, value in meta.items():
        assert header[key] == pytest.approx(value) if isinstance(value, float) else header[key] == value
    assert [p.name for p in tmp_path.iterdir()] == ["out.exr"]


def test_png_preview_is_srgb_encoded_with_exposure(tmp_path):
    from PIL import Image

    image = np.full((2, 2, 3), 0.25, np.float32)
    write_png(tmp_path / "a.png", image, exposure_stops=1.0)  # 0.25 * 2 = 0.5 linear
    pixels = np.asarray(Image.open(tmp_path / "a.png"))
    assert pixels.shape == (2, 2, 3)
    assert pixels[0, 0, 0] == round(float(srgb_encode(np.float32(0.5))) * 255) == 188


def test_failed_write_leaves_no_file(tmp_path):
    def broken(name: str) -> None:
        with open(name, "wb") as f:
            f.write(b"partial")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(tmp_path / "x.exr", broken)
    assert list(tmp_path.iterdir()) == []


def test_unwritable_destinations_are_reported_before_rendering(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        check_writable(tmp_path / "nope" / "a.exr")
    with pytest.raises(UserError, match="directory"):
        check_writable(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_read_only_directory_is_reported(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(UserError, match="permission denied"):
            check_writable(locked / "a.exr")
    finally:
        locked.chmod(0o700)


def test_written_files_get_ordinary_permissions(tmp_path):
    import stat

    path = tmp_path / "out.txt"
    write_atomically(path, lambda temporary: Path(temporary).write_text("x"))
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask
