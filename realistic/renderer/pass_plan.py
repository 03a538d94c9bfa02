"""Which samples each pass covers, and the order passes run in.

A pass is a ``SampleBlock`` (``realistic.camera.base``): a run of pixels times a slice of each
pixel's samples, so a camera makes its rays in one call. The plan takes sample slices outermost
(every pixel's first slice before anyone's second; slices double in width) and runs of pixels
inside, so after any prefix of passes that finishes a slice every pixel has the same number of
samples: an interrupted, checkpointed or previewed image is a whole noisy frame. Within a slice the runs of pixels are
visited in bit-reversed order (van der Corput), so a slice in progress is spread over the frame
too. A pass is about ``pass_samples`` pairs. Random numbers depend on (pixel, sample, dimension,
seed) only, so the plan changes only the float64 summation order of an image. The film adds pass
sums in plan index order whatever order they finish in (``film.PassFilm``), so an image does not
depend on threads, workers or retries.
"""

from __future__ import annotations

import numpy as np

from realistic.camera.base import SampleBlock

#: Camera plus shadow rays a pass traces by default. Memory in flight and a pass's fixed costs (kernel
#: launches, embree calls, Python) both go with it: 2^19 rays is 2^18 samples of one camera ray and one
#: shadow ray each, 104,857 at four light samples: large enough that the fixed costs are small against
#: the tracing, small enough that the rays in flight stay a modest part of a render's memory
#: (bench/render.py and bench/scenes.py measure both sides).
PASS_RAYS = 1 << 19


def default_pass_samples(rays_per_sample: int = 1, light_samples: int = 1) -> int:
    """Samples per pass for a camera tracing ``rays_per_sample`` rays per sample (a spectral camera's
    wavelengths) with ``light_samples`` shadow rays per hit: ``PASS_RAYS`` rays in all, so passes
    of the homework scenes' four light samples hold a fifth of the samples, not more memory."""
    return max(1, PASS_RAYS // (max(1, rays_per_sample) * (1 + max(0, light_samples))))


DEFAULT_PASS_SAMPLES = default_pass_samples()  # one camera ray and one light sample per sample: 2^18


def progressive_order(count: int) -> np.ndarray:
    """Permutation of 0 .. count - 1 sorted by bit-reversed index (ties cannot occur)."""
    if count <= 1:
        return np.arange(count, dtype=np.int64)
    bits = int(count - 1).bit_length()
    index = np.arange(count, dtype=np.int64)
    reversed_index = np.zeros(count, dtype=np.int64)
    for bit in range(bits):
        reversed_index |= ((index >> bit) & 1) << (bits - 1 - bit)
    return np.argsort(reversed_index, kind="stable")


def slice_bounds(pixels: int, spp: int, pass_samples: int) -> list[int]:
    """Sample boundaries 0 = b0 < b1 < ... = spp of the slices: the first slice is as wide as lets
    one pass hold every pixel (at least 1 sample), and each later one as wide as all before it
    (capped at ``pass_samples``). The first whole frame comes after 1/spp of the render at most;
    the samples per pixel double from slice to slice, so there are about log2(spp) + 1 slices and
    a pixel's sums are sent and added that many times, not spp times."""
    bounds = [0, min(spp, max(1, pass_samples // pixels))]
    while bounds[-1] < spp:
        bounds.append(min(spp, bounds[-1] + min(bounds[-1], pass_samples)))
    return bounds


def plan_passes(pixels: int, spp: int, pass_samples: int = DEFAULT_PASS_SAMPLES) -> list[SampleBlock]:
    """The passes of a render of ``pixels`` pixels at ``spp`` samples each, in progressive order:
    slices (``slice_bounds``) outermost, runs of about pass_samples / slice width pixels inside."""
    if pass_samples < 1:
        raise ValueError(f"pass_samples must be >= 1, got {pass_samples}")
    bounds = slice_bounds(pixels, spp, pass_samples)
    plan = []
    for first_sample, end in zip(bounds[:-1], bounds[1:]):
        samples = end - first_sample
        run = max(1, pass_samples // samples)
        starts = np.arange(0, pixels, run, dtype=np.int64)
        plan += [SampleBlock.of_pixels(int(starts[i]), int(min(run, pixels - starts[i])), first_sample, samples)
                 for i in progressive_order(len(starts))]
    return plan
