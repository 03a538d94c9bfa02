"""The film: per-pixel sums of weight x radiance over the samples taken so far, divided by their count.

The pixel filter is not applied here: the camera draws each sample's film position from the filter
around its own pixel and folds sign(f) integral|f| / integral(f) into its weight
(``realistic.core.pixel_filter``), so sum / samples is the filtered value whatever the filter, and
a pass never spills into neighbouring pixels."""

from __future__ import annotations

import numpy as np

from realistic.camera.base import SampleBlock
from realistic.renderer.crop import PixelBounds


def pass_sums(pixel: np.ndarray, value: np.ndarray, first_pixel: int, pixel_count: int) -> np.ndarray:
    """Sums (pixel_count, 3) of ``value`` rows per pixel, pixels first_pixel .. + pixel_count - 1."""
    local = pixel - first_pixel
    return np.column_stack([np.bincount(local, weights=value[:, c], minlength=pixel_count)
                            for c in range(3)])


class Film:
    """Accumulates contributions of sample blocks; pixel value = sum / samples taken.

    Every sample counts, vignetted ones included (their contribution is 0), so a pixel's value is
    the film irradiance estimate E = mean(weight * radiance).
    """

    def __init__(self, width: int, height: int, spp: int, bounds: PixelBounds | None = None):
        self.width, self.height, self.spp = width, height, spp
        self.bounds = PixelBounds.whole(width, height) if bounds is None else bounds  # what ``image`` shows
        self.sums = np.zeros((width * height, 3), np.float64)
        self.samples = np.zeros(width * height, np.int64)

    def add(self, block: SampleBlock, first_pixel: int, sums: np.ndarray) -> None:
        """Add the sums of a pass (from ``pass_sums``) of the samples of ``block``."""
        self.sums[first_pixel:first_pixel + len(sums)] += sums
        self.samples[block.first_pixel:block.first_pixel + block.pixel_count] += block.samples_per_pixel()

    def image(self) -> np.ndarray:
        """(height, width, 3) float32 film values of ``bounds`` (the whole film unless cropped);
        pixels with no samples yet are 0."""
        b = self.bounds
        sums = self.sums.reshape(self.height, self.width, 3)[b.y0:b.y1, b.x0:b.x1]
        samples = self.samples.reshape(self.height, self.width, 1)[b.y0:b.y1, b.x0:b.x1]
        value = np.divide(sums, samples, out=np.zeros(sums.shape), where=samples > 0)
        return value.astype(np.float32)


class PassFilm:
    """A ``Film`` fed the sums of numbered passes in pass-index order, whatever order they arrive in.

    Sums that arrive early wait until every pass before them is in, so float64 additions happen in
    one order and the image is bit-identical however passes were scheduled. ``passes`` holds each
    pass's ``SampleBlock`` in index order (``pass_plan.plan_passes``).
    """

    def __init__(self, film: Film, passes: list[SampleBlock]):
        self.film, self.passes = film, passes
        self.next_pass = 0  # passes 0 .. next_pass - 1 are in film
        self.waiting: dict[int, tuple[int, np.ndarray]] = {}  # index -> (first pixel, sums)

    def add(self, index: int, first_pixel: int, sums: np.ndarray) -> None:
        """Take pass ``index``'s sums (from ``pass_sums``) starting at pixel ``first_pixel``."""
        if self.has(index):
            return  # a retried task's duplicate
        self.waiting[index] = (first_pixel, sums)
        while self.next_pass in self.waiting:
            first_pixel, sums = self.waiting.pop(self.next_pass)
            self.film.add(self.passes[self.next_pass], first_pixel, sums)
            self.next_pass += 1

    def has(self, index: int) -> bool:
        """Whether pass ``index`` has been taken."""
        return index < self.next_pass or index in self.waiting

    @property
    def passes_taken(self) -> int:
        return self.next_pass + len(self.waiting)

    def image(self) -> np.ndarray:
        """The image of every pass taken so far, waiting ones included (``Film.image``)."""
        if not self.waiting:
            return self.film.image()
        film = Film(self.film.width, self.film.height, self.film.spp, self.film.bounds)
        film.sums[:], film.samples[:] = self.film.sums, self.film.samples
        for index in sorted(self.waiting):
            film.add(self.passes[index], *self.waiting[index])
        return film.image()
