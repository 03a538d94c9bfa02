"""``kernels/ewa.cl`` against its numpy reference ``MipMap.ewa`` (itself checked against a scalar
transcription of pbrt-v3's loop in test_textures.py): same taps, same weights, float32 rounding."""

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import vectoriser_remarks
from ewa_helpers import pbrt_ellipse
from realistic.renderer.backends import backend_for
from realistic.scene.mipmap import MipMap


def ellipses(count: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points over three repeats (so every wrap mode is crossed), ellipses of every orientation and
    eccentricity up to 40:1 (past the anisotropy clamp), some wider than the image, some degenerate."""
    rng = np.random.default_rng(seed)
    st = rng.random((count, 2)) * 3 - 1
    angle = rng.random(count) * 2 * np.pi
    major = 0.002 * (1 + 8 * rng.random(count)) * np.where(rng.random(count) < 0.05, 200, 1)
    minor = major / (1 + 39 * rng.random(count)) * (rng.random(count) > 0.03)
    axis0 = np.column_stack([np.cos(angle), np.sin(angle)]) * major[:, None]
    axis1 = np.column_stack([-np.sin(angle), np.cos(angle)]) * minor[:, None]
    return st, axis0, axis1


@pytest.mark.parametrize("wrap", ["repeat", "black", "clamp"])
@pytest.mark.parametrize("shape", [(64, 64), (48, 80)])  # power of two, and resampled to one
def test_the_kernel_equals_the_numpy_reference(opencl_platform, wrap, shape):
    image = np.random.default_rng(7).random((*shape, 3))
    mipmap = MipMap(image, wrap, max_anisotropy=8.0)
    st, axis0, axis1 = ellipses(3000, 11)
    reference = mipmap.ewa(st, axis0, axis1)
    device = backend_for("opencl").image_lookup(mipmap, "ewa", st, (axis0, axis1))
    assert device.dtype == np.float32 and device.shape == reference.shape
    np.testing.assert_allclose(device, reference, rtol=1e-6, atol=1e-6)


def test_an_empty_batch(opencl_platform):
    mipmap = MipMap(np.ones((8, 8, 3)))
    empty = np.zeros((0, 2))
    assert backend_for("opencl").image_lookup(mipmap, "ewa", empty, (empty, empty)).shape == (0, 3)


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_a_magnified_lookup_reads_the_finest_level_alone(opencl_platform, backend):
    """pbrt-v3's EWA blends the levels around lod with weight lod - floor(lod); where the footprint's
    minor axis is under a texel, lod is clamped to 0 and the next level's weight is 0. Both paths skip
    that level: poisoning every coarser level changes no magnified lookup, but does change lookups
    whose lod lies between 0 and 1, which read level 1."""
    image = np.random.default_rng(3).random((32, 32, 3))
    poisoned = MipMap(image)
    poisoned.texels[poisoned.level_base[1]:] = np.nan
    rng = np.random.default_rng(5)
    st = rng.random((500, 2))
    angle = rng.random(500) * 2 * np.pi
    # in texels of level 0: under one and exactly one (lod 0, the kernel skips log2), then lod in (0, 1);
    # the filters round the axes to float32, where a length is exactly one texel along the texel axes
    angle[300:400] = rng.integers(0, 4, 100) * (np.pi / 2)
    minor = np.select([np.arange(500) < 300, np.arange(500) < 400], [0.9, 1.0], 1.5) / 32
    major = minor * (1 + 7 * rng.random(500))
    axis0 = np.column_stack([np.cos(angle), np.sin(angle)]) * major[:, None]
    axis1 = np.column_stack([-np.sin(angle), np.cos(angle)]) * minor[:, None]
    lookup = backend_for(backend).image_lookup
    clean, dirty = lookup(MipMap(image), "ewa", st, (axis0, axis1)), lookup(poisoned, "ewa", st, (axis0, axis1))
    assert np.array_equal(dirty[:400], clean[:400])
    assert np.isnan(dirty[400:]).all() and np.isfinite(clean).all()


def magnified(count: int, seed: int, side: int, longest: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lookups over three repeats whose minor axis is at most a texel of a ``side``-texel level 0
    (lod clamped to 0) and whose major axis is up to ``longest`` times it."""
    rng = np.random.default_rng(seed)
    st = rng.random((count, 2)) * 3 - 1
    angle = rng.random(count) * 2 * np.pi
    minor = rng.random(count) / side
    major = minor * (1 + (longest - 1) * rng.random(count))
    axis0 = np.column_stack([np.cos(angle), np.sin(angle)]) * major[:, None]
    axis1 = np.column_stack([-np.sin(angle), np.cos(angle)]) * minor[:, None]
    return st, axis0, axis1


@pytest.mark.parametrize("wrap", ["repeat", "black", "clamp"])
def test_magnified_lookups_are_the_references_bit_for_bit(opencl_platform, wrap):
    """``ewa_small`` (vectorised) filters the magnified lookups over small ellipses and leaves the
    longer ones to ``ewa``: in the same float32 operations and order as the reference, so each
    colour is the reference's, exactly, on both sides of the split (the ellipses reach 4 texels,
    past ``ewa_small``'s 3 x 3)."""
    mipmap = MipMap(np.random.default_rng(2).random((64, 64, 3)), wrap)
    st, axis0, axis1 = magnified(20000, 4, 64, 4.0)
    device = backend_for("opencl").image_lookup(mipmap, "ewa", st, (axis0, axis1))
    assert np.array_equal(device, mipmap.ewa(st, axis0, axis1).astype(np.float32))


@pytest.mark.parametrize("texture_filter,blend_from", [("point", 0), ("bilinear", 0), ("trilinear", 0),
                                                      ("trilinear", 1)])
@pytest.mark.parametrize("wrap", ["repeat", "black", "clamp"])
@pytest.mark.parametrize("shape", [(64, 64), (48, 80), (1, 1)])
def test_point_bilinear_and_trilinear_lookups_are_the_references(opencl_platform, texture_filter, blend_from, wrap,
                                                                 shape):
    """The point, bilinear and trilinear kernels are pbrt's filters (pbrt-v4 mipmap.cpp,
    MIPMap::Filter; trilinear blending from level 0 as pbrt-v3's and from level 1 as pbrt-v4's) as
    ``MipMap.point``, ``bilinear_at_width`` and ``trilinear`` compute them in float64, with the width
    ``textures._image`` takes (twice the largest axis component): point and bilinear colours are the
    reference's rounded to float32, trilinear's within float32 rounding (its blend weight is log2's
    fraction, the library's) and exactly so where it reads level 0 alone, on every level (the
    footprints run from none and under a texel of level 0 to wider than the image, and st crosses
    texel edges exactly, where the point filter rounds halves)."""
    mipmap = MipMap(np.random.default_rng(4).random((*shape, 3)), wrap, trilinear_blend_from=blend_from)
    st, axis0, axis1 = ellipses(20000, 13)
    st[:2000] = np.round(st[:2000] * 64) / 64  # on texel edges of the finest levels
    lengths = 10.0 ** np.random.default_rng(14).uniform(-4, 0.7, (len(st), 1))  # log-uniform: every level
    axis0, axis1 = axis0 * lengths / 0.01, axis1 * lengths / 0.01
    axis0[-500:] = axis1[-500:] = 0.0  # no footprint
    width = 2 * np.maximum(np.abs(axis0).max(axis=1), np.abs(axis1).max(axis=1))
    continuous = mipmap.level_count - 1 + np.log2(np.maximum(width, 1e-8))
    levels = np.clip(np.floor(continuous), 0, mipmap.level_count - 1)
    assert set(levels) == set(range(mipmap.level_count))
    device = backend_for("opencl").ewa_kernel(mipmap)(st, axis0, axis1, texture_filter)
    reference = {"point": mipmap.point, "bilinear": mipmap.bilinear_at_width,
                 "trilinear": mipmap.trilinear}[texture_filter](st, width).astype(np.float32)
    if texture_filter == "trilinear":
        np.testing.assert_allclose(device, reference, rtol=1e-6, atol=1e-7)
        assert np.mean(device == reference) > 0.99
        alone = continuous < blend_from - 1e-9  # level 0's lookup alone: no blend weight from log2
        assert alone.any() and np.array_equal(device[alone], reference[alone])
    else:
        assert np.array_equal(device, reference)


def pbrt_level0(image: np.ndarray, st_: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
    """pbrt-v3's MIPMap::EWA (src/core/mipmap.h) on the repeating ``image`` (level 0), in float64 and
    in pbrt's own formulas (F = A C - B^2 / 4, r^2 = A s^2 + B s t + C t^2 over F) over the ellipse's
    whole bounding box, at one lookup rounded to float32 as the filters take it."""
    st_, axis0, axis1 = (np.asarray(v, np.float32).astype(np.float64) for v in (st_, axis0, axis1))
    h, w = image.shape[:2]
    s, t, a, b, c = pbrt_ellipse(image.shape, st_, axis0, axis1)
    det = 4 * a * c - b * b
    half_s, half_t = 2 * np.sqrt(det * c) / det, 2 * np.sqrt(a * det) / det
    x, y = np.meshgrid(np.arange(np.ceil(s - half_s), np.floor(s + half_s) + 1),
                       np.arange(np.ceil(t - half_t), np.floor(t + half_t) + 1))
    r2 = a * (x - s) ** 2 + b * (x - s) * (y - t) + c * (y - t) ** 2
    inside = r2 < 1
    weight = (np.exp(-2.0 * np.arange(128) / 127) - np.exp(-2.0))[np.minimum((r2[inside] * 128).astype(int), 127)]
    texels = image[y[inside].astype(int) % h, x[inside].astype(int) % w].astype(np.float64)
    return (texels * weight[:, None]).sum(axis=0) / weight.sum()


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_eccentric_and_degenerate_footprints_are_pbrts_ellipses(opencl_platform, backend):
    """The filters compute EWA in float32, with pbrt-v3's ellipse arranged so that no step cancels: at
    the eccentricities maxanisotropy allows (up to 1024:1, up to 500 texels long, under a texel wide:
    level 0 alone), and over parallel axes (a singular footprint, which the texel of widening keeps an
    ellipse), they are pbrt's arithmetic in float64 within float32 rounding of sums over up to a
    thousand texels (pbrt's own formulas in float32 are 1.5e-4 off here: A C - B^2 / 4 cancels)."""
    rng = np.random.default_rng(0)
    image = rng.random((256, 256, 3)).astype(np.float32)
    mipmap = MipMap(image, "repeat", max_anisotropy=1024.0)
    count = 40
    angle = rng.random(count) * 2 * np.pi
    major = (100 + 400 * rng.random(count)) / 256
    minor = major / 1024 * (1 + rng.random(count))
    axis0 = np.column_stack([np.cos(angle), np.sin(angle)]) * major[:, None]
    axis1 = np.column_stack([-np.sin(angle), np.cos(angle)]) * minor[:, None]
    axis1[-10:] = axis0[-10:] * (0.3 / 256 / major[-10:, None])  # parallel to the major axis, under a texel long
    st_ = rng.random((count, 2))
    got = backend_for(backend).image_lookup(mipmap, "ewa", st_, (axis0, axis1))
    expected = np.array([pbrt_level0(image, st_[i], axis0[i], axis1[i]) for i in range(count)])
    np.testing.assert_allclose(got, expected, rtol=0, atol=5e-5)


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_footprints_past_float32s_squares_keep_their_answers(opencl_platform, backend):
    """The axes are float32 but their lengths, the eccentricity clamp and the level float64 (a float32
    square overflows past 1.8e19 and underflows under 1e-19): a minor axis of 1e-30 is still stretched
    to the major one over max_anisotropy (not taken for 0: bilinear), axes of 1e-30 are the texel-wide
    ellipse that axes of 1e-12 are, and axes of 1e30 read the coarsest level's one texel."""
    mipmap = MipMap(np.random.default_rng(1).random((64, 64, 3)), "repeat", max_anisotropy=8.0)
    lookup = backend_for(backend).image_lookup
    st_ = np.random.default_rng(2).random((50, 2))
    ones = np.ones((50, 1))
    major, across = ones * [[0.05, 0.0]], ones * [[0.0, 1.0]]
    np.testing.assert_allclose(lookup(mipmap, "ewa", st_, (major, across * 1e-30)),
                               lookup(mipmap, "ewa", st_, (major, across * (0.05 / 8))), rtol=0, atol=1e-6)
    tiny = lookup(mipmap, "ewa", st_, (ones * [[1e-30, 0.0]], across * 1e-30))
    assert np.array_equal(tiny, lookup(mipmap, "ewa", st_, (ones * [[1e-12, 0.0]], across * 1e-12)))
    assert not np.allclose(tiny, mipmap.bilinear(st_.astype(np.float32).astype(np.float64)), rtol=0, atol=1e-3)
    huge = lookup(mipmap, "ewa", st_, (ones * [[1e30, 0.0]], across * 1e29))
    np.testing.assert_allclose(huge, np.broadcast_to(mipmap.texels[-1], huge.shape), rtol=1e-6)  # two levels' blend


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_lookups_that_are_not_finite_filter_to_zero(opencl_platform, backend):
    """A NaN or infinite s, t or axis component (or one past float32's range) gives 0 on both paths,
    whatever the other values (the float64 reference used to index out of its levels with some)."""
    mipmap = MipMap(np.random.default_rng(3).random((32, 32, 3)) + 0.5)
    st_, axis0, axis1 = (np.tile(value, (18, 1)) for value in ([0.3, 0.4], [0.02, 0.0], [0.0, 0.01]))
    for row, bad in enumerate(np.repeat([np.nan, np.inf, -1e39], 6)):
        [st_, axis0, axis1][row % 6 // 2][row, row % 2] = bad
    got = backend_for(backend).image_lookup(mipmap, "ewa", st_, (axis0, axis1))
    assert np.array_equal(got, np.zeros((18, 3)))


_COMPONENT = st.one_of(st.just(0.0), st.builds(lambda mantissa, exponent: mantissa * 10.0 ** exponent,
                                               st.floats(-1, 1), st.integers(-44, 30)))
_MAPS: dict[tuple[str, float], MipMap] = {}


@given(lookups=st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3), *[_COMPONENT] * 4), min_size=1, max_size=8),
       wrap=st.sampled_from(["repeat", "black", "clamp"]), max_anisotropy=st.sampled_from([1.0, 8.0, 1024.0]))
def test_any_footprint_is_filtered_alike_on_both_paths(opencl_platform, lookups, wrap, max_anisotropy):
    """Footprints of every size from 1e-44 to 1e30, zero, parallel and eccentric past the clamp: the
    kernel's colours are the reference's (to the rounding of the level's log2, the tolerance of
    test_the_kernel_equals_the_numpy_reference), finite, and averages of the map's texels (black's
    outside texels are 0)."""
    mipmap = _MAPS.get((wrap, max_anisotropy))
    if mipmap is None:
        mipmap = _MAPS[wrap, max_anisotropy] = MipMap(np.random.default_rng(9).random((16, 16, 3)), wrap,
                                                      max_anisotropy=max_anisotropy)
    rows = np.array(lookups)
    st_, axis0, axis1 = rows[:, :2], rows[:, 2:4], rows[:, 4:]
    reference = mipmap.ewa(st_, axis0, axis1)
    device = backend_for("opencl").image_lookup(mipmap, "ewa", st_, (axis0, axis1))
    np.testing.assert_allclose(device, reference, rtol=1e-6, atol=1e-6)
    low = min(0.0, float(mipmap.texels.min())) if wrap == "black" else float(mipmap.texels.min())
    assert np.isfinite(device).all() and (device >= low - 1e-6).all() and (device <= mipmap.texels.max() + 1e-6).all()


def test_two_threads_lookups_equal_one_threads(opencl_platform):
    """A render's threads filter through one ``EwaKernel`` at once, each on its own queue and kernel
    objects: batches of both paths (``ewa_small`` and the long ellipses left to ``ewa``) filtered by
    two threads started together, each many times, are the colours one thread makes of them."""
    mipmap = MipMap(np.random.default_rng(5).random((64, 64, 3)), "repeat", max_anisotropy=8.0)
    kernel = backend_for("opencl").ewa_kernel(mipmap)
    batches = [ellipses(500 + 37 * k, 20 + k) for k in range(8)]
    alone = [kernel(*batch) for batch in batches]
    start = threading.Barrier(2)

    def filter_all(order: list[int]) -> list[tuple[int, np.ndarray]]:
        start.wait()
        return [(k, kernel(*batches[k])) for _ in range(3) for k in order]

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(filter_all, [list(range(8)), list(range(7, -1, -1))]))
    for k, colours in (pair for result in results for pair in result):
        assert np.array_equal(colours, alone[k])


def test_the_small_lookups_vectorise(tmp_path):
    """PoCL's work-group vectoriser widens ``ewa_small`` (``ewa`` and ``hit_lookups`` loop over
    ellipses and run scalar): both of the work-group functions PoCL makes of it, for any group and
    for whole ones. Lookups it takes alone launch nothing else, so every remark is its; the
    remarks need a fresh build, so this runs in a process of its own."""
    script = (
        "import numpy as np\n"
        "from realistic.renderer.backends import backend_for\n"
        "from realistic.scene.mipmap import MipMap\n"
        "mipmap = MipMap(np.random.default_rng(0).random((32, 32, 3)))\n"
        "point = np.full((300, 2), 0.3)\n"
        "axes = (np.full((300, 2), 1e-3), np.full((300, 2), -1e-3))\n"
        "backend_for('opencl').image_lookup(mipmap, 'ewa', point, axes)\n")
    remarks = vectoriser_remarks(script, pocl_cache=tmp_path)
    assert remarks.count("vectorized loop (") >= 2


@pytest.mark.parametrize("texture_filter", ["point", "bilinear", "trilinear"])
def test_the_small_point_bilinear_and_trilinear_lookups_vectorise(tmp_path, texture_filter):
    """``point_small``, ``bilinear_small`` and ``trilinear_small`` (level-0 lookups: no library log2)
    are widened by PoCL's vectoriser as ``ewa_small`` is; lookups one takes alone launch nothing else,
    so every remark is its."""
    script = (
        "import numpy as np\n"
        "from realistic.renderer.backends import backend_for\n"
        "from realistic.scene.mipmap import MipMap\n"
        "kernel = backend_for('opencl').ewa_kernel(MipMap(np.random.default_rng(0).random((32, 32, 3))))\n"
        f"kernel(np.full((300, 2), 0.3), np.full((300, 2), 1e-3), np.full((300, 2), -1e-3), {texture_filter!r})\n")
    remarks = vectoriser_remarks(script, pocl_cache=tmp_path)
    assert remarks.count("vectorized loop (") >= 2


def test_the_kernel_refuses_a_map_whose_sides_are_not_powers_of_two(opencl_platform):
    """The kernel wraps a repeating texture with x & (w - 1): MipMap always resamples to powers of two,
    and a map that did not would be refused rather than read at the wrong texels."""
    from types import SimpleNamespace

    from realistic.scene.ewa_kernel import EwaKernel

    odd = SimpleNamespace(level_width=np.array([48, 24]), level_height=np.array([32, 16]))
    with pytest.raises(ValueError, match="power-of-two"):
        EwaKernel(odd)
