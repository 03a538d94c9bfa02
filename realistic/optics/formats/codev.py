"""CODE V sequence files (``.seq``) as lens prescriptions.

Read: ``RDM`` (radius mode; ``RDM N`` is curvature mode, and a file without ``RDM`` is refused
rather than guessed), ``DIM M|C|I`` (mm, cm, inch), ``SO`` (object), ``S radius thickness
[glass]`` per surface, ``SI`` (image: flat; its thickness is a defocus added to the film gap),
``STO`` (the current surface is the stop), ``CIR r`` (clear aperture radius, required on every
surface), ``SPH``/``CON``/``ASP`` with ``K`` (conic) and ``A`` .. ``J`` (coefficients of r^4 ..
r^20), ``RDY``/``CUY``/``THI`` without qualifiers (change the current surface). Commands are one
per line or separated by ``;``; ``!`` starts a comment. CODE V's radius 0 is a flat surface; on the
``STO`` surface it becomes the planar stop; a curved ``STO`` surface, or one with glass on a side,
stays that surface, whose aperture is the stop.

Glass: a fictitious glass code ``NNNNNN.VVVV`` (n_d = 1 + 0.NNNNNN, V_d = 100 x 0.VVVV, as CODE V
writes model glasses; ``517642.6417`` is n_d 1.517642, V_d 64.17), a catalogue glass
``NAME_CATALOGUE`` (``NBK7_SCHOTT``, ``SLAH58_OHARA``; looked up in ``realistic.optics.glass``, in
any catalogue when the suffix is absent), or none for air. Unknown glass names are refused with the
closest catalogue names, as are mirrors (``REFL``), decentres and tilts,
non-circular apertures and obscurations, and other surface shapes, each with file:line.
Everything else (wavelengths, fields, pupil, title, solves) is ignored.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from realistic.errors import LensFileError, UserError
from realistic.optics.asphere import COEFFICIENT_COUNT
from realistic.optics.dispersion import GlassFormula
from realistic.optics.formats.pbrt_dat import text_lines
from realistic.optics.glass.catalogue import catalogue_stem, find_glass, unknown_glass
from realistic.optics.lens import MAX_SURFACES, LensSystem, build_lens, too_many_surfaces

UNIT_MM = {"M": 1.0, "MM": 1.0, "C": 10.0, "CM": 10.0, "I": 25.4, "IN": 25.4}
COEFFICIENT_LETTERS = "ABCDEFGHJ"  # r^4 .. r^20 (CODE V skips I)
REFUSED = {
    **{k: "decentres and tilts" for k in ("XDE", "YDE", "ZDE", "ADE", "BDE", "CDE", "DAR", "BEN", "REV", "RET")},
    **{k: "non-circular apertures" for k in ("REX", "REY", "ELX", "ELY", "POL")},
    **{k: "surface shape" for k in ("XTO", "YTO", "SPS", "UDS", "HOE", "DOE", "GRT", "XYP", "ZRN", "ODD",
                                    "CYL", "ZFR", "QCN", "QBF")},
}
_GLASS_CODE = re.compile(r"^(\d+)(?:\.(\d*))?$")


@dataclass
class _Surface:
    line: int
    radius: float
    thickness: float
    index: float = 1.0
    abbe: float = 0.0
    glass: GlassFormula | None = None
    semi: float | None = None
    stop: bool = False
    conic: float = 0.0
    coefficients: list[float] = field(default_factory=lambda: [0.0] * COEFFICIENT_COUNT)


def _number(token: str | None, path: str, line: int, what: str) -> float:
    if token is None:
        raise LensFileError(path, line, f"{what} has no value")
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise LensFileError(path, line, f"{what} {token!r} is not a finite number")
    return value


def _glass(token: str, path: str, line: int) -> tuple[float, float, GlassFormula | None]:
    """(n_d, V_d, catalogue glass) of a fictitious glass code or a catalogue name; mirrors are refused."""
    name = token.strip("'\"")
    if name.upper() == "REFL":
        raise LensFileError(path, line, "mirror surfaces (REFL) are not supported")
    match = _GLASS_CODE.match(name)
    if match and not match.group(1).startswith("0"):
        return _index_of(match.group(1)), _abbe_of(match.group(2) or ""), None
    glass_name, _, suffix = name.rpartition("_")
    stem = catalogue_stem(suffix) if glass_name else None
    glass = find_glass(glass_name, stem) if stem else find_glass(name)
    if glass is None:
        raise LensFileError(path, line, unknown_glass(name) + " (or give a fictitious glass code such as "
                            "517642.6417: n_d 1.517642, V_d 64.17)")
    return 0.0, 0.0, glass


def _index_of(digits: str) -> float:
    """n_d = 1.DIGITS, parsed as one decimal (correctly rounded)."""
    return float("1." + digits)


def _abbe_of(digits: str) -> float:
    """V_d = 100 x 0.DIGITS, parsed as one decimal (correctly rounded); 0 when there are none."""
    digits = digits.ljust(2, "0")
    return float(digits[:2] + "." + digits[2:])


def _radius_mm(value: float, is_radius: bool, unit_mm: float) -> float:
    """A radius (or curvature in 1/unit) in mm; 0 stays 0, CODE V's flat surface."""
    if is_radius or value == 0:
        return value * unit_mm
    return unit_mm / value


def _commands(text: str) -> Iterator[tuple[int, list[str]]]:
    """(line, tokens) per command: ``;`` separates commands, ``!`` starts a comment."""
    for number, raw in enumerate(text_lines(text), start=1):
        for command in raw.split("!", 1)[0].split(";"):
            tokens = command.split()
            if tokens:
                yield number, tokens


def parse_codev(text: str, path: str = "<string>", name: str | None = None) -> LensSystem:
    """Parse a CODE V ``.seq`` file into a validated LensSystem; raise LensFileError with file:line."""
    surfaces: list[_Surface] = []
    unit_mm, radius_mode, seen_object, image_line, defocus, title = 1.0, None, False, 0, 0.0, ""

    def current(line: int, what: str) -> _Surface:
        if not surfaces or image_line:
            raise LensFileError(path, line, f"{what} before any lens surface (S) or after the image surface (SI)")
        return surfaces[-1]

    for line, tokens in _commands(text):
        command, args = tokens[0].upper(), tokens[1:]
        if command == "RDM":
            radius_mode = not (args and args[0].upper() in ("N", "NO"))
        elif command == "DIM":
            unit = args[0].upper() if args else ""
            if unit not in UNIT_MM:
                raise LensFileError(path, line, f"DIM {unit!r} is not supported (M, C or I)")
            unit_mm = UNIT_MM[unit]
        elif command == "TIT" and args:
            title = " ".join(args).strip("'\"")
        elif command in ("SO", "S", "SI"):
            if radius_mode is None:
                raise LensFileError(path, line, "surface before an RDM line: say RDM (radii) or RDM N (curvatures)")
            if command == "SO":
                seen_object = True
                if len(args) > 2:
                    raise LensFileError(path, line, "object space must be air")
                continue
            if not seen_object:
                raise LensFileError(path, line, "lens surface before the object surface (SO)")
            if image_line:
                raise LensFileError(path, line, f"surface after the image surface (SI on line {image_line})")
            value = _number(args[0] if args else None, path, line, "radius" if radius_mode else "curvature")
            thickness = _number(args[1] if len(args) > 1 else "0", path, line, "thickness")
            radius = _radius_mm(value, radius_mode, unit_mm)
            if command == "SI":
                if radius != 0:
                    raise LensFileError(path, line, "a curved image surface is not supported")
                if len(args) > 2:
                    raise LensFileError(path, line, "glass behind the image surface is not supported")
                image_line, defocus = line, thickness * unit_mm
                continue
            if len(surfaces) == MAX_SURFACES:
                raise LensFileError(path, line, too_many_surfaces(MAX_SURFACES + 1, at_least=True))
            surface = _Surface(line, radius, thickness * unit_mm)
            if len(args) > 2:
                surface.index, surface.abbe, surface.glass = _glass(args[2], path, line)
            surfaces.append(surface)
        elif command == "STO":
            current(line, "STO").stop = True
        elif command == "CIR":
            if args and args[0].upper() in ("OBS", "HOL"):
                raise LensFileError(path, line, f"obscurations and holes (CIR {args[0]}) are not supported")
            if args and args[0].upper() == "EDG":
                continue  # a mechanical edge, not a clear aperture
            current(line, "CIR").semi = _number(args[-1] if args else None, path, line, "CIR") * unit_mm
        elif command in ("SPH", "CON", "ASP"):
            current(line, command)
        elif command == "K":
            current(line, "K").conic = _number(args[0] if args else None, path, line, "K")
        elif len(command) == 1 and command in COEFFICIENT_LETTERS:
            power = 4 + 2 * COEFFICIENT_LETTERS.index(command)
            value = _number(args[0] if args else None, path, line, command)
            current(line, command).coefficients[COEFFICIENT_LETTERS.index(command)] = value * unit_mm ** (1 - power)
        elif command in ("RDY", "CUY", "THI"):
            if len(args) != 1:
                raise LensFileError(path, line, f"{command} with qualifiers (surface index or solve) is not supported")
            surface = current(line, command)
            value = _number(args[0], path, line, command)
            if command == "THI":
                surface.thickness = value * unit_mm
            else:
                surface.radius = _radius_mm(value, command == "RDY", unit_mm)
        elif command in REFUSED:
            raise LensFileError(path, line, f"{REFUSED[command]} ({command}) are not supported")
    if not image_line:
        raise LensFileError(path, None, "no image surface (SI)")
    if not surfaces:
        raise LensFileError(path, None, "no lens surfaces (S)")
    return _build(surfaces, defocus, path, name, title)


def _build(surfaces: list[_Surface], defocus: float, path: str, name: str | None, title: str) -> LensSystem:
    stops = [s for s in surfaces if s.stop]
    if len(stops) != 1:
        raise LensFileError(path, stops[1].line if stops else None,
                            "a second STO" if stops else "no stop surface (STO)")
    stop = stops[0]
    if surfaces[-1].index != 1.0 or surfaces[-1].glass is not None:
        raise LensFileError(path, surfaces[-1].line, "the space before the image surface must be air")
    apertures = []
    for s in surfaces:
        if s.semi is None:
            raise LensFileError(path, s.line, "surface has no clear aperture (CIR radius)")
        apertures.append(2 * s.semi)
    surfaces[-1].thickness += defocus
    radius = [s.radius if s.radius != 0 or s is stop else math.inf for s in surfaces]
    return build_lens(path, [s.line for s in surfaces], radius, [s.thickness for s in surfaces],
                      [s.index for s in surfaces], [s.abbe for s in surfaces], apertures,
                      name=name, conic=[s.conic for s in surfaces], coefficients=[s.coefficients for s in surfaces],
                      description=title, glass=[s.glass for s in surfaces], stop=surfaces.index(stop))


def _digits(fraction: float, value: float, decode: Callable[[str], float]) -> str:
    """The shortest digit string d of ``fraction`` (no leading zero) with decode(d) == value exactly, or ''."""
    for count in range(1, 18):
        digits = str(round(fraction * 10**count))
        if len(digits) == count and decode(digits) == value:
            return digits
    return ""


def _glass_code(n: float, v: float) -> str:
    """A fictitious glass code that decodes (``_glass``) to exactly these n_d and V_d."""
    index = _digits(n - 1.0, n, _index_of) if 1.1 <= n < 2 else ""
    if not index:
        raise UserError(f"index {n!r} cannot be written exactly as a CODE V glass code (needs 1.1 <= n_d < 2)")
    if not v:
        return index
    abbe = _digits(v / 100.0, v, _abbe_of) if 0 < v < 100 else ""
    if not abbe:
        raise UserError(f"Abbe number {v!r} cannot be written exactly as a CODE V glass code (needs V_d < 100)")
    return f"{index}.{abbe}"


def format_codev(lens: LensSystem) -> str:
    """``lens`` as a CODE V sequence file in mm (radius mode) that ``parse_codev`` reads back exactly."""
    lens.refuse_paraxial(".seq")
    title = (lens.description or lens.name).replace("'", " ").replace("\n", " ")
    lines = ["RDM", "DIM M", f"TIT '{title}'", "SO 0.0 1e20"]
    for i in range(lens.surface_count):
        radius = float(lens.radius_mm[i])
        radius = 0.0 if math.isinf(radius) else radius
        catalogue = lens.glass[i]
        glass = "" if lens.index_d[i] == 1 else " " + (
            f"{catalogue.name}_{catalogue.catalogue.upper()}" if catalogue is not None
            else _glass_code(float(lens.index_d[i]), float(lens.abbe_v[i])))
        lines.append(f"S {radius!r} {float(lens.thickness_mm[i])!r}{glass}")
        if i == lens.stop:
            lines.append("  STO")
        lines.append(f"  CIR {float(lens.aperture_mm[i]) / 2!r}")
        if lens.aspheric[i]:
            lines += ["  ASP", f"  K {float(lens.conic[i])!r}"]
            terms = zip(COEFFICIENT_LETTERS, lens.aspheric_coefficients[i])
            lines += [f"  {letter} {float(a)!r}" for letter, a in terms if a != 0]
    lines += ["SI 0.0 0.0", "GO"]
    return "\n".join(lines) + "\n"
