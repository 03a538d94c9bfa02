"""The film: per-pixel sums of weight x radiance over the samples taken so far, divided by their count.

The pixel filter is not applied here: the camera draws each sample's film position from the filter
around its own pixel and folds sign(f) integral|f| / integral(f) into its weight
(``realistic.core.pixel_filter``), so sum / samples is the filtered value whatever the filter, and
a pass never spills into neighbouring pixels.

Lens flare (``realistic.renderer.flare``) is light traced from the lights, which lands anywhere on
the film: each pass brings its ``Splats`` (per pixel reached, the sum over the pass's light paths,
one per sample id), kept in a film-sized ``flare`` array and divided by every sample taken so far,
so a pixel's value is its camera estimate plus the flare's irradiance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realistic.camera.base import SampleBlock
from realistic.core.jit import compiled, compiled_loops
from realistic.renderer.crop import PixelBounds


@dataclass(frozen=True)
class Splats:
    """One pass's light-traced contributions: per pixel reached (ascending, each once), the sum
    of its light paths' values (float64 RGB); the film divides by the samples taken."""

    pixel: np.ndarray  # (M,) int64
    value: np.ndarray  # (M, 3) float64

    @classmethod
    def of(cls, pixel: np.ndarray, value: np.ndarray) -> Splats:
        """The splats of (pixel, value) rows, summed per pixel in row order (deterministic)."""
        unique, where = np.unique(np.asarray(pixel, np.int64), return_inverse=True)
        sums = np.zeros((len(unique), 3))
        for c in range(3):
            sums[:, c] = np.bincount(where, weights=value[:, c], minlength=len(unique))
        return cls(unique, sums)

    @classmethod
    def empty(cls) -> Splats:
        """A pass whose light paths reached no pixel."""
        return cls(np.zeros(0, np.int64), np.zeros((0, 3)))


def _add_rows(pixel: np.ndarray, first_pixel: int, value: np.ndarray, weight: np.ndarray, sums: np.ndarray) -> bool:
    """Add value[i] * weight[i] (in value's precision) to sums[pixel[i] - first_pixel] (float64),
    row by row in order; False, with nothing more added, at the first pixel outside ``sums`` (a
    numba loop, ``core.jit``: one pass over the rows, where a ``np.bincount`` per column read them
    once each; the pixels are read as the camera made them, int32, not cast and shifted first).
    Three columns (radiance) are spelt out: a loop over them cost a third more."""
    for i in range(pixel.shape[0]):
        p = pixel[i] - first_pixel
        if p < 0 or p >= sums.shape[0]:
            return False
        w = weight[i]
        if value.shape[1] == 3:
            sums[p, 0] += np.float64(value[i, 0] * w)
            sums[p, 1] += np.float64(value[i, 1] * w)
            sums[p, 2] += np.float64(value[i, 2] * w)
        else:
            for c in range(value.shape[1]):
                sums[p, c] += np.float64(value[i, c] * w)
    return True


def pass_sums(pixel: np.ndarray, value: np.ndarray, first_pixel: int, pixel_count: int,
              weight: np.ndarray | None = None) -> np.ndarray:
    """Sums (pixel_count, columns) float64 of ``value`` rows (N, columns) per pixel, pixels
    first_pixel .. + pixel_count - 1, each row added in turn in float64 (the same bits whatever the
    executor). ``weight`` (N,), of value's dtype: each row times its weight first, rounded to
    value's precision (the film's sample weights, without an (N, columns) product array)."""
    value = np.asarray(value)
    if value.dtype != np.float32:
        value = value.astype(np.float64, copy=False)
    weight = np.ones(len(value), value.dtype) if weight is None else np.asarray(weight, value.dtype)
    pixel = np.asarray(pixel)
    if pixel.dtype != np.int32:  # the cameras' pixels are int32, read as they are
        pixel = pixel.astype(np.int64, copy=False)
    outside = ValueError(f"pass_sums: a pixel outside {first_pixel} .. {first_pixel + pixel_count - 1}")
    if not compiled_loops():  # numpy's form (``core.jit.use_compiled_loops``): np.bincount adds each
        local = pixel - np.int64(first_pixel)
        if len(local) and (local.min() < 0 or local.max() >= pixel_count):  # weight in turn, in float64
            raise outside
        products = (value * weight[:, None]).astype(np.float64)
        # float64 whatever the rows: np.bincount of no rows gives int64 zeros, weights or not
        return np.stack([np.bincount(local, products[:, c], pixel_count) for c in range(value.shape[1])],
                        axis=1).astype(np.float64, copy=False) if value.shape[1] else np.zeros((pixel_count, 0))
    sums = np.zeros((pixel_count, value.shape[1]), np.float64)
    if not compiled(_add_rows)(pixel, np.int64(first_pixel), value, weight, sums):
        raise outside
    return sums


class Film:
    """Accumulates contributions of sample blocks; pixel value = sum / samples taken.

    Every sample counts, vignetted ones included (their contribution is 0), so a pixel's value is
    the film irradiance estimate E = mean(weight * radiance). ``columns`` beyond the radiance's 3
    hold the AOVs' sums (``aov.AovLayout``). ``flare``: the film also holds passes' ``Splats``
    (module docstring).
    """

    def __init__(self, width: int, height: int, spp: int, *, bounds: PixelBounds | None = None, columns: int = 3,
                 flare: bool = False):
        self.width, self.height, self.spp = width, height, spp
        self.bounds = PixelBounds.whole(width, height) if bounds is None else bounds  # what ``image`` shows
        self.sums = np.zeros((width * height, columns), np.float64)
        self.samples = np.zeros(width * height, np.int64)
        self.flare = np.zeros((width * height, 3), np.float64) if flare else None

    def add(self, block: SampleBlock, first_pixel: int, sums: np.ndarray, splats: Splats | None = None) -> None:
        """Add the sums of a pass (from ``pass_sums``) of the samples of ``block``, and its flare."""
        self.sums[first_pixel:first_pixel + len(sums)] += sums
        self.samples[block.first_pixel:block.first_pixel + block.pixel_count] += block.samples_per_pixel()
        if self.flare is not None and splats is not None:
            self.flare[splats.pixel] += splats.value

    def image(self) -> np.ndarray:
        """(height, width, 3) float32 film values of ``bounds`` (the whole film unless cropped);
        pixels with no samples yet are 0."""
        b = self.bounds
        sums = self.sums[:, :3].reshape(self.height, self.width, 3)[b.y0:b.y1, b.x0:b.x1]
        samples = self.samples.reshape(self.height, self.width, 1)[b.y0:b.y1, b.x0:b.x1]
        value = np.divide(sums, samples, out=np.zeros(sums.shape), where=samples > 0)
        taken = int(self.samples.sum())
        if self.flare is not None and taken:
            value += self.flare.reshape(self.height, self.width, 3)[b.y0:b.y1, b.x0:b.x1] / taken
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
        self.waiting: dict[int, tuple[int, np.ndarray, Splats | None]] = {}  # index -> (first pixel, sums, flare)

    def add(self, index: int, first_pixel: int, sums: np.ndarray, splats: Splats | None = None) -> None:
        """Take pass ``index``'s sums (from ``pass_sums``) starting at pixel ``first_pixel``, and its
        flare ``splats``; a RuntimeError for a pass index, first pixel, sums' shape or splats that
        are not the plan's (a result from a worker is checked here, on arrival, before anything is
        added)."""
        if not 0 <= index < len(self.passes):
            raise RuntimeError(f"pass {index} is not in the plan of {len(self.passes)} passes")
        block = self.passes[index]
        shape = (block.pixel_count, self.film.sums.shape[1])
        if first_pixel != block.first_pixel or sums.shape != shape or sums.dtype != np.float64:
            raise RuntimeError(f"pass {index}: sums {sums.dtype}{sums.shape} from pixel {first_pixel}, "
                               f"expected float64{shape} from pixel {block.first_pixel}")
        if (splats is not None) != (self.film.flare is not None):
            raise RuntimeError(f"pass {index}: flare {'given' if splats is not None else 'missing'}, expected "
                               f"{'some' if self.film.flare is not None else 'none'}")
        if splats is not None and (splats.value.shape != (len(splats.pixel), 3) or splats.value.dtype != np.float64
                                   or (len(splats.pixel) and not 0 <= splats.pixel.min() <= splats.pixel.max()
                                       < len(self.film.samples))):
            raise RuntimeError(f"pass {index}: flare splats {splats.value.dtype}{splats.value.shape} "
                               "outside the film or of the wrong shape")
        if self.has(index):
            return  # a retried task's duplicate
        self.waiting[index] = (first_pixel, sums, splats)
        while self.next_pass in self.waiting:
            self.film.add(self.passes[self.next_pass], *self.waiting.pop(self.next_pass))
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
        film = Film(self.film.width, self.film.height, self.film.spp, bounds=self.film.bounds,
                    columns=self.film.sums.shape[1], flare=self.film.flare is not None)
        film.sums[:], film.samples[:] = self.film.sums, self.film.samples
        if film.flare is not None and self.film.flare is not None:
            film.flare[:] = self.film.flare
        for index in sorted(self.waiting):
            film.add(self.passes[index], *self.waiting[index])
        return film.image()

    def sums(self) -> np.ndarray:
        """The film's sums (pixels, columns) of every pass taken so far, waiting ones included."""
        if not self.waiting:
            return self.film.sums
        sums = self.film.sums.copy()
        for index in sorted(self.waiting):
            first_pixel, waiting, _ = self.waiting[index]
            sums[first_pixel:first_pixel + len(waiting)] += waiting
        return sums
