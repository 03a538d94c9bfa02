"""pbrt's Film, Sampler and PixelFilter: the image's resolution, samples per pixel and output
name, the film types and sensor settings we do not model (warnings), and the pixel filter read in
the file's dialect."""

from __future__ import annotations

from dataclasses import dataclass

from realistic.core import validation
from realistic.core.pixel_filter import PixelFilter, filter_name
from realistic.errors import UserError
from realistic.scene.pbrt.dialect import Dialect
from realistic.scene.pbrt.parser import Directive, Params, PbrtScene
from realistic.scene.pbrt.values import located, whole_number


def import_pixel_filter(parsed: PbrtScene, dialect: Dialect) -> PixelFilter:
    """The scene's ``PixelFilter`` read in ``dialect`` (its default when the scene names none).

    A filter name pbrt does not know is a warning and the dialect's default, not an error: pbrt-v2
    itself warns and goes on, and this importer renders what it can of a scene everywhere else
    (unknown shapes, materials and lights are warnings too); bad parameters of a known filter are
    one-line errors naming the file and line."""
    directive = parsed.pixel_filter
    if directive is None:
        return dialect.pixel_filter()
    try:
        filter_name(directive.type)
    except UserError:
        parsed.warn(directive.where, f'PixelFilter "{directive.type}" (the pbrt-{dialect.name} default, '
                                     f'{dialect.default_filter_name}, is used)')
        return dialect.pixel_filter()
    with located(directive.where):
        return dialect.pixel_filter(directive.type, directive.params)


#: Film types read as an RGB image: pbrt-v1/v2/v3's "image" and pbrt-v4's "rgb" (src/pbrt/film.cpp).
RGB_FILMS = ("image", "rgb")
#: pbrt-v4's other films: what we render of them is their RGB image.
V4_OTHER_FILMS = ("gbuffer", "spectral")
#: pbrt-v4's sensor model (src/pbrt/film.cpp, PixelSensor::Create) and its neutral values: ISO 100,
#: no white balance and the CIE 1931 sensor leave the image as the film's radiance.
V4_SENSOR_DEFAULTS = {"iso": 100.0, "whitebalance": 0.0, "sensor": "cie1931"}


def _check_film(parsed: PbrtScene, film: Directive) -> None:
    """Warn, with the Film's file and line, about a film type or sensor setting we do not model."""
    if film.type in V4_OTHER_FILMS:
        parsed.warn(film.where, f'Film "{film.type}" (its RGB image is rendered; the other channels are not)')
    elif film.type not in RGB_FILMS:
        parsed.warn(film.where, f'Film "{film.type}" (rendered as an RGB image film)')
    for name, neutral in V4_SENSOR_DEFAULTS.items():
        given = film.params.get_string(name) if isinstance(neutral, str) else film.params.get_float(name)
        if given is not None and given != neutral:
            parsed.warn(film.where, f'Film "{name}" {given} (the image is the film\'s radiance, as with pbrt-v4\'s '
                                    f"{name} {neutral})")


@dataclass(frozen=True)
class FilmSettings:
    """The image a pbrt file asks for: resolution (``Film``), samples per pixel (``Sampler``) and
    the output file the Film names (None: none)."""

    width: int
    height: int
    spp: int
    output_name: str | None


def import_film(parsed: PbrtScene) -> FilmSettings:
    """The file's Film and Sampler settings (pbrt's defaults: 640 x 480, 16 samples), with a
    warning for what we do not model."""
    film = parsed.film.params if parsed.film else Params()
    film_where = parsed.film.where if parsed.film else str(parsed.path)
    if parsed.film and parsed.film.params.has("cropwindow"):
        parsed.warn(parsed.film.where, "Film cropwindow (the whole image is rendered)")
    if parsed.film:
        _check_film(parsed, parsed.film)
    with located(film_where):
        width, height = validation.resolution(whole_number(film, "xresolution", 640, film_where),
                                              whole_number(film, "yresolution", 480, film_where))
    spp = 16
    if parsed.sampler:
        with located(parsed.sampler.where):
            spp = validation.samples_per_pixel(whole_number(parsed.sampler.params, "pixelsamples", 16,
                                                            parsed.sampler.where))
    return FilmSettings(width, height, spp, film.get_string("filename"))
