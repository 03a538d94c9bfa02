"""The measured path's light numbers in one compiled loop (``rng.all_light_uniforms``): bit for bit
``rng.light_uniforms`` of every light sample, so renders keep their numbers whatever the executor."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from realistic.core import rng


def _reference(pixel: np.ndarray, sample: np.ndarray, light_samples: int, seed: int, pick: bool) -> np.ndarray:
    return np.stack([np.stack(rng.light_uniforms(pixel, sample, k, light_samples, seed, pick=pick))
                     for k in range(light_samples)], axis=1)


def test_all_light_uniforms_are_light_uniforms_bit_for_bit():
    generator = np.random.default_rng(11)
    pixel = np.concatenate([[0, 2**32 - 1, 2**31], generator.integers(0, 2**32, 2000)])
    sample = np.concatenate([[2**32 - 1, 0, 7], generator.integers(0, 2**32, 2000)])  # wrapping indices too
    for light_samples, seed, pick in ((128, 0, True), (4, 12345, False), (3, 2**40 + 7, True), (1, -5, True)):
        got = rng.all_light_uniforms(pixel, sample, light_samples, seed, pick=pick)
        assert got.shape == (3, light_samples, len(pixel)) and got.dtype == np.float32
        assert np.array_equal(got, _reference(pixel, sample, light_samples, seed, pick))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(0, 2**32 - 1))
def test_all_light_uniforms_match_at_any_pixel_sample_count_and_seed(pixel, sample, light_samples, seed):
    p, s = np.array([pixel], np.int64), np.array([sample], np.int64)
    assert np.array_equal(rng.all_light_uniforms(p, s, light_samples, seed),
                          _reference(p, s, light_samples, seed, True))
