"""Zemax ``.zmx`` sequential files as lens prescriptions.

Supported: ``MODE SEQ`` files of ``TYPE STANDARD`` spheres and conics and ``TYPE EVENASPH`` even
aspheres (``CONI`` conic constant; ``PARM 2`` .. ``PARM 8`` the coefficients of r^4 .. r^16 in
unit^(1-p), converted to mm; ``PARM 1``, the r^2 term, must be 0 since it would move the paraxial
curvature away from CURV), ``TYPE PARAXIAL`` ideal thin lenses (``PARM 1`` the focal length in lens
units) and ``TYPE PARAXIAL_XY`` ones (``PARM 1`` and ``PARM 2`` the x and y powers in 1/unit), traced
as ``realistic.optics.lens`` describes (their OPD mode parameter is ignored: the wave optics take
such a surface to image perfectly, as Zemax's default mode does), with ``CURV`` in 1/unit,
``DISZ`` thickness to the next surface, ``DIAM`` semi-diameter, or ``CLAP 0 max`` whose hard
circular aperture takes precedence over DIAM; ``MEMA``, the mechanical semi-diameter, stands in
when neither is given; ``FLAP``, the flat annulus beyond the clear aperture, changes nothing the
light meets), in ``UNIT`` MM, CM, IN or METER, with model glasses ``GLAS ___BLANK code pickup n_d
V_d ...`` and catalogue glasses (``GLAS N-BK7 ...``) looked up in ``realistic.optics.glass``, in the
catalogues the ``GCAT`` line lists first. A glass none of our catalogues holds is refused with the
closest names, unless ``GCAT`` lists a catalogue we lack and the line carries n_d and V_d: then those
are read (the lens notes which glasses were read so). Files are UTF-16 (Zemax's default, with or
without BOM) or ASCII/UTF-8.

Mapping: SURF 0 (object) and the last SURF (image) are not lens surfaces; SURF 1 .. N-1 become the
prescription rows in order, and the last lens surface's ``DISZ`` becomes the film gap. Zemax's
``GLAS`` and ``DISZ`` of a surface describe the space after it, as our columns do. The ``STOP``
surface is the stop: a flat one in air becomes the radius-0 stop; a curved one, or one with glass on
a side (a STOP on a singlet's first face), stays that surface, which refracts and whose aperture is
the stop (``realistic.optics.lens``). A ``DISZ 0`` gap (a stop on a lens vertex) is kept when the two
surfaces only touch. Semi-diameters are kept as the file gives them.

Rejected with the line that holds them: other surface types (coordinate breaks, TOROIDAL, ODDASPH,
...), a non-zero r^2 term, mirrors, tilts and decentres (``SCBD``/``SCAD``, ``OBDC``), obscurations and
non-circular apertures, glass in object or image space, a curved image surface, non-sequential mode.
Everything else (fields, wavelengths, solves, tolerances, display settings) is ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from realistic.errors import LensFileError, UserError
from realistic.optics.asphere import COEFFICIENT_POWERS
from realistic.optics.dispersion import GlassFormula
from realistic.optics.formats.pbrt_dat import text_lines
from realistic.optics.glass.catalogue import catalogue_stem, find_glass, unknown_glass
from realistic.optics.lens import MAX_SURFACES, LensSystem, build_lens, too_many_surfaces

#: Surface types read: spheres and conics, even aspheres with PARM 1..8 on r^2 .. r^16, and ideal thin lenses.
SURFACE_TYPES = ("STANDARD", "EVENASPH", "PARAXIAL", "PARAXIAL_XY")
EVENASPH_TERMS = 8

#: Lens units Zemax writes on the ``UNIT`` line, in millimetres.
UNIT_MM = {"MM": 1.0, "CM": 10.0, "IN": 25.4, "INCH": 25.4, "M": 1000.0, "METER": 1000.0}

#: Surface keywords for apertures we cannot model (only circular apertures are supported).
#: Why each surface type real rays cannot trace is refused.
REFUSED_TYPES = {"COORDBRK": "coordinate breaks (tilts and decentres) are not supported"}

UNSUPPORTED_APERTURES = {"OBSC": "circular obscuration", "SQAP": "rectangular aperture",
                         "ELAP": "elliptical aperture", "UDAP": "user-defined aperture",
                         "SPID": "spider obscuration"}


@dataclass
class _Surface:
    """One ``SURF`` block in file units, with the lines that gave its values."""

    number: int
    line: int
    curvature: float = 0.0
    curvature_line: int = 0
    thickness: float = 0.0
    index: float = 1.0
    abbe: float = 0.0
    glass_line: int = 0
    semi_diameter: float | None = None
    mechanical_semi_diameter: float | None = None
    clear_semi_diameter: float | None = None
    stop_line: int = 0
    kind: str = "STANDARD"
    conic: float = 0.0
    parms: dict[int, tuple[float, int]] = field(default_factory=dict)  # PARM n: (value, line)
    catalogue: list[str] = field(default_factory=list)
    glass: GlassFormula | None = None


def decode_zmx(data: bytes, path: str) -> str:
    """Text of a .zmx file: UTF-16 (with BOM, or detected by its NUL bytes) or ASCII/UTF-8."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        encoding = "utf-16"
    elif len(data) >= 2 and data[1] == 0 and data[0] != 0:
        encoding = "utf-16-le"
    elif len(data) >= 2 and data[0] == 0 and data[1] != 0:
        encoding = "utf-16-be"
    else:
        try:
            return data.decode("utf-8-sig")
        except UnicodeDecodeError:
            return data.decode("latin-1")  # older Zemax ASCII files (Windows code page) in comments
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        raise LensFileError(path, None, f"cannot read as {encoding}: {err}") from None


def _number(token: str | None, path: str, line: int, what: str) -> float:
    if token is None:
        raise LensFileError(path, line, f"{what} has no value")
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if math.isnan(value):
        raise LensFileError(path, line, f"{what} {token!r} is not a number")
    return value


def _glass(tokens: list[str], surface: _Surface, path: str, line: int, catalogues: list[str]) -> None:
    """Apply a ``GLAS name code pickup n_d V_d ...`` line to the space after the surface;
    ``catalogues``: the ``GCAT`` line's names, in its order."""
    name = tokens[1] if len(tokens) > 1 else ""
    if name.upper() == "MIRROR":
        raise LensFileError(path, line, "mirror surfaces (GLAS MIRROR) are not supported")
    surface.glass_line = line
    if name.upper() == "AIR":
        surface.index, surface.abbe = 1.0, 0.0
        return
    has_model = len(tokens) >= 6 and _number(tokens[4], path, line, "n_d") > 0
    if name != "___BLANK":
        ours = [stem for stem in map(catalogue_stem, catalogues) if stem]
        glass = next(filter(None, (find_glass(name, stem) for stem in ours)), None) or find_glass(name)
        if glass is not None:
            surface.glass = glass
            return
        if not (has_model and len(ours) < len(catalogues)):
            raise LensFileError(path, line, unknown_glass(name))
    if not has_model:
        raise LensFileError(path, line, "model glass ___BLANK has no n_d and V_d on the line "
                            "(GLAS ___BLANK 1 0 n_d V_d ...)")
    nd, vd = _number(tokens[4], path, line, "n_d"), _number(tokens[5], path, line, "V_d")
    if nd < 1 or vd < 0 or not (math.isfinite(nd) and math.isfinite(vd)):
        raise LensFileError(path, line, f"glass n_d {nd:g} must be >= 1 and V_d {vd:g} >= 0")
    surface.index, surface.abbe = nd, vd
    if name != "___BLANK":
        surface.catalogue.append(f"{name} (line {line})")


def _surface_keyword(tokens: list[str], surface: _Surface, path: str, line: int, catalogues: list[str]) -> None:
    """Apply one keyword line inside a ``SURF`` block (``catalogues``: the ``GCAT`` line's names)."""
    keyword, args = tokens[0], tokens[1:]
    first = args[0] if args else None
    if keyword == "TYPE":
        if first in REFUSED_TYPES:
            raise LensFileError(path, line, f"TYPE {first}: {REFUSED_TYPES[first]}")
        if first not in SURFACE_TYPES:
            raise LensFileError(path, line, f"surface type {first} is not supported (only TYPE "
                                f"{', '.join(SURFACE_TYPES[:-1])} and {SURFACE_TYPES[-1]})")
        surface.kind = first
    elif keyword == "PARM":
        number = _number(first, path, line, "PARM number")
        value = _number(args[1] if len(args) > 1 else None, path, line, f"PARM {first}")
        surface.parms[int(number) if number.is_integer() else -1] = (value, line)
    elif keyword == "CURV":
        surface.curvature, surface.curvature_line = _number(first, path, line, "CURV"), line
        if not math.isfinite(surface.curvature):
            raise LensFileError(path, line, f"CURV {first} is not a finite curvature (a flat surface is CURV 0)")
    elif keyword == "DISZ":
        surface.thickness = _number(first, path, line, "DISZ")
    elif keyword == "GLAS":
        _glass(tokens, surface, path, line, catalogues)
    elif keyword == "DIAM":
        surface.semi_diameter = _number(first, path, line, "DIAM")
    elif keyword == "MEMA":
        surface.mechanical_semi_diameter = _number(first, path, line, "MEMA")
    elif keyword == "CLAP":
        low, high = _number(first, path, line, "CLAP minimum"), _number(args[1] if len(args) > 1 else None,
                                                                         path, line, "CLAP maximum")
        if low != 0:
            raise LensFileError(path, line, f"annular aperture (CLAP minimum radius {low:g}) is not supported")
        surface.clear_semi_diameter = high
    elif keyword == "STOP":
        surface.stop_line = line
    elif keyword == "CONI":
        surface.conic = _number(first, path, line, "CONI")
    elif keyword in ("SCBD", "SCAD", "OBDC") and any(_number(a, path, line, keyword) != 0 for a in
                                                    args[1 if keyword != "OBDC" else 0:]):
        raise LensFileError(path, line, f"tilted or decentred surfaces and apertures ({keyword}) are not supported")
    elif keyword in UNSUPPORTED_APERTURES:
        raise LensFileError(path, line, f"{UNSUPPORTED_APERTURES[keyword]} ({keyword}) is not supported "
                            f"(only circular DIAM or CLAP apertures)")


def _read_surfaces(text: str, path: str) -> tuple[list[_Surface], float]:
    """The SURF blocks in file order and the lens unit in millimetres."""
    surfaces: list[_Surface] = []
    unit_mm = 1.0
    catalogues: list[str] = []
    for number, raw in enumerate(text_lines(text), start=1):
        tokens = raw.split()
        if not tokens:
            continue
        keyword = tokens[0]
        if keyword == "UNIT":
            unit = tokens[1].upper() if len(tokens) > 1 else ""
            if unit not in UNIT_MM:
                raise LensFileError(path, number, f"lens unit {unit!r} is not supported (MM, CM, IN or METER)")
            unit_mm = UNIT_MM[unit]
        elif keyword == "GCAT":
            catalogues = tokens[1:]
        elif keyword == "MODE" and tokens[1:2] != ["SEQ"]:
            raise LensFileError(path, number, f"MODE {' '.join(tokens[1:])} is not supported (sequential only)")
        elif keyword == "SURF":
            index = _number(tokens[1] if len(tokens) > 1 else None, path, number, "surface number")
            if index != len(surfaces):
                raise LensFileError(path, number, f"SURF {tokens[1]} out of order (expected SURF {len(surfaces)})")
            if len(surfaces) == MAX_SURFACES + 2:  # the object and image surfaces are not lens surfaces
                raise LensFileError(path, number, too_many_surfaces(MAX_SURFACES + 1, at_least=True))
            surfaces.append(_Surface(len(surfaces), number))
        elif surfaces:
            _surface_keyword(tokens, surfaces[-1], path, number, catalogues)
    return surfaces, unit_mm


def parse_zmx(text: str, path: str = "<string>") -> LensSystem:
    """Parse a Zemax sequential file into a validated LensSystem; raise LensFileError with file:line."""
    surfaces, unit_mm = _read_surfaces(text, path)
    if len(surfaces) < 3:
        raise LensFileError(path, None, f"{len(surfaces)} SURF blocks: need an object surface, at least "
                            f"one lens surface and an image surface")
    obj, lens, image = surfaces[0], surfaces[1:-1], surfaces[-1]
    if obj.index != 1.0 or obj.glass is not None:
        raise LensFileError(path, obj.glass_line, "object space must be air")
    if lens[-1].index != 1.0 or lens[-1].glass is not None:
        raise LensFileError(path, lens[-1].glass_line, "the space before the image surface must be air")
    if image.curvature != 0:
        raise LensFileError(path, image.curvature_line, "a curved image surface is not supported")
    for end in (obj, image):
        if end.stop_line:
            raise LensFileError(path, end.stop_line, "the stop must be a lens surface, not the object or image")

    stops = [s for s in lens if s.stop_line]
    if not stops:
        raise LensFileError(path, None, "no STOP surface")
    if len(stops) > 1:
        raise LensFileError(path, stops[1].stop_line, f"a second STOP; the first is on line {stops[0].stop_line}")
    stop = stops[0]
    apertures = []
    for s in lens:
        semi = next((d for d in (s.clear_semi_diameter, s.semi_diameter, s.mechanical_semi_diameter)
                     if d is not None), None)
        if semi is None:
            raise LensFileError(path, s.line, f"SURF {s.number} has no DIAM or MEMA (semi-diameter)")
        apertures.append(2 * semi * unit_mm)

    radius = [(0.0 if s is stop else math.inf) if s.curvature == 0 else unit_mm / s.curvature for s in lens]
    coefficients = [_coefficients(s, unit_mm, path) for s in lens]
    power = [_paraxial_power(s, unit_mm, path) for s in lens]
    catalogue = [name for s in lens for name in s.catalogue]
    note = (f"catalogue glasses read from the n_d/V_d on their GLAS lines: {', '.join(catalogue)}"
            if catalogue else "")
    return build_lens(path, [s.line for s in lens], radius, [s.thickness * unit_mm for s in lens],
                      [s.index for s in lens], [s.abbe for s in lens],
                      apertures, note=note, conic=[s.conic for s in lens], coefficients=coefficients,
                      glass=[s.glass for s in lens], stop=lens.index(stop), paraxial_power=power)


def _paraxial_power(surface: _Surface, unit_mm: float, path: str) -> tuple[float, float]:
    """(1/f_x, 1/f_y) in 1/mm of a PARAXIAL or PARAXIAL_XY surface, (0, 0) for the others."""
    if surface.kind == "PARAXIAL":
        focal, line = surface.parms.get(1, (0.0, surface.line))
        if focal == 0 or not math.isfinite(focal):
            raise LensFileError(path, line, f"a PARAXIAL surface needs a finite, non-zero focal length (PARM 1), "
                                f"got {focal:g}")
        return 1 / (focal * unit_mm), 1 / (focal * unit_mm)
    if surface.kind == "PARAXIAL_XY":
        x, y = (surface.parms.get(k, (0.0, surface.line)) for k in (1, 2))
        if x[0] == 0 and y[0] == 0:
            raise LensFileError(path, surface.line, "a PARAXIAL_XY surface has no power (PARM 1 and PARM 2 are 0)")
        for value, line in (x, y):
            if not math.isfinite(value):
                raise LensFileError(path, line, f"PARAXIAL_XY power {value:g} is not a finite number")
        return x[0] / unit_mm, y[0] / unit_mm
    return 0.0, 0.0


def _coefficients(surface: _Surface, unit_mm: float, path: str) -> list[float]:
    """A4 .. A16 in mm of an EVENASPH surface (none for STANDARD, whose PARMs mean nothing)."""
    if surface.kind != "EVENASPH":
        return []
    values = [0.0] * EVENASPH_TERMS
    for number, (value, line) in surface.parms.items():
        if not 1 <= number <= EVENASPH_TERMS:
            if value != 0:
                raise LensFileError(path, line, f"EVENASPH has PARM 1 .. {EVENASPH_TERMS}; PARM {number} = {value:g} "
                                    f"is not supported")
            continue
        if number == 1 and value != 0:
            raise LensFileError(path, line, f"an r^2 aspheric term (PARM 1 = {value:g}) is not supported: fold it "
                                f"into CURV")
        values[number - 1] = value
    return [a * unit_mm ** (1 - power) for a, power in zip(values[1:], COEFFICIENT_POWERS)]



def format_zmx(lens: LensSystem) -> str:
    """``lens`` as a Zemax sequential file in mm (ASCII) that ``parse_zmx`` reads back exactly;
    aspheres as EVENASPH, which carries terms up to r^16, paraxial surfaces as PARAXIAL (PARAXIAL_XY
    where the two powers differ)."""
    beyond = np.flatnonzero(np.any(lens.aspheric_coefficients[:, EVENASPH_TERMS - 1:] != 0, axis=1))
    if len(beyond):
        raise UserError(f"{lens.name}: surface {beyond[0]} has r^18 or r^20 terms, which Zemax's EVENASPH "
                        f"(up to r^16) cannot hold: convert to .json or .seq")
    lines = ["VERS 190513 80 123", "MODE SEQ", f"NAME {lens.name}", "UNIT MM X W X CM MR CPMM",
             "SURF 0", "  TYPE STANDARD", "  CURV 0.0", "  DISZ INFINITY"]
    used = sorted({g.catalogue.upper() for g in lens.glass if g is not None})
    if used:
        lines.insert(4, "GCAT " + " ".join(used))
    for i in range(lens.surface_count):
        radius = float(lens.radius_mm[i])
        curvature = 0.0 if radius == 0 or math.isinf(radius) else 1.0 / radius
        lines += [f"SURF {i + 1}"] + (["  STOP"] if i == lens.stop else [])
        px, py = (float(p) for p in lens.paraxial_power_per_mm[i])
        kind = ("PARAXIAL" if px == py else "PARAXIAL_XY") if lens.paraxial[i] else (
            "EVENASPH" if lens.aspheric[i] else "STANDARD")
        lines += [f"  TYPE {kind}", f"  CURV {curvature!r}"]
        if kind == "PARAXIAL":
            lines.append(f"  PARM 1 {1 / px!r}")
        elif kind == "PARAXIAL_XY":
            lines += [f"  PARM 1 {px!r}", f"  PARM 2 {py!r}"]
        if lens.aspheric[i]:
            lines.append(f"  CONI {float(lens.conic[i])!r}")
            terms = [0.0, *lens.aspheric_coefficients[i, :EVENASPH_TERMS - 1]]
            lines += [f"  PARM {k} {float(a)!r}" for k, a in enumerate(terms, start=1)]
        lines.append(f"  DISZ {float(lens.thickness_mm[i])!r}")
        glass = lens.glass[i]
        if glass is not None:
            lines.append(f"  GLAS {glass.name} 0 0 {float(lens.index_d[i])!r} {float(lens.abbe_v[i])!r} 0 0 0 0 0 0")
        elif lens.index_d[i] != 1:
            lines.append(f"  GLAS ___BLANK 1 0 {float(lens.index_d[i])!r} {float(lens.abbe_v[i])!r} 0 0 0 0 0 0")
        lines.append(f"  DIAM {float(lens.aperture_mm[i]) / 2!r}")
    lines += [f"SURF {lens.surface_count + 1}", "  TYPE STANDARD", "  CURV 0.0", "  DISZ 0",
              f"  DIAM {float(lens.aperture_mm.max())!r}"]
    return "\n".join(lines) + "\n"
