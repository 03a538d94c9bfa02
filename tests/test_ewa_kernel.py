"""``kernels/ewa.cl`` against its numpy reference ``MipMap.ewa`` (itself checked against a scalar
transcription of pbrt-v3's loop in test_textures.py): same taps, same weights, float32 rounding."""

import numpy as np
import pytest

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
    device = mipmap.ewa(st, axis0, axis1, "opencl")
    assert device.dtype == np.float32 and device.shape == reference.shape
    np.testing.assert_allclose(device, reference, rtol=1e-6, atol=1e-6)


def test_an_empty_batch(opencl_platform):
    mipmap = MipMap(np.ones((8, 8, 3)))
    empty = np.zeros((0, 2))
    assert mipmap.ewa(empty, empty, empty, "opencl").shape == (0, 3)
