"""One check per quantity, used wherever that quantity enters: the CLI, the pbrt importer and the
Python API all reach these through the constructors that take the value (``LensCamera``,
``ThinLensCamera``, ``RenderOptions``, ``bladed_stop``), so a value is judged the same way
whichever door it came in by. Each check returns the value (converted where that is exact) or
raises ``UserError`` with one line naming the quantity, the value and the allowed range.

The limits are what the arithmetic represents exactly (sample ids and random-number counters are
32-bit in the OpenCL kernel) or what no real camera comes near; docs/robustness.md lists them.
"""

from __future__ import annotations

import math
import numbers
import unicodedata
from collections.abc import Sequence

from realistic.errors import UserError

#: Longest image side in pixels, and most pixels in an image (the kernel's pixel index is int32).
MAX_IMAGE_SIDE = 65_536
MAX_PIXELS = 2**31 - 1
#: Samples per pixel: the kernel counts a pixel's samples in uint32; far below that, 2^24 already
#: means days of rendering per megapixel.
MAX_SPP = 2**24
#: Seeds are 32-bit keys of the counter-based generator.
MAX_SEED = 2**32 - 1
MAX_LIGHT_SAMPLES = 1024
#: Film diagonals from a phone sensor's fraction of a millimetre to beyond large format (8x10 in
#: is 325 mm).
MAX_FILM_DIAGONAL_MM = 1000.0
#: Diaphragm blades: real lenses have 5 to 18; the kernel unrolls one test per blade.
MIN_BLADES, MAX_BLADES = 3, 64
#: The stop's diameter and f-number: pinhole cameras reach f/500 and a stop of a few micrometres;
#: far beyond, no light passes and the image is black (a 1e-300 mm stop is 0 in the kernel's floats).
MIN_STOP_DIAMETER_MM = 1e-3
MAX_F_NUMBER = 1e4
#: Pixel filter radius in pixels: pbrt's widest default is 4 (sinc); beyond 16 a filter is a blur.
MAX_FILTER_RADIUS = 16.0


def _integer(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise UserError(f"{name} must be a whole number, got {value!r}")
    return int(value)


def _in_range(value: int, name: str, low: int, high: int) -> int:
    if not low <= value <= high:
        raise UserError(f"{name} must be between {low} and {high}, got {value}")
    return value


def positive_length(value: float, name: str, maximum: float = math.inf) -> float:
    """A finite length > 0 (and <= ``maximum``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise UserError(f"{name} must be a number, got {value!r}")
    if not (value > 0 and math.isfinite(value)):
        raise UserError(f"{name} must be a positive finite number, got {value:g}")
    if value > maximum:
        raise UserError(f"{name} must be at most {maximum:g}, got {value:g}")
    return float(value)


#: Wavelengths the lens commands trace at: the glasses' Cauchy fit from n_d and V_d means something
#: from the near ultraviolet to the near infrared, and nothing far beyond (1e-300 nm divided by zero).
MIN_WAVELENGTH_NM, MAX_WAVELENGTH_NM = 200.0, 2000.0


def focus_distance(value: float) -> float:
    """A focus distance (scene units from the film plane): a positive length, or ``inf``."""
    if value == math.inf:
        return math.inf
    return positive_length(value, "focus distance")


def wavelength_nm(value: float) -> float:
    """A wavelength in nm from ``MIN_WAVELENGTH_NM`` to ``MAX_WAVELENGTH_NM``."""
    value = positive_length(value, "wavelength (nm)", MAX_WAVELENGTH_NM)
    if value < MIN_WAVELENGTH_NM:
        raise UserError(f"wavelength (nm) must be at least {MIN_WAVELENGTH_NM:g}, got {value:g}")
    return value


def ghost_threshold(value: float) -> float:
    """A ghost's least on-axis throughput to be listed (``realistic.optics.ghosts``): from 0 to 1."""
    value = finite(value, "ghost threshold")
    if not 0.0 <= value <= 1.0:
        raise UserError(f"ghost threshold must be between 0 and 1 (a fraction of the light), got {value:g}")
    return value


def field_angle_deg(value: float) -> float:
    """A field angle in degrees: finite, strictly between -90 and 90."""
    value = finite(value, "field angle (deg)")
    if not abs(value) < 90:
        raise UserError(f"field angle {value:g} deg must be between -90 and 90")
    return value


def spectral_weights(weights: Sequence[float] | None, count: int) -> list[float]:
    """Relative powers of ``count`` wavelengths (None: equal), normalised to sum to 1: one per
    wavelength, finite and not negative, not all 0."""
    if weights is None:
        return [1.0 / count] * count
    values = [float(w) for w in weights]
    if len(values) != count:
        raise UserError(f"{len(values)} weights given for {count} wavelengths: give one per wavelength")
    if not all(math.isfinite(w) and w >= 0 for w in values) or sum(values) <= 0:
        raise UserError(f"wavelength weights must be finite, not negative and not all 0, got "
                        f"{', '.join(f'{w:g}' for w in values)}")
    total = sum(values)
    return [w / total for w in values]


def resolution(width: int, height: int) -> tuple[int, int]:
    width = _in_range(_integer(width, "resolution width"), "resolution width", 1, MAX_IMAGE_SIDE)
    height = _in_range(_integer(height, "resolution height"), "resolution height", 1, MAX_IMAGE_SIDE)
    if width * height > MAX_PIXELS:
        raise UserError(f"resolution {width}x{height} has more than {MAX_PIXELS} pixels")
    return width, height


def samples_per_pixel(spp: int) -> int:
    return _in_range(_integer(spp, "samples per pixel"), "samples per pixel", 1, MAX_SPP)


#: Wavelengths (rays) per spectral camera sample: past a handful the colour noise is gone and each
#: one costs a ray; 16 keeps a largest pass's rays (16 x 2^26) within the kernel's 2^31 work items.
MAX_WAVELENGTHS_PER_SAMPLE = 16


def wavelengths_per_sample(count: int) -> int:
    """Wavelengths traced per spectral camera sample: 1 to ``MAX_WAVELENGTHS_PER_SAMPLE``."""
    return _in_range(_integer(count, "wavelengths per sample"), "wavelengths per sample", 1,
                     MAX_WAVELENGTHS_PER_SAMPLE)


def seed(value: int) -> int:
    return _in_range(_integer(value, "seed"), "seed", 0, MAX_SEED)


def light_samples(count: int) -> int:
    return _in_range(_integer(count, "light samples"), "light samples", 1, MAX_LIGHT_SAMPLES)


#: Deepest path (bounces) an integrator may be asked for; beyond a few hundred nothing changes in float32.
MAX_DEPTH = 1000


def max_depth(depth: int) -> int:
    return _in_range(_integer(depth, "maximum path depth"), "maximum path depth", 0, MAX_DEPTH)


def blades(count: int) -> int:
    return _in_range(_integer(count, "blade count"), "blade count", MIN_BLADES, MAX_BLADES)


def stop_diameter_mm(value: float) -> float:
    """A stop diameter: a positive finite number of mm (``LensSystem.with_stop_diameter`` also
    bounds it by the lens's widest element)."""
    is_number = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not (is_number and value > 0 and math.isfinite(value)):
        shown = f"{value:g}" if is_number else repr(value)
        raise UserError(f"aperture diameter must be a positive number of mm, got {shown}")
    if value < MIN_STOP_DIAMETER_MM:
        raise UserError(f"aperture diameter must be at least {MIN_STOP_DIAMETER_MM:g} mm (a stop smaller than a "
                        f"micrometre passes no light), got {value:g}")
    return float(value)


def f_number(value: float) -> float:
    """An f-number to size the stop for: positive, finite and at most ``MAX_F_NUMBER`` (whether the
    lens opens that wide is the lens's to say: ``paraxial.stop_diameter_for_f_number``)."""
    return positive_length(value, "f-number", MAX_F_NUMBER)


def film_diagonal_mm(value: float) -> float:
    return positive_length(value, "film diagonal (mm)", MAX_FILM_DIAGONAL_MM)


def filter_radius(value: float, name: str = "filter radius (pixels)") -> float:
    """A pixel filter radius: positive, finite, at most ``MAX_FILTER_RADIUS`` pixels."""
    return positive_length(value, name, MAX_FILTER_RADIUS)


def finite(value: object, name: str) -> float:
    """Any finite number (an exposure in stops, a rotation in degrees)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise UserError(f"{name} must be a finite number, got {value!r}")
    return float(value)


#: Image-texture filters and wrap modes, by pbrt's names (pbrt-v4 ``filter``; pbrt-v2/v3 choose
#: between trilinear and EWA with the bool ``trilinear``).
TEXTURE_FILTERS = ("point", "bilinear", "trilinear", "ewa")
TEXTURE_WRAPS = ("repeat", "black", "clamp")
#: The MIP level from which a trilinear lookup blends two levels, below it reading level 0 alone:
#: 0 in pbrt-v1 to v3 (``MIPMap::Lookup`` blends levels 0 and 1 for a level in [0, 1)), 1 in pbrt-v4
#: (``MIPMap::Filter``: ``if (iLevel == 0) return Bilerp<T>(0, st)``).
TRILINEAR_BLEND_STARTS = (0, 1)
#: Longest-to-shortest axis ratio of an EWA ellipse: 1 (a circle) up to far beyond pbrt's default 8.
MAX_ANISOTROPY = 1024.0


def texture_filter(name: str) -> str:
    if name not in TEXTURE_FILTERS:
        raise UserError(f"image texture filter must be one of {', '.join(TEXTURE_FILTERS)}, got {name!r}")
    return name


def texture_wrap(name: str) -> str:
    if name not in TEXTURE_WRAPS:
        raise UserError(f"image texture wrap must be one of {', '.join(TEXTURE_WRAPS)}, got {name!r}")
    return name


def trilinear_blend_from(value: int) -> int:
    """The level a trilinear lookup's blend starts from: an integer of ``TRILINEAR_BLEND_STARTS``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value not in TRILINEAR_BLEND_STARTS:
        raise UserError(f"trilinear blend start level must be 0 (pbrt-v1 to v3) or 1 (pbrt-v4), got {value!r}")
    return int(value)


def max_anisotropy(value: float) -> float:
    """An EWA eccentricity limit: a finite number from 1 to ``MAX_ANISOTROPY``."""
    value = finite(value, "maxanisotropy")
    if not 1.0 <= value <= MAX_ANISOTROPY:
        raise UserError(f"maxanisotropy must be between 1 and {MAX_ANISOTROPY:g}, got {value:g}")
    return value


#: Worker processes of a local render farm (a LocalCluster on this machine), and render threads
#: in one process.
MAX_WORKERS = 1024
MAX_THREADS = 1024
#: Sample ids per pass: the kernel launches at most 2^31 work items; far below that, a pass's
#: rays no longer fit in memory (about 200 bytes a sample in flight).
MAX_PASS_SAMPLES = 1 << 26


def workers(count: int) -> int:
    """Worker processes for a LocalCluster: 1 to ``MAX_WORKERS``."""
    return _in_range(_integer(count, "workers"), "workers", 1, MAX_WORKERS)


def threads(count: int) -> int:
    """Render threads in this process: 1 to ``MAX_THREADS``."""
    return _in_range(_integer(count, "threads"), "threads", 1, MAX_THREADS)


def pass_samples(count: int) -> int:
    """Sample ids per render pass: 1 to ``MAX_PASS_SAMPLES``."""
    return _in_range(_integer(count, "pass size (samples)"), "pass size (samples)", 1, MAX_PASS_SAMPLES)


#: First-hit outputs a render can add (``renderer.aov``), in the order their channels are laid out.
AOV_NAMES = ("albedo", "position", "depth", "normal")


def aovs(value: str | Sequence[str] | None) -> tuple[str, ...]:
    """AOV names from "depth,normal" or a sequence of names: each one of ``AOV_NAMES``, none
    repeated, returned in ``AOV_NAMES`` order; () for None or ""."""
    if value is None:
        return ()
    names = [part.strip() for part in value.split(",")] if isinstance(value, str) else list(value)
    if isinstance(value, str) and names == [""]:
        return ()
    for name in names:
        if not isinstance(name, str) or name not in AOV_NAMES:
            raise UserError(f"unknown AOV {name!r} (choose from {', '.join(AOV_NAMES)}, comma-separated)")
        if names.count(name) > 1:
            raise UserError(f"AOV {name!r} is named twice")
    return tuple(name for name in AOV_NAMES if name in names)


#: Shutter times from a nanosecond to about eleven days: real shutters span 1/32000 s to hours.
MIN_SHUTTER_SECONDS, MAX_SHUTTER_SECONDS = 1e-9, 1e6
#: ISO speeds: the most sensitive cameras reach a few million; below 1 no film or sensor goes.
MIN_ISO, MAX_ISO = 1.0, 1e7
#: Preview exposure in stops: 2^64 is about 1.8e19, already beyond any scene's dynamic range, and
#: film values times it stay within float32.
MAX_EXPOSURE_STOPS = 64.0


def _bounded(value: float, name: str, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise UserError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise UserError(f"{name} must be a finite number, got {value!r}")
    if not low <= value <= high:
        raise UserError(f"{name} must be between {low:g} and {high:g}, got {value:g}")
    return float(value)


def shutter_seconds(value: float) -> float:
    """A shutter time in seconds, ``MIN_SHUTTER_SECONDS`` to ``MAX_SHUTTER_SECONDS``."""
    return _bounded(value, "shutter time (seconds)", MIN_SHUTTER_SECONDS, MAX_SHUTTER_SECONDS)


def iso_speed(value: float) -> float:
    """An ISO speed, ``MIN_ISO`` to ``MAX_ISO``."""
    return _bounded(value, "ISO speed", MIN_ISO, MAX_ISO)


def exposure_stops(value: float) -> float:
    """An exposure adjustment in stops, within +-``MAX_EXPOSURE_STOPS``."""
    return _bounded(value, "exposure", -MAX_EXPOSURE_STOPS, MAX_EXPOSURE_STOPS)


def _escaped(character: str) -> str:
    code = ord(character)
    return f"\\x{code:02x}" if code < 0x100 else (f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")


def printable_text(text: str, multiline: bool = False) -> str:
    """``text`` safe to print on a terminal or write into another file: control and format characters
    (escape sequences, carriage returns, bidirectional overrides) and line or paragraph separators
    become visible escapes such as ``\\x1b``; with ``multiline``, line ends (CR, LF, CRLF) stay, as LF.
    A lens name with a newline could otherwise add a row to a ``.dat`` written from it."""
    if multiline:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return "".join(c if c == "\t" or (c == "\n" and multiline) or
                   not (unicodedata.category(c)[0] == "C" or unicodedata.category(c) in ("Zl", "Zp"))
                   else _escaped(c) for c in text)


#: Largest component of an emitted RGB (a light's radiance or intensity after its scale): the
#: renderer accumulates in float32 (largest 3.4e38), and 1e32 leaves six orders for a pixel's sum
#: of samples and a light's sampling weight before a pixel overflows.
MAX_EMISSION = 1e32


def _rgb_within(values: Sequence[float], name: str, high: float) -> tuple[float, float, float]:
    """Three finite components, each from 0 to ``high`` (``_bounded``'s messages)."""
    if isinstance(values, str) or not isinstance(values, Sequence) or len(values) != 3:
        raise UserError(f"{name} must be an RGB triple, got {values!r}")
    red, green, blue = (_bounded(finite(v, name), name, 0.0, high) for v in values)
    return red, green, blue


def emission(values: Sequence[float], name: str) -> tuple[float, float, float]:
    """An emitted RGB (radiance or intensity, after any scale): three finite components from 0 to
    ``MAX_EMISSION``. pbrt does not check these; a negative or overflowing value renders NaN, inf or
    black pixels, so it is refused here."""
    return _rgb_within(values, name, MAX_EMISSION)


def reflectance(values: Sequence[float], name: str) -> tuple[float, float, float]:
    """A diffuse reflectance (albedo) RGB: three finite components in [0, 1], the range in which a
    surface neither emits nor absorbs negative light (pbrt-v4 clamps a diffuse reflectance to it;
    see ``scene/pbrt/materials.py``)."""
    return _rgb_within(values, name, 1.0)


#: Film distance behind the lens's rear vertex, in mm: real bellows reach about a metre; beyond
#: 10 m the image of any lens is a blur the single-precision tracer cannot place.
MAX_FILM_DISTANCE_MM = 10_000.0


def film_distance_mm(value: float) -> float:
    """A film distance: positive, finite, at most ``MAX_FILM_DISTANCE_MM``."""
    return positive_length(value, "film distance (mm)", MAX_FILM_DISTANCE_MM)


def crop_window(x0: float, x1: float, y0: float, y1: float) -> tuple[float, float, float, float]:
    """A crop window in NDC, as pbrt-v4's ``--cropwindow x0,x1,y0,y1`` takes it (fractions of the
    image, y down): each in [0, 1], x0 < x1 and y0 < y1. pbrt clamps a Film's cropwindow into
    [0, 1]; a value outside it here is a mistake to name, not to guess around."""
    values = tuple(finite(v, f"crop window {name}") for v, name in zip((x0, x1, y0, y1), ("x0", "x1", "y0", "y1")))
    if not all(0.0 <= v <= 1.0 for v in values) or not (values[0] < values[1] and values[2] < values[3]):
        shown = " ".join(f"{v:g}" for v in values)
        raise UserError(f"crop window {shown} is not x0 x1 y0 y1 with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1")
    return values[0], values[1], values[2], values[3]


def pixel_bounds(x0: int, x1: int, y0: int, y1: int, width: int, height: int) -> tuple[int, int, int, int]:
    """Pixel bounds x0 x1 y0 y1 (``--pixelbounds``, pbrt-v4's Film ``pixelbounds``: pixels x0 .. x1 - 1
    and y0 .. y1 - 1) within a ``width`` x ``height`` image, not empty. pbrt clamps bounds beyond the
    image with a warning; here they are refused in one line naming the resolution."""
    values = tuple(_integer(v, f"pixel bounds {name}") for v, name in zip((x0, x1, y0, y1), ("x0", "x1", "y0", "y1")))
    if not (0 <= values[0] < values[1] <= width and 0 <= values[2] < values[3] <= height):
        shown = " ".join(str(v) for v in values)
        raise UserError(f"pixel bounds {shown} are not x0 x1 y0 y1 with 0 <= x0 < x1 <= {width} and "
                        f"0 <= y0 < y1 <= {height} (the image is {width}x{height})")
    return values[0], values[1], values[2], values[3]


def display_address(text: str) -> tuple[str, int]:
    """A display server's ``HOST:PORT`` (``--display``; ``[::1]:14158`` for an IPv6 host): the host
    and a port from 1 to 65535, as tev listens on (its default: ``127.0.0.1:14158``)."""
    host, colon, port = str(text).rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not colon or not host or not port.isascii() or not port.isdigit() or not 1 <= int(port) <= 65535 \
            or not host.isprintable() or any(c.isspace() or c in "[]/" for c in host):
        raise UserError(f"display address '{printable_text(str(text))}' is not HOST:PORT with a port from 1 to "
                        "65535 (e.g. 127.0.0.1:14158, where tev listens by default)")
    return host, int(port)
