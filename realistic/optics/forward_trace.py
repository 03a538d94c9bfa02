"""Rays from an object point through the lens to the image side: the forward direction.

The float64 tracer (``realistic.optics.tracer``) runs from the film toward the scene. A lens traced
the other way is the same tracer on the *reversed* lens: surfaces in the opposite order, radii
negated, each surface's media swapped. Its frame is the lens frame mirrored in z, which leaves x
and y as they are, so image-side points come back in the lens frame's x and y.

Image-side rays are returned as their crossing of the rear-vertex plane and their slopes, so the
spot on any film plane ``s`` mm behind the rear vertex is ``point + slope * s`` (no retracing to
refocus). Object points are at infinity (a collimated beam at a field angle) or at a finite
distance in front of the lens; the entrance-pupil plane is sampled on an equal-area grid over a
disk found to hold the whole beam that passes (the real stop clips what lies outside, so every
surviving ray carries the same share of the light the lens collects).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from realistic.errors import UserError
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data
from realistic.optics.tracer import TraceResult, trace_from_film


def reversed_lens(lens: LensSystem) -> LensSystem:
    """The lens seen from the film side: the order of surfaces reversed (their coatings with them),
    radii negated, and the medium behind each surface the one in front of it in the original (a
    paraxial surface keeps its powers)."""
    count = lens.surface_count
    medium_in_front = np.concatenate([[1.0], lens.index_d[:-1]])
    abbe_in_front = np.concatenate([[0.0], lens.abbe_v[:-1]])
    conic, coefficients = lens.conic, lens.aspheric_coefficients
    if lens.asphere_count:
        # Even aspheres: the sag changes sign, as the radius does.
        conic, coefficients = lens.conic[::-1].copy(), -lens.aspheric_coefficients[::-1].copy()
    return dataclasses.replace(
        lens, name=f"{lens.name} (reversed)", radius_mm=-lens.radius_mm[::-1].copy(),
        thickness_mm=np.concatenate([lens.thickness_mm[:-1][::-1], [0.0]]),
        index_d=medium_in_front[::-1].copy(), abbe_v=abbe_in_front[::-1].copy(),
        aperture_mm=lens.aperture_mm[::-1].copy(), stop=count - 1 - lens.stop,
        glass=((None, *lens.glass[:-1]))[::-1], coating=lens.coating[::-1],
        conic=conic, aspheric_coefficients=coefficients,
        paraxial_power_per_mm=lens.paraxial_power_per_mm[::-1].copy())


def pupil_grid(samples_across: int) -> np.ndarray:
    """(N, 2) points of a square grid of ``samples_across`` cells across the unit disk, cell
    centres inside the disk only: equal-area samples of a uniform disk, symmetric under x <-> y
    and under sign changes."""
    if samples_across < 2:
        raise UserError(f"pupil samples across must be at least 2, got {samples_across}")
    c = (np.arange(samples_across) + 0.5) / samples_across * 2.0 - 1.0
    x, y = np.meshgrid(c, c, indexing="xy")
    keep = x * x + y * y <= 1.0
    return np.column_stack([x[keep], y[keep]])


@dataclass(frozen=True)
class ImageRays:
    """Rays that passed the lens, on the image side, in the lens frame's x and y (mm).

    ``point`` is where each ray crosses the plane of the rear vertex, ``slope`` its (dx/ds, dy/ds)
    per mm travelled toward the film, so ``at(s)`` is the spot ``s`` mm behind the rear vertex.
    ``launched`` is how many rays were sent (the passed fraction is ``len(point) / launched``);
    each stands for ``ray_area_mm2`` of the entrance-pupil plane (perpendicular to the axis).
    """

    point: np.ndarray  # (N, 2)
    slope: np.ndarray  # (N, 2)
    launched: int
    ray_area_mm2: float = 0.0

    @property
    def beam_area_mm2(self) -> float:
        """Area of the entrance-pupil plane whose rays pass the lens."""
        return len(self.point) * self.ray_area_mm2

    def at(self, film_distance_mm: float) -> np.ndarray:
        """(N, 2) crossings of the plane ``film_distance_mm`` behind the rear vertex."""
        return self.point + self.slope * film_distance_mm


#: Pupil-disk radii tried, in entrance-pupil radii, while searching for the beam that passes.
_SEARCH_RADII = (1.6, 3.2, 6.4, 12.8, 25.6, 51.2)
#: Samples across the disk while searching.
_SEARCH_SAMPLES = 48


@dataclass(frozen=True)
class _Launch:
    """Rays from one object point toward points of the entrance-pupil plane (reversed-lens frame)."""

    lens: LensSystem
    reverse: LensSystem
    gap_mm: float  # launch plane z = 0 to the front vertex
    pupil_z_mm: float
    field_deg: float
    wavelength_nm: float
    object_distance_mm: float

    def trace(self, pupil_xy: np.ndarray) -> TraceResult:
        targets = np.column_stack([pupil_xy, np.full(len(pupil_xy), self.pupil_z_mm)])
        angle = math.radians(self.field_deg)
        if math.isinf(self.object_distance_mm):
            direction = np.array([0.0, -math.sin(angle), math.cos(angle)])
            origins = targets - direction * (self.pupil_z_mm / direction[2])
            directions = np.broadcast_to(direction, targets.shape)
        else:
            d = self.object_distance_mm
            source = np.array([0.0, d * math.tan(angle), self.pupil_z_mm - d])
            origins = np.broadcast_to(source, targets.shape)
            directions = targets - source
        return trace_from_film(self.reverse, self.gap_mm, origins, directions, self.wavelength_nm)


def _beam_disk(launch: _Launch, pupil_radius_mm: float) -> tuple[np.ndarray, float]:
    """(centre, radius) of a disk on the entrance-pupil plane holding every ray that passes.

    Grids of growing radius are traced until some rays pass and none of them lies on the grid's
    rim (the beam is then inside it; the real pupil of a wide-angle lens can lie far from the
    paraxial one). The disk is centred on the axis of symmetry x = 0 (and on the axis for the
    axial field) and grown by one search cell.
    """
    unit = pupil_grid(_SEARCH_SAMPLES)
    for factor in _SEARCH_RADII:
        radius = factor * pupil_radius_mm
        passed = launch.trace(unit * radius).passed
        if not passed.any():
            continue
        points = unit[passed] * radius
        on_rim = np.hypot(unit[passed, 0], unit[passed, 1]).max() > 1 - 2.0 / _SEARCH_SAMPLES
        if on_rim and factor != _SEARCH_RADII[-1]:
            continue
        cell = 2 * radius / _SEARCH_SAMPLES
        centre_y = 0.0 if launch.field_deg == 0 else 0.5 * (points[:, 1].min() + points[:, 1].max())
        reach = np.hypot(points[:, 0], points[:, 1] - centre_y).max()
        return np.array([0.0, centre_y]), float(reach + 1.5 * cell)
    raise UserError(f"no ray from a point at {launch.field_deg:g} deg passes {launch.lens.name} "
                    f"(vignetted or beyond its field)")


def trace_object_point(lens: LensSystem, field_deg: float, wavelength_nm: float = D_LINE_NM,
                       object_distance_mm: float = math.inf, samples_across: int = 64) -> ImageRays:
    """Trace an equal-area grid over the beam that passes, from an object point to the image side.

    ``field_deg`` is the angle of the chief ray in object space, seen from the centre of the
    paraxial entrance pupil, toward +y; ``object_distance_mm`` is measured from that pupil (inf: a
    collimated beam). The grid covers a disk on the entrance-pupil plane found to hold the whole
    passing beam (``_beam_disk``); rays blocked anywhere in the lens are dropped.
    """
    if not (abs(field_deg) < 90):
        raise UserError(f"field angle {field_deg:g} deg must be between -90 and 90")
    if not object_distance_mm > 0:
        raise UserError(f"object distance {object_distance_mm:g} mm must be > 0")
    para = paraxial_data(lens, wavelength_nm)
    # Reversed frame: launch plane z = 0, front vertex at z = gap (beyond any sag of the front surface).
    gap = abs(float(lens.radius_mm[0])) if math.isfinite(lens.radius_mm[0]) else 0.0
    gap = max(gap, float(lens.aperture_mm[0])) + 1.0
    launch = _Launch(lens, reversed_lens(lens), gap, gap + para.entrance_pupil_mm, field_deg, wavelength_nm,
                     object_distance_mm)
    centre, radius = _beam_disk(launch, para.entrance_pupil_diameter_mm / 2)
    pupil = centre + pupil_grid(samples_across) * radius
    traced = launch.trace(pupil)
    o, d = traced.origin[traced.passed], traced.direction[traced.passed]
    rear_vertex_z = gap + lens.track_length_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = d[:, :2] / d[:, 2:3]
    forward = d[:, 2] > 0
    point = o[:, :2] + slope * (rear_vertex_z - o[:, 2:3])
    cell = 2 * radius / samples_across
    return ImageRays(point[forward], slope[forward], len(pupil), cell * cell)
