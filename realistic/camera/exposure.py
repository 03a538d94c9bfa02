"""Photographic exposure: from film irradiance to image values by shutter time and ISO speed.

The renderer's film holds irradiance in units of scene radiance (a uniform field of radiance L seen
through an aperture of f-number N gives E = pi L / (4 N^2) on the axis). A camera exposed for t
seconds at ISO S, calibrated like a reflected-light meter (ISO 2720: N^2 / t = L S / K with
K = 12.5), records middle grey (0.18) for a correctly metered field, so the image value is

    value = E * t * S * 0.18 * 4 / (pi * K).

Brightness then follows the exposure value EV = log2(N^2 / t): one stop more light per EV less.

A film image is metered as a through-the-lens averaging meter reads (``metered_log2``): the image
value it reads is the film irradiance E above, so the exposure that maps it to middle grey is
t S = pi K / (4 E), and at ISO 100 the scene wants EV100 = log2(N^2 400 E / (pi K)). The PNG
preview's automatic exposure (``--exposure auto``) is this meter; ``MeterReading`` compares a
``--shutter``/``--iso`` pair with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic.core import validation
from realistic.errors import UserError

METER_CALIBRATION_K = 12.5
MIDDLE_GREY = 0.18


def parse_shutter(text: str) -> float:
    """Shutter time in seconds from ``"0.01"`` or ``"1/125"``, within ``validation.shutter_seconds``."""
    try:
        if "/" in text:
            numerator, denominator = text.split("/", 1)
            seconds = float(numerator) / float(denominator)
        else:
            seconds = float(text)
    except (ValueError, ZeroDivisionError, OverflowError):
        seconds = math.nan
    if not (seconds > 0 and math.isfinite(seconds)):
        raise UserError(f"shutter time {text!r} is not a positive number of seconds (e.g. 1/125 or 0.008)")
    return validation.shutter_seconds(seconds)


def exposure_scale(shutter_s: float, iso: float) -> float:
    """Factor from film irradiance to image value for shutter time ``shutter_s`` at ISO ``iso``."""
    shutter_s = validation.shutter_seconds(shutter_s)
    iso = validation.iso_speed(iso)
    return shutter_s * iso * MIDDLE_GREY * 4.0 / (math.pi * METER_CALIBRATION_K)


def exposure_value(f_number: float, shutter_s: float) -> float:
    """EV = log2(N^2 / t)."""
    return math.log2(f_number * f_number / shutter_s)


#: The film is linear sRGB (Rec. 709 primaries): luminance is Y of its RGB.
LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)
#: How far above the lit pixels' log-average (geometric mean) luminance a pixel counts in the
#: meter's average, in stops: a light source or a specular highlight in view clips in the image
#: (middle grey 0.18 leaves 2.5 stops to white) and moves the reading by at most 2^3 times its share
#: of the frame.
METER_HEADROOM_STOPS = 3.0
#: ``--exposure auto``: the preview exposed by the meter (``metered_stops``).
AUTO = "auto"


def metered_log2(image: np.ndarray) -> float | None:
    """log2 of an averaging meter's reading of the linear RGB ``image`` (H, W, 3): the mean
    luminance of its lit pixels (positive and finite), each counted at most ``METER_HEADROOM_STOPS``
    above their log-average. None when no pixel is lit.

    An arithmetic mean, as a reflected-light meter integrates light and ISO 2720's K assumes, so a
    uniform field reads its own value and a dark backdrop behind a bright subject does not blow the
    subject out; with a ceiling, so that near-identical scenes meter alike (where the 97th
    percentile the preview used to take jumped by 13 stops): a small highlight moves the reading by
    its share of the frame times 2^3 at most, and the log-average the ceiling follows moves by that
    share times the highlight's stops. A few black pixels do not count at all: unlit pixels are
    left out, so that a frame the lens's image circle does not fill meters what the lens shows."""
    luminance = np.asarray(image, dtype=np.float64).reshape(-1, 3) @ np.asarray(LUMINANCE_WEIGHTS)
    lit = luminance[np.isfinite(luminance) & (luminance > 0)]
    if lit.size == 0:
        return None
    ceiling = 2.0 ** (float(np.mean(np.log2(lit))) + METER_HEADROOM_STOPS)
    return math.log2(float(np.mean(np.minimum(lit, ceiling))))


def metered_stops(image: np.ndarray) -> float:
    """The exposure in stops that brings the meter's reading of ``image`` to middle grey (0.18);
    0 for a black image."""
    reading = metered_log2(image)
    return 0.0 if reading is None else math.log2(MIDDLE_GREY) - reading


def parse_exposure(text: str) -> float | str:
    """``--exposure``: ``"auto"`` (``AUTO``) or stops within ``validation.exposure_stops``."""
    if text.strip().lower() == AUTO:
        return AUTO
    try:
        stops = float(text)
    except ValueError:
        raise UserError(f"exposure {text!r} is neither a number of stops nor 'auto'") from None
    return validation.exposure_stops(stops)


@dataclass(frozen=True)
class MeterReading:
    """What the averaging meter (``metered_log2``) says of a film image against a shutter time and
    ISO speed: how far they are from the exposure that maps the reading to middle grey."""

    irradiance_log2: float  # log2 of the meter's reading (film irradiance, or a thin lens's radiance)
    shutter_s: float
    iso: float
    f_number: float | None  # the lens's, for the exposure values; None for a thin lens

    @property
    def stops_over(self) -> float:
        """Stops the given exposure lies above the metered one (negative: under-exposed)."""
        return math.log2(exposure_scale(self.shutter_s, self.iso) / MIDDLE_GREY) + self.irradiance_log2

    @property
    def metered_shutter_s(self) -> float:
        """The shutter time that meters correctly at this ISO."""
        return self.shutter_s / 2.0**self.stops_over

    @property
    def wanted_ev100(self) -> float | None:
        """The EV at ISO 100 the metered scene wants at the lens's f-number (EV = log2(N^2 / t))."""
        if self.f_number is None:
            return None
        return exposure_value(self.f_number, self.shutter_s) - math.log2(self.iso / 100.0) + self.stops_over

    @property
    def given_ev100(self) -> float | None:
        """The EV at ISO 100 equivalent to the given shutter and ISO at the lens's f-number."""
        if self.f_number is None:
            return None
        return exposure_value(self.f_number, self.shutter_s) - math.log2(self.iso / 100.0)

    def describe(self) -> str:
        """One line: the wanted and given EVs, the stops under or over, and the shutter that meters."""
        settings = f"{format_shutter(self.shutter_s)} s at ISO {self.iso:g}"
        over = self.stops_over
        direction = "over" if over > 0 else "under"
        verdict = "metered correctly" if abs(over) < 0.05 else f"{abs(over):.1f} stops {direction}"
        if self.wanted_ev100 is not None and self.given_ev100 is not None:
            evs = (f"the scene meters EV {self.wanted_ev100:.1f} (ISO 100) at f/{self.f_number:.3g}; "
                   f"{settings} is EV {self.given_ev100:.1f}")
        else:
            evs = settings
        return (f"meter (averaging): {evs}: {verdict}; {format_shutter(self.metered_shutter_s)} s at ISO "
                f"{self.iso:g} would meter correctly")


def meter_reading(image: np.ndarray, shutter_s: float, iso: float, f_number: float | None) -> MeterReading | None:
    """The meter's reading of the film ``image`` against ``shutter_s`` and ``iso``; None for a black image."""
    reading = metered_log2(image)
    if reading is None:
        return None
    return MeterReading(reading, validation.shutter_seconds(shutter_s), validation.iso_speed(iso), f_number)


def format_shutter(seconds: float) -> str:
    """A shutter time as a photographer writes it, to two digits or whole numbers: ``1/125`` and
    ``1/2.5`` below a second, ``1.6`` and ``30`` above."""
    if seconds < 1:
        return f"1/{1 / seconds:.0f}" if 1 / seconds >= 10 else f"1/{1 / seconds:.2g}"
    return f"{seconds:.0f}" if seconds >= 10 else f"{seconds:.2g}"
