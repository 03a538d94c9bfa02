"""Photographic exposure: from film irradiance to image values by shutter time and ISO speed.

The renderer's film holds irradiance in units of scene radiance (a uniform field of radiance L seen
through an aperture of f-number N gives E = pi L / (4 N^2) on the axis). A camera exposed for t
seconds at ISO S, calibrated like a reflected-light meter (ISO 2720: N^2 / t = L S / K with
K = 12.5), records middle grey (0.18) for a correctly metered field, so the image value is

    value = E * t * S * 0.18 * 4 / (pi * K).

Brightness then follows the exposure value EV = log2(N^2 / t): one stop more light per EV less.
"""

from __future__ import annotations

import math

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
