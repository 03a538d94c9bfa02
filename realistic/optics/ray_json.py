"""JSON input and output of ``realistic lens trace`` (the interface outside optics software checks)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.optics.tracer import REASONS, TraceResult


def read_rays(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions (N, 3) from ``{"rays": [{"origin": [..], "direction": [..]}, ...]}``."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise UserError(f"{path}: cannot read: {err.strerror}") from None
    except json.JSONDecodeError as err:
        raise UserError(f"{path}:{err.lineno}: not valid JSON: {err.msg}") from None
    rays = data.get("rays") if isinstance(data, dict) else None
    if not isinstance(rays, list):
        raise UserError(f'{path}: expected an object with a "rays" list')
    origins, directions = [], []
    for i, ray in enumerate(rays):
        vectors = []
        for key in ("origin", "direction"):
            value = ray.get(key) if isinstance(ray, dict) else None
            if (not isinstance(value, list) or len(value) != 3
                    or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in value)):
                raise UserError(f'{path}: rays[{i}].{key} must be a list of 3 finite numbers, got {value!r}')
            vectors.append(value)
        if vectors[1] == [0, 0, 0]:
            raise UserError(f"{path}: rays[{i}].direction is the zero vector")
        origins.append(vectors[0])
        directions.append(vectors[1])
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
