"""Counter-based random numbers, bit-identical in numpy and in ``kernels/lens.cl`` and ``kernels/shade.cl``.

Every number is a pure function of (pixel, sample index, dimension, seed), so a render does not
depend on batch size, pass order or the number of workers, and the numpy reference can be fed the
kernel's samples exactly. All arithmetic is on uint32 and wraps modulo 2^32 in both languages.

Stratification within a pixel: the first four dimensions (film x, film y, lens u, lens v) are the
4-D Kronecker sequence R4 (generalised golden ratio; Roberts 2018) over the pixel's sample index,
computed in 32-bit fixed point and shifted by a per-pixel random toroidal offset (Cranley-Patterson
rotation). Any sample count is well stratified, jointly in the four dimensions. A spectral sample
draws its wavelength as a fifth dimension of the same kind of sequence: its five numbers are the 5-D
Kronecker sequence R5 (the real root of x^6 = x + 1) with the rotation extended by a fifth per-pixel
offset, so a pixel's film points, lens points and wavelengths are stratified together
(``stratified5``). Non-spectral samples keep R4. Other dimensions (``uniform``) are plain hashes.

Light samples of direct lighting (``light_bits``): a pixel's spp x L light samples (L per camera
sample) are the points 0 .. spp L - 1 of a per-pixel randomised Sobol' sequence over the index
sample L + k. The light's 2-D point (u1, u2) is Sobol's first two dimensions, a (0, 2)-sequence in
base 2 (every aligned block of 2^m points has one point in each of the 2^m elementary boxes of any
shape; Niederreiter 1992), Owen-scrambled per pixel and dimension with the hash-based scrambler of
pbrt-v4 (``FastOwenScrambler``, src/pbrt/util/lowdiscrepancy.h; Burley 2020, "Practical hash-based
Owen scrambling", JCGT 9(4)), which keeps the net property and makes each point uniform. The index
itself is shuffled per pixel by the same kind of scramble (applied to its bits from the top), which
permutes aligned blocks of 2^m indices among themselves: the pairing of light points with camera
samples is random ("padding", as pbrt's samplers pad dimensions), yet the L light samples of one
camera sample (L a power of two) still form a net, and so do the pixel's. The light pick u0 is the
same construction in one dimension (a scrambled van der Corput sequence, index shuffled with its own
key): stratified, but independent of the point, as pbrt samples a light's index and point from
separate dimensions. Why Sobol' and not a Kronecker sequence like the camera's: its 2-D points are
(0, m, 2)-nets, and for the discontinuous visibility of a soft shadow an Owen-scrambled net's
variance falls like N^-1.5 (Owen 1997); on a disk light half-covered by random edges and blobs,
measured at N = 16 / 64 / 256 points, the mean squared error was 0.0119 / 0.0032 / 0.00072 with iid
numbers, 0.0093 / 0.00073 / 0.000092 with R3's last two dimensions (Cranley-Patterson rotated), and
0.0029 / 0.00039 / 0.000046 with these. The per-pixel keys are
``hash_key(pixel, 0xFFFFFFFF, d, seed)`` at d = ``LIGHT_KEYS`` (the camera's rotations use d = 0 .. 4).
The index is uint32: distinct while spp x L <= 2^32 (beyond, at the validation's extremes of 2^24
spp and 1024 light samples, samples 2^32 / L apart repeat their light numbers).

Several wavelengths per sample (``spectral_rays``): a spectral sample traced at K wavelengths takes
the K numbers (u4 + j) / K, j = 0 .. K - 1, from its one R5 value u4: exactly one in each 1/K of
[0, 1), as in pbrt-v4's ``SampledWavelengths`` and the hero wavelength of Wilkie et al. 2014. Placing
u4 itself inside each stratum (rather than rotating, (u4 + j / K) mod 1, whose offset inside a
stratum is frac(K u4)) keeps a pixel's spp x K numbers as evenly spread as R5's fifth dimension
(largest gap at most 1.9 / (spp K) measured for spp up to 64, any K; the rotation's reaches 6.8 and
12.9 / (spp K) for K = 8 and 16 at 64 spp) and jointly stratified with the film and lens numbers.
In 32-bit fixed point the number is bits // K + j floor(2^32 / K), which the kernel computes bit
for bit and which never wraps. The K
rays share the sample's film and lens numbers (and its sample index, so whatever else is drawn from
``uniform(pixel, sample, ...)`` too).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from realistic.core.jit import compiled

#: frac(phi_4^-k) * 2^32, k = 1..4, phi_4 the real root of x^5 = x + 1.
KRONECKER_R4 = (0xDB4F0B91, 0xBBE05633, 0xA0F2EC76, 0x89E18285)
#: frac(phi_5^-k) * 2^32 rounded, k = 1..5, phi_5 the real root of x^6 = x + 1 (spectral samples).
KRONECKER_R5 = (0xE19B01AB, 0xC6D1D6C9, 0xAF36D01F, 0x9A69443F, 0x881403B9)
_GOLDEN = 0x9E3779B9
_TO_UNIT = np.float32(1.0 / (1 << 24))


def hash32(x: ArrayLike) -> np.ndarray:
    """Chris Wellons's lowbias32 integer hash on uint32 arrays."""
    h = np.asarray(x, dtype=np.uint32)
    h = h ^ (h >> np.uint32(16))
    h = h * np.uint32(0x7FEB352D)
    h = h ^ (h >> np.uint32(15))
    h = h * np.uint32(0x846CA68B)
    h = h ^ (h >> np.uint32(16))
    return h


def hash_keys(pixel: np.ndarray, sample: ArrayLike, dims: tuple[int, ...], seed: int) -> list[np.ndarray]:
    """``hash_key`` at each of ``dims``, hashing (seed, pixel, sample) once."""
    with np.errstate(over="ignore"):
        h = hash32(np.uint32((seed + _GOLDEN) & 0xFFFFFFFF))
        h = hash32(h ^ np.asarray(pixel, dtype=np.uint32))
        h = hash32(h ^ np.asarray(sample, dtype=np.uint32))
        return [hash32(h ^ np.uint32(dim)) for dim in dims]


def hash_key(pixel: np.ndarray, sample: ArrayLike, dim: int, seed: int) -> np.ndarray:
    """uint32 hash of (pixel, sample, dim, seed); pass sample = 0xFFFFFFFF for per-pixel values."""
    return hash_keys(pixel, sample, (dim,), seed)[0]


def to_unit_float(bits: np.ndarray) -> np.ndarray:
    """Top 24 bits of a uint32 as a float32 in [0, 1), exactly as the kernel converts."""
    return (bits >> np.uint32(8)).astype(np.float32) * _TO_UNIT


def uniform(pixel: np.ndarray, sample: np.ndarray, dim: int, seed: int) -> np.ndarray:
    """Independent uniform float32 in [0, 1) for dimension ``dim`` (use dim >= 4)."""
    return to_unit_float(hash_key(pixel, sample, dim, seed))


def kronecker_bits(pixel: np.ndarray, sample: np.ndarray, seed: int, steps: tuple[int, ...]) -> list[np.ndarray]:
    """uint32 values of the Kronecker sequence with ``steps`` over the sample index, dimension d
    shifted by the per-pixel offset hash_key(pixel, 0xFFFFFFFF, d, seed)."""
    sample = np.asarray(sample, dtype=np.uint32)
    with np.errstate(over="ignore"):
        return [sample * np.uint32(step) + hash_key(pixel, np.uint32(0xFFFFFFFF), dim, seed)
                for dim, step in enumerate(steps)]


def stratified4(pixel: np.ndarray, sample: np.ndarray, seed: int) -> list[np.ndarray]:
    """Film x, film y, lens u, lens v in [0, 1) (float32): R4 rotated by a per-pixel offset."""
    return [to_unit_float(bits) for bits in kronecker_bits(pixel, sample, seed, KRONECKER_R4)]


def wavelength_step(wavelengths: int) -> int:
    """The 32-bit fixed-point width of one of K wavelength strata: floor(2^32 / K) (exactly 2^32 / K
    for K a power of two; 0 for K = 1, which has one stratum)."""
    return ((1 << 32) // wavelengths) & 0xFFFFFFFF


def stratified5(pixel: np.ndarray, sample: np.ndarray, seed: int) -> list[np.ndarray]:
    """Film x, film y, lens u, lens v, wavelength in [0, 1) (float32) of a spectral sample: R5
    rotated by a per-pixel offset (the first four offsets are those of ``stratified4``)."""
    return [to_unit_float(bits) for bits in kronecker_bits(pixel, sample, seed, KRONECKER_R5)]


def spectral_rays(pixel: np.ndarray, sample: np.ndarray, seed: int, wavelengths: int) -> list[np.ndarray]:
    """``stratified5`` for each of the ``wavelengths`` (K) rays of every sample, sample-major (ray
    j of sample i is row i K + j; N K rows): film x, film y, lens u, lens v repeat the sample's, and
    ray j's wavelength number is (u4 + j) / K, u4 the sample's R5 value (in fixed point
    u4_bits // K + j ``wavelength_step(K)``). K = 1 is ``stratified5``."""
    bits = kronecker_bits(np.repeat(np.asarray(pixel), wavelengths), np.repeat(np.asarray(sample), wavelengths),
                          seed, KRONECKER_R5)
    j = np.tile(np.arange(wavelengths, dtype=np.uint32), len(bits[0]) // wavelengths)
    bits[4] = bits[4] // np.uint32(wavelengths) + j * np.uint32(wavelength_step(wavelengths))
    return [to_unit_float(b) for b in bits]


#: Per-pixel key dimensions (``hash_key`` with sample 0xFFFFFFFF) of the light samples: index
#: shuffle and scrambles of u1, u2 (the light point), index shuffle and scramble of u0 (the pick).
LIGHT_KEYS = (16, 17, 18, 19, 20)
#: Per-pixel key dimensions of the BSDF sample that goes with each light sample (MIS direct
#: lighting in ``kernels/shade.cl``): scrambles of its two numbers, at the light point's shuffled index.
BSDF_KEYS = (21, 22)


def reverse_bits(x: np.ndarray) -> np.ndarray:
    """uint32 with its 32 bits in reverse order."""
    x = np.asarray(x, dtype=np.uint32)
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF)):
        x = ((x >> np.uint32(shift)) & np.uint32(mask)) | ((x & np.uint32(mask)) << np.uint32(shift))
    return (x >> np.uint32(16)) | (x << np.uint32(16))


def owen_scramble_digits(digits: np.ndarray, key: np.ndarray) -> np.ndarray:
    """A hashed Owen scramble of a number's base-2 digits stored lowest bit first (bit r holds the
    digit of 2^-(r + 1)): each bit is flipped or not by a function of the key and the bits below it,
    i.e. of the more significant digits (pbrt-v4 ``FastOwenScrambler``'s steps and constants,
    applied to the already reversed bits)."""
    v = np.asarray(digits, dtype=np.uint32)
    key = np.asarray(key, dtype=np.uint32)
    with np.errstate(over="ignore"):
        v = v ^ (v * np.uint32(0x3D20ADEA))
        v = v + key
        v = v * ((key >> np.uint32(16)) | np.uint32(1))
        v = v ^ (v * np.uint32(0x05526C56))
        return v ^ (v * np.uint32(0x53A22864))


def sobol2_digits(index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sobol's first two dimensions of ``index`` as digits lowest bit first (``reverse_bits`` gives
    the 32-bit fixed-point value). Dimension 0 is the van der Corput sequence: the index's own bits.
    Dimension 1's generator matrix is Pascal's triangle mod 2: digit r is the XOR of the index bits c
    with binomial(c, r) odd, i.e. (Lucas) with c a bit superset of r; five butterfly steps sum over
    supersets."""
    y = np.asarray(index, dtype=np.uint32)
    x = y
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF), (16, 0x0000FFFF)):
        x = x ^ ((x >> np.uint32(shift)) & np.uint32(mask))
    return y, x


def _light_index(sample: np.ndarray, k: int, light_samples: int) -> np.ndarray:
    """The light-sample index sample * light_samples + k (uint32, wrapping)."""
    with np.errstate(over="ignore"):
        return np.asarray(sample, dtype=np.uint32) * np.uint32(light_samples) + np.uint32(k)


def _light_sobol_bits(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int,
                      keys: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """uint32 pair of light sample ``k``: the pixel's Sobol' point at the index sample * light_samples + k
    shuffled by key dimension keys[0], its two dimensions Owen-scrambled by keys[1] and keys[2]."""
    shuffle, key1, key2 = hash_keys(pixel, np.uint32(0xFFFFFFFF), keys, seed)
    index = reverse_bits(owen_scramble_digits(reverse_bits(_light_index(sample, k, light_samples)), shuffle))
    d1, d2 = sobol2_digits(index)
    return reverse_bits(owen_scramble_digits(d1, key1)), reverse_bits(owen_scramble_digits(d2, key2))


def light_point_bits(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """uint32 (u1, u2) of light sample ``k`` of ``light_samples`` per camera sample: the pixel's
    Owen-scrambled Sobol' point at its shuffled index sample * light_samples + k (module notes)."""
    return _light_sobol_bits(pixel, sample, k, light_samples, seed, (LIGHT_KEYS[0], LIGHT_KEYS[1], LIGHT_KEYS[2]))


def light_bsdf_uniforms(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """float32 (v1, v2) of the BSDF sample paired with light sample ``k``: the light point's shuffled
    Sobol' index (``light_point_bits``), its two dimensions scrambled with keys of their own
    (``BSDF_KEYS``), so the pixel's BSDF directions are a net as its light points are, independent of them."""
    v1, v2 = _light_sobol_bits(pixel, sample, k, light_samples, seed, (LIGHT_KEYS[0], BSDF_KEYS[0], BSDF_KEYS[1]))
    return to_unit_float(v1), to_unit_float(v2)


def light_pick_bits(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int) -> np.ndarray:
    """uint32 u0 (the light pick) of light sample ``k``: a scrambled van der Corput number at the
    index shuffled by a key of its own (module notes)."""
    shuffle, key = hash_keys(pixel, np.uint32(0xFFFFFFFF), LIGHT_KEYS[3:], seed)
    index = reverse_bits(owen_scramble_digits(reverse_bits(_light_index(sample, k, light_samples)), shuffle))
    return reverse_bits(owen_scramble_digits(index, key))


def light_bits(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int) -> list[np.ndarray]:
    """uint32 values (u0 pick, u1, u2 point) of light sample ``k`` of ``light_samples`` per camera
    sample, as ``kernels/shade.cl`` computes them."""
    return [light_pick_bits(pixel, sample, k, light_samples, seed),
            *light_point_bits(pixel, sample, k, light_samples, seed)]


def light_uniforms(pixel: np.ndarray, sample: np.ndarray, k: int, light_samples: int, seed: int,
                   pick: bool = True) -> list[np.ndarray]:
    """``light_bits`` as float32 in [0, 1): the light pick u0 and the light point u1, u2. ``pick``
    False leaves u0 at 0 without computing it (a scene with one light needs no pick; the kernel's
    compiler drops the pick there too)."""
    u1, u2 = (to_unit_float(bits) for bits in light_point_bits(pixel, sample, k, light_samples, seed))
    u0 = to_unit_float(light_pick_bits(pixel, sample, k, light_samples, seed)) if pick else np.zeros_like(u1)
    return [u0, u1, u2]


def _all_light_loop(pixel: np.ndarray, sample: np.ndarray, light_samples: int, seed: int, pick: bool,
                    out: np.ndarray) -> None:
    """``light_uniforms`` for k = 0 .. light_samples - 1 into ``out`` (3, light_samples, N): the same
    steps on int64 values kept in [0, 2^32) (each product, sum and left shift masked to 32 bits; a
    product past 2^63 wraps, as numba's fixed-width integers do, which leaves its low 32 bits exact),
    so every bit is the uint32 arithmetic's; the per-pixel keys are hashed once per row."""
    m32 = 0xFFFFFFFF
    unit = np.float32(1.0 / (1 << 24))
    swaps = ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF))
    pairs = ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF), (16, 0x0000FFFF))
    keys = np.empty(5, np.int64)
    for r in range(pixel.shape[0]):
        h = (seed + 0x9E3779B9) & m32
        for part in (-1, pixel[r] & m32, m32):  # hash32(seed + golden), then ^ pixel, then ^ 0xFFFFFFFF
            if part >= 0:
                h ^= part
            h ^= h >> 16
            h = (h * 0x7FEB352D) & m32
            h ^= h >> 15
            h = (h * 0x846CA68B) & m32
            h ^= h >> 16
        for j in range(5):
            x = h ^ (16 + j)  # LIGHT_KEYS
            x ^= x >> 16
            x = (x * 0x7FEB352D) & m32
            x ^= x >> 15
            x = (x * 0x846CA68B) & m32
            x ^= x >> 16
            keys[j] = x
        base = ((sample[r] & m32) * light_samples) & m32
        for k in range(light_samples):
            for which in range(3 if pick else 2):  # the point's index (keys 0-2), the pick's (keys 3, 4)
                shuffle = keys[0] if which < 2 else keys[3]
                x = (base + k) & m32
                for step in range(2):  # reverse_bits(owen_scramble_digits(reverse_bits(index), shuffle))
                    for shift, mask in swaps:
                        x = ((x >> shift) & mask) | ((x & mask) << shift)
                    x = ((x >> 16) | (x << 16)) & m32
                    if step == 0:
                        x ^= (x * 0x3D20ADEA) & m32
                        x = (x + shuffle) & m32
                        x = (x * ((shuffle >> 16) | 1)) & m32
                        x ^= (x * 0x05526C56) & m32
                        x ^= (x * 0x53A22864) & m32
                if which == 1:  # Sobol' dimension 1: the butterfly over bit supersets
                    for shift, mask in pairs:
                        x ^= (x >> shift) & mask
                key = keys[1 + which] if which < 2 else keys[4]
                x ^= (x * 0x3D20ADEA) & m32  # reverse_bits(owen_scramble_digits(digits, key))
                x = (x + key) & m32
                x = (x * ((key >> 16) | 1)) & m32
                x ^= (x * 0x05526C56) & m32
                x ^= (x * 0x53A22864) & m32
                for shift, mask in swaps:
                    x = ((x >> shift) & mask) | ((x & mask) << shift)
                x = ((x >> 16) | (x << 16)) & m32
                out[(which + 1) % 3, k, r] = np.float32(x >> 8) * unit
        if not pick:
            for k in range(light_samples):
                out[0, k, r] = 0.0


def all_light_uniforms(pixel: np.ndarray, sample: np.ndarray, light_samples: int, seed: int,
                       pick: bool = True) -> np.ndarray:
    """``light_uniforms`` of every light sample k = 0 .. ``light_samples`` - 1 at once, bit for bit:
    (3, light_samples, N) float32, row [:, k] the list (u0 pick, u1, u2) of sample k. One compiled
    loop (GIL released) instead of numpy's passes over temporaries, once per k."""
    pixel = np.ascontiguousarray(np.asarray(pixel).astype(np.uint32).astype(np.int64))
    sample = np.ascontiguousarray(np.broadcast_to(np.asarray(sample).astype(np.uint32).astype(np.int64),
                                                  pixel.shape))
    out = np.empty((3, light_samples, len(pixel)), np.float32)
    compiled(_all_light_loop)(pixel, sample, int(light_samples), int(seed) & 0xFFFFFFFF, bool(pick), out)
    return out
