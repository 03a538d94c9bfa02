"""Command-line values: text to numbers, tuples and vectors, with one-line errors naming the value."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TypeVar

import numpy as np

from realistic.core import validation
from realistic.core.atomic_files import check_writable
from realistic.errors import UserError
from realistic.optics.formats import BUNDLED_LENSES

Value = TypeVar("Value")
Checked = TypeVar("Checked")


def checked(convert: Callable[[str], Value], check: Callable[[Value], Checked]) -> Callable[[str], Checked]:
    """An argparse type: ``convert`` the text, then apply the library's own check of the quantity
    (``realistic.core.validation``), so the CLI refuses exactly what the library would."""
    def parse(text: str) -> Checked:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {'whole ' if convert is int else ''}number") from None
        try:
            return check(value)
        except UserError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
    return parse


def positive(name: str) -> Callable[[str], float]:
    """An argparse type for a positive finite length or quantity called ``name``."""
    return checked(float, partial(validation.positive_length, name=name))


def parse_resolution(text: str) -> tuple[int, int]:
    """``"640x480"`` -> (640, 480), within ``validation.resolution``'s limits."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise UserError(f"resolution {text!r} is not WIDTHxHEIGHT (e.g. 640x480)")
    return validation.resolution(int(parts[0]), int(parts[1]))


def parse_vector(text: str, name: str) -> np.ndarray:
    """``"X,Y,Z"`` -> array of three finite numbers; ``name`` is what the error calls it."""
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        values = np.array([])
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise UserError(f"{name} {text!r} is not three finite numbers X,Y,Z")
    return values


def parse_pixel(text: str) -> tuple[float, float]:
    """``"X,Y"`` -> a raster position for ``--focus-on``."""
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--focus-on {text!r} is not a pixel X,Y (e.g. 150,120)") from None
    return x, y


def parse_spp_list(text: str) -> list[int]:
    """``"1,4,16"`` -> [1, 4, 16]; each a positive integer."""
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or any(v < 1 for v in values):
        raise UserError(f"--spp {text!r} is not a comma-separated list of positive integers")
    return [validation.samples_per_pixel(v) for v in values]


def checked_plot(path: Path) -> Path:
    """``path`` after ``check_writable``, with a suffix matplotlib can save (png, pdf, svg, ...):
    checked before the work, since matplotlib refuses an unknown one only when it saves."""
    from matplotlib.backend_bases import FigureCanvasBase

    check_writable(path, {f".{name}" for name in FigureCanvasBase.get_supported_filetypes()})
    return path


def checked_exr(path: Path) -> Path:
    """``path`` after ``check_writable``, named ``.exr`` (what is written there is OpenEXR)."""
    check_writable(path, {".exr"})
    return path


#: Help for a LENS argument (every command that takes one).
LENS_HELP = (f"bundled lens name ({', '.join(BUNDLED_LENSES)}, or any name 'realistic lens list' shows) "
             "or path to a prescription file (.dat, .json, .zmx, .seq)")
