"""Ghost paths through a lens prescription: light that reflects twice inside the lens and reaches the film.

Surfaces are numbered as in ``realistic.optics.lens``: 0 at the front, the first met by light from the
scene. A ghost ``GhostPath(first, second)`` (first < second) is the path on which light from the scene
refracts through surfaces 0 .. second - 1, *reflects* at ``second`` back toward the scene, refracts
back through second - 1 .. first + 1, *reflects* at ``first`` toward the film again and refracts
through first + 1 .. the rear surface onto the film (Hullin et al., "Physically-Based Real-Time Lens
Flare Rendering", SIGGRAPH 2011, section 3). ``trace_direct`` is the ordinary path, every surface
refracting. Every pass is clipped by every surface's clear aperture and by the stop; the stop in air
does not reflect (it is no interface: its coating model is ``IDEAL``).

Rays travel the lens frame (film at z = 0, +z toward the scene) from the scene side, in float64, with
the real-ray tracer's primitives (``realistic.optics.tracer``: the same surface intersections, the
same refraction); a reflection at a surface is d - 2 (d . n) n about the normal the tracer returns.
Each ray's weight is the product of the Fresnel factors on its way, from
``realistic.optics.coating`` with the lens's ``interface_models``, polarisation-averaged, at the
ray's own incidence angle and wavelength: R at the two reflections, T at every refraction.

``ghost_paths`` lists the pairs with their on-axis throughput: the same product for the axial ray at
normal incidence (every surface met perpendicularly, paraxially), whatever the apertures do to a
real bundle. It ranks the ghosts; a traced bundle's weights say how much light each carries.

``kernels/ghost.cl`` (host: ``realistic.camera.ghost_host``) is the same trace in float32, over the
same sequence of steps (``path_steps``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.coating import IDEAL, reflectance, transmittance
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem
from realistic.optics.tracer import Vectors, incidence_cosine, intersect_asphere, intersect_surface, refract

#: The default wavelength of ``ghost_paths``: the helium d line, as the lens's n_d.
GHOST_WAVELENGTH_NM = D_LINE_NM
#: Ghosts whose on-axis throughput is below this are left out by default: low enough to keep the
#: ghosts of a lens coated with MgF2 (those of the double Gauss are 1e-6 to 4e-5).
DEFAULT_THRESHOLD = 1e-6


@dataclass(frozen=True)
class GhostPath:
    """The ghost reflecting at surface ``second`` and then at ``first`` (first < second; module
    docstring). ``throughput``: the on-axis throughput ``ghost_paths`` found (NaN when made by hand);
    it takes no part in comparisons, so ``GhostPath(1, 4)`` equals the listed one."""

    first: int
    second: int
    throughput: float = field(default=math.nan, compare=False)


@dataclass(frozen=True)
class GhostTrace:
    """Per ray, where it meets the film along a path and with what weight.

    ``weight`` is the product of the Fresnel factors on the way (module docstring), 0 where the ray
    did not pass; ``film_xy`` and ``direction`` are NaN there. ``passed`` is False for a ray clipped by
    any clear aperture or the stop, totally reflected on a refraction, missing a surface, or leaving
    the last surface away from the film.
    """

    film_xy: np.ndarray  # (N, 2) mm, on the film plane z = 0
    direction: np.ndarray  # (N, 3) unit direction at the film
    weight: np.ndarray  # (N,)
    passed: np.ndarray  # (N,) bool


#: What traces rays along a path (None: the direct path) onto the film, as ``trace_ghost`` does (a render
#: backend's: the float64 reference or ``kernels/ghost.cl``): (film distance mm, path, origins (N, 3),
#: directions (N, 3), wavelength nm, one or one per ray) -> ``GhostTrace``.
GhostTracer = Callable[[float, "GhostPath | None", np.ndarray, np.ndarray, "float | np.ndarray"], GhostTrace]


#: One step of a path: the surface met and whether the ray reflects there (else it refracts).
Step = tuple[int, bool]


def path_steps(lens: LensSystem, path: GhostPath | None) -> list[Step]:
    """The surfaces a ray meets in order along ``path`` (None: the direct path), each with whether
    it reflects there. A path must name two surfaces of the lens, ``first`` < ``second``."""
    count = lens.surface_count
    forward = [(i, False) for i in range(count)]
    if path is None:
        return forward
    if not (0 <= path.first < path.second < count):
        raise UserError(f"{lens.name}: a ghost reflects at two surfaces 0 <= first < second <= {count - 1}, "
                        f"got first {path.first}, second {path.second}")
    back = [(i, False) for i in range(path.second - 1, path.first, -1)]
    return forward[:path.second] + [(path.second, True)] + back + [(path.first, True)] + forward[path.first + 1:]


def _media(lens: LensSystem, wavelength_nm: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per surface, the indices of the media in front of it (scene side) and behind it, at the
    wavelength(s): (surfaces,) arrays, or (surfaces, N) for one wavelength per ray."""
    behind = lens.index_at(wavelength_nm)
    front = np.concatenate([np.ones((1, *behind.shape[1:])), behind[:-1]])
    return front, behind


def _throughput(lens: LensSystem, steps: list[Step], wavelength_nm: float) -> float:
    """The product of the Fresnel factors along ``steps`` at normal incidence (the axial ray)."""
    front, behind = _media(lens, wavelength_nm)
    models = lens.interface_models
    toward_film = True
    product = 1.0
    for surface, reflects in steps:
        n_from, n_to = (front[surface], behind[surface]) if toward_film else (behind[surface], front[surface])
        fresnel = reflectance if reflects else transmittance
        product *= float(fresnel(int(models[surface]), n_from, n_to, 1.0, wavelength_nm))
        toward_film ^= reflects
    return product


@lru_cache(maxsize=32)
def _all_paths(lens: LensSystem, wavelength_nm: float) -> tuple[GhostPath, ...]:
    """Every pair of reflecting surfaces (models other than IDEAL) with its on-axis throughput, the
    brightest first: enumerated once per lens (``LensSystem`` hashes by identity) and wavelength."""
    reflecting = np.flatnonzero(lens.interface_models != IDEAL)
    paths = [GhostPath(int(j), int(i), _throughput(lens, path_steps(lens, GhostPath(int(j), int(i))), wavelength_nm))
             for k, i in enumerate(reflecting) for j in reflecting[:k]]
    return tuple(sorted(paths, key=lambda p: (-p.throughput, p.first, p.second)))


def ghost_paths(lens: LensSystem, *, wavelength_nm: float = GHOST_WAVELENGTH_NM,
                threshold: float = DEFAULT_THRESHOLD) -> list[GhostPath]:
    """The lens's ghosts whose on-axis throughput (module docstring) is at least ``threshold``, the
    brightest first. Under the ``ideal`` coating nothing reflects, so there are none."""
    wavelength_nm = validation.wavelength_nm(wavelength_nm)
    threshold = validation.ghost_threshold(threshold)
    return [path for path in _all_paths(lens, wavelength_nm) if path.throughput >= threshold]


def _rows_of_three(array: np.ndarray, name: str, count: int | None = None) -> np.ndarray:
    """``array`` as (N, 3) float64 (N = ``count`` when given), or a UserError naming it."""
    rows = np.asarray(array, dtype=np.float64)
    if rows.ndim != 2 or rows.shape[1] != 3 or (count is not None and len(rows) != count):
        expected = f"({count}, 3)" if count is not None else "(N, 3)"
        raise UserError(f"{name} must be an {expected} array, got shape {rows.shape}")
    return rows


def _trace(lens: LensSystem, film_distance_mm: float, steps: list[Step], origins: np.ndarray,
           directions: np.ndarray, wavelength_nm: float | np.ndarray) -> GhostTrace:
    """Rays from the scene side along ``steps`` to the film (``trace_ghost``)."""
    origins = _rows_of_three(origins, "origins")
    directions = _rows_of_three(directions, "directions", len(origins))
    count = len(origins)
    length = np.sqrt(np.sum(directions * directions, axis=1))
    o: Vectors = (origins[:, 0], origins[:, 1], origins[:, 2])
    d: Vectors = (directions[:, 0] / length, directions[:, 1] / length, directions[:, 2] / length)
    lam = np.broadcast_to(np.asarray(wavelength_nm, np.float64), (count,))
    front, behind = (np.broadcast_to(n.reshape(lens.surface_count, -1), (lens.surface_count, count))
                     for n in _media(lens, wavelength_nm))
    vertex_z = lens.vertex_z_mm(film_distance_mm)
    models = lens.interface_models
    passed = np.ones(count, dtype=bool)
    weight = np.ones(count)
    previous = -1
    toward_film = True
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for surface, reflects in steps:
            ahead = previous < 0 or lens.thickness_mm[min(previous, surface)] != 0
            if lens.aspheric[surface]:
                o, normal, miss = intersect_asphere(o, d, vertex_z[surface], lens.radius_mm[surface],
                                                    lens.conic[surface], lens.aspheric_coefficients[surface], ahead)
            else:
                o, normal, miss = intersect_surface(o, d, vertex_z[surface], lens.radius_mm[surface], ahead)
            half = lens.aperture_mm[surface] / 2
            if surface == lens.stop and lens.stop_shape is not None:
                inside = lens.stop_shape.inside(o[0], o[1], lens.aperture_mm[surface])
            else:
                inside = o[0] * o[0] + o[1] * o[1] <= half * half
            passed &= ~miss & inside
            n_from, n_to = (front[surface], behind[surface]) if toward_film else (behind[surface], front[surface])
            cosine = incidence_cosine(d, normal)
            model = int(models[surface])
            if reflects:
                weight = weight * reflectance(model, n_from, n_to, cosine, lam)
                d = (d[0] + 2 * cosine * normal[0], d[1] + 2 * cosine * normal[1], d[2] + 2 * cosine * normal[2])
                toward_film = not toward_film
            elif not np.array_equal(n_from, n_to) or model != IDEAL:
                if model != IDEAL:
                    weight = weight * transmittance(model, n_from, n_to, cosine, lam)
                d, tir = refract(d, normal, n_from / n_to)
                passed &= ~tir
            previous = surface
        t = -o[2] / d[2]
        passed &= (t > 0) & np.isfinite(t)
        film = np.column_stack([o[0] + t * d[0], o[1] + t * d[1]])
    film[~passed] = np.nan
    direction = np.stack(d, axis=1)
    direction[~passed] = np.nan
    return GhostTrace(film, direction, np.where(passed, weight, 0.0), passed)


def trace_ghost(lens: LensSystem, film_distance_mm: float, path: GhostPath, origins: np.ndarray,
                directions: np.ndarray, wavelength_nm: float | np.ndarray = GHOST_WAVELENGTH_NM) -> GhostTrace:
    """Rays from the scene along the ghost ``path`` onto the film, in float64.

    ``origins`` (N, 3) and ``directions`` (N, 3, any length) are in the lens frame with the film
    ``film_distance_mm`` behind the rear vertex: origins in front of the front surface, directions
    heading toward -z. ``wavelength_nm`` is one wavelength or one per ray (N,).
    """
    return _trace(lens, film_distance_mm, path_steps(lens, path), origins, directions, wavelength_nm)


def trace_direct(lens: LensSystem, film_distance_mm: float, origins: np.ndarray, directions: np.ndarray,
                 wavelength_nm: float | np.ndarray = GHOST_WAVELENGTH_NM) -> GhostTrace:
    """``trace_ghost`` for the ordinary path: every surface refracts, the weight is the product of
    the transmittances (the image a camera ray traced back from the film would find)."""
    return _trace(lens, film_distance_mm, path_steps(lens, None), origins, directions, wavelength_nm)


def collimated_rays(lens: LensSystem, film_distance_mm: float, field_deg: float, across: int = 64
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(origins, directions) of a square grid of parallel rays from a point at infinity ``field_deg``
    off the axis (toward +y on the scene side, so its image lies toward -y), covering the front
    surface's clear aperture and launched in front of it. The grid is mirror-symmetric in x."""
    field_deg = validation.field_angle_deg(field_deg)
    half = (across - 1) / 2
    g = (np.arange(across) - half) / half
    x, y = np.meshgrid(g, g)
    keep = x * x + y * y <= 1.0
    angle = math.radians(field_deg)
    height = float(lens.aperture_mm.max())  # in front of any sag of the front surface
    radius = lens.aperture_mm[0] / 2 + height * abs(math.tan(angle))  # the beam's shift across the sag
    origins = np.column_stack([x[keep] * radius, y[keep] * radius + math.tan(angle) * height,
                               np.full(keep.sum(), lens.vertex_z_mm(film_distance_mm)[0] + height)])
    return origins, np.broadcast_to([0.0, -math.sin(angle), -math.cos(angle)], origins.shape).copy()


@dataclass(frozen=True)
class GhostSummary:
    """One row of ``summarise``: a path (None: the direct image) and its image on the film.

    ``focus_mm``: the lens-frame z (film at 0, + toward the scene) where the image of an on-axis point
    at infinity along the path is smallest (least weighted mean squared distance from the axis), NaN
    where no ray passes; ``spot_rms_mm`` and ``centroid_mm``: the weighted RMS radius about the
    centroid and the centroid (x, y) of the image on the film of a point at the field angle;
    ``light``: the fraction of that bundle's light (the grid of ``collimated_rays``) that arrives,
    to be read against the direct image's.
    """

    path: GhostPath | None
    focus_mm: float
    spot_rms_mm: float
    centroid_mm: tuple[float, float]
    light: float


def _best_focus_z(trace: GhostTrace) -> float:
    """The z of least weighted mean squared distance from the axis of the rays that passed."""
    w = trace.weight[trace.passed]
    if not w.sum() > 0:
        return math.nan
    slope = trace.direction[trace.passed, :2] / trace.direction[trace.passed, 2:3]
    return float(-np.sum(w[:, None] * trace.film_xy[trace.passed] * slope) / np.sum(w[:, None] * slope * slope))


def summarise(lens: LensSystem, film_distance_mm: float, paths: list[GhostPath], field_deg: float = 0.0,
              wavelength_nm: float = GHOST_WAVELENGTH_NM, across: int = 64) -> list[GhostSummary]:
    """The direct image and each of ``paths`` on the film (``GhostSummary``), traced with grids of
    ``across`` rays across the front aperture (``collimated_rays``)."""
    axial = collimated_rays(lens, film_distance_mm, 0.0, across)
    field = axial if field_deg == 0 else collimated_rays(lens, film_distance_mm, field_deg, across)
    rows = []
    for path in [None, *paths]:
        traced = [trace_direct(lens, film_distance_mm, *rays, wavelength_nm) if path is None
                  else trace_ghost(lens, film_distance_mm, path, *rays, wavelength_nm) for rays in (axial, field)]
        spot = traced[1]
        w = spot.weight[spot.passed]
        if w.sum() > 0:
            centroid = np.sum(w[:, None] * spot.film_xy[spot.passed], axis=0) / w.sum()
            rms = float(np.sqrt(np.sum(w * np.sum((spot.film_xy[spot.passed] - centroid) ** 2, axis=1)) / w.sum()))
        else:
            centroid, rms = np.full(2, math.nan), math.nan
        rows.append(GhostSummary(path, _best_focus_z(traced[0]), rms, (float(centroid[0]), float(centroid[1])),
                                 float(spot.weight.sum() / len(spot.weight))))
    return rows
