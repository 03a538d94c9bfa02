"""Paraxial (first-order) analysis and thick-lens focusing.

Works in the optics textbook convention: light runs from the scene to the film and every position
is signed + toward the film, measured from the vertex named in the field. Focusing results are
plain distances (film distance from the rear vertex, object distance from the film plane) that
mean the same in the lens frame of ``realistic.optics.lens``.

The trace is the y-nu method: at a surface of curvature c between indices n and n',
n'u' = nu - y ((n' - n) c + p), with p the power of a paraxial surface (an ideal thin lens, 0
elsewhere; of a PARAXIAL_XY surface the y power, the meridional plane being y's); across a gap t
in index n', y <- y + t u'.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.lens import LensSystem


@dataclass(frozen=True)
class ParaxialData:
    """First-order properties of a lens at one wavelength, focused at infinity."""

    wavelength_nm: float
    efl_mm: float
    bfl_mm: float  # last vertex to rear focal point
    ffd_mm: float  # front vertex to front focal point (negative: in front of the lens)
    front_principal_plane_mm: float  # from the front vertex
    rear_principal_plane_mm: float  # from the last vertex
    entrance_pupil_mm: float  # from the front vertex
    entrance_pupil_diameter_mm: float
    exit_pupil_mm: float  # from the last vertex
    exit_pupil_diameter_mm: float
    f_number: float
    track_length_mm: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class _Surfaces:
    """The arrays a paraxial trace needs, at one wavelength."""

    curvature: np.ndarray
    n_before: np.ndarray
    n_after: np.ndarray
    gaps: np.ndarray  # len(curvature) - 1 distances between vertices
    stop: int
    stop_radius: float
    power: np.ndarray  # a paraxial surface's (y) power, 0 elsewhere

    def reversed(self) -> _Surfaces:
        """The same lens seen from the film side: order reversed, curvatures and media swapped."""
        return _Surfaces(-self.curvature[::-1], self.n_after[::-1], self.n_before[::-1],
                         self.gaps[::-1], len(self.curvature) - 1 - self.stop, self.stop_radius, self.power[::-1])


def _surfaces(lens: LensSystem, wavelength_nm: float) -> _Surfaces:
    n_after = lens.index_at(wavelength_nm)
    n_before = np.concatenate([[1.0], n_after[:-1]])
    return _Surfaces(lens.curvature_per_mm, n_before, n_after, lens.thickness_mm[:-1],
                     lens.stop, lens.stop_diameter_mm / 2, lens.paraxial_power_per_mm[:, 1])


def _trace(surfaces: _Surfaces, y: float, nu: float) -> tuple[np.ndarray, float, float]:
    """Heights at every surface and the final (y, u) of a ray entering surface 0 at (y, nu)."""
    heights = np.empty(len(surfaces.curvature))
    for i, c in enumerate(surfaces.curvature):
        heights[i] = y
        nu = nu - y * ((surfaces.n_after[i] - surfaces.n_before[i]) * c + surfaces.power[i])
        if i < len(surfaces.gaps):
            y = y + surfaces.gaps[i] * nu / surfaces.n_after[i]
    return heights, y, nu / surfaces.n_after[-1]


def lens_label(lens: LensSystem) -> str:
    """How messages name a lens: its file (or bundled name and file), else its name."""
    return lens.source or lens.name


def _focal_lengths(surfaces: _Surfaces, label: str) -> tuple[float, float]:
    """(EFL, back focal distance) from a ray parallel to the axis."""
    _, y_last, u_last = _trace(surfaces, 1.0, 0.0)
    if u_last == 0:
        raise UserError(f"{label}: the lens is afocal (a ray parallel to the axis leaves parallel), so it has "
                        f"no focal length")
    return -1.0 / u_last, -y_last / u_last


def _entrance_pupil(surfaces: _Surfaces, label: str) -> tuple[float, float]:
    """(position from surface 0, diameter) of the stop's image through the surfaces before it."""
    marginal, _, _ = _trace(surfaces, 1.0, 0.0)
    slope, _, _ = _trace(surfaces, 0.0, 1.0)
    ya, yb = marginal[surfaces.stop], slope[surfaces.stop]
    if ya == 0:
        raise UserError(f"{label}: the elements on one side of the stop focus a parallel beam onto it, so the "
                        f"stop has no pupil image")
    return yb / ya, 2 * surfaces.stop_radius / abs(ya)


def paraxial_data(lens: LensSystem, wavelength_nm: float = D_LINE_NM) -> ParaxialData:
    """EFL, BFL, FFD, principal planes, pupils and F-number of ``lens`` at ``wavelength_nm``."""
    label = lens_label(lens)
    fwd = _surfaces(lens, wavelength_nm)
    rev = fwd.reversed()
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # judged below, as a whole
        efl, bfl = _focal_lengths(fwd, label)
        _, bfl_reversed = _focal_lengths(rev, label)
        ffd = -bfl_reversed
        ep, epd = _entrance_pupil(fwd, label)
        xp_reversed, xpd = _entrance_pupil(rev, label)
        data = ParaxialData(
            wavelength_nm=wavelength_nm, efl_mm=float(efl), bfl_mm=float(bfl), ffd_mm=float(ffd),
            front_principal_plane_mm=float(ffd + efl), rear_principal_plane_mm=float(bfl - efl),
            entrance_pupil_mm=float(ep), entrance_pupil_diameter_mm=float(epd),
            exit_pupil_mm=float(-xp_reversed), exit_pupil_diameter_mm=float(xpd),
            f_number=float(efl / epd), track_length_mm=lens.track_length_mm,
        )
    bad = [name for name, value in data.as_dict().items() if not math.isfinite(value)]
    if bad:
        raise UserError(f"{label}: the paraxial trace overflows ({', '.join(bad)} not finite): the lens's "
                        f"lengths or powers are out of any usable range")
    return data


@dataclass(frozen=True)
class ThickLens:
    """Thick-lens model in the lens frame: principal planes as distances from the rear vertex."""

    focal_length_mm: float
    rear_principal_from_rear_vertex_mm: float  # + toward the scene
    front_principal_from_rear_vertex_mm: float  # + toward the scene

    @property
    def principal_gap_mm(self) -> float:
        return self.front_principal_from_rear_vertex_mm - self.rear_principal_from_rear_vertex_mm


def thick_lens(lens: LensSystem, wavelength_nm: float = D_LINE_NM) -> ThickLens:
    p = paraxial_data(lens, wavelength_nm)
    return ThickLens(p.efl_mm, -p.rear_principal_plane_mm,
                     p.track_length_mm - p.front_principal_plane_mm)


def nearest_focus_mm(lens: LensSystem, wavelength_nm: float = D_LINE_NM) -> float:
    """Closest object distance (from the film plane) the thick-lens model can focus."""
    t = thick_lens(lens, wavelength_nm)
    return 4 * t.focal_length_mm + t.principal_gap_mm


def film_distance_for_focus(lens: LensSystem, focus_distance_mm: float,
                            wavelength_nm: float = D_LINE_NM) -> float:
    """Rear vertex to film distance that focuses an object ``focus_distance_mm`` from the film.

    Gaussian lens formula between the principal planes, 1/s_o + 1/s_i = 1/f, solved for the image
    distance s_i = x: x^2 - (Z - D) x + f (Z - D) = 0 with D the principal-plane gap; the root near
    f is the real focus. ``inf`` gives the film at the rear focal point.
    """
    t = thick_lens(lens, wavelength_nm)
    f = t.focal_length_mm
    if math.isinf(focus_distance_mm):
        return f - t.rear_principal_from_rear_vertex_mm
    span = focus_distance_mm - t.principal_gap_mm
    if not (span > 4 * f and span > 0):
        raise UserError(f"{lens_label(lens)}: focus distance {focus_distance_mm:g} mm is closer than the "
                        f"lens '{lens.name}' can focus (nearest: {nearest_focus_mm(lens, wavelength_nm):.6g} mm "
                        f"from the film)")
    # the root near f as 2 f span / (span + sqrt(span (span - 4 f))): the product of the roots is
    # f span, and this form keeps the digits that span - sqrt(...) cancels for a far focus (1e20 mm);
    # the square root is taken as a product, which does not overflow
    image_distance = 2 * f * span / (span + math.sqrt(span) * math.sqrt(span - 4 * f))
    return image_distance - t.rear_principal_from_rear_vertex_mm


def focus_distance_for_film(lens: LensSystem, film_distance_mm: float,
                            wavelength_nm: float = D_LINE_NM) -> float:
    """Object distance from the film plane that is sharp at ``film_distance_mm`` (inf at the focal point)."""
    t = thick_lens(lens, wavelength_nm)
    image_distance = film_distance_mm + t.rear_principal_from_rear_vertex_mm
    f = t.focal_length_mm
    if math.isclose(image_distance, f, rel_tol=1e-12, abs_tol=1e-12):
        return math.inf
    if image_distance < f:
        raise UserError(f"film distance {film_distance_mm:g} mm is shorter than the back focal distance "
                        f"({f - t.rear_principal_from_rear_vertex_mm:.6g} mm): nothing is in focus")
    object_distance = 1.0 / (1.0 / f - 1.0 / image_distance)
    return object_distance + t.front_principal_from_rear_vertex_mm + film_distance_mm


class FasterThanLens(UserError):
    """An f-number faster than the lens opens; ``widest`` is the fastest it does (the CLI takes that,
    as a camera does, where the API refuses)."""

    def __init__(self, message: str, lens_name: str, widest: float):
        super().__init__(message)
        self.lens_name, self.widest = lens_name, widest


def stop_diameter_for_f_number(lens: LensSystem, f_number: float, wavelength_nm: float = D_LINE_NM) -> float:
    """Stop diameter (mm) that gives the paraxial ``f_number`` (EFL over entrance pupil diameter).

    The entrance pupil is the stop's paraxial image, so its diameter scales linearly with the
    stop's. A number faster than the lens file's own stop allows is an error: the other elements'
    apertures were designed around that stop.
    """
    f_number = validation.f_number(f_number)
    widest = paraxial_data(lens, wavelength_nm).f_number
    if f_number < widest * (1 - 1e-9):
        raise FasterThanLens(f"f/{f_number:g} is faster than {lens.name} opens (f/{widest:.3g} at its stop of "
                             f"{lens.stop_diameter_mm:g} mm)", lens.name, widest)
    return lens.stop_diameter_mm * widest / f_number
