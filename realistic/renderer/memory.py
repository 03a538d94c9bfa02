"""Peak memory of a render, estimated before any work, and the guard that refuses what will not fit.

The estimate is a linear model fitted on this project's renders (peak RSS of the default scene at
64x64, 1024x1024 and 2048x2048, 1 spp) and rounded up: the interpreter with numpy, embree, PoCL
and the lens tables; the film (float64 sums, sample counts, float32 images for EXR and PNG) per
pixel; the rays and shading arrays of the passes in flight per camera ray (a spectral camera
traces ``rays_per_sample`` rays per sample, one per wavelength); and embree's world-space
copy of every instance's triangles with the shading tables per triangle.
"""

from __future__ import annotations

import os
import re

from realistic.camera.base import Camera
from realistic.errors import UserError
from realistic.scene.model import Scene

BASE_BYTES = 350 * 2**20
FILM_BYTES_PER_PIXEL = 80
PASS_BYTES_PER_SAMPLE = 600  # per camera ray in flight
SCENE_BYTES_PER_TRIANGLE = 256
_SIZE = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*([kmgt]?)i?b?\s*$", re.IGNORECASE)


def estimate_peak_bytes(scene: Scene, camera: Camera, pass_samples: int, threads: int) -> int:
    """Bytes a render of ``scene`` through ``camera`` holds at its peak."""
    pixels = camera.width * camera.height
    in_flight = min(pass_samples, camera.sample_count) * max(1, threads) * camera.rays_per_sample
    triangles = sum(len(scene.meshes[inst.mesh].faces) for inst in scene.instances) + 256 * len(scene.area_lights)
    return (BASE_BYTES + FILM_BYTES_PER_PIXEL * pixels + PASS_BYTES_PER_SAMPLE * in_flight
            + SCENE_BYTES_PER_TRIANGLE * triangles)


def available_bytes() -> int:
    """Memory the system can give this process now (Linux MemAvailable; else free physical pages)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def parse_size(text: str) -> int:
    """``"8G"``, ``"512M"``, ``"2.5GiB"`` or a number of bytes -> bytes."""
    match = _SIZE.match(text)
    if not match or float(match.group(1)) <= 0:
        raise UserError(f"memory size {text!r} is not a positive size such as 8G, 512M or 2.5GiB")
    power = " kmgt".index(match.group(2).lower() or " ")
    return int(float(match.group(1)) * 1024**power)


def check_memory(scene: Scene, camera: Camera, pass_samples: int, threads: int, limit_bytes: int | None) -> None:
    """Refuse, in one line with the estimate and the limit, a render that would not fit in memory
    (``limit_bytes`` None: what the system has available)."""
    need = estimate_peak_bytes(scene, camera, pass_samples, threads)
    limit = available_bytes() if limit_bytes is None else limit_bytes
    if need > limit:
        source = "available" if limit_bytes is None else "allowed by --max-memory"
        raise UserError(f"a {camera.width}x{camera.height} render of this scene needs about {need / 2**30:.1f} GiB, "
                        f"more than the {limit / 2**30:.1f} GiB {source}; lower --res, or raise --max-memory "
                        "if the estimate is too cautious")
