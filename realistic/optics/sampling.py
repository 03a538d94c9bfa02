"""Film-side sampling: where a camera ray from a film point is aimed, and its radiometric weight.

Two samplers aim rays at a plane z = ``plane_z_mm`` just behind the lens (lens frame, film at
z = 0), both covering every direction in which the rear element can be reached:

* ``RearElementSampler``: a disk on the axis whose radius covers the rear element's real extent
  (its curved cap, not only a flat disk at the vertex) as seen from the film point.
* ``ExitPupilTable``: per radial film interval, the bounding box of the directions that pass the
  whole lens (found by tracing a grid), sampled in the box rotated to the film point's polar
  angle. Fewer samples are wasted on rays the lens blocks.

Both sample their region uniformly, so the Kolb et al. weight cos^4(theta) * A / Z^2 (A: area of
the region, Z: film-to-plane distance) is exact per sample.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from realistic.core.disk_cache import cache_key, load_arrays, store_arrays
from realistic.core.warp import concentric_disk
from realistic.optics.asphere import sag_mm
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem
from realistic.optics.pupil_search import SEARCH_VERSION, pupil_boxes
from realistic.optics.tracer import trace_from_film

PUPIL_INTERVALS = 64
#: Part of an aspheric lens's pupil-table key: change it when the tracer's asphere rules change.
ASPHERE_KEY = b"asphere-2"
#: Part of a lens with paraxial surfaces' pupil-table key: change it when their tracing rules change.
PARAXIAL_KEY = b"paraxial-1"


def rear_surface_depths_mm(lens: LensSystem, film_distance_mm: float) -> tuple[float, float]:
    """(nearest, farthest) z of the rear element's clear cap in the lens frame."""
    vertex = film_distance_mm
    radius = lens.radius_mm[-1]
    half = lens.aperture_mm[-1] / 2
    rim = vertex
    if lens.aspheric[-1]:  # the sag need not be monotonic: its extremes over the clear radius
        c = 1.0 / radius if radius != 0 and np.isfinite(radius) else 0.0
        depth = vertex - sag_mm(np.linspace(0.0, half, 257) ** 2, c, lens.conic[-1], lens.aspheric_coefficients[-1])
        return float(depth.min()), float(depth.max())
    if radius != 0 and np.isfinite(radius):
        rim = vertex - radius + np.sign(radius) * np.sqrt(radius * radius - half * half)
    return min(vertex, rim), max(vertex, rim)


def camera_weight(film_points: np.ndarray, plane_points: np.ndarray, area_mm2: np.ndarray,
                  plane_z_mm: float) -> np.ndarray:
    """cos^4(theta) * A / Z^2 for rays from film points to uniformly sampled plane points."""
    delta = plane_points - film_points
    cos_theta = delta[:, 2] / np.linalg.norm(delta, axis=1)
    return cos_theta**4 * area_mm2 / (plane_z_mm * plane_z_mm)


@dataclass(frozen=True)
class RearElementSampler:
    """Uniform disk on the plane z = plane_z_mm covering the rear element from each film point.

    Every point of the rear cap lies between the planes z_near and z_far within the clear radius
    a. Seen from a film point at radius rho and projected onto the plane z_near, such a point lands
    within rho (1 - t) + a t of the axis, t = z_near / z in [z_near / z_far, 1]; the maximum over
    t is the disk radius.
    """

    plane_z_mm: float
    far_z_mm: float
    clear_radius_mm: float

    def radius_mm(self, film_radius_mm: np.ndarray) -> np.ndarray:
        t_far = self.plane_z_mm / self.far_z_mm
        return np.maximum(self.clear_radius_mm,
                          film_radius_mm * (1 - t_far) + self.clear_radius_mm * t_far)

    def sample(self, film_xy: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane points (N, 3) and the sampled area (N,) for film points (N, 2)."""
        radius = self.radius_mm(np.hypot(film_xy[:, 0], film_xy[:, 1]))
        dx, dy = concentric_disk(u1, u2)
        points = np.stack([dx * radius, dy * radius, np.full_like(radius, self.plane_z_mm)], axis=1)
        return points, np.pi * radius * radius


def rear_element_sampler(lens: LensSystem, film_distance_mm: float) -> RearElementSampler:
    near, far = rear_surface_depths_mm(lens, film_distance_mm)
    return RearElementSampler(near, far, lens.aperture_mm[-1] / 2)


@dataclass(frozen=True)
class ExitPupilTable:
    """Bounds of the passing directions on the plane z = plane_z_mm, per radial film interval.

    ``bounds[k] = (x0, x1, y0, y1)`` for film points on the +x axis with radius in
    [k, k+1) * film_radius_mm / len(bounds); an interval no ray passes has x0 > x1 (area 0).
    """

    plane_z_mm: float
    film_radius_mm: float
    bounds: np.ndarray
    padding_mm: np.ndarray  # (K, 2) how far each box was grown beyond the passing directions found, x and y

    def interval(self, film_radius_mm: np.ndarray) -> np.ndarray:
        k = np.floor(film_radius_mm / self.film_radius_mm * len(self.bounds)).astype(np.int64)
        return np.clip(k, 0, len(self.bounds) - 1)

    def area_mm2(self) -> np.ndarray:
        width = self.bounds[:, 1] - self.bounds[:, 0]
        height = self.bounds[:, 3] - self.bounds[:, 2]
        return np.where((width > 0) & (height > 0), width * height, 0.0)

    def sample(self, film_xy: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane points (N, 3) and the sampled box area (N,) for film points (N, 2)."""
        radius = np.hypot(film_xy[:, 0], film_xy[:, 1])
        box = self.bounds[self.interval(radius)]
        x = box[:, 0] + u1 * (box[:, 1] - box[:, 0])
        y = box[:, 2] + u2 * (box[:, 3] - box[:, 2])
        safe = np.where(radius > 0, radius, 1.0)
        cos_phi = np.where(radius > 0, film_xy[:, 0] / safe, 1.0)
        sin_phi = np.where(radius > 0, film_xy[:, 1] / safe, 0.0)
        points = np.stack([x * cos_phi - y * sin_phi, x * sin_phi + y * cos_phi,
                           np.full_like(x, self.plane_z_mm)], axis=1)
        return points, self.area_mm2()[self.interval(radius)]

    def contains(self, film_xy: np.ndarray, plane_xy: np.ndarray) -> np.ndarray:
        """Whether each plane point lies in the bounds of its film point's interval."""
        radius = np.hypot(film_xy[:, 0], film_xy[:, 1])
        safe = np.where(radius > 0, radius, 1.0)
        cos_phi = np.where(radius > 0, film_xy[:, 0] / safe, 1.0)
        sin_phi = np.where(radius > 0, film_xy[:, 1] / safe, 0.0)
        x = plane_xy[:, 0] * cos_phi + plane_xy[:, 1] * sin_phi
        y = -plane_xy[:, 0] * sin_phi + plane_xy[:, 1] * cos_phi
        box = self.bounds[self.interval(radius)]
        return (x >= box[:, 0]) & (x <= box[:, 1]) & (y >= box[:, 2]) & (y <= box[:, 3])


#: Exit-pupil tables kept per lens, focus, film and wavelength set: a render needs one, a bench or
#: a focus search a few; older ones are dropped.
PUPIL_CACHE_SIZE = 32


@dataclass(frozen=True)
class _PupilRequest:
    """The key of a cached table (``key``) with the lens it was computed from (not compared)."""

    # radii (and asphere terms), gaps, indices, Abbe numbers, apertures; film distance and diagonal,
    # intervals, wavelengths
    key: tuple[bytes, bytes, bytes, bytes, bytes, float, float, int, tuple[float, ...]]
    lens: LensSystem = field(compare=False, hash=False)


def exit_pupil_table(lens: LensSystem, film_distance_mm: float, film_diagonal_mm: float,
                     intervals: int = PUPIL_INTERVALS,
                     wavelengths_nm: tuple[float, ...] = (D_LINE_NM,)) -> ExitPupilTable:
    """Bound the exit pupil per radial film interval (cached per lens, focus and film).

    The boxes hold what passes at any of ``wavelengths_nm``: a spectral camera passes the ends of
    its wavelength range and the d line, so no wavelength's pupil is cut off.
    """
    if lens.stop_shape is not None:
        # The pupil bounds are found for film points on +x and turned to each film point's angle,
        # which assumes a round stop. A shaped opening lies inside the circle of its reach, so that
        # circular stop's bounds hold every ray the shape passes; rays the shape blocks get weight 0.
        reach = lens.stop_shape.reach_mm(lens.stop_diameter_mm)
        circle = lens.aperture_mm.copy()
        circle[lens.stop] = 2 * reach  # may exceed the widest element: only the bounds use it
        lens = dataclasses.replace(lens, stop_shape=None, aperture_mm=circle)
    shape = lens.radius_mm.tobytes()
    if lens.aspheric.any():  # spherical lenses keep their keys (and cached tables)
        shape += ASPHERE_KEY + lens.conic.tobytes() + lens.aspheric_coefficients.tobytes()
    if lens.paraxial.any():  # ideal thin lenses' powers (lenses without keep their keys)
        shape += PARAXIAL_KEY + lens.paraxial_power_per_mm.tobytes()
    if any(g is not None for g in lens.glass):  # a catalogue formula, not Cauchy, away from the d line
        shape += repr(lens.glass).encode()
    key = (shape, lens.thickness_mm[:-1].tobytes(), lens.index_d.tobytes(),
           lens.abbe_v.tobytes(), lens.aperture_mm.tobytes(), film_distance_mm, film_diagonal_mm,
           intervals, wavelengths_nm)
    return _cached_table(_PupilRequest(key, lens))


def _disk_key(request: _PupilRequest) -> str:
    """The disk-cache key of a table."""
    return cache_key("exit-pupil", SEARCH_VERSION, *request.key)


#: A dark interval's row, as ``_build_exit_pupil_table`` writes it (x0 > x1: no area).
DARK_BOUNDS = (1.0, -1.0, 1.0, -1.0)


def _trusted_table(stored: dict[str, np.ndarray], request: _PupilRequest) -> ExitPupilTable | None:
    """The table a cache entry holds, when it is one ``_build_exit_pupil_table`` could have made for
    this request, else None (rebuild). The entry's digest proves only that it was stored whole: a file
    written by hand or by another program can hold zeros, NaN or boxes of any size, and the kernel
    trusts the table (a NaN or empty box crashed it). Checked: names, shapes and dtypes; the plane and
    film radius this lens and film give; every dark row exactly ``DARK_BOUNDS`` with no padding; every
    lit row a finite box symmetric in y, padding >= 0, within the reach of the rear-element sampler
    at the interval's outer radius grown by its padding."""
    film_distance_mm, film_diagonal_mm, intervals = request.key[5:8]
    names = ("plane_z_mm", "film_radius_mm", "bounds", "padding_mm")
    shapes = ((), (), (intervals, 4), (intervals, 2))
    if set(stored) != set(names) or any(stored[n].shape != shape or stored[n].dtype != np.float64
                                        for n, shape in zip(names, shapes)):
        return None
    rear = rear_element_sampler(request.lens, film_distance_mm)
    film_radius = film_diagonal_mm / 2
    if float(stored["plane_z_mm"]) != rear.plane_z_mm or float(stored["film_radius_mm"]) != film_radius:
        return None
    bounds, padding = stored["bounds"], stored["padding_mm"]
    if not (np.all(np.isfinite(bounds)) and np.all(np.isfinite(padding)) and np.all(padding >= 0)):
        return None
    dark = np.all(bounds == DARK_BOUNDS, axis=1)
    reach = rear.radius_mm(np.linspace(0.0, film_radius, intervals + 1)[1:])
    limit = (reach[:, None] + padding[:, [0, 0, 1, 1]]) * (1 + 1e-9)
    lit_ok = (bounds[:, 0] < bounds[:, 1]) & (bounds[:, 2] == -bounds[:, 3]) & (bounds[:, 2] < bounds[:, 3]) \
        & np.all(np.abs(bounds) <= limit, axis=1)
    if not np.all(np.where(dark, np.all(padding == 0, axis=1), lit_ok)):
        return None
    return ExitPupilTable(rear.plane_z_mm, film_radius, bounds, padding)


@lru_cache(maxsize=PUPIL_CACHE_SIZE)
def _cached_table(request: _PupilRequest) -> ExitPupilTable:
    """The table from memory, else from the disk cache (``realistic.core.disk_cache``) when it passes
    ``_trusted_table``, else built."""
    key = _disk_key(request)
    stored = load_arrays(key)
    trusted = _trusted_table(stored, request) if stored is not None else None
    if trusted is not None:
        return trusted
    film_distance_mm, film_diagonal_mm, intervals, wavelengths_nm = request.key[5:]
    table = _build_exit_pupil_table(request.lens, film_distance_mm, film_diagonal_mm, intervals, wavelengths_nm)
    store_arrays(key, {"plane_z_mm": np.asarray(table.plane_z_mm), "film_radius_mm": np.asarray(table.film_radius_mm),
                       "bounds": table.bounds, "padding_mm": table.padding_mm})
    return table


#: Extra film radii searched inside an interval whose pupil changes fast: one end lit and the other
#: dark (an image circle's edge, where the pupil is a moving sliver), or an edge that moves by more
#: than a quarter of the box's width between the ends.
INTERIOR_RADII = 6


def _build_exit_pupil_table(lens: LensSystem, film_distance_mm: float, film_diagonal_mm: float,
                            intervals: int, wavelengths_nm: tuple[float, ...]) -> ExitPupilTable:
    """Bound the exit pupil per radial film interval from the boxes found at sampled film radii.

    Every interval is sampled at its ends, and where its pupil changes fast at ``INTERIOR_RADII``
    radii between them too. Its box holds the samples' boxes, grown by their padding and by half
    the largest difference between neighbouring samples (an extreme between two sampled radii
    exceeds the nearer one by at most that; ``realistic.optics.pupil_search``).
    """
    rear = rear_element_sampler(lens, film_distance_mm)
    film_radius = film_diagonal_mm / 2
    edges = np.linspace(0.0, film_radius, intervals + 1)

    def search(radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return pupil_boxes(lens, film_distance_mm, rear.plane_z_mm, radii, rear.radius_mm(radii), wavelengths_nm)

    boxes, pad = search(edges)
    # samples (K, S, 3) per interval in radius order: its inner end, interior radii where searched
    # (else NaN), its outer end
    samples = np.full((intervals, 2 + INTERIOR_RADII, 3), np.nan)
    padding = np.zeros((intervals, 2 + INTERIOR_RADII, 3))
    samples[:, 0], samples[:, -1] = boxes[:-1], boxes[1:]
    padding[:, 0], padding[:, -1] = pad[:-1], pad[1:]
    lit = ~np.isnan(boxes[:, 0])
    width = boxes[:, 1] - boxes[:, 0]
    with np.errstate(invalid="ignore"):
        moves = np.abs(boxes[1:] - boxes[:-1]).max(axis=1) > 0.25 * np.fmin(width[:-1], width[1:])
    refine = np.flatnonzero((lit[:-1] != lit[1:]) | (lit[:-1] & lit[1:] & moves))
    if len(refine):
        inside = np.linspace(edges[refine], edges[refine + 1], INTERIOR_RADII + 2, axis=1)[:, 1:-1]
        found, found_pad = search(inside.ravel())
        samples[refine, 1:-1] = found.reshape(len(refine), INTERIOR_RADII, 3)
        padding[refine, 1:-1] = found_pad.reshape(len(refine), INTERIOR_RADII, 3)
    known = ~np.isnan(samples)
    lo = np.where(known, samples, np.inf).min(axis=1)
    hi = np.where(known, samples, -np.inf).max(axis=1)
    steps = np.abs(np.diff(samples, axis=1))  # NaN where either neighbour is unsampled or dark
    spread = 0.5 * np.where(np.isnan(steps), 0.0, steps).max(axis=1)
    grow = padding.max(axis=1) + spread
    x0, x1, y1 = lo[:, 0] - grow[:, 0], hi[:, 1] + grow[:, 1], hi[:, 2] + grow[:, 2]
    none = ~np.isfinite(x0)
    bounds = np.where(none[:, None], DARK_BOUNDS, np.stack([x0, x1, -y1, y1], axis=1))
    grown = np.where(none[:, None], 0.0, np.stack([np.maximum(grow[:, 0], grow[:, 1]), grow[:, 2]], axis=1))
    return ExitPupilTable(rear.plane_z_mm, film_radius, bounds, grown)


def pass_fractions(lens: LensSystem, film_distance_mm: float, table: ExitPupilTable, film_radius_mm: float,
                   samples: int = 100_000, seed: int = 0) -> dict[str, float]:
    """Fraction of rays that pass the lens from a film point at ``film_radius_mm``, per sampler."""
    rng = np.random.default_rng(seed)
    angle = np.pi / 4  # along the diagonal, toward a film corner
    film_xy = np.tile([film_radius_mm * np.cos(angle), film_radius_mm * np.sin(angle)], (samples, 1))
    film = np.column_stack([film_xy, np.zeros(samples)])
    u1, u2 = rng.random(samples), rng.random(samples)
    result = {}
    for name, sampler in (("rear", rear_element_sampler(lens, film_distance_mm)), ("pupil", table)):
        points, _ = sampler.sample(film_xy, u1, u2)
        result[name] = float(trace_from_film(lens, film_distance_mm, film, points - film).passed.mean())
    return result
