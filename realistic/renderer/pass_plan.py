"""Which samples each pass covers, and the order passes run in.

A pass is a ``SampleBlock`` (``realistic.camera.base``): a run of pixels times a slice of each
pixel's samples, so a camera makes its rays in one call. The plan takes sample slices outermost
(every pixel's first slice before anyone's second) and runs of pixels inside, so after any prefix
of passes that finishes a slice every pixel has the same number of samples: an interrupted,
checkpointed or previewed image is a whole noisy frame. Within a slice the runs of pixels are
visited in bit-reversed order (van der Corput), so a slice in progress is spread over the frame
too. A pass is about ``pass_samples`` pairs. Random numbers depend on (pixel, sample, dimension,
seed) only, so the plan changes only the float64 summation order of an image. The film adds pass
sums in plan index order whatever order they finish in (``film.PassFilm``), so an image does not
depend on threads, workers or retries.
"""

from __future__ import annotations

import numpy as np

from realistic.camera.base import SampleBlock

DEFAULT_PASS_SAMPLES = 1 << 17


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


def slice_samples(pixels: int, spp: int, pass_samples: int) -> int:
    """Samples of each pixel per slice: as many as let one pass hold every pixel (at least 1)."""
    return max(1, min(spp, pass_samples // pixels))


def plan_passes(pixels: int, spp: int, pass_samples: int = DEFAULT_PASS_SAMPLES) -> list[SampleBlock]:
    """The passes of a render of ``pixels`` pixels at ``spp`` samples each, in progressive order:
    slices of ``slice_samples`` samples outermost, runs of about pass_samples / slice pixels inside."""
    if pass_samples < 1:
        raise ValueError(f"pass_samples must be >= 1, got {pass_samples}")
    width = slice_samples(pixels, spp, pass_samples)
    run = max(1, pass_samples // width)
    starts = np.arange(0, pixels, run, dtype=np.int64)
    plan = []
    for first_sample in range(0, spp, width):
        samples = min(width, spp - first_sample)
        plan += [SampleBlock.of_pixels(int(starts[i]), int(min(run, pixels - starts[i])), first_sample, samples)
                 for i in progressive_order(len(starts))]
    return plan
