"""Spot diagrams: where the rays from one object point land on the film, and how widely they spread.

An object point at infinity per field angle, traced at each wavelength through an equal-area grid
over the entrance pupil (``realistic.optics.forward_trace``), lands on a film plane at the paraxial
focus of the d line or at *best focus*: the film distance that minimises the mean square spot
radius summed over all fields (each field's wavelengths together). Because each ray is a straight
line behind the lens, that sum is a quadratic in the film distance and its minimum is found in
closed form.

Radii are measured from the centroid of all wavelengths' rays of a field: the RMS radius
sqrt(mean |p - c|^2) and the geometric radius max |p - c|. Every ray carries the same weight (the
grid samples the pupil by equal areas).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.dispersion import LAMBDA_C_UM, LAMBDA_D_UM, LAMBDA_F_UM
from realistic.optics.forward_trace import ImageRays, trace_object_point
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data

#: Fraunhofer lines by name (nm), for ``--wavelengths F,d,C``.
NAMED_WAVELENGTHS_NM = {"F": LAMBDA_F_UM * 1000, "d": LAMBDA_D_UM * 1000, "C": LAMBDA_C_UM * 1000}
FOCUS_MODES = ("paraxial", "best")


def parse_wavelengths(text: str) -> list[float]:
    """``"F,d,C"`` or nanometres ``"486.1,587.6"`` (or a mix) as a list of wavelengths in nm."""
    result = []
    for item in text.split(","):
        item = item.strip()
        if item in NAMED_WAVELENGTHS_NM:
            result.append(NAMED_WAVELENGTHS_NM[item])
            continue
        try:
            value = float(item)
        except ValueError:
            value = math.nan
        if not (validation.MIN_WAVELENGTH_NM <= value <= validation.MAX_WAVELENGTH_NM):
            raise UserError(f"wavelength {item!r} is neither F, d, C nor a number of nm in "
                            f"{validation.MIN_WAVELENGTH_NM:g}..{validation.MAX_WAVELENGTH_NM:g}")
        result.append(value)
    if not result:
        raise UserError("no wavelengths given")
    return result


def parse_weights(text: str) -> list[float]:
    """``"1,2,1"``: relative powers of the wavelengths, in their order (checked against them by
    ``validation.spectral_weights``)."""
    values = []
    for item in text.split(","):
        try:
            values.append(float(item))
        except ValueError:
            raise UserError(f"weight {item.strip()!r} is not a number") from None
    return values


@dataclass(frozen=True)
class Spot:
    """One field's spot on the film: points per wavelength (film x, y in mm) and their spread."""

    field_deg: float
    wavelengths_nm: tuple[float, ...]
    points: tuple[np.ndarray, ...]  # per wavelength, (N_i, 2)
    launched: int  # rays sent per wavelength

    @property
    def all_points(self) -> np.ndarray:
        return np.concatenate(self.points)

    @property
    def centroid_mm(self) -> np.ndarray:
        return self.all_points.mean(axis=0)

    @property
    def rms_radius_mm(self) -> float:
        delta = self.all_points - self.centroid_mm
        return float(math.sqrt(np.mean(np.sum(delta * delta, axis=1))))

    @property
    def geometric_radius_mm(self) -> float:
        delta = self.all_points - self.centroid_mm
        return float(np.sqrt(np.max(np.sum(delta * delta, axis=1))))

    def as_dict(self) -> dict[str, object]:
        return {
            "field_deg": self.field_deg, "centroid_mm": [float(v) for v in self.centroid_mm],
            "rms_radius_mm": self.rms_radius_mm, "geometric_radius_mm": self.geometric_radius_mm,
            "rays_per_wavelength": [len(p) for p in self.points], "rays_launched_per_wavelength": self.launched,
            "wavelengths_nm": list(self.wavelengths_nm),
        }


def best_focus_mm(fields: list[list[ImageRays]]) -> float:
    """Film distance (mm behind the rear vertex) minimising the sum over fields of the mean square
    spot radius, each field's rays of all wavelengths taken together about their centroid (the
    radius ``Spot`` reports).

    With p(s) = a + b s per ray, a field's mean square radius is Var(a) + 2 s Cov(a, b) + s^2 Var(b)
    (summed over x and y), so the sum is minimal at s = -sum Cov(a, b) / sum Var(b).
    """
    cov = var = 0.0
    for rays in fields:
        point = np.concatenate([r.point for r in rays])
        slope = np.concatenate([r.slope for r in rays])
        if len(point) < 2:
            continue
        a = point - point.mean(axis=0)
        b = slope - slope.mean(axis=0)
        cov += float(np.sum(a * b)) / len(a)
        var += float(np.sum(b * b)) / len(a)
    if var <= 0:
        raise UserError("too few rays pass the lens to find a best focus")
    return -cov / var


@dataclass(frozen=True)
class SpotReport:
    """Spots of several fields on one film plane."""

    lens_name: str
    focus: str
    film_distance_mm: float  # film plane, mm behind the rear vertex
    spots: tuple[Spot, ...]

    def as_dict(self) -> dict[str, object]:
        return {"lens": self.lens_name, "focus": self.focus, "film_distance_mm": self.film_distance_mm,
                "spots": [s.as_dict() for s in self.spots]}


def trace_fields(lens: LensSystem, fields_deg: list[float], wavelengths_nm: list[float],
                 samples_across: int) -> list[list[ImageRays]]:
    """Image-side rays per field (outer) and wavelength (inner) for objects at infinity."""
    return [[trace_object_point(lens, f, w, samples_across=samples_across) for w in wavelengths_nm]
            for f in fields_deg]


def film_distance_for(lens: LensSystem, traced: list[list[ImageRays]], focus: str | float) -> float:
    """The film plane of ``focus``: the d line's paraxial back focus, best focus of ``traced``, or
    (a number) the film that focuses that object distance, mm from the film (thick-lens model)."""
    if not isinstance(focus, str):
        return film_distance_for_focus(lens, focus)
    if focus not in FOCUS_MODES:
        raise UserError(f"focus must be one of {', '.join(FOCUS_MODES)}, got {focus!r}")
    if focus == "paraxial":
        return paraxial_data(lens).bfl_mm
    return best_focus_mm(traced)


def focus_label(focus: str | float) -> str:
    """How a report names ``focus``: the mode, or the distance in focus (mm from the film)."""
    return focus if isinstance(focus, str) else f"{focus:g} mm"


def spots_at(traced: list[list[ImageRays]], fields_deg: list[float], wavelengths_nm: list[float],
             film_distance_mm: float) -> tuple[Spot, ...]:
    """The spots of ``traced`` on the film plane ``film_distance_mm`` behind the rear vertex."""
    spots = []
    for field, rays in zip(fields_deg, traced):
        if sum(len(r.point) for r in rays) == 0:
            raise UserError(f"no ray of the {field:g} deg field passes the lens (vignetted or beyond its field)")
        spots.append(Spot(field, tuple(wavelengths_nm), tuple(r.at(film_distance_mm) for r in rays), rays[0].launched))
    return tuple(spots)


def spot_diagram(lens: LensSystem, fields_deg: list[float], wavelengths_nm: list[float],
                 focus: str | float = "paraxial", samples_across: int = 64) -> SpotReport:
    """Spots of objects at infinity at ``fields_deg`` on the paraxial or best-focus film plane, or
    on the film focused ``focus`` mm away (``film_distance_for``)."""
    traced = trace_fields(lens, fields_deg, wavelengths_nm, samples_across)
    film = film_distance_for(lens, traced, focus)
    return SpotReport(lens.name, focus_label(focus), film, spots_at(traced, fields_deg, wavelengths_nm, film))
