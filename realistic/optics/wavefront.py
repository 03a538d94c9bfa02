"""The wavefront of a real lens: optical path difference (OPD) over the pupil from traced rays, and its
Zernike fit.

Rays from one object point (at infinity at ``field_deg``, or at a finite distance) are traced
through a square grid over the entrance-pupil plane with the float64 tracer on the reversed lens
(``realistic.optics.forward_trace``), keeping every surface's hit point. The optical path length of
a ray is sum n_i |p_(i+1) - p_i| from the object (a point source, or for an object at infinity
the plane wavefront through the origin of the launch frame) to the *reference sphere*
(a paraxial surface adds the path of an ideal lens, ``ideal_lens_path``): the
sphere centred on the reference point on the film (by default the centroid of the ray landings)
that passes through the centre of the paraxial exit pupil. The OPD of a ray is its path minus the
mean path of all passing rays (piston removed), in waves:

    W = (OPL(ray) - mean OPL) / lambda,

so a ray that travels further than the mean lags (W > 0). The pupil function of the FFT
(``realistic.optics.diffraction``) is exp(2 pi i W) on the grid cells whose ray passes, 0 elsewhere
(vignetting and the stop's shape included).

Zernike terms follow Noll's (1976) numbering and normalisation (each term has unit RMS over the
unit disk, so the RMS wavefront error is the root sum of squares of the coefficients j >= 2);
the unit disk is the circle about the passing rays' centroid through the farthest of them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.forward_trace import reversed_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import paraxial_data
from realistic.optics.tracer import paraxial_deflect, trace_from_film

#: Entrance-pupil radii (paraxial) tried for the square grid, until no passing ray lies on its rim.
_GRID_RADII = (1.25, 2.5, 5.0, 10.0, 20.0)
#: RMS spread of a beam's slopes at a paraxial surface below which it is a plane wave (``ideal_lens_path``):
#: directions from float64 hit points scatter by ~1e-14, and an object 1e10 pupil radii away spreads them
#: by 1e-10 while its wave differs from a plane one by a 1e-10 pupil radius.
PLANE_WAVE_SLOPES = 1e-10
#: Noll terms fitted by default (through the secondary spherical, j = 22).
ZERNIKE_TERMS = 22
#: Names of the first Noll terms.
NOLL_NAMES = ("piston", "tilt x", "tilt y", "defocus", "astigmatism 45", "astigmatism 0", "coma y", "coma x",
              "trefoil y", "trefoil x", "spherical", "2nd astigmatism 0", "2nd astigmatism 45", "tetrafoil 0",
              "tetrafoil 45", "2nd coma x", "2nd coma y", "2nd trefoil x", "2nd trefoil y", "pentafoil x",
              "pentafoil y", "2nd spherical")


@dataclass(frozen=True)
class Wavefront:
    """OPD (waves) on an (n, n) grid over the entrance-pupil plane; NaN where no ray passes.

    ``spacing_mm`` is the grid's cell size on the entrance-pupil plane (its rows run along +y,
    columns along +x); ``reference_mm`` the reference point on the film (x, y, mm); ``scale_mm``
    per axis (x, y) the least-squares slope of pupil height against the image-space direction sine
    of the passing rays (the focal length, for an object at infinity and a lens obeying the sine
    condition; off the axis the two differ, as the beam meets the film obliquely).
    """

    opd_waves: np.ndarray
    spacing_mm: float
    wavelength_nm: float
    field_deg: float
    film_distance_mm: float
    reference_mm: tuple[float, float]
    scale_mm: tuple[float, float]  # (L_x, L_y): pupil height h gives the image-space direction sine h / L
    pupil_xy_mm: np.ndarray  # (n, n, 2) grid cell centres on the entrance-pupil plane
    # (n, n, 3) where each ray crosses the reference sphere, from the reference point on the film (NaN
    # where none passes; the film's x, y and the axis toward it); empty where not traced
    sphere_mm: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0, 3)))

    @property
    def passed(self) -> np.ndarray:
        return np.isfinite(self.opd_waves)

    @property
    def rms_waves(self) -> float:
        """RMS OPD over the passing rays (piston removed)."""
        w = self.opd_waves[self.passed]
        return float(np.sqrt(np.mean((w - w.mean()) ** 2)))

    @property
    def undersampled_fraction(self) -> float:
        """Fraction of neighbouring passing cells whose OPD differs by more than half a wave (the
        phase's Nyquist limit): where it is more than a few percent the FFT aliases."""
        steps = np.concatenate([np.abs(np.diff(self.opd_waves, axis=axis)).ravel() for axis in (0, 1)])
        steps = steps[np.isfinite(steps)]
        return float(np.mean(steps > 0.5)) if steps.size else 0.0

    @property
    def peak_to_valley_waves(self) -> float:
        w = self.opd_waves[self.passed]
        return float(w.max() - w.min())


def _grid(count: int, spacing_mm: float) -> np.ndarray:
    """(count, count, 2) cell centres, symmetric about 0, rows along y."""
    c = (np.arange(count) - (count - 1) / 2) * spacing_mm
    x, y = np.meshgrid(c, c, indexing="xy")
    return np.stack([x, y], axis=-1)


@dataclass(frozen=True)
class _Beam:
    """Rays from the object point to points of the entrance-pupil plane (reversed-lens frame, image side +z)."""

    lens: LensSystem
    field_deg: float
    wavelength_nm: float
    object_distance_mm: float

    @property
    def gap_mm(self) -> float:
        gap = abs(float(self.lens.radius_mm[0])) if math.isfinite(self.lens.radius_mm[0]) else 0.0
        return max(gap, float(self.lens.aperture_mm[0])) + 1.0

    def trace(self, pupil_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(passed, optical path to the rear surface, hit on the rear surface, direction behind it)."""
        para = paraxial_data(self.lens, self.wavelength_nm)
        reverse = reversed_lens(self.lens)
        pupil_z = self.gap_mm + para.entrance_pupil_mm
        targets = np.column_stack([pupil_xy, np.full(len(pupil_xy), pupil_z)])
        angle = math.radians(self.field_deg)
        if math.isinf(self.object_distance_mm):
            direction = np.array([0.0, -math.sin(angle), math.cos(angle)])
            origins = targets - direction * (pupil_z / direction[2])
            directions = np.broadcast_to(direction, targets.shape)
            start = origins @ direction  # path from the plane wavefront through the frame's origin
        else:
            d = self.object_distance_mm
            source = np.array([0.0, d * math.tan(angle), pupil_z - d])
            origins = np.broadcast_to(source, targets.shape)
            directions = targets - source
            start = np.zeros(len(targets))
        path: list[np.ndarray] = []
        traced = trace_from_film(reverse, self.gap_mm, origins, directions, self.wavelength_nm, path)
        index = reverse.index_at(self.wavelength_nm)
        count = reverse.surface_count
        media = [1.0] + [float(index[count - 2 - k]) for k in range(count - 1)]  # before each hit, in order
        opl = start.copy()
        previous = np.asarray(origins, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            for k, hit in enumerate(path):  # hit k is on surface k of the lens, front first
                step = np.linalg.norm(hit - previous, axis=1)
                opl += media[k] * step
                if self.lens.paraxial[k]:
                    opl += ideal_lens_path(hit[:, :2], (hit - previous) / step[:, None],
                                           float(self.lens.paraxial_power_per_mm[k, 0]))
                previous = hit
        return traced.passed, opl, previous, traced.direction


def ideal_lens_path(hit_xy: np.ndarray, incoming: np.ndarray, power: float) -> np.ndarray:
    """The optical path a paraxial surface of ``power`` adds to the rays of one beam meeting it at
    ``hit_xy`` (from its vertex) with unit directions ``incoming``: the path that makes the ideal lens
    image perfectly, as Zemax's default OPD mode takes it (0 through the vertex).

    The beam's object is the point its rays come from, at the distance a in front of the surface that
    fits their lines best (1/a = sum |du|^2 / sum dh.du over the rays' heights h and slopes u about
    their means; 0, a plane wave, when their RMS slope spread is below ``PLANE_WAVE_SLOPES``, the
    rounding of directions taken from hit points); the lens images it at b, 1/b = 1/f - 1/a.
    A ray from S (on its line, a in front) to its image Q (b behind) then gains the chief ray's path
    less its own, sign(a)|S| - A + sign(b)|Q| - B (A, B the ray's lengths to the two planes), written
    in 1/A and 1/B so that a plane wave or an image at infinity (1/A or 1/B = 0) stays exact:
    (|h|^2 / A - 2 s.h) / (1 + sqrt(1 - 2 s.h / A + |h|^2 / A^2)), and the same in s' and -B."""
    rows = np.all(np.isfinite(hit_xy), axis=1) & np.all(np.isfinite(incoming), axis=1)
    slopes = incoming[:, :2] / np.abs(incoming[:, 2:3])
    dh = hit_xy[rows] - hit_xy[rows].mean(axis=0)
    du = slopes[rows] - slopes[rows].mean(axis=0)
    spread, coupling = float(np.sum(du * du)), float(np.sum(dh * du))
    parallel = spread <= len(du) * PLANE_WAVE_SLOPES ** 2 or coupling == 0
    inverse_a = 0.0 if parallel else spread / coupling
    outgoing = np.stack(paraxial_deflect((hit_xy[:, 0], hit_xy[:, 1]), (incoming[:, 0], incoming[:, 1], incoming[:, 2]),
                                         np.array([power, power])), axis=1)
    h2 = np.sum(hit_xy * hit_xy, axis=1)

    def leg(direction: np.ndarray, inverse_length: np.ndarray, sign: float) -> np.ndarray:
        along = sign * np.sum(direction[:, :2] * hit_xy, axis=1)
        return (h2 * inverse_length - 2 * along) / (1 + np.sqrt(1 - 2 * along * inverse_length
                                                                 + h2 * inverse_length ** 2))

    return (leg(incoming, np.abs(incoming[:, 2]) * inverse_a, 1.0)
            + leg(outgoing, np.abs(outgoing[:, 2]) * (power - inverse_a), -1.0))


def wavefront(lens: LensSystem, field_deg: float, wavelength_nm: float, film_distance_mm: float,
              samples_across: int = 64, object_distance_mm: float = math.inf,
              reference_mm: tuple[float, float] | None = None, spacing_mm: float | None = None) -> Wavefront:
    """OPD map of the point at ``field_deg`` (see the module docstring) on the film ``film_distance_mm``
    behind the rear vertex.

    The grid has ``samples_across`` cells across the paraxial entrance pupil (or cells of
    ``spacing_mm``) and is widened until no passing ray lies on its rim.
    """
    validation.wavelength_nm(wavelength_nm)
    anamorphic = np.flatnonzero(lens.paraxial_power_per_mm[:, 0] != lens.paraxial_power_per_mm[:, 1])
    if len(anamorphic):
        raise UserError(f"{lens.name}: surface {anamorphic[0]} is a paraxial lens with different x and y powers, "
                        f"whose wavefront is not modelled: use --model geometric")
    if not (abs(field_deg) < 90):
        raise UserError(f"field angle {field_deg:g} deg must be between -90 and 90")
    if not 2 <= samples_across <= 1024:
        raise UserError(f"pupil samples {samples_across} must be 2..1024")
    para = paraxial_data(lens, wavelength_nm)
    beam = _Beam(lens, field_deg, wavelength_nm, object_distance_mm)
    pupil_radius = para.entrance_pupil_diameter_mm / 2
    spacing = spacing_mm if spacing_mm is not None else 2 * pupil_radius / samples_across
    for factor in _GRID_RADII:
        count = 2 * math.ceil(factor * pupil_radius / spacing)
        grid = _grid(count, spacing)
        flat = grid.reshape(-1, 2)
        passed, opl, point, direction = beam.trace(flat)
        passed = passed & (direction[:, 2] > 0)
        if not passed.any():
            continue
        mask = passed.reshape(count, count)
        rim = mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any()
        if not rim or factor == _GRID_RADII[-1]:
            break
    else:
        raise UserError(f"no ray from a point at {field_deg:g} deg passes {lens.name} (vignetted or beyond "
                        f"its field)")
    rear_z = beam.gap_mm + lens.track_length_mm
    film_z = rear_z + film_distance_mm
    p, d = point[passed], direction[passed]
    landing = p[:, :2] + d[:, :2] / d[:, 2:3] * (film_z - p[:, 2:3])
    ref = landing.mean(axis=0) if reference_mm is None else np.asarray(reference_mm, dtype=np.float64)
    centre = np.array([ref[0], ref[1], film_z])
    exit_pupil = np.array([0.0, 0.0, rear_z + para.exit_pupil_mm])
    radius = float(np.linalg.norm(centre - exit_pupil))
    v = p - centre
    b = np.sum(v * d, axis=1)
    disc = b * b - np.sum(v * v, axis=1) + radius * radius
    if np.any(disc < 0):
        raise UserError(f"{lens.name}: rays at {field_deg:g} deg miss the reference sphere about the image point")
    t = -b - np.sqrt(disc)  # the crossing before the centre (negative: behind the rear surface's hit)
    total = opl[passed] + t  # image space is air
    h = flat[passed] - flat[passed].mean(axis=0)
    sines = d[:, :2] - d[:, :2].mean(axis=0)
    turn = np.sum(h * sines, axis=0)
    if not np.all(turn != 0):
        raise UserError(f"{lens.name}: the beam at {field_deg:g} deg does not converge (no focal length)")
    scale = np.abs(np.sum(h * h, axis=0) / turn)
    opd = np.full(count * count, np.nan)
    opd[passed] = (total - total.mean()) / (wavelength_nm * 1e-6)
    sphere = np.full((count * count, 3), np.nan)
    sphere[passed] = p + t[:, None] * d - centre
    return Wavefront(opd.reshape(count, count), spacing, wavelength_nm, field_deg, film_distance_mm,
                     (float(ref[0]), float(ref[1])),
                     (float(scale[0]), float(scale[1])), grid, sphere.reshape(count, count, 3))


def noll_indices(j: int) -> tuple[int, int]:
    """(n, m) of Noll's term j >= 1 (m signed: m > 0 cosine, m < 0 sine)."""
    n = 0
    while (n + 1) * (n + 2) // 2 < j:
        n += 1
    m_abs = n % 2 + 2 * ((j - n * (n + 1) // 2 - 1 + (n + 1) % 2) // 2)
    return n, (m_abs if m_abs == 0 or j % 2 == 0 else -m_abs)


def zernike(j: int, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Noll's Zernike term j (unit RMS over the unit disk) at polar points."""
    n, m = noll_indices(j)
    ma = abs(m)
    radial = np.zeros_like(rho)
    for k in range((n - ma) // 2 + 1):
        coefficient = ((-1) ** k * math.factorial(n - k)
                       / (math.factorial(k) * math.factorial((n + ma) // 2 - k) * math.factorial((n - ma) // 2 - k)))
        radial += coefficient * rho ** (n - 2 * k)
    if m == 0:
        return math.sqrt(n + 1) * radial
    angular = np.cos(ma * theta) if m > 0 else np.sin(ma * theta)
    return math.sqrt(2 * (n + 1)) * radial * angular


def zernike_fit(front: Wavefront, terms: int = ZERNIKE_TERMS) -> np.ndarray:
    """Least-squares Noll coefficients (waves) 1..``terms`` of the OPD over the passing rays."""
    if not 1 <= terms <= 66:
        raise UserError(f"Zernike terms {terms} must be 1..66")
    xy = front.pupil_xy_mm[front.passed]
    centre = xy.mean(axis=0)
    rel = xy - centre
    scale = float(np.hypot(rel[:, 0], rel[:, 1]).max()) or 1.0
    rho = np.hypot(rel[:, 0], rel[:, 1]) / scale
    theta = np.arctan2(rel[:, 1], rel[:, 0])
    basis = np.column_stack([zernike(j, rho, theta) for j in range(1, terms + 1)])
    coefficients, *_ = np.linalg.lstsq(basis, front.opd_waves[front.passed], rcond=None)
    return coefficients


def term_name(j: int) -> str:
    """A Noll term's usual name, or its (n, m)."""
    n, m = noll_indices(j)
    return NOLL_NAMES[j - 1] if j <= len(NOLL_NAMES) else f"Z(n={n}, m={m})"
