"""The lens model: a prescription held as plain arrays, and its validation.

It knows no file format: readers in ``realistic.optics.formats`` parse files and feed ``build_lens``.

Frames and units (shared by every module of the package):

* All lens lengths are millimetres.
* Surfaces are numbered from 0 at the front (scene side) to the rear (film side), the order of
  the rows of a prescription file.
* The *lens frame* is the camera frame: the film plane is z = 0, +z points toward the scene, x and
  y are the film's axes. The rear lens vertex sits at z = film distance and the front vertex at
  z = film distance + total track. Tracers and samplers work in this frame.
* Paraxial analysis (``realistic.optics.paraxial``) uses the optics textbook convention instead: light
  travels from the scene toward the film and positions are signed + toward the film. It converts
  at its boundary.

A prescription row is ``radius thickness n_d [V_d] aperture``: signed radius of curvature (> 0:
centre of curvature on the film side, i.e. convex toward the scene; 0: the planar aperture stop;
``inf``: a flat refracting surface), distance to the next surface, index of the medium behind the
surface (0, 1 or blank: air), optional Abbe number, clear aperture diameter. A radius of 0 is the
stop only where the media on its two sides are the same (air); where they differ it is a flat
refracting face, as ``inf`` is (a plano-convex lens's flat face). A reader whose format marks the
stop itself passes ``stop`` to ``build_lens``, and every other radius 0 is then a plane; such a stop
may also be curved or have glass on one side (Zemax's STOP on a lens's first face): it then refracts
as any surface, and its clear aperture is the stop (``stop_is_flat_in_air`` is False).

A medium may be a catalogue glass (``realistic.optics.glass``): its maker's dispersion formula then
gives n(lambda), and n_d and V_d are the formula's own (``realistic.optics.dispersion``).

A surface may be an even asphere (``realistic.optics.asphere``): a conic constant k and the
coefficients A4 .. A20 of r^4 .. r^20 beside its base radius. A surface with k = 0 and every
coefficient 0 is a sphere and is traced exactly as one; paraxial analysis uses the base curvature.

A surface may be paraxial (Zemax's PARAXIAL and PARAXIAL_XY): an ideal thin lens of powers
(1/f_x, 1/f_y) on the plane of its vertex, with air on both sides. A ray meeting it at (x, y) with
slopes (u_x, u_y) = (dx/dz, dy/dz) along its travel leaves with slopes (u_x - x/f_x, u_y - y/f_y):
every field is imaged perfectly onto the focal plane, and the lens is achromatic.
``paraxial_power_per_mm`` holds the two powers per surface (0, 0 for the others).

Two surfaces may be 0 mm apart (a stop on a lens vertex) where they touch without crossing inside
their clear apertures; the tracer then meets the second wherever the ray meets it.

A lens has at most ``MAX_SURFACES`` surfaces: real photographic lenses have well under 50, and the
tracer's cost grows with the count, so a file with thousands of rows is refused (the readers stop
at the first row past the limit, so even a huge file is refused quickly). The limit leaves room for
stacks of thin elements (a 1,000-surface prescription traces in linear time).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.core import validation
from realistic.errors import LensFileError, UserError
from realistic.optics.asphere import COEFFICIENT_COUNT, COEFFICIENT_POWERS, conic_radicand, sag_mm
from realistic.optics.coating import COATINGS, interface_models
from realistic.optics.dispersion import D_LINE_NM, GlassFormula, refractive_index
from realistic.optics.stop_shape import StopShape

#: Most surfaces a prescription may have (stop included); real lenses have well under 50.
MAX_SURFACES = 1024
#: Largest float32: lens values are written into the OpenCL kernel as float32 literals.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def too_many_surfaces(count: int, at_least: bool = False) -> str:
    """The message for a lens of ``count`` surfaces (``at_least``: a reader that stopped counting there)."""
    counted = f"at least {count}" if at_least else str(count)
    return f"{counted} surfaces exceed the limit of {MAX_SURFACES} (real lenses have well under 50)"


@dataclass(frozen=True, eq=False)
class LensSystem:
    """A lens as arrays indexed by surface, front (scene side) first.

    ``thickness_mm[i]`` is the axial distance from surface i to surface i+1; the last entry is the
    film gap given by the file (0 when the file leaves focusing to the scene). ``index_d[i]`` and
    ``abbe_v[i]`` describe the medium behind surface i (toward the film); air has index 1 and V 0.
    """

    name: str
    radius_mm: np.ndarray
    thickness_mm: np.ndarray
    index_d: np.ndarray
    abbe_v: np.ndarray
    aperture_mm: np.ndarray
    stop: int
    source: str = ""
    convention_note: str = ""
    description: str = ""  # the file's own words about the lens: its origin (patent, example), focal length
    stop_shape: StopShape | None = None  # None: the stop is the circle of its aperture diameter
    # (N,) conic constant k; empty (the default): all spheres
    conic: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    # (N, 9) A4 .. A20 (mm^(1-p) for r^p); empty (the default): all 0
    aspheric_coefficients: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, COEFFICIENT_COUNT)))
    # per surface, the catalogue glass behind it (None: n_d and V_d only); empty (the default): none
    glass: tuple[GlassFormula | None, ...] = ()
    # per surface, its coating (``realistic.optics.coating.COATINGS``); empty (the default): all ideal
    coating: tuple[str, ...] = ()
    # (N, 2) powers 1/f_x, 1/f_y (1/mm) of a paraxial surface, 0 for the others; empty (the default): none
    paraxial_power_per_mm: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))

    def __post_init__(self) -> None:
        """Make the text printable (``validation.printable_text``: it reaches terminals and the files
        ``lens convert`` writes) and expand the empty defaults of ``conic``, ``aspheric_coefficients``,
        ``glass``, ``coating`` and ``paraxial_power_per_mm`` per surface, so that they are always (N,),
        (N, 9) and (N, 2) arrays and N-tuples."""
        count = len(self.radius_mm)
        object.__setattr__(self, "name", validation.printable_text(self.name))
        object.__setattr__(self, "source", validation.printable_text(self.source))
        object.__setattr__(self, "description", validation.printable_text(self.description, multiline=True))
        if self.conic.size == 0:
            object.__setattr__(self, "conic", np.zeros(count))
        if self.aspheric_coefficients.size == 0:
            object.__setattr__(self, "aspheric_coefficients", np.zeros((count, COEFFICIENT_COUNT)))
        if not self.glass:
            object.__setattr__(self, "glass", (None,) * count)
        if not self.coating:
            object.__setattr__(self, "coating", ("ideal",) * count)
        if self.paraxial_power_per_mm.size == 0:
            object.__setattr__(self, "paraxial_power_per_mm", np.zeros((count, 2)))

    def __repr__(self) -> str:
        """One line, no arrays: the name, surfaces, stop and length (``lens info`` says the rest)."""
        glass = ", dispersive" if self.has_dispersion else ""
        aspheres = f", {self.asphere_count} aspheric" if self.asphere_count else ""
        return (f"LensSystem({self.name!r}, {self.surface_count} surfaces{aspheres}, stop {self.stop_diameter_mm:.4g} "
                f"mm, track {self.track_length_mm:.4g} mm{glass})")

    @property
    def surface_count(self) -> int:
        return len(self.radius_mm)

    @property
    def aspheric(self) -> np.ndarray:
        """Per surface: True for an asphere (k != 0 or a coefficient != 0), False for a sphere or plane."""
        return (self.conic != 0) | np.any(self.aspheric_coefficients != 0, axis=1)

    @property
    def asphere_count(self) -> int:
        return int(np.count_nonzero(self.aspheric))

    @property
    def paraxial(self) -> np.ndarray:
        """Per surface: True for a paraxial surface (an ideal thin lens of some power)."""
        return np.any(self.paraxial_power_per_mm != 0, axis=1)

    @property
    def curvature_per_mm(self) -> np.ndarray:
        """1/R per surface, 0 for the stop and for flat surfaces."""
        with np.errstate(divide="ignore"):
            c = np.where(self.radius_mm == 0, 0.0, 1.0 / self.radius_mm)
        return np.where(np.isfinite(c), c, 0.0)

    @property
    def track_length_mm(self) -> float:
        """Axial distance from the front vertex to the rear vertex."""
        return float(np.sum(self.thickness_mm[:-1]))

    @property
    def film_gap_mm(self) -> float:
        """Rear vertex to film distance written in the file, 0 when the file gives none."""
        return float(self.thickness_mm[-1])

    @property
    def stop_diameter_mm(self) -> float:
        return float(self.aperture_mm[self.stop])

    @property
    def stop_is_flat_in_air(self) -> bool:
        """True for the usual stop, a plane (radius 0) with air on both sides; False for a curved,
        refracting or paraxial stop surface, which only formats that mark the stop (.zmx, .seq) can hold."""
        before = self.index_d[self.stop - 1] if self.stop > 0 else 1.0
        return bool(self.radius_mm[self.stop] == 0 and self.index_d[self.stop] == 1.0 and before == 1.0
                    and not self.paraxial[self.stop])

    @property
    def has_dispersion(self) -> bool:
        return bool(np.any(self.abbe_v > 0)) or any(g is not None for g in self.glass)

    def dispersion_warning(self, wavelengths_nm: list[float]) -> str | None:
        """Why a trace at ``wavelengths_nm`` shows less colour than the lens has: a glass with neither
        V_d nor a catalogue formula keeps n_d at every wavelength; None when nothing is missing or
        only the d line is asked for."""
        constant = [i for i in range(self.surface_count)
                    if self.index_d[i] != 1 and self.abbe_v[i] == 0 and self.glass[i] is None]
        if not constant or all(abs(w - D_LINE_NM) < 1e-9 for w in wavelengths_nm):
            return None
        data = "dispersion data (an Abbe number or a catalogue glass)"
        if len(constant) == np.count_nonzero(self.index_d != 1):
            return f"{self.name}: no glass has {data}: every wavelength asked for traces as the d line"
        which = "surface" + ("s " if len(constant) > 1 else " ") + ", ".join(map(str, constant))
        return (f"{self.name}: the glass behind {which} has no {data}, so it keeps n_d at every wavelength: "
                f"the colours differ less than in the real lens")

    def index_at(self, wavelength_nm: float | np.ndarray) -> np.ndarray:
        """Index of the medium behind each surface at ``wavelength_nm`` (``dispersion.refractive_index``):
        a catalogue glass's formula, else Cauchy from n_d and V_d."""
        return refractive_index(self.index_d, self.abbe_v, wavelength_nm, self.glass)

    def vertex_offset_from_rear_mm(self) -> np.ndarray:
        """Axial position of each vertex measured from the rear vertex, + toward the scene."""
        gaps = self.thickness_mm[:-1]
        return np.concatenate([np.cumsum(gaps[::-1])[::-1], [0.0]])

    def vertex_z_mm(self, film_distance_mm: float) -> np.ndarray:
        """Vertex positions in the lens frame (film at z = 0) for a given film distance."""
        return film_distance_mm + self.vertex_offset_from_rear_mm()

    def with_stop_diameter(self, diameter_mm: float) -> LensSystem:
        """The same lens with the stop opened or closed to ``diameter_mm``: the one check of a stop
        diameter from the CLI, a pbrt file or the API. A stop wider than every element of the lens
        would stop nothing (and report an f-number the lens cannot have), so it is refused."""
        diameter_mm = validation.stop_diameter_mm(diameter_mm)
        widest = float(self.aperture_mm.max())
        if diameter_mm > widest:
            raise UserError(f"aperture diameter {diameter_mm:g} mm is wider than {self.name}'s widest element "
                            f"({widest:g} mm)")
        aperture = self.aperture_mm.copy()
        aperture[self.stop] = diameter_mm
        return dataclasses.replace(self, aperture_mm=aperture)

    def with_stop_shape(self, shape: StopShape | None) -> LensSystem:
        """The same lens with its stop cut to ``shape`` (``realistic.optics.stop_shape``), scaled to its diameter.
        A shape needs a flat stop in air (the kernel cuts it on a plane)."""
        if shape is not None and not self.stop_is_flat_in_air:
            raise UserError(f"{self.name}: a shaped stop needs a flat stop in air, and this lens's stop (surface "
                            f"{self.stop}) is curved or has glass on one side")
        return dataclasses.replace(self, stop_shape=shape)

    def with_coating(self, coating: str | Sequence[str]) -> LensSystem:
        """The same lens with ``coating`` (one of ``COATINGS``) on every surface, or one per surface, front first."""
        names = (coating,) * self.surface_count if isinstance(coating, str) else tuple(coating)
        if len(names) != self.surface_count:
            raise UserError(f"{self.name}: {len(names)} coatings given for {self.surface_count} surfaces")
        for name in names:
            if name not in COATINGS:
                raise UserError(f"unknown coating {name!r}: choose one of {', '.join(COATINGS)}")
        return dataclasses.replace(self, coating=names)

    def refuse_paraxial(self, format_name: str) -> None:
        """A UserError for a file format that cannot hold this lens's paraxial surfaces, if it has any."""
        if self.paraxial.any():
            raise UserError(f"{self.name}: surface {int(self.paraxial.argmax())} is paraxial (an ideal thin lens), "
                            f"which a {format_name} prescription cannot hold: convert to .zmx or .json")

    @property
    def interface_models(self) -> np.ndarray:
        """Per surface, what it does to a ray's weight (``realistic.optics.coating.interface_models``)."""
        front = np.concatenate([[1.0], self.index_d[:-1]])
        return interface_models(self.coating, self.index_d, front)


#: Lens lengths (radii, thicknesses, apertures) in mm: from a picometre to a kilometre. The OpenCL
#: kernel holds them (and the squared semi-apertures) in float32, whose range this keeps far inside.
MIN_LENGTH_MM, MAX_LENGTH_MM = 1e-9, 1e6
#: A radius beyond this is flat in float32 arithmetic at any aperture: ``inf`` says so exactly.
MAX_RADIUS_MM = 1e12
#: Refractive indices (besides 0 or 1 for air): from 1 to beyond germanium's 4.
MAX_INDEX = 10.0
#: Abbe numbers (besides 0, no dispersion): below 1 the Cauchy fit bends n_d below 1 inside the visible.
MIN_ABBE, MAX_ABBE = 1.0, 1000.0
#: Conic constants: real hyperboloids and ellipsoids stay within a few hundred.
MAX_CONIC = 1e6


@dataclass(frozen=True)
class _Limits:
    """The range of one prescription quantity: ``low`` <= |value| <= ``high`` unless it is 0 and
    ``zero`` allows that (the stop's radius, air's index) or inf and ``infinite`` does (a flat radius).
    ``signed`` quantities (radius, conic) take either sign; the others' negative values are refused
    earlier, with their own words."""

    name: str
    unit: str
    low: float
    high: float
    zero: bool = False
    infinite: bool = False
    signed: bool = False
    advice: str = ""

    def problem(self, value: float) -> str | None:
        """Why ``value`` is out of range, or None."""
        size = abs(value)
        if math.isnan(value) or (math.isinf(value) and not self.infinite):
            return f"{self.name} must be a finite number, got {value:g}"
        if (size == 0 and self.zero) or (math.isinf(value) and self.infinite) or self.low <= size <= self.high:
            return None
        bound = f"between {self.low:g} and {self.high:g}" if self.low > 0 else f"at most {self.high:g}"
        sign = "in magnitude " if self.signed else ""
        return f"{self.name} {value:g}{self.unit} is out of range: it must be {sign}{bound}{self.unit}{self.advice}"


#: One range per quantity of a prescription row, checked for every format in ``build_lens``.
LIMITS = {
    "radius": _Limits("radius", " mm", 0.0, MAX_RADIUS_MM, zero=True, infinite=True, signed=True,
                      advice=" (0 for the stop, inf for a flat surface)"),
    "thickness": _Limits("thickness", " mm", MIN_LENGTH_MM, MAX_LENGTH_MM, zero=True),
    "index": _Limits("index", "", 1.0, MAX_INDEX, zero=True, advice=" (0, 1 or blank for air)"),
    "abbe": _Limits("Abbe number", "", MIN_ABBE, MAX_ABBE, zero=True, advice=" (0 for no dispersion)"),
    "aperture": _Limits("aperture diameter", " mm", MIN_LENGTH_MM, MAX_LENGTH_MM),
    "conic": _Limits("conic constant", "", 0.0, MAX_CONIC, zero=True, signed=True),
}


def _check_coefficients(path: str, line: int, aperture: float, coefficients: list[float]) -> None:
    """Each polynomial term A_p h^p at the clear semi-diameter h must be a length the kernel holds
    (at most ``MAX_LENGTH_MM``), and each coefficient a float32 number."""
    half = aperture / 2
    for power, a in zip(COEFFICIENT_POWERS, coefficients):
        term = abs(a) * half ** power if a else 0.0  # (a power of h <= 5e5 stays finite)
        if not (abs(a) <= FLOAT32_MAX and term <= MAX_LENGTH_MM):
            raise LensFileError(path, line, f"aspheric coefficient A{power} {a:g} is out of range: its term "
                                f"A{power} r^{power} at the clear semi-diameter {half:g} mm must be at most "
                                f"{MAX_LENGTH_MM:g} mm")


def _check_asphere(path: str, line: int, radius: float, aperture: float, conic: float,
                   coefficients: list[float]) -> None:
    """An aspheric surface's own rules: finite values, at most nine coefficients, not the stop,
    and a conic defined over the whole clear aperture."""
    if len(coefficients) > COEFFICIENT_COUNT:
        raise LensFileError(path, line, f"{len(coefficients)} aspheric coefficients: at most {COEFFICIENT_COUNT} "
                            f"(A4 .. A20, the coefficients of r^{COEFFICIENT_POWERS[0]} .. r^{COEFFICIENT_POWERS[-1]})")
    if not all(math.isfinite(x) for x in [conic, *coefficients]):
        raise LensFileError(path, line, "the conic constant and aspheric coefficients must be finite numbers")
    _check_coefficients(path, line, aperture, coefficients)
    if radius == 0 and (conic != 0 or any(coefficients)):
        raise LensFileError(path, line, "the aperture stop (radius 0) cannot be aspheric")
    c = 1.0 / radius if radius != 0 and math.isfinite(radius) else 0.0
    half = aperture / 2
    if conic_radicand(half * half, c, conic) < 0:  # (a product overflows to inf; a power would raise)
        reach = 1.0 / (abs(c) * math.sqrt(1.0 + conic))
        raise LensFileError(path, line, f"aperture diameter {aperture:g} mm is larger than the conic (radius "
                            f"{radius:g} mm, k {conic:g}) allows: its sag is defined only to a semi-diameter "
                            f"of {reach:g} mm")


def build_lens(path: str, lines: list[int], radius: list[float], thickness: list[float], index: list[float],
               abbe: list[float], aperture: list[float], name: str | None = None, note: str = "",
               conic: list[float] | None = None, coefficients: list[list[float]] | None = None,
               description: str = "", glass: list[GlassFormula | None] | None = None,
               stop: int | None = None, paraxial_power: list[tuple[float, float]] | None = None) -> LensSystem:
    """Validate per-surface values (prescription conventions) into a LensSystem.

    ``lines[i]`` is the file line that errors about surface i name; every parser feeds this one
    constructor so that all lens files obey the same rules. ``conic`` and ``coefficients`` (per
    surface: k, and up to nine coefficients A4, A6, ... of r^4, r^6, ...) make surfaces aspheric.
    ``glass`` (per surface, None where the row's n_d and V_d stand) sets a medium's index and V_d
    from a catalogue formula. ``stop`` marks the stop row where the format says which it is; without
    it the stop is the radius-0 row with the same medium on both sides. ``paraxial_power`` (per surface,
    (1/f_x, 1/f_y) in 1/mm, (0, 0) for an ordinary surface) makes surfaces paraxial thin lenses.
    """
    count = len(lines)
    glass = [None] * count if glass is None else list(glass)
    index = [float(g.n_d) if g is not None else n for g, n in zip(glass, index)]
    abbe = [float(g.abbe_v) if g is not None else v for g, v in zip(glass, abbe)]
    conic = [0.0] * count if conic is None else list(conic)
    coefficients = [[] for _ in range(count)] if coefficients is None else [list(a) for a in coefficients]
    power = [(0.0, 0.0)] * count if paraxial_power is None else [(float(x), float(y)) for x, y in paraxial_power]
    if len(lines) > MAX_SURFACES:
        raise LensFileError(path, lines[MAX_SURFACES], too_many_surfaces(len(lines)))
    for i, line in enumerate(lines):
        values = (radius[i], thickness[i], index[i], abbe[i], aperture[i])
        if any(math.isnan(x) for x in values) or any(math.isinf(x) for x in values[1:]):
            raise LensFileError(path, line, "values must be finite numbers (only a radius may be inf)")
        if i < len(lines) - 1 and thickness[i] < 0:
            raise LensFileError(path, line, f"thickness {thickness[i]:g} mm to the next surface must not be negative")
        if i == len(lines) - 1 and thickness[i] < 0:
            raise LensFileError(path, line, f"film gap {thickness[i]:g} mm must not be negative")
        if index[i] < 0 or 0 < index[i] < 1:
            raise LensFileError(path, line, f"index {index[i]:g} is below 1 (use 0, 1 or blank for air)")
        if abbe[i] < 0:
            raise LensFileError(path, line, f"Abbe number {abbe[i]:g} must not be negative")
        if aperture[i] <= 0:
            raise LensFileError(path, line, f"aperture diameter {aperture[i]:g} mm must be > 0")
        problem = next(filter(None, (limits.problem(value) for limits, value in zip(LIMITS.values(),
                                                                                  (*values, conic[i])))), None)
        if problem:
            raise LensFileError(path, line, problem)
        if conic[i] != 0 or any(coefficients[i]) or len(coefficients[i]) > COEFFICIENT_COUNT:
            _check_asphere(path, line, radius[i], aperture[i], conic[i], coefficients[i])
        elif radius[i] != 0 and math.isfinite(radius[i]) and aperture[i] / 2 > abs(radius[i]):
            raise LensFileError(path, line, f"aperture diameter {aperture[i]:g} mm is larger than the "
                                f"sphere of radius {radius[i]:g} mm allows (semi-diameter > |R|)")

    index = [1.0 if n in (0.0, 1.0) else n for n in index]
    abbe = [0.0 if n == 1.0 else v for n, v in zip(index, abbe)]
    paraxial = [i for i in range(count) if power[i] != (0.0, 0.0)]
    for i in paraxial:
        _check_paraxial(path, lines[i], radius[i], power[i], conic[i], coefficients[i],
                        (index[i - 1] if i > 0 else 1.0, index[i]), glass[i])
    radius = _flat_faces(radius, index, abbe, glass, stop, paraxial)
    _check_touching(path, lines, radius, thickness, aperture, conic, coefficients)
    if stop is None:
        stop = _implicit_stop(path, lines, radius, index)
    elif conic[stop] != 0 or any(coefficients[stop]):
        raise LensFileError(path, lines[stop], "the aperture stop cannot be aspheric")
    refracting = [i for i in range(count) if index[i] != (index[i - 1] if i > 0 else 1.0) or i in paraxial]
    if not refracting:
        raise LensFileError(path, None, "no refracting surface (every row is the stop or has air on both sides): "
                            "the lens would not form an image")

    return LensSystem(
        name=name or Path(path).stem,
        radius_mm=np.array(radius), thickness_mm=np.array(thickness), index_d=np.array(index),
        abbe_v=np.array(abbe), aperture_mm=np.array(aperture), stop=stop,
        source=path, convention_note=note, description=description, conic=np.array(conic, dtype=np.float64),
        glass=tuple(None if index[i] == 1.0 else g for i, g in enumerate(glass)),
        aspheric_coefficients=np.array([a + [0.0] * (COEFFICIENT_COUNT - len(a)) for a in coefficients],
                                       dtype=np.float64).reshape(count, COEFFICIENT_COUNT),
        paraxial_power_per_mm=np.array(power, dtype=np.float64).reshape(count, 2),
    )


def _check_paraxial(path: str, line: int, radius: float, power: tuple[float, float], conic: float,
                    coefficients: list[float], media: tuple[float, float], glass: GlassFormula | None) -> None:
    """A paraxial surface's own rules: a plane with air on both sides, and focal lengths of a usable size."""
    for axis, p in zip("xy", power):
        if not math.isfinite(p) or (p != 0 and not MIN_LENGTH_MM <= 1 / abs(p) <= MAX_LENGTH_MM):
            raise LensFileError(path, line, f"paraxial focal length in {axis} {1 / p if p else math.inf:g} mm is out "
                                f"of range: its magnitude must be between {MIN_LENGTH_MM:g} and {MAX_LENGTH_MM:g} mm")
    if radius != 0 and math.isfinite(radius):
        raise LensFileError(path, line, f"a paraxial surface is a plane, but it has radius {radius:g} mm")
    if conic != 0 or any(coefficients):
        raise LensFileError(path, line, "a paraxial surface cannot be aspheric")
    if media != (1.0, 1.0) or glass is not None:
        raise LensFileError(path, line, "a paraxial surface needs air on both sides")


def _implicit_stop(path: str, lines: list[int], radius: list[float], index: list[float]) -> int:
    """The one radius-0 row (flat faces already made planes), which must sit in air."""
    stops = [i for i, r in enumerate(radius) if r == 0]
    if not stops:
        raise LensFileError(path, None, "no aperture stop (a row with radius 0 and the same medium on both sides)")
    if len(stops) > 1:
        raise LensFileError(path, lines[stops[1]], f"a second aperture stop (radius 0 with air on both sides); "
                            f"the first is on line {lines[stops[0]]}")
    stop = stops[0]
    before_stop = index[stop - 1] if stop > 0 else 1.0
    if index[stop] != 1.0 or before_stop != 1.0:
        raise LensFileError(path, lines[stop], "the aperture stop (radius 0) must sit in air")
    return stop


def _flat_faces(radius: list[float], index: list[float], abbe: list[float], glass: list[GlassFormula | None],
                stop: int | None, paraxial: list[int]) -> list[float]:
    """The radii with each radius 0 that is not the stop made ``inf``, a plane: every one but ``stop``
    when the format marks it, else those between different media (a flat glass face) and the
    ``paraxial`` surfaces."""
    def medium(i: int) -> tuple[float, float, GlassFormula | None]:
        return (index[i], abbe[i], glass[i]) if i >= 0 else (1.0, 0.0, None)

    flat = [i for i, r in enumerate(radius) if r == 0 and (i != stop if stop is not None else
                                                           medium(i) != medium(i - 1) or i in paraxial)]
    return [math.inf if i in flat else r for i, r in enumerate(radius)]


#: Heights (fractions of the smaller clear semi-diameter) at which two surfaces 0 mm apart are compared.
TOUCHING_SAMPLES = 65


def _check_touching(path: str, lines: list[int], radius: list[float], thickness: list[float],
                    aperture: list[float], conic: list[float], coefficients: list[list[float]]) -> None:
    """Surfaces 0 mm apart (a stop on a lens vertex, a dummy surface) touch at the vertex only: the
    front one may nowhere lie behind the rear one inside both clear apertures, or a ray would have
    to travel backwards between them (the tracer, like the kernel, meets surfaces in order)."""
    def sag(i: int, rho2: np.ndarray) -> np.ndarray:
        c = 1.0 / radius[i] if radius[i] != 0 and math.isfinite(radius[i]) else 0.0
        return sag_mm(rho2, c, conic[i], np.array(coefficients[i] or [0.0]))

    for i in range(len(lines) - 1):
        if thickness[i] != 0:
            continue
        rho = np.linspace(0.0, min(aperture[i], aperture[i + 1]) / 2, TOUCHING_SAMPLES)
        behind = np.flatnonzero(sag(i, rho * rho) > sag(i + 1, rho * rho) + 1e-12)
        if len(behind):
            raise LensFileError(path, lines[i], f"thickness 0 mm: this surface and the next (line {lines[i + 1]}) "
                                f"cross inside their clear apertures (at height {rho[behind[0]]:.4g} mm)")
