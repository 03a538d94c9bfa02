"""Sequences of frames that vary one camera quantity: ``--sweep focus=0.5:5:24``.

``parse_sweep`` reads ``NAME=START:STOP:COUNT`` (COUNT values from START to STOP inclusive, evenly
spaced; COUNT 1 gives START); ``sweep_cameras`` makes one camera per value. Quantities: ``focus``
(scene units from the film, as ``--focus``), ``aperture`` (stop diameter, mm), ``fstop`` (paraxial
f-number) and ``film-distance`` (mm from the rear vertex). Frame i (from 0) is written to
``OUT_0001.exr`` onwards (``frame_path``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.lens_camera import LensCamera
from realistic.core import validation
from realistic.errors import UserError

QUANTITIES = ("focus", "aperture", "fstop", "film-distance")
#: Frames in one sequence: seven minutes of film at 24 frames/s. Every frame's camera is made (its
#: focus solved) before the first frame renders, so this also bounds the wait for the first frame.
MAX_FRAMES = 10_000


@dataclass(frozen=True)
class Sweep:
    """One quantity and the value it takes in each frame."""

    quantity: str
    values: tuple[float, ...]


def parse_sweep(text: str) -> Sweep:
    """``NAME=START:STOP:COUNT`` as a Sweep; UserError (one line) for anything else."""
    name, equals, rest = text.partition("=")
    name = name.strip().lower()
    if not equals or name not in QUANTITIES:
        raise UserError(f"--sweep {text!r}: expected NAME=START:STOP:COUNT with NAME one of {', '.join(QUANTITIES)}")
    parts = rest.split(":")
    if len(parts) != 3:
        raise UserError(f"--sweep {text!r}: expected {name}=START:STOP:COUNT, e.g. {name}=1:4:24")
    try:
        start, stop = float(parts[0]), float(parts[1])
        count = int(parts[2])
    except ValueError:
        raise UserError(f"--sweep {text!r}: START and STOP must be numbers and COUNT a whole number") from None
    if not 1 <= count <= MAX_FRAMES:
        raise UserError(f"--sweep {text!r}: COUNT must be between 1 and {MAX_FRAMES}, got {count}")
    for value in (start, stop):
        if not (math.isfinite(value) and value > 0):
            raise UserError(f"--sweep {text!r}: {name} values must be positive finite numbers, got {value:g}")
    values = (start,) if count == 1 else tuple(float(v) for v in np.linspace(start, stop, count))
    check = {"aperture": validation.stop_diameter_mm, "fstop": validation.f_number}.get(name)
    if check is not None:
        for value in (start, stop):
            check(value)
    return Sweep(name, values)


def sweep_cameras(camera: Camera, sweep: Sweep) -> list[Camera]:
    """``camera`` with ``sweep.quantity`` set to each value in turn (a lens camera only)."""
    if not isinstance(camera, LensCamera):
        raise UserError(f"--sweep {sweep.quantity} needs a lens camera; this scene's camera is a "
                        f"{type(camera).__name__}")
    return [_with(camera, sweep.quantity, value) for value in sweep.values]


def _with(camera: LensCamera, quantity: str, value: float) -> LensCamera:
    if quantity == "focus":
        return camera.with_focus(value)
    if quantity == "aperture":
        return camera.with_stop(aperture_mm=value)
    if quantity == "fstop":
        return camera.with_stop(f_number=value)
    return dataclasses.replace(camera, film_distance_mm=validation.positive_length(value, "film distance (mm)"))


def frame_path(out: Path, index: int) -> Path:
    """Where frame ``index`` (from 0) of a sequence to ``out`` goes: ``out_0001.exr`` for index 0."""
    out = Path(out)
    return out.with_name(f"{out.stem}_{index + 1:04d}{out.suffix}")
