"""Field curves of a lens: relative illumination (vignetting x cos^4) and distortion.

Measured by tracing: for film points at increasing radius, rays sampled uniformly over the exit
pupil bounds carry the camera weight cos^4(theta) A / Z^2; their mean, relative to the film
centre, is the relative illumination, and the passing fraction of the pupil area the vignetting.
The centroid of the passing bundle is the chief ray; its angle theta in the scene gives the
distortion (r - f tan theta) / (f tan theta) against an ideal rectilinear lens of the same EFL.
"""

from __future__ import annotations

import math
from typing import TypedDict

import numpy as np

from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM, pixel_pitch_mm
from realistic.errors import UserError
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, lens_label, paraxial_data
from realistic.optics.sampling import ExitPupilTable, camera_weight, exit_pupil_table
from realistic.optics.tracer import trace_from_film


class FieldPoint(TypedDict):
    """The field curves at one film radius (a row of ``lens curves --json``)."""

    film_radius_mm: float
    relative_illumination: float
    vignetting: float
    field_angle_deg: float | None  # None (and no distortion) where no ray passes
    distortion_percent: float | None


def field_curves(lens: LensSystem, film_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM,
                 film_distance_mm: float | None = None,
                 points: int = 33, samples: int = 20_000, seed: int = 0) -> list[FieldPoint]:
    """Per film radius (0 to half the diagonal): field angle, relative illumination, vignetting, distortion."""
    if film_distance_mm is None:
        film_distance_mm = film_distance_for_focus(lens, math.inf)
    efl = paraxial_data(lens).efl_mm
    table = exit_pupil_table(lens, film_distance_mm, film_diagonal_mm)
    rng = np.random.default_rng(seed)
    u1, u2 = rng.random(samples), rng.random(samples)
    rows: list[FieldPoint] = []
    for i, radius in enumerate(np.linspace(0.0, film_diagonal_mm / 2 * 0.999, points)):
        film_xy = np.tile([radius, 0.0], (samples, 1))
        film = np.column_stack([film_xy, np.zeros(samples)])
        targets, area = table.sample(film_xy, u1, u2)
        traced = trace_from_film(lens, film_distance_mm, film, targets - film)
        ok = traced.passed
        weight = float(np.mean(np.where(ok, camera_weight(film, targets, area, table.plane_z_mm), 0.0)))
        open_area = float(np.mean(ok) * area[0])
        if i == 0:  # the film centre, which the other radii are relative to
            centre_weight, centre_area = weight, open_area
            if not ok.any():
                raise UserError(f"{lens_label(lens)}: no ray from the film centre passes the lens (stop "
                                f"{lens.stop_diameter_mm:g} mm), so there is no illumination to compare with")
        row: FieldPoint = {"film_radius_mm": float(radius), "relative_illumination": weight / centre_weight,
               "vignetting": open_area / centre_area, "field_angle_deg": None, "distortion_percent": None}
        if ok.any():
            chief = traced.direction[ok].mean(axis=0)
            theta = math.atan2(math.hypot(chief[0], chief[1]), chief[2])
            row["field_angle_deg"] = math.degrees(theta)
            if radius > 0:
                ideal = efl * math.tan(theta)
                row["distortion_percent"] = 100.0 * (radius - ideal) / ideal
        rows.append(row)
    return rows


def vignetting_map(rows: list[FieldPoint], width: int, height: int, film_diagonal_mm: float) -> np.ndarray:
    """Relative illumination over a film of ``width`` x ``height`` pixels, interpolated radially."""
    pixel_mm = pixel_pitch_mm(film_diagonal_mm, width, height)
    x = (np.arange(width) + 0.5 - width / 2) * pixel_mm
    y = (np.arange(height) + 0.5 - height / 2) * pixel_mm
    radius = np.hypot(x[None, :], y[:, None])
    radii = [r["film_radius_mm"] for r in rows]
    values = [r["relative_illumination"] for r in rows]
    return np.interp(radius, radii, values, right=values[-1]).astype(np.float32)


def meridional_fan(lens: LensSystem, film_distance_mm: float, film_radius_mm: float, table: ExitPupilTable,
                   rays: int = 11) -> list[np.ndarray]:
    """Polylines (K, 3) of rays from a film point across the pupil in the x-z plane that pass the lens."""
    x0, x1 = table.bounds[table.interval(np.array([film_radius_mm]))[0], :2]
    xs = np.linspace(x0, x1, rays)
    film = np.tile([film_radius_mm, 0.0, 0.0], (rays, 1))
    targets = np.column_stack([xs, np.zeros(rays), np.full(rays, table.plane_z_mm)])
    path: list[np.ndarray] = []
    traced = trace_from_film(lens, film_distance_mm, film, targets - film, path=path)
    lines = []
    for k in np.flatnonzero(traced.passed):
        points = [film[k]] + [hits[k] for hits in path]
        points.append(traced.origin[k] + traced.direction[k] * (lens.track_length_mm * 0.6))
        lines.append(np.array(points))
    return lines

