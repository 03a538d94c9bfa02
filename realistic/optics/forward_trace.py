"""Rays from an object point through the lens to the image side: the forward direction.

The float64 tracer (``realistic.optics.tracer``) runs from the film toward the scene. A lens traced
the other way is the same tracer on the *reversed* lens: surfaces in the opposite order, radii
negated, each surface's media swapped. Its frame is the lens frame mirrored in z, which leaves x
and y as they are, so image-side points come back in the lens frame's x and y.

Image-side rays are returned as their crossing of the rear-vertex plane and their slopes, so the
spot on any film plane ``s`` mm behind the rear vertex is ``point + slope * s`` (no retracing to
refocus). Object points are at infinity (a collimated beam at a field angle) or at a finite
distance in front of the front vertex; the pupil is sampled on a square grid over the paraxial
entrance pupil grown by ``margin`` (the real stop clips what lies outside, so every surviving ray
carries the same share of the light the entrance pupil collects).
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
from realistic.optics.tracer import trace_from_film


def reversed_lens(lens: LensSystem) -> LensSystem:
    """The lens seen from the film side: the order of surfaces reversed, radii negated, and the
    medium behind each surface the one in front of it in the original."""
    count = lens.surface_count
    medium_in_front = np.concatenate([[1.0], lens.index_d[:-1]])
    abbe_in_front = np.concatenate([[0.0], lens.abbe_v[:-1]])
    changes = {
        "name": f"{lens.name} (reversed)", "radius_mm": -lens.radius_mm[::-1].copy(),
        "thickness_mm": np.concatenate([lens.thickness_mm[:-1][::-1], [0.0]]),
        "index_d": medium_in_front[::-1].copy(), "abbe_v": abbe_in_front[::-1].copy(),
        "aperture_mm": lens.aperture_mm[::-1].copy(), "stop": count - 1 - lens.stop,
    }
    if getattr(lens, "asphere_count", 0):
        # Even aspheres (when the lens model has them): the sag changes sign, as the radius does.
        changes["conic"] = lens.conic[::-1].copy()
        changes["aspheric_coefficients"] = -lens.aspheric_coefficients[::-1].copy()
    return dataclasses.replace(lens, **changes)


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
    ``launched`` is how many rays were sent (the passed fraction is ``len(point) / launched``).
    """

    point: np.ndarray  # (N, 2)
    slope: np.ndarray  # (N, 2)
    launched: int

    def at(self, film_distance_mm: float) -> np.ndarray:
        """(N, 2) crossings of the plane ``film_distance_mm`` behind the rear vertex."""
        return self.point + self.slope * film_distance_mm


def trace_object_point(lens: LensSystem, field_deg: float, wavelength_nm: float = D_LINE_NM,
                       object_distance_mm: float = math.inf, samples_across: int = 64,
                       margin: float = 1.6) -> ImageRays:
    """Trace a grid over the entrance pupil from an object point to the image side.

    ``field_deg`` is the angle of the chief ray in object space, seen from the centre of the
    paraxial entrance pupil, toward +y; ``object_distance_mm`` is measured from that pupil (inf: a
    collimated beam). Rays blocked anywhere in the lens are dropped.
    """
    if not (abs(field_deg) < 90):
        raise UserError(f"field angle {field_deg:g} deg must be between -90 and 90")
    if not object_distance_mm > 0:
        raise UserError(f"object distance {object_distance_mm:g} mm must be > 0")
    para = paraxial_data(lens, wavelength_nm)
    reverse = reversed_lens(lens)
    # Reversed frame: launch plane z = 0, front vertex at z = gap (beyond any sag of the front surface).
    gap = abs(float(lens.radius_mm[0])) if math.isfinite(lens.radius_mm[0]) else 0.0
    gap = max(gap, float(lens.aperture_mm[0])) + 1.0
    pupil_z = gap + para.entrance_pupil_mm
    pupil = pupil_grid(samples_across) * (margin * para.entrance_pupil_diameter_mm / 2)
    targets = np.column_stack([pupil, np.full(len(pupil), pupil_z)])
    angle = math.radians(field_deg)
    if math.isinf(object_distance_mm):
        direction = np.array([0.0, -math.sin(angle), math.cos(angle)])
        origins = targets - direction * (pupil_z / direction[2])
        directions = np.broadcast_to(direction, targets.shape)
    else:
        source = np.array([0.0, object_distance_mm * math.tan(angle), pupil_z - object_distance_mm])
        origins = np.broadcast_to(source, targets.shape)
        directions = targets - source
    traced = trace_from_film(reverse, gap, origins, directions, wavelength_nm)
    o, d = traced.origin[traced.passed], traced.direction[traced.passed]
    rear_vertex_z = gap + lens.track_length_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = d[:, :2] / d[:, 2:3]
    forward = d[:, 2] > 0
    point = o[:, :2] + slope * (rear_vertex_z - o[:, 2:3])
    return ImageRays(point[forward], slope[forward], len(pupil))
