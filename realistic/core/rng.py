"""Counter-based random numbers, bit-identical in numpy and in ``kernels/lens.cl``.

Every number is a pure function of (pixel, sample index, dimension, seed), so a render does not
depend on batch size, pass order or the number of workers, and the numpy reference can be fed the
kernel's samples exactly. All arithmetic is on uint32 and wraps modulo 2^32 in both languages.

Stratification within a pixel: the first four dimensions (film x, film y, lens u, lens v) are the
4-D Kronecker sequence R4 (generalised golden ratio; Roberts 2018) over the pixel's sample index,
computed in 32-bit fixed point and shifted by a per-pixel random toroidal offset (Cranley-Patterson
rotation). Any sample count is well stratified, jointly in the four dimensions. The wavelength of
a spectral sample is stratified the same way in one dimension: the golden-ratio Kronecker
sequence over the sample index plus a per-pixel hashed offset, on dimension ``WAVELENGTH_DIM``,
which no other sampler uses. Further dimensions (light samples) are plain hashes.
"""

from __future__ import annotations

import numpy as np

#: frac(phi_4^-k) * 2^32, k = 1..4, phi_4 the real root of x^5 = x + 1.
KRONECKER_R4 = (0xDB4F0B91, 0xBBE05633, 0xA0F2EC76, 0x89E18285)
_GOLDEN = 0x9E3779B9
#: frac(golden ratio) * 2^32: the 1-D Kronecker step of the wavelength dimension.
KRONECKER_1D = 0x9E3779B9
#: Dimension of the per-pixel wavelength offset (far above the light sampler's 4 + 3k .. 6 + 3k).
WAVELENGTH_DIM = 0x7FFFFFFF
_TO_UNIT = np.float32(1.0 / (1 << 24))


def hash32(x: np.ndarray) -> np.ndarray:
    """Chris Wellons's lowbias32 integer hash on uint32 arrays."""
    x = np.asarray(x, dtype=np.uint32)
    x = x ^ (x >> np.uint32(16))
    x = x * np.uint32(0x7FEB352D)
    x = x ^ (x >> np.uint32(15))
    x = x * np.uint32(0x846CA68B)
    x = x ^ (x >> np.uint32(16))
    return x


def hash_key(pixel: np.ndarray, sample: np.ndarray, dim: int, seed: int) -> np.ndarray:
    """uint32 hash of (pixel, sample, dim, seed); pass sample = 0xFFFFFFFF for per-pixel values."""
    with np.errstate(over="ignore"):
        h = hash32(np.uint32((seed + _GOLDEN) & 0xFFFFFFFF))
        h = hash32(h ^ np.asarray(pixel, dtype=np.uint32))
        h = hash32(h ^ np.asarray(sample, dtype=np.uint32))
        return hash32(h ^ np.uint32(dim))


def to_unit_float(bits: np.ndarray) -> np.ndarray:
    """Top 24 bits of a uint32 as a float32 in [0, 1), exactly as the kernel converts."""
    return (bits >> np.uint32(8)).astype(np.float32) * _TO_UNIT


def uniform(pixel: np.ndarray, sample: np.ndarray, dim: int, seed: int) -> np.ndarray:
    """Independent uniform float32 in [0, 1) for dimension ``dim`` (use dim >= 4)."""
    return to_unit_float(hash_key(pixel, sample, dim, seed))


def stratified4(pixel: np.ndarray, sample: np.ndarray, seed: int) -> list[np.ndarray]:
    """Film x, film y, lens u, lens v in [0, 1) (float32): R4 rotated by a per-pixel offset."""
    sample = np.asarray(sample, dtype=np.uint32)
    out = []
    with np.errstate(over="ignore"):
        for dim, step in enumerate(KRONECKER_R4):
            offset = hash_key(pixel, np.uint32(0xFFFFFFFF), dim, seed)
            out.append(to_unit_float(sample * np.uint32(step) + offset))
    return out


def wavelength_bits(pixel: np.ndarray, sample: np.ndarray, seed: int) -> np.ndarray:
    """The uint32 wavelength value of each sample: 1-D Kronecker step plus a per-pixel offset."""
    with np.errstate(over="ignore"):
        offset = hash_key(pixel, np.uint32(0xFFFFFFFF), WAVELENGTH_DIM, seed)
        return np.asarray(sample, dtype=np.uint32) * np.uint32(KRONECKER_1D) + offset
