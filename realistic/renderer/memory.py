"""Peak memory of a render, estimated before any set-up, and the guard that refuses what will not fit.

The estimate is a sum of parts, each a count of what the render holds times bytes per item, the
factors measured on this project's renders (peak RSS; docs/robustness.md has the table) and rounded
up:

- the interpreter with numpy, embree, PoCL and the lens tables (a constant);
- the scene's meshes as loaded (their arrays' bytes), and per triangle embree traces its copy, BVH
  and shading tables: a large mesh placed several times once (embree instances it), any other
  instance's triangles each time; area lights count as small meshes;
- light tables: an emitting instance's triangles in world space with their area CDF (held by each
  pass runner: two at a frame boundary of a sequence), an environment map's sampling tables;
- image textures with their MIP maps;
- the film (float64 sums and counts, float32 images for EXR and PNG) per pixel of each frame being
  rendered, plus the images of finished frames a job keeps (``RenderJob.keep_images``);
- the rays and shading arrays of the passes in flight per camera ray: one pass per thread, but never
  more samples than the frame has (a spectral camera traces ``rays_per_sample`` rays per sample).
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections import Counter

import numpy as np

from realistic.camera.base import Camera
from realistic.errors import UserError
from realistic.renderer.aov import RADIANCE_COLUMNS, AovLayout
from realistic.renderer.job import RenderJob
from realistic.scene.intersect import SHARE_MIN_FACES
from realistic.scene.lights import EmissiveInstance, InfiniteLight
from realistic.scene.model import ImageTexture, Scene

BASE_BYTES = 350 * 2**20
FILM_BYTES_PER_PIXEL = 80
IMAGE_BYTES_PER_PIXEL = 12  # a finished frame's float32 RGB image
PASS_BYTES_PER_SAMPLE = 600  # per camera ray in flight
AOV_BYTES_PER_COLUMN = 12  # per AOV film column: a float64 sum per pixel (or ray in flight) and its float32 image
SCENE_BYTES_PER_TRIANGLE = 192  # per instanced triangle: embree's copy and BVH, shading tables (150 measured)
AREA_LIGHT_TRIANGLES = 256
EMITTER_BYTES_PER_TRIANGLE = 176  # per emitting triangle and runner: corners, edges, normal, CDF (142 measured)
ENVIRONMENT_BYTES_PER_TEXEL = 48  # the map (float32 RGB), its luminance and 2D distribution (float64)
TEXTURE_FACTOR = 6  # a texture's pixels: resampled to powers of two (up to 4x), MIP levels (4/3), a copy
#: Frames whose films and pass runners are alive at once in a sequence (one finishing, one starting).
FRAMES_ALIVE = 2
_SIZE = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*([kmgt]?)i?b?\s*$", re.IGNORECASE)


def memory_parts(scene: Scene, camera: Camera, pass_samples: int, threads: int, frames: int = 1,
                 kept_images: int = 0, aov_columns: int = 0) -> dict[str, int]:
    """Bytes a render of ``scene`` through ``camera`` (one of ``frames`` alike) holds at its peak, by
    what they go to; ``kept_images`` finished frames' images are held to the end; ``aov_columns``
    film columns beyond the radiance's hold AOV sums (``aov.AovLayout``)."""
    pixels = camera.width * camera.height
    alive = min(frames, FRAMES_ALIVE)
    in_flight = min(pass_samples * max(1, threads), camera.sample_count) * camera.rays_per_sample
    triangles = _traced_triangles(scene)
    triangles += AREA_LIGHT_TRIANGLES * len(scene.area_lights)
    emitting = sum(len(scene.meshes[scene.instances[light.instance].mesh].faces) for light in scene.lights
                   if isinstance(light, EmissiveInstance))
    texels = sum(light.image.shape[0] * light.image.shape[1] for light in scene.lights
                 if isinstance(light, InfiniteLight) and light.image is not None)
    return {
        "the interpreter and libraries": BASE_BYTES,
        "geometry": sum(_mesh_bytes(mesh) for mesh in scene.meshes) + SCENE_BYTES_PER_TRIANGLE * triangles,
        "light tables": alive * EMITTER_BYTES_PER_TRIANGLE * emitting + ENVIRONMENT_BYTES_PER_TEXEL * texels,
        "textures": TEXTURE_FACTOR * sum(texture.pixels.nbytes for texture in _image_textures(scene)),
        "film": alive * (FILM_BYTES_PER_PIXEL + AOV_BYTES_PER_COLUMN * aov_columns) * pixels
        + IMAGE_BYTES_PER_PIXEL * pixels * kept_images,
        "passes in flight": (PASS_BYTES_PER_SAMPLE + AOV_BYTES_PER_COLUMN * aov_columns) * in_flight,
    }


def estimate_peak_bytes(scene: Scene, camera: Camera, pass_samples: int, threads: int, frames: int = 1,
                        kept_images: int = 0, aov_columns: int = 0) -> int:
    """Bytes a render of ``scene`` through ``camera`` holds at its peak (``memory_parts`` summed)."""
    return sum(memory_parts(scene, camera, pass_samples, threads, frames, kept_images, aov_columns).values())


def _traced_triangles(scene: Scene) -> int:
    """Triangles embree holds: a mesh it shares between instances (``intersect.SHARE_MIN_FACES``)
    once, every other instance's triangles in world space."""
    placed = Counter(instance.mesh for instance in scene.instances)
    return sum(len(scene.meshes[mesh].faces) * (1 if count > 1 and len(scene.meshes[mesh].faces) >= SHARE_MIN_FACES
                                                else count) for mesh, count in placed.items())


def _mesh_bytes(mesh: object) -> int:
    """The bytes of a mesh's arrays (vertices, faces, normals, uv)."""
    return sum(value.nbytes for value in vars(mesh).values() if isinstance(value, np.ndarray))


def _image_textures(scene: Scene) -> list[ImageTexture]:
    """Every image texture the scene's materials use (nested textures too), each once."""
    found: dict[int, ImageTexture] = {}
    todo: list[object] = [instance.material for instance in scene.instances]
    seen: set[int] = set()
    while todo:
        item = todo.pop()
        if id(item) in seen or not dataclasses.is_dataclass(item):
            continue
        seen.add(id(item))
        if isinstance(item, ImageTexture):
            found[id(item)] = item
            continue
        todo.extend(getattr(item, field.name) for field in dataclasses.fields(item))
    return list(found.values())


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


def machine_bytes() -> int:
    """The most memory this machine could ever give: physical memory plus swap (Linux; else physical)."""
    total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("SwapTotal:"):
                    total += int(line.split()[1]) * 1024
    except OSError:
        pass
    return total


def parse_size(text: str) -> int:
    """``"8G"``, ``"512M"``, ``"2.5GiB"`` or a number of bytes -> bytes."""
    match = _SIZE.match(text)
    if not match or float(match.group(1)) <= 0:
        raise UserError(f"memory size {text!r} is not a positive size such as 8G, 512M or 2.5GiB")
    power = " kmgt".index(match.group(2).lower() or " ")
    return int(float(match.group(1)) * 1024**power)


_ADVICE = {
    "geometry": "fewer or coarser meshes",
    "light tables": "fewer or coarser emitting shapes",
    "textures": "smaller textures",
    "film": "lower --res",
    "passes in flight": "fewer --threads or a smaller --pass-samples",
}


def check_memory(scene: Scene, camera: Camera, pass_samples: int, threads: int, limit_bytes: int | None,
                 frames: int = 1, kept_images: int = 0, limit_source: str = "allowed by --max-memory",
                 aov_columns: int = 0) -> None:
    """Refuse, in one line with the estimate, what it goes to and the limit, a render that would not
    fit in memory: more than ``limit_bytes`` (None: what the system has available now; its name in
    the message: ``limit_source``), and never more than the machine has at all, whatever
    ``limit_bytes`` says."""
    parts = memory_parts(scene, camera, pass_samples, threads, frames, kept_images, aov_columns)
    need = sum(parts.values())
    machine = machine_bytes()
    raise_hint = ", or raise --max-memory if the estimate is too cautious"
    if limit_bytes is None:
        limit, source = available_bytes(), "available"
    elif limit_bytes > machine:
        limit, source, raise_hint = machine, "this machine has in all (memory and swap)", ""
    else:
        limit, source = limit_bytes, limit_source
    if need <= limit:
        return
    largest = sorted((name for name in parts if name in _ADVICE), key=parts.__getitem__, reverse=True)
    detail = ", ".join(f"{name} {parts[name] / 2**30:.1f}" for name in largest[:3])
    raise UserError(f"a {camera.width}x{camera.height} render of this scene needs about {need / 2**30:.1f} GiB "
                    f"(GiB: {detail}), more than the {limit / 2**30:.1f} GiB {source}; try "
                    f"{_ADVICE[largest[0]]}{raise_hint}")


def check_job_memory(job: RenderJob, threads: int, limit_bytes: int | None, frames: int = 1, kept_images: int = 0,
                     limit_source: str = "allowed by --max-memory") -> None:
    """``check_memory`` for every kind of frame ``job`` renders (a sweep's frames are alike, so one
    check serves them), on ``threads`` threads, holding ``frames`` films and ``kept_images`` images."""
    alike = {(c.width, c.height, c.spp, c.rays_per_sample): c for c in job.cameras}
    # lens flare's film and splats are three float64 sums per pixel or landed path, as RGB AOV columns are
    aov_columns = AovLayout(job.settings.aovs).columns - RADIANCE_COLUMNS + (RADIANCE_COLUMNS if job.flare else 0)
    for camera in alike.values():
        check_memory(job.scene, camera, job.pass_size, threads, limit_bytes, frames, kept_images, limit_source,
                     aov_columns)
