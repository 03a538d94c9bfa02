"""Finding the exit-pupil boxes: which directions from a film point pass the whole lens.

pbrt bounds the exit pupil per radial film interval by tracing a dense grid of directions from
several film points in each interval and keeping the bounding box of those that pass (pbrt-v3
``src/cameras/realistic.cpp``, ``BoundExitPupil``: 1024 x 1024 samples per interval). Most of those
rays tell nothing: only the ones near the box's edges decide it. This search traces about 1,300 rays
per film radius instead of pbrt's million, with the float64 reference tracer, and costs one trace
per surface, so its time grows linearly with the number of surfaces:

1. a coarse grid over the whole region the rear element can be reached in (``RearElementSampler``)
   finds where the passing directions are (and a dense grid where the coarse one finds none: at
   every radius when it finds none at all, as for a small stop, else next to the radii it lit;
   then a fine scan of the line y = 0, across which the last sliver of a vignetted pupil lies);
2. a finer grid over that region grown by a cell and a half gives, row by row and column by
   column, a passing point next to a blocked one (where the pupil reaches the window's edge, the
   coarse grid missed part of it: the window doubles that way, up to ``WINDOW_GROWTHS`` times);
3. bisection between each such pair finds the edge on that row or column to 1/256 of a cell.

The box per film radius is the extreme of its rows' and columns' edges. An extreme that falls
between two rows (or between two film radii) can exceed the nearest sampled one by at most half
the difference to its neighbour, both for a smooth edge (the excess is second order) and for a
corner where two apertures' edges meet (first order, at most half the step); each box is grown by
that much, and by the bisection's final bracket. Directions are sampled on the plane z = plane_z
in the frame of a film point on the +x axis; the pupil is symmetric in y, so only y >= 0 is traced.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from realistic.optics.lens import LensSystem
from realistic.optics.tracer import trace_from_film

#: Grid sizes (x columns, y rows over y >= 0) of the three stages, and the bisection steps.
COARSE_GRID = (24, 12)
DENSE_GRID = (64, 32)
#: The line y = 0 (and the reach, a row that passes nothing) scanned where the dense grid finds nothing.
LINE_SCAN = (2048, 2)
FINE_GRID = (32, 16)
BISECTION_STEPS = 8
#: How many times a search window may double where the pupil reaches its edge.
WINDOW_GROWTHS = 3
#: Radii next to a lit one that the dense grid searches when the coarse grid finds nothing there.
DENSE_NEIGHBOURS = 2
#: Changes with the search, so that tables an older search cached on disk are not used.
SEARCH_VERSION = repr((4, COARSE_GRID, DENSE_GRID, LINE_SCAN, FINE_GRID, BISECTION_STEPS, DENSE_NEIGHBOURS,
                       WINDOW_GROWTHS))


class _Passes:
    """Whether directions from film points on +x reach the scene at any of the wavelengths."""

    def __init__(self, lens: LensSystem, film_distance_mm: float, plane_z_mm: float,
                 wavelengths_nm: tuple[float, ...]):
        self.lens, self.film_distance_mm, self.plane_z_mm = lens, film_distance_mm, plane_z_mm
        self.wavelengths_nm = wavelengths_nm

    def __call__(self, film_x: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Pass mask of the shape of the broadcast arrays (film radius, plane x, plane y)."""
        film_x, x, y = np.broadcast_arrays(film_x, x, y)
        shape = film_x.shape
        origins = np.zeros((film_x.size, 3))
        origins[:, 0] = film_x.ravel()
        directions = np.stack([x.ravel() - film_x.ravel(), y.ravel(), np.full(film_x.size, self.plane_z_mm)], axis=1)
        # every wavelength in one trace (a ray per direction and wavelength): the tracer's cost is
        # mostly numpy's per-call overhead, so one call of 3N rays takes about what one of N does
        count = len(self.wavelengths_nm)
        wavelengths = np.repeat(np.asarray(self.wavelengths_nm, np.float64), film_x.size) if count > 1 \
            else self.wavelengths_nm[0]
        passed = trace_from_film(self.lens, self.film_distance_mm, np.tile(origins, (count, 1)),
                                 np.tile(directions, (count, 1)), wavelengths).passed
        return np.any(passed.reshape(count, -1), axis=0).reshape(shape)


def _grid(lo: np.ndarray, hi: np.ndarray, count: int) -> np.ndarray:
    """(R, count) evenly spaced points from lo to hi per row."""
    return lo[:, None] + np.linspace(0.0, 1.0, count)[None, :] * (hi - lo)[:, None]


def _found_region(passes: _Passes, film_x: np.ndarray, reach: np.ndarray, grid: tuple[int, int],
                  rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """On a grid over x in [-reach, reach], y in [0, reach] for film radii ``rows``: whether any
    point passed, the passing points' (x0, x1, y1) and the grid's cell size (x, y)."""
    xs = _grid(-reach[rows], reach[rows], grid[0])
    ys = _grid(np.zeros(len(rows)), reach[rows], grid[1])
    passed = passes(film_x[rows, None, None], xs[:, :, None], ys[:, None, :])
    any_x, any_y = np.any(passed, axis=2), np.any(passed, axis=1)
    found = np.any(any_x, axis=1)
    first = np.argmax(any_x, axis=1)
    last = grid[0] - 1 - np.argmax(any_x[:, ::-1], axis=1)
    top = grid[1] - 1 - np.argmax(any_y[:, ::-1], axis=1)
    index = np.arange(len(rows))
    box = np.stack([xs[index, first], xs[index, last], ys[index, top]], axis=1)
    cell = np.stack([2 * reach[rows] / (grid[0] - 1), reach[rows] / (grid[1] - 1)], axis=1)
    return found, box, cell


#: One bisection problem: film x, inside, outside, other, along_x, needed (``_bisect``).
_Problem = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool, np.ndarray]


def _bisect(passes: _Passes, problems: list[_Problem]) -> list[np.ndarray]:
    """Per problem (film_x, inside, outside, other, along_x, needed): the outer end of the final
    bracket between passing ``inside`` and blocked ``outside`` coordinates (x when ``along_x``, else
    y; ``other`` is the fixed coordinate), traced only where ``needed``; elsewhere ``inside`` itself
    (a grid point at the window's edge, or nothing passing). The problems are independent, so every
    step traces all of their pairs at once: one call instead of one per problem."""
    edges, parts = [], []
    for film_x, inside, outside, other, along, needed in problems:
        edges.append(inside.copy())
        parts.append((film_x[needed], inside[needed], outside[needed], other[needed],
                      np.full(int(np.count_nonzero(needed)), along)))
    film_x, inside, outside, other, along_x = (np.concatenate(column) for column in zip(*parts))
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (inside + outside)
        passed = passes(film_x, np.where(along_x, middle, other), np.where(along_x, other, middle))
        inside = np.where(passed, middle, inside)
        outside = np.where(passed, outside, middle)
    ends = np.cumsum([len(part[0]) for part in parts])
    for edge, (_, _, _, _, _, needed), found in zip(edges, problems, np.split(outside, ends[:-1])):
        edge[needed] = found
    return edges


def _edges(passes: _Passes, film_x: np.ndarray, x_lo: np.ndarray, x_hi: np.ndarray, y_hi: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (R, 3) = (x0, x1, y1) of the passing directions for film radii ``film_x`` found in the
    windows [x_lo, x_hi] x [0, y_hi], and their padding (R, 3)."""
    columns, rows = FINE_GRID
    xs, ys = _grid(x_lo, x_hi, columns), _grid(np.zeros_like(y_hi), y_hi, rows)
    passed = passes(film_x[:, None, None], xs[:, :, None], ys[:, None, :])  # (R, columns, rows)
    radii = np.arange(len(film_x))[:, None]
    # per row: the first and last passing column; per column: the topmost passing row
    row_any = passed.any(axis=1)  # (R, rows)
    first = np.argmax(passed, axis=1)  # (R, rows)
    last = columns - 1 - np.argmax(passed[:, ::-1, :], axis=1)
    column_any = passed.any(axis=2)  # (R, columns)
    top = rows - 1 - np.argmax(passed[:, :, ::-1], axis=2)
    film_rows = np.broadcast_to(film_x[:, None], first.shape)
    film_columns = np.broadcast_to(film_x[:, None], top.shape)
    left, right, upper = _bisect(passes, [
        (film_rows, xs[radii, first], xs[radii, np.maximum(first - 1, 0)], ys, True, row_any & (first > 0)),
        (film_rows, xs[radii, last], xs[radii, np.minimum(last + 1, columns - 1)], ys, True,
         row_any & (last < columns - 1)),
        (film_columns, ys[radii, top], ys[radii, np.minimum(top + 1, rows - 1)], xs, False,
         column_any & (top < rows - 1))])
    left = np.where(row_any, left, np.inf)
    right = np.where(row_any, right, -np.inf)
    upper = np.where(column_any, upper, -np.inf)
    box = np.stack([left.min(axis=1), right.max(axis=1), upper.max(axis=1)], axis=1)
    bracket = np.stack([(x_hi - x_lo) / (columns - 1), (x_hi - x_lo) / (columns - 1), y_hi / (rows - 1)], axis=1)
    pad = bracket / 2**BISECTION_STEPS + np.stack([_between(left, np.argmin, -1), _between(right, np.argmax, 1),
                                                   _between(upper, np.argmax, 1)], axis=1)
    return box, pad


def _between(edges: np.ndarray, pick: Callable[..., np.ndarray], sign: int) -> np.ndarray:
    """Half the largest step from the extreme sample to its neighbours (R,): how far the extreme
    can lie beyond it between samples. Unsampled neighbours (inf) do not count."""
    count = edges.shape[1]
    at = pick(np.where(np.isfinite(edges), edges, -sign * np.inf), axis=1)
    index = np.arange(len(edges))
    extreme = edges[index, at]
    steps = []
    for offset in (-1, 1):
        neighbour = edges[index, np.clip(at + offset, 0, count - 1)]
        steps.append(np.where(np.isfinite(neighbour) & np.isfinite(extreme), np.abs(neighbour - extreme), 0.0))
    return 0.5 * np.maximum(*steps)


def pupil_boxes(lens: LensSystem, film_distance_mm: float, plane_z_mm: float, film_radii_mm: np.ndarray,
                reach_mm: np.ndarray, wavelengths_nm: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per film radius on +x: the box (x0, x1, y1) of the passing directions on the plane (R, 3),
    or NaN where none pass, and how far each edge may lie beyond (R, 3), for a lens whose stop is
    round (``exit_pupil_table`` replaces a shaped stop by its circle first)."""
    passes = _Passes(lens, film_distance_mm, plane_z_mm, wavelengths_nm)
    everything = np.arange(len(film_radii_mm))
    found, box, cell = _found_region(passes, film_radii_mm, reach_mm, COARSE_GRID, everything)
    missed = np.flatnonzero(~found)
    if found.any():  # beyond an image circle's edge nothing passes: look densely only next to the lit radii
        lit_near = np.convolve(found, np.ones(2 * DENSE_NEIGHBOURS + 1), mode="same") > 0
        missed = missed[lit_near[missed]]
    if len(missed):  # a pupil smaller than a coarse cell (a small stop), or one vignetted nearly away
        found[missed], box[missed], cell[missed] = _found_region(passes, film_radii_mm, reach_mm, DENSE_GRID, missed)
        missed = missed[~found[missed]]
    if len(missed):  # at an image circle's edge the pupil is a sliver across y = 0: scan that line finely
        found[missed], box[missed], cell[missed] = _found_region(passes, film_radii_mm, reach_mm, LINE_SCAN, missed)
    lit = np.flatnonzero(found)
    result = np.full((len(film_radii_mm), 3), np.nan)
    pad = np.zeros((len(film_radii_mm), 3))
    if len(lit):
        grow = 1.5 * cell[lit]
        x_lo = np.maximum(box[lit, 0] - grow[:, 0], -reach_mm[lit])
        x_hi = np.minimum(box[lit, 1] + grow[:, 0], reach_mm[lit])
        y_hi = np.minimum(box[lit, 2] + grow[:, 1], reach_mm[lit])
        todo = np.arange(len(lit))
        for _ in range(WINDOW_GROWTHS + 1):
            radii = lit[todo]
            result[radii], pad[radii] = _edges(passes, film_radii_mm[radii], x_lo[todo], x_hi[todo], y_hi[todo])
            # a passing direction on the window's edge, short of the reach: the coarse grid missed part
            # of the pupil there, so the window doubles that way and the search runs again
            reach = reach_mm[radii]
            low = (result[radii, 0] <= x_lo[todo]) & (x_lo[todo] > -reach)
            high = (result[radii, 1] >= x_hi[todo]) & (x_hi[todo] < reach)
            top = (result[radii, 2] >= y_hi[todo]) & (y_hi[todo] < reach)
            span_x, span_y = x_hi[todo] - x_lo[todo], y_hi[todo]
            x_lo[todo] = np.where(low, np.maximum(x_lo[todo] - span_x, -reach), x_lo[todo])
            x_hi[todo] = np.where(high, np.minimum(x_hi[todo] + span_x, reach), x_hi[todo])
            y_hi[todo] = np.where(top, np.minimum(2 * span_y, reach), y_hi[todo])
            todo = todo[low | high | top]
            if not len(todo):
                break
    return result, pad
