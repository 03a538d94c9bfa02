"""Which sample ids each pass covers, and the order passes run in.

A pass is a contiguous range of sample ids (``realistic.camera.base``: id = pixel * spp + sample),
so a camera makes its rays in one call. Passes are numbered in *progressive order*: the raster
ranges are visited in bit-reversed order (van der Corput), so the first 2^k passes of any plan are
spread evenly over the frame (consecutive ones at most about n / 2^k ranges apart) instead of
filling it from the top. The film adds pass sums in this pass index order whatever order they
finish in (``film.PassFilm``), so an image does not depend on threads, workers or retries.
"""

from __future__ import annotations

import numpy as np

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


def plan_passes(total_samples: int, pass_samples: int = DEFAULT_PASS_SAMPLES) -> list[tuple[int, int]]:
    """(first sample id, count) of every pass of a render of ``total_samples`` ids, in progressive order."""
    if pass_samples < 1:
        raise ValueError(f"pass_samples must be >= 1, got {pass_samples}")
    starts = np.arange(0, total_samples, pass_samples, dtype=np.int64)
    return [(int(starts[i]), int(min(pass_samples, total_samples - starts[i]))) for i in progressive_order(len(starts))]
