"""JSON lens prescriptions as ISET3d/isetlens and pbrt-v4's omni camera write them.

The document is ``{"name": ..., "description": ..., "surfaces": [...]}`` with the surfaces from the
scene side to the film side, lengths in millimetres (isetlens ``data/lens/*.json``; pbrt-v4-iset
``src/pbrt/cameras.cpp``, OmniCamera::Create, reads the same keys). Per surface:

- ``radius``: signed radius of curvature, 0 for the aperture stop (as in pbrt's ``.dat`` files) or,
  between different media, a flat face (``realistic.optics.lens``);
  pbrt-v4's omni camera also accepts an ``[x, y]`` pair, read here only when both are equal.
- ``thickness``: distance to the next surface; the last one's is the film gap (0: focus decides).
- ``ior``: index of the medium behind the surface, 0 or 1 for air; omni's per-wavelength form
  ``[[wavelengths], [indices]]`` is read only when the indices are all equal (else give n_d).
- ``semi_aperture``: clear semi-diameter (half the ``.dat`` aperture diameter).
- ``conic_constant``: the conic k (omni's key; number or equal ``[x, y]`` pair), default 0.
- ``aspheric_coefficients``: A4, A6, ... A20, the coefficients of r^4 .. r^20 in mm^(1-p). Neither
  isetlens nor omni defines a key for these; this is the name this package reads and writes.
- ``abbe_number``: V_d of the medium behind the surface (this package's key, for dispersion).
- ``glass``: a catalogue glass name for the medium behind the surface (``"N-BK7"``, or with its
  catalogue, ``"N-BK7 (Schott)"``), looked up in ``realistic.optics.glass``; its formula then gives
  the index (this package's key; ``ior`` may be 0 beside it).
- ``focal_length_mm``: makes the surface paraxial, an ideal thin lens of that focal length
  (``realistic.optics.lens``; this package's key, as Zemax's PARAXIAL), or of ``[f_x, f_y]`` (Zemax's
  PARAXIAL_XY; ``null`` for an axis without power). Its radius is 0 and it has air on both sides.
- ``transform``: only absent, null or the identity is accepted (no tilts or decentres).

Unknown surface keys are refused (a misspelt ``conic_constant`` must not silently give a sphere).
Errors name the line where the surface's object starts.
"""

from __future__ import annotations

import json
import math
from typing import NamedTuple

import numpy as np

from realistic.core.input_files import parse_json
from realistic.errors import LensFileError, UserError
from realistic.optics.dispersion import GlassFormula
from realistic.optics.glass.catalogue import catalogue_stem, find_glass, unknown_glass
from realistic.optics.lens import MAX_SURFACES, LensSystem, build_lens, too_many_surfaces

SURFACE_KEYS = ("radius", "thickness", "ior", "semi_aperture", "conic_constant", "aspheric_coefficients",
                "abbe_number", "transform", "glass", "focal_length_mm")
IDENTITY = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]]


def _skip(text: str, i: int) -> int:
    while i < len(text) and text[i] in " \t\r\n":
        i += 1
    return i


def _surface_lines(text: str) -> list[int]:
    """The line on which each element of the top-level ``surfaces`` array starts (text already valid JSON)."""
    decoder = json.JSONDecoder()
    lines: list[int] = []
    i = _skip(text, 0) + 1  # past the top-level "{"
    while True:
        i = _skip(text, i)
        if text[i] == "}":
            return lines
        key, i = decoder.raw_decode(text, i)  # an object's key: a JSON string
        i = _skip(text, _skip(text, i) + 1)  # past ":"
        if key == "surfaces" and text[i] == "[":
            lines = []
            i = _skip(text, i + 1)
            while text[i] != "]":
                lines.append(text.count("\n", 0, i) + 1)
                _, i = decoder.raw_decode(text, i)
                i = _skip(text, i)
                i = _skip(text, i + 1) if text[i] == "," else i
            i += 1
        else:
            _, i = decoder.raw_decode(text, i)
        i = _skip(text, i)
        if text[i] == ",":
            i += 1


def _number(value: object, path: str, line: int, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LensFileError(path, line, f"{what} must be a number, got {json.dumps(value)[:40]}")
    return float(value)


def _scalar(value: object, path: str, line: int, what: str) -> float:
    """A number, or omni's ``[x, y]`` pair when both are equal (a rotationally symmetric surface)."""
    if isinstance(value, list) and len(value) == 2:
        x, y = (_number(v, path, line, what) for v in value)
        if x != y and not (math.isnan(x) and math.isnan(y)):
            raise LensFileError(path, line, f"{what} [{x:g}, {y:g}] differs in x and y: anamorphic (toric) "
                                f"surfaces are not supported")
        return x
    return _number(value, path, line, what)


def _index(value: object, path: str, line: int) -> float:
    if isinstance(value, list) and len(value) == 2 and all(isinstance(v, list) for v in value):
        indices = {_number(v, path, line, "ior") for v in value[1]}
        if len(indices) != 1:
            raise LensFileError(path, line, "a per-wavelength ior table is not supported: give ior as n_d and "
                                "abbe_number")
        return indices.pop()
    return _number(value, path, line, "ior")


class _Surface(NamedTuple):
    """One surface object's values, in ``build_lens``'s units (aperture as a diameter)."""

    radius: float
    thickness: float
    index_d: float
    abbe: float
    aperture: float
    conic: float
    coefficients: list[float]
    glass: GlassFormula | None
    power: tuple[float, float]


def _paraxial_power(value: object, path: str, line: int) -> tuple[float, float]:
    """(1/f_x, 1/f_y) of a ``focal_length_mm`` value: a number, or an [x, y] pair whose null is no power."""
    if value is None:
        return 0.0, 0.0
    pair = value if isinstance(value, list) and len(value) == 2 else [value, value]
    focal = [math.inf if f is None and pair is value else _number(f, path, line, "focal_length_mm")
             for f in pair]
    if any(f == 0 or math.isnan(f) for f in focal) or all(math.isinf(f) for f in focal):
        raise LensFileError(path, line, f"focal_length_mm {json.dumps(value)[:40]} must be a non-zero number or an "
                            f"[x, y] pair of them (null for an axis without power)")
    return 1 / focal[0], 1 / focal[1]


def _catalogue_glass(value: object, path: str, line: int) -> GlassFormula | None:
    """The glass a ``glass`` value names (``"N-BK7"`` or ``"N-BK7 (Schott)"``), None when absent."""
    if value is None:
        return None
    if not isinstance(value, str):
        raise LensFileError(path, line, f"glass must be a glass name, got {json.dumps(value)[:40]}")
    name, _, rest = value.partition("(")
    stem = catalogue_stem(rest.rstrip(") ")) if rest else None
    if rest and stem is None:
        raise LensFileError(path, line, f"glass {value!r}: unknown catalogue {rest.rstrip(') ')!r}")
    glass = find_glass(name.strip(), stem)
    if glass is None:
        raise LensFileError(path, line, unknown_glass(name.strip()))
    return glass


def _surface(item: object, path: str, line: int) -> _Surface:
    if not isinstance(item, dict):
        raise LensFileError(path, line, "each surface must be an object with radius, thickness, ior, semi_aperture")
    unknown = [key for key in item if key not in SURFACE_KEYS]
    if unknown:
        raise LensFileError(path, line, f"unknown surface key {unknown[0]!r} (known: {', '.join(SURFACE_KEYS)})")
    missing = [key for key in SURFACE_KEYS[:4] if key not in item]
    if missing:
        raise LensFileError(path, line, f"surface has no {missing[0]!r}")
    if item.get("transform") not in (None, IDENTITY):
        raise LensFileError(path, line, "a surface transform (tilt or decentre) is not supported")
    coefficients = item.get("aspheric_coefficients", [])
    if not isinstance(coefficients, list):
        raise LensFileError(path, line, "aspheric_coefficients must be a list of numbers (A4, A6, ...)")
    return _Surface(_scalar(item["radius"], path, line, "radius"),
                    _number(item["thickness"], path, line, "thickness"),
                    _index(item["ior"], path, line), _number(item.get("abbe_number", 0), path, line, "abbe_number"),
                    2 * _scalar(item["semi_aperture"], path, line, "semi_aperture"),
                    _scalar(item.get("conic_constant", 0), path, line, "conic_constant"),
                    [_number(a, path, line, "aspheric coefficient") for a in coefficients],
                    _catalogue_glass(item.get("glass"), path, line),
                    _paraxial_power(item.get("focal_length_mm"), path, line))


def parse_json_lens(text: str, path: str = "<string>", name: str | None = None) -> LensSystem:
    """Parse an isetlens/omni JSON prescription into a validated LensSystem (LensFileError with file:line)."""
    document = parse_json(text, path, LensFileError)
    if not isinstance(document, dict):
        raise LensFileError(path, 1, "the document must be an object with a \"surfaces\" list")
    surfaces = document.get("surfaces")
    if not isinstance(surfaces, list) or not surfaces:
        raise LensFileError(path, None, "no \"surfaces\" list (or it is empty)")
    lines = _surface_lines(text)
    if len(surfaces) > MAX_SURFACES:
        raise LensFileError(path, lines[MAX_SURFACES], too_many_surfaces(len(surfaces)))
    if "microlens" in document:
        raise LensFileError(path, None, "microlens arrays (omni's \"microlens\") are not supported")
    rows = [_surface(item, path, line) for item, line in zip(surfaces, lines)]
    label = document.get("name")
    description = document.get("description")
    return build_lens(path, lines, [s.radius for s in rows], [s.thickness for s in rows], [s.index_d for s in rows],
                      [s.abbe for s in rows], [s.aperture for s in rows], conic=[s.conic for s in rows],
                      coefficients=[s.coefficients for s in rows], glass=[s.glass for s in rows],
                      paraxial_power=[s.power for s in rows],
                      name=name or (label.strip() if isinstance(label, str) and label.strip() else None),
                      description=description.strip() if isinstance(description, str) else "")


def format_json_lens(lens: LensSystem) -> str:
    """``lens`` as an isetlens/omni JSON document (floats written exactly: repr round-trips)."""
    if not lens.stop_is_flat_in_air:
        what, formats = ("paraxial", ".zmx") if lens.paraxial[lens.stop] else ("curved or has glass on one side",
                                                                               ".zmx or .seq")
        raise UserError(f"{lens.name}: its stop is {what}, and in a .json prescription the stop is a radius-0 "
                        f"surface in air: convert to {formats}")
    surfaces = []
    before = np.concatenate([[1.0], lens.index_d[:-1]])
    for i in range(lens.surface_count):
        radius = float(lens.radius_mm[i])
        flat_face = math.isinf(radius) and (lens.index_d[i] != before[i] or lens.glass[i] != (
            lens.glass[i - 1] if i else None))
        surface: dict[str, str | float | list[float] | list[float | None]] = {
            "radius": 0.0 if flat_face or lens.paraxial[i] else radius, "thickness": float(lens.thickness_mm[i]),
            "ior": 0.0 if i == lens.stop else float(lens.index_d[i]), "semi_aperture": float(lens.aperture_mm[i]) / 2}
        if lens.abbe_v[i] > 0:
            surface["abbe_number"] = float(lens.abbe_v[i])
        glass = lens.glass[i]
        if glass is not None:
            surface["glass"] = glass.label
        if lens.paraxial[i]:
            px, py = (float(p) for p in lens.paraxial_power_per_mm[i])
            surface["focal_length_mm"] = 1 / px if px == py else [1 / p if p else None for p in (px, py)]
        if lens.aspheric[i]:
            coefficients = [float(a) for a in lens.aspheric_coefficients[i]]
            while coefficients and coefficients[-1] == 0:
                coefficients.pop()
            surface["conic_constant"] = float(lens.conic[i])
            surface["aspheric_coefficients"] = coefficients
        surfaces.append(surface)
    document = {"name": lens.name, "description": lens.description, "type": "multi element lens",
                "surfaces": surfaces}
    return json.dumps(document, indent=1) + "\n"
