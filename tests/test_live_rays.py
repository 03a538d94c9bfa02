"""A pass's live camera rays (``runner.live_rays``): the compiled loop and the numpy form both pick
numpy's ``values[weight != 0]`` of every array, in order, with each ray's sample id that of
``SampleBlock.sample_ids`` (repeated per wavelength), from the kernel's layout of rays."""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from realistic.camera.base import RayBatch, SampleBlock
from realistic.core import jit
from realistic.core.jit import compiled
from realistic.renderer import runner
from realistic.renderer.runner import LiveRays, live_rays

#: How the rays' weights are drawn: some zero (vignetted), some negative (a filter's negative lobe).
WEIGHTS = ("mixed", "all live", "none live", "negative lobes")


def kernel_rays(rng: np.random.Generator, count: int, spectral: bool, weights: str, padding: int) -> RayBatch:
    """Rays laid out as the lens kernel returns them: views of a (rows, count + padding) float32
    output and an int32 pixel array."""
    out = rng.standard_normal((8 if spectral else 7, count + padding)).astype(np.float32)
    weight = out[6, :count]
    if weights == "mixed":
        weight[rng.random(count) < 0.35] = 0
    elif weights == "none live":
        weight[:] = 0
    elif weights == "all live":
        weight[weight == 0] = 1
    else:  # each ray's weight of either sign, a few zeros, negative zero among them
        weight[rng.random(count) < 0.1] = -0.0
    pixel = rng.integers(0, 10_000, count + padding).astype(np.int32)
    return RayBatch(origin=out[0:3, :count].T, direction=out[3:6, :count].T, weight=weight, pixel=pixel[:count],
                    wavelength_nm=out[7, :count] if spectral else None)


def numpy_picks(rays: RayBatch, block: SampleBlock, rays_per_sample: int) -> LiveRays:
    """The picks as numpy spells them, each array by itself."""
    alive = np.flatnonzero(rays.weight != 0)
    sample = np.repeat(block.sample_ids(), rays_per_sample)
    wavelength = None if rays.wavelength_nm is None else rays.wavelength_nm[alive]
    return LiveRays(np.ascontiguousarray(rays.origin[alive], np.float32),
                    np.ascontiguousarray(rays.direction[alive], np.float32), rays.pixel[alive], rays.weight[alive],
                    sample[alive], wavelength)


def assert_same(live: LiveRays, expected: LiveRays) -> None:
    for name in ("origin", "direction", "pixel", "weight", "sample", "wavelength"):
        got, want = getattr(live, name), getattr(expected, name)
        if want is None:
            assert got is None, name
            continue
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert np.array_equal(got, want), name
    assert live.origin.flags.c_contiguous and live.direction.flags.c_contiguous


@settings(max_examples=60, deadline=None)
@given(first=st.integers(0, 5000), count=st.integers(1, 400), samples=st.integers(1, 9),
       first_sample=st.integers(0, 40), rays_per_sample=st.sampled_from([1, 2, 3]), spectral=st.booleans(),
       weights=st.sampled_from(WEIGHTS), padding=st.sampled_from([0, 37]), seed=st.integers(0, 2**32 - 1),
       compiled=st.booleans())
def test_the_live_rays_are_numpys_picks(first: int, count: int, samples: int, first_sample: int, rays_per_sample: int,
                                        spectral: bool, weights: str, padding: int, seed: int, compiled: bool) -> None:
    """Any block (slices of pixels' samples starting mid-pixel), one or K rays a sample, padded or
    unpadded launches, any weights: both forms give numpy's picks, the sample ids derived in the loop
    equal to ``block.sample_ids()``'s."""
    block = SampleBlock(first, count, samples, first_sample)
    rays = kernel_rays(np.random.default_rng(seed), count * rays_per_sample, spectral, weights, padding)
    with mock.patch.object(jit, "_use_compiled", [compiled]):
        live = live_rays(rays, block, rays_per_sample)
    expected = numpy_picks(rays, block, rays_per_sample)
    assert_same(live, expected)
    if weights == "none live":
        assert len(live.weight) == 0
    if weights == "all live":
        assert len(live.weight) == count * rays_per_sample


@pytest.mark.parametrize("compiled", [False, True])
def test_the_numpy_references_rays_keep_their_types(compiled: bool) -> None:
    """Rays of other types than the kernel's (the float64 references, int64 pixels) are picked by
    numpy whatever the loops' setting: only origin and direction become float32."""
    rng = np.random.default_rng(3)
    block, n = SampleBlock(12, 300, 4), 300
    weight = np.where(rng.random(n) < 0.3, 0.0, rng.standard_normal(n))
    rays = RayBatch(rng.standard_normal((n, 3)), rng.standard_normal((n, 3)), weight, rng.integers(0, 99, n),
                    rng.random(n) * 300 + 400)
    with mock.patch.object(jit, "_use_compiled", [compiled]):
        live = live_rays(rays, block, 1)
    assert live.weight.dtype == np.float64 and live.pixel.dtype == np.int64
    assert_same(live, numpy_picks(rays, block, 1))


def test_the_live_rays_rows_are_each_arrays_rows() -> None:
    """A crop's or Morton order's rows of the live rays: every array's rows, in that order."""
    rng = np.random.default_rng(4)
    block = SampleBlock(5, 200, 3)
    rays = kernel_rays(rng, 600, True, "mixed", 10)
    live = live_rays(rays, block, 3)
    rows = rng.permutation(len(live.weight))[:50]
    picked = live.rows(rows)
    for name in ("origin", "direction", "pixel", "weight", "sample", "wavelength"):
        assert np.array_equal(getattr(picked, name), getattr(live, name)[rows]), name


def test_rays_of_unequal_lengths_are_refused() -> None:
    rays = kernel_rays(np.random.default_rng(5), 30, False, "mixed", 0)
    with mock.patch.object(jit, "_use_compiled", [True]), pytest.raises(ValueError, match="unequal lengths"):
        live_rays(rays, SampleBlock(0, 20, 2), 1)


def test_the_loop_stops_at_the_end_of_its_rows() -> None:
    """Given rows for fewer live rays than there are (less the spare row), the loop writes nothing
    past its arrays and says so."""
    rays = kernel_rays(np.random.default_rng(6), 50, False, "all live", 0)
    rows = 40
    out = (np.empty((rows, 3), np.float32), np.empty((rows, 3), np.float32), np.empty(rows, np.int32),
           np.empty(rows, np.float32), np.empty(0, np.float32), np.empty(rows, np.int64))
    loop = compiled(runner._pick_live, runner.PICK_SIGNATURE)
    assert loop(rays.origin, rays.direction, rays.weight, rays.pixel, np.empty(0, np.float32), 0, 5, 0, 1, *out) == -1
