"""JSON input and output of ``realistic lens trace`` (the interface outside optics software checks)."""

from __future__ import annotations

import json
import math
import reprlib

import numpy as np

from realistic.core.input_files import decode_text, parse_json, read_input
from realistic.errors import UserError
from realistic.optics.lens import MAX_LENGTH_MM
from realistic.optics.tracer import REASONS, TraceResult


def _shown(value: object) -> str:
    """A JSON value as its JSON text (``null``, ``true``), shortened: containers by ``reprlib``, which
    also bounds their depth."""
    return reprlib.repr(value) if isinstance(value, (list, dict)) else json.dumps(value)[:40]


def read_rays(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Origins and unit directions (N, 3) from ``{"rays": [{"origin": [..], "direction": [..]}, ...]}``:
    origins within ``MAX_LENGTH_MM`` of the film centre, directions of any non-zero length (normalised
    here, scaled first, so that no length overflows or vanishes in the tracer)."""
    data = parse_json(decode_text(read_input(path, "rays file"), path, "the rays file"), path)
    rays = data.get("rays") if isinstance(data, dict) else None
    if not isinstance(rays, list):
        raise UserError(f'{path}: expected an object with a "rays" list')
    origins, directions = [], []
    for i, ray in enumerate(rays):
        vectors = []
        for key in ("origin", "direction"):
            if not isinstance(ray, dict):
                raise UserError(f'{path}: rays[{i}] must be an object with "origin" and "direction", got '
                                f"{_shown(ray)}")
            if key not in ray:
                raise UserError(f'{path}: rays[{i}] has no "{key}"')
            value = ray[key]
            if (not isinstance(value, list) or len(value) != 3
                    or not all(isinstance(x, float) and math.isfinite(x) for x in value)):
                raise UserError(f"{path}: rays[{i}].{key} must be a list of 3 finite numbers, got "
                                f"{_shown(value)}")
            vectors.append(value)
        origin, direction = vectors
        if max(abs(x) for x in origin) > MAX_LENGTH_MM:
            raise UserError(f"{path}: rays[{i}].origin {origin} lies beyond {MAX_LENGTH_MM:g} mm of the film centre")
        peak = max(abs(x) for x in direction)
        if peak == 0:
            raise UserError(f"{path}: rays[{i}].direction is the zero vector")
        scaled = [x / peak for x in direction]  # largest component 1: no square overflows or vanishes
        length = math.hypot(*scaled)
        origins.append(origin)
        directions.append([x / length for x in scaled])
    return np.array(origins, dtype=np.float64).reshape(-1, 3), np.array(directions, dtype=np.float64).reshape(-1, 3)


def rays_to_json(result: TraceResult) -> dict[str, list[dict[str, object]]]:
    """The trace result in the documented JSON shape, rays in input order."""
    rays: list[dict[str, object]] = []
    for origin, direction, surface, reason in zip(result.origin, result.direction, result.blocked_surface,
                                                  result.blocked_reason):
        if reason:
            rays.append({"blocked_by": {"surface": int(surface), "reason": REASONS[int(reason)]}})
        else:
            rays.append({"origin": origin.tolist(), "direction": direction.tolist()})
    return {"rays": rays}
