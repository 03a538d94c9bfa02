"""pbrt's ``LightSource`` directives and ``Integrator`` line turned into our lights and integrator.

Parameter names, defaults and frames follow pbrt-v3 ``src/lights/{point,spot,distant,infinite}.cpp``
and pbrt-v4 ``src/pbrt/lights.cpp`` (``...Light::Create``); what differs between versions (scale,
power, spot falloff, the environment map's parameter and parameterisation) comes from
``Dialect.lights``. ``goniometric`` and ``projection`` lights are reported, with file and line, and
left dark. Spectral values (``blackbody``, ``spectrum``, v1-v3's ``xyz``) render as the RGB the
file's pbrt version records for them (``realistic.scene.pbrt.values.spectral_rgb``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from realistic.core import validation
from realistic.core.image_files import read_linear_rgb
from realistic.errors import UserError
from realistic.scene.lights import (
    DistantLight,
    InfiniteLight,
    Light,
    PointLight,
    SpotLight,
    equal_area_square_to_sphere,
)
from realistic.scene.model import RGB
from realistic.scene.pbrt.dialect import Dialect
from realistic.scene.pbrt.parser import Directive, Params, PbrtScene
from realistic.scene.pbrt.values import SPECTRAL_TYPES, located, spectral_rgb

#: Integrators pbrt names that we render with path tracing (pbrt-v2/v3/v4 integrator lists).
PATH_FALLBACKS = ("volpath", "bdpt", "mlt", "sppm", "lightpath", "simplepath", "simplevolpath", "randomwalk",
                  "photonmap", "exphotonmap", "igi", "irradiancecache", "ambientocclusion", "aov", "useprobes",
                  "diffuseprt", "glossyprt", "dipolesubsurface", "single", "emission")
#: LUMINANCE of linear sRGB (Rec. 709), for pbrt-v4's illuminance of an environment map.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
DEFAULT_MAX_DEPTH = 5


def _finite(values: list[float], name: str, where: str) -> list[float]:
    if not all(math.isfinite(v) for v in values):
        raise UserError(f'{where}: light "{name}" must be finite numbers, got {" ".join(f"{v:g}" for v in values)}')
    return values


def _colour(params: Params, name: str, default: RGB, where: str, warn: Callable[[str, str], None]) -> RGB:
    """An RGB parameter (one value: grey); other counts render white with a warning."""
    p = params.items.get(name)
    if p is None:
        return default
    if len(p.values) not in (1, 3):
        warn(where, f'a light "{name}" of {len(p.values)} values (rendered white)')
        return (1.0, 1.0, 1.0)
    values = _finite(params.get_floats(name, []), name, where)
    return (values[0], values[0], values[0]) if len(values) == 1 else (values[0], values[1], values[2])


def _point(params: Params, name: str, default: tuple[float, float, float], where: str) -> np.ndarray:
    values = params.get_floats(name)
    if values is None:
        return np.array(default, np.float64)
    if len(values) != 3:
        raise UserError(f'{where}: light "{name}" needs 3 numbers, got {len(values)}')
    return np.array(_finite(values, name, where), np.float64)


def _scalar(params: Params, name: str, default: float, where: str) -> float:
    return _finite([params.get_float(name, default)], name, where)[0]


class _LightImporter:
    def __init__(self, dialect: Dialect, warn: Callable[[str, str], None], find: Callable[..., Path]):
        self.conventions, self.spectra, self.warn, self.find = dialect.lights, dialect.spectra, warn, find

    def colour(self, params: Params, name: str, where: str) -> np.ndarray:
        """An emission parameter (default white): RGB as given, a spectrum as the RGB pbrt records for it."""
        p = params.items.get(name)
        if p is not None and p.type in SPECTRAL_TYPES:
            return np.array(spectral_rgb(p, self.spectra, self.find, self.warn))
        return np.array(_colour(params, name, (1.0, 1.0, 1.0), where, self.warn))

    def scale(self, params: Params, where: str) -> np.ndarray:
        if self.conventions.scale_is_spectrum:
            return self.colour(params, "scale", where)
        return np.full(3, _scalar(params, "scale", 1.0, where))

    def photometric(self, params: Params, name: str, where: str) -> float | None:
        """pbrt-v4's "power" or "illuminance" when given and positive (else None)."""
        if not self.conventions.photometric or not params.has(name):
            return None
        value = _scalar(params, name, -1.0, where)
        return value if value > 0 else None

    def light(self, directive: Directive) -> Light | None:
        p, where, kind = directive.params, directive.where, directive.type
        m = np.asarray(directive.transform, np.float64)
        if kind == "point":
            intensity = self.colour(p, "I", where) * self.scale(p, where)
            power = self.photometric(p, "power", where)
            if power is not None:
                intensity *= power / (4 * math.pi)
            position = m @ np.append(_point(p, "from", (0, 0, 0), where), 1.0)
            return PointLight(tuple(intensity), position[:3] / position[3])
        if kind == "spot":
            return self.spot(p, m, where)
        if kind == "distant":
            radiance = self.colour(p, "L", where) * self.scale(p, where)
            illuminance = self.photometric(p, "illuminance", where)
            if illuminance is not None:
                radiance *= illuminance
            towards = m[:3, :3] @ (_point(p, "from", (0, 0, 0), where) - _point(p, "to", (0, 0, 1), where))
            if not np.linalg.norm(towards) > 0 or not np.all(np.isfinite(towards)):
                raise UserError(f'{where}: distant light with "from" equal to "to" has no direction')
            return DistantLight(tuple(radiance), towards / np.linalg.norm(towards))
        if kind == "infinite":
            return self.infinite(directive, m)
        if kind in ("goniometric", "projection"):
            self.warn(where, f'LightSource "{kind}" is not supported (left dark)')
            return None
        self.warn(where, f'LightSource "{kind}" is not a pbrt light (ignored)')
        return None

    def spot(self, p: Params, m: np.ndarray, where: str) -> SpotLight:
        intensity = self.colour(p, "I", where) * self.scale(p, where)
        cone = _scalar(p, "coneangle", 30.0, where)
        delta = _scalar(p, "conedeltaangle", 5.0, where)
        if not 0 < cone <= 180 or not 0 <= delta <= cone:
            raise UserError(f"{where}: spot light coneangle {cone:g} and conedeltaangle {delta:g} must satisfy "
                            f"0 < coneangle <= 180 and 0 <= conedeltaangle <= coneangle (degrees)")
        cos_total, cos_start = math.cos(math.radians(cone)), math.cos(math.radians(cone - delta))
        power = self.photometric(p, "power", where)
        if power is not None:
            intensity *= power / (2 * math.pi * ((1 - cos_start) + (cos_start - cos_total) / 2))
        start, end = _point(p, "from", (0, 0, 0), where), _point(p, "to", (0, 0, 1), where)
        axis = end - start
        if not np.linalg.norm(axis) > 0:
            raise UserError(f'{where}: spot light with "from" equal to "to" has no direction')
        z = axis / np.linalg.norm(axis)
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        frame = np.eye(4)
        frame[:3, 0], frame[:3, 1], frame[:3, 2], frame[:3, 3] = x, np.cross(z, x), z, start
        return SpotLight(tuple(intensity), m @ frame, cos_total, cos_start, self.conventions.spot_falloff)

    def infinite(self, directive: Directive, m: np.ndarray) -> InfiniteLight:
        p, where = directive.params, directive.where
        radiance = self.colour(p, "L", where) * self.scale(p, where)
        name = p.get_string(self.conventions.map_parameter)
        image = None
        if name:
            if self.conventions.photometric and p.has("L"):
                raise UserError(f'{where}: infinite light with both "L" and "filename" (pbrt-v4 refuses it)')
            image = read_linear_rgb(self.find(name, Path(where.rsplit(":", 1)[0]).parent, where, "environment map"))
            if self.conventions.mapping == "equal-area" and image.shape[0] != image.shape[1]:
                raise UserError(f'{where}: environment map "{name}" is {image.shape[1]}x{image.shape[0]}; pbrt-v4 '
                                f"needs a square equal-area image")
            if not np.all(np.isfinite(image)):
                raise UserError(f'{where}: environment map "{name}" has texels that are not finite')
        illuminance = self.photometric(p, "illuminance", where)
        if illuminance is not None:
            radiance *= illuminance / self.map_illuminance(image)
        return InfiniteLight(tuple(radiance), image, self.conventions.mapping, m)

    @staticmethod
    def map_illuminance(image: np.ndarray | None) -> float:
        """pbrt-v4's k_e for "illuminance": pi for a constant light; for an equal-area map the sum of
        its upper-hemisphere texels' luminance times cos(theta), times 2 pi / texel count, as pbrt-v4
        ``Light::Create`` computes it."""
        if image is None:
            return math.pi
        h, w = image.shape[:2]
        v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
        cos = equal_area_square_to_sphere(np.column_stack([u.ravel(), v.ravel()]))[:, 2]
        lum = np.asarray(image, np.float64).reshape(-1, 3) @ LUMINANCE
        total = float(np.sum(np.where(cos > 0, lum * cos, 0.0))) * 2 * math.pi / (h * w)
        if not total > 0:
            raise UserError("an environment map with no light above the horizon cannot be scaled to an illuminance")
        return total


def light_scale(params: Params, where: str, dialect: Dialect, warn: Callable[[str, str], None],
                find: Callable[..., Path]) -> tuple[float, float, float]:
    """A light's ``scale`` as its pbrt version reads it (a spectrum in v1-v3, blackbodies included; a
    float in v4): shared by ``LightSource`` lights and area lights."""
    red, green, blue = _LightImporter(dialect, warn, find).scale(params, where)
    return float(red), float(green), float(blue)


def import_lights(parsed: PbrtScene, dialect: Dialect, find: Callable[..., Path]) -> list[Light]:
    """The scene's ``LightSource`` lights (unsupported ones reported on ``parsed`` and skipped)."""
    importer = _LightImporter(dialect, parsed.warn, find)
    lights: list[Light] = []
    for directive in parsed.lights:
        # a light's emission is judged by its constructor (an overflow there, not as a numpy warning)
        with located(directive.where), np.errstate(over="ignore", invalid="ignore"):
            light = importer.light(directive)
        if light is not None:
            lights.append(light)
    return lights


def import_integrator(parsed: PbrtScene, default: str) -> tuple[str, int]:
    """(integrator name, max depth) of the scene's Integrator line: "directlighting" (pbrt's
    ``whitted`` too) or "path", pbrt's others falling back to "path" with a warning; ``default``
    (the dialect's) when there is no such line."""
    directive = parsed.integrator
    if directive is None:
        return default, DEFAULT_MAX_DEPTH
    value = directive.params.get_float("maxdepth", DEFAULT_MAX_DEPTH)
    if not (math.isfinite(value) and value == int(value)):
        raise UserError(f"{directive.where}: Integrator maximum path depth must be a whole number, got {value!r}")
    try:
        depth = validation.max_depth(int(value))
    except UserError as err:
        raise UserError(f"{directive.where}: Integrator {err}") from None
    kind = directive.type
    if kind in ("directlighting", "whitted", "path"):
        return ("path" if kind == "path" else "directlighting"), depth
    if kind not in PATH_FALLBACKS:
        parsed.warn(directive.where, f'Integrator "{kind}" is not a pbrt integrator (rendered with "path")')
    else:
        parsed.warn(directive.where, f'Integrator "{kind}" (rendered with "path")')
    return "path", depth
