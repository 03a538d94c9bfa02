"""Pass scheduling: ``render(scene, camera, ...)`` returns the film image as an array.

A render is the range of sample ids 0 .. W*H*spp - 1 cut into passes of at most ``pass_samples``
ids, so memory stays flat as resolution and spp grow. Two worker threads each run whole passes
(camera rays, embree, shading, per-pass accumulation); embreex and most numpy loops release the
GIL, so one thread's ray generation overlaps the other's intersection. The main thread adds the
pass sums to the film. Ctrl-C stops submitting passes, lets the passes in flight finish, and
returns what has accumulated (``RenderResult.interrupted``).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from realistic.camera.base import Camera
from realistic.core import validation
from realistic.core.spectrum import rgb_response
from realistic.errors import UserError
from realistic.renderer.film import Film, pass_sums
from realistic.renderer.integrators import make_integrator
from realistic.renderer.memory import check_memory
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Intersector
from realistic.scene.model import Scene

DEFAULT_PASS_SAMPLES = 1 << 17


@dataclass
class RenderResult:
    """The film image and how it was made."""

    image: np.ndarray  # (H, W, 3) float32 film irradiance
    samples_done: int
    samples_total: int
    primary_rays: int  # camera rays that left the lens (traced by embree)
    shadow_rays: int
    seconds: float
    interrupted: bool
    stage_seconds: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class _PassResult:
    first_sample: int
    count: int
    first_pixel: int
    sums: np.ndarray
    primary_rays: int
    shadow_rays: int


def morton_order(pixel: np.ndarray, width: int) -> np.ndarray:
    """Permutation that visits pixels along a Z-order (Morton) curve over (x, y)."""
    def spread(v: np.ndarray) -> np.ndarray:
        v = v.astype(np.uint64) & np.uint64(0xFFFF)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        return v
    code = spread(pixel % width) | (spread(pixel // width) << np.uint64(1))
    return np.argsort(code, kind="stable")


class _PassRunner:
    """Runs one pass of sample ids: rays, hits, shading, per-pixel sums."""

    def __init__(self, scene: Scene, camera: Camera, backend: str, seed: int, cl_device: str | None,
                 light_samples: int, morton: bool, clock: StageClock):
        self.camera, self.morton, self.clock = camera, morton, clock
        self.generate = camera.ray_generator(backend, seed, cl_device)
        self.integrator = make_integrator(scene, Intersector(scene), light_samples, seed,
                                          camera.pixel_spread_radians())

    def __call__(self, first: int, count: int) -> _PassResult:
        spp = self.camera.spp
        with self.clock("ray generation"):
            rays = self.generate(first, count)
        with self.clock("shading"):
            alive = np.flatnonzero(rays.weight != 0)  # a negative filter lobe gives negative weights
            if self.morton:
                alive = alive[morton_order(rays.pixel[alive], self.camera.width)]
            pixel = rays.pixel[alive]
            origin = rays.origin[alive].astype(np.float32)
            direction = rays.direction[alive].astype(np.float32)
            wavelength = None if rays.wavelength_nm is None else rays.wavelength_nm[alive]
        radiance, shadow_rays = self.integrator.radiance(origin, direction, pixel, (first + alive) % spp,
                                                         self.clock, wavelength)
        with self.clock("accumulation"):
            first_pixel = first // spp
            pixel_count = (first + count - 1) // spp - first_pixel + 1
            value = radiance * rays.weight[alive, None].astype(np.float32)
            if wavelength is not None:
                value *= rgb_response(wavelength)
            sums = pass_sums(pixel, value, first_pixel, pixel_count)
        return _PassResult(first, count, first_pixel, sums, len(alive), shadow_rays)


def render_passes(scene: Scene, camera: Camera, backend: str = "opencl", seed: int = 0,
                  cl_device: str | None = None, light_samples: int = 1,
                  pass_samples: int = DEFAULT_PASS_SAMPLES, threads: int = 2, morton: bool = False,
                  progress: bool = False, on_pass: Callable[[RenderResult], None] | None = None,
                  max_memory_bytes: int | None = None) -> RenderResult:
    """Render and return the image with statistics; ``on_pass`` is called after each pass is added.

    Before any work, a render whose estimated peak memory exceeds ``max_memory_bytes`` (None: what
    the system has available) is refused with a UserError (``realistic.renderer.memory``). A first
    KeyboardInterrupt finishes the passes in flight and returns what has accumulated
    (``RenderResult.interrupted``); a second one while they finish propagates at once.
    """
    validation.seed(seed)
    check_memory(scene, camera, pass_samples, threads, max_memory_bytes)
    start = time.perf_counter()
    clock = StageClock()
    with clock("exit pupil"):  # the lens's sampling table (``Camera.prepare``)
        camera.prepare()
    with clock("setup"):  # ray generator, BVH build, shading tables
        runner = _PassRunner(scene, camera, backend, seed, cl_device, light_samples, morton, clock)
    film = Film(camera.width, camera.height, camera.spp)
    total = camera.sample_count
    starts = list(range(0, total, pass_samples))
    result = RenderResult(film.image(), 0, total, 0, 0, 0.0, False)
    bar = _progress_bar(len(starts)) if progress else None
    pending: set[Future] = set()
    next_pass = 0
    pool = ThreadPoolExecutor(max_workers=threads)
    finished = False
    try:
        try:
            while next_pass < len(starts) or pending:
                while next_pass < len(starts) and len(pending) < threads:
                    first = starts[next_pass]
                    pending.add(pool.submit(runner, first, min(pass_samples, total - first)))
                    next_pass += 1
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    _add(film, result, future.result(), bar, start)
                    if on_pass is not None:
                        on_pass(result)
        except KeyboardInterrupt:
            result.interrupted = True
            if progress:
                print(f"\nrealistic: interrupted: finishing the {len(pending)} passes in flight, then writing what "
                      "is done (interrupt again to stop at once and keep nothing)", file=sys.stderr)
            for future in pending:
                if not future.cancel():
                    _add(film, result, future.result(), bar, start)
        finished = True
    finally:  # a second interrupt while passes finish leaves them running: the caller stops at once
        pool.shutdown(wait=finished, cancel_futures=not finished)
    if bar is not None:
        bar.close()
    result.image = film.image()
    result.seconds = time.perf_counter() - start
    result.stage_seconds = dict(clock.seconds)
    return result


def render(scene: Scene, camera: Camera | None = None, backend: str = "opencl", seed: int = 0, *,
           spp: int | None = None, **options) -> np.ndarray:
    """The film image (H, W, 3) float32: film irradiance per pixel in units of scene radiance.

    ``camera`` None renders through the scene's own camera (``Scene.camera``: a pbrt file's, or the
    framing of a loaded mesh); ``spp`` overrides the camera's samples per pixel. ``options`` are
    those of ``render_passes`` (``light_samples`` defaults to the scene's). A spectral camera
    renders through the colour matching functions to linear sRGB (``realistic.core.spectrum``);
    others render RGB directly.
    """
    camera = camera if camera is not None else scene.camera
    if camera is None:
        raise UserError("no camera: pass one, or load a scene that brings its own")
    if spp is not None:
        camera = dataclasses.replace(camera, spp=spp)
    options.setdefault("light_samples", scene.light_samples)
    return render_passes(scene, camera, backend, seed, **options).image


def _add(film: Film, result: RenderResult, done: _PassResult, bar, start: float) -> None:
    film.add(done.first_sample, done.count, done.first_pixel, done.sums)
    result.samples_done += done.count
    result.primary_rays += done.primary_rays
    result.shadow_rays += done.shadow_rays
    if bar is not None:
        rate = (result.primary_rays + result.shadow_rays) / max(time.perf_counter() - start, 1e-9)
        bar.set_postfix_str(f"{rate / 1e6:.2f} M rays/s", refresh=False)
        bar.update(1)


def _progress_bar(passes: int):
    from tqdm import tqdm

    return tqdm(total=passes, unit="pass", desc="render", leave=False, dynamic_ncols=True)
