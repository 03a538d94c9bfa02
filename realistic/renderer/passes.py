"""Pass scheduling: ``render(scene, camera, ...)`` returns the film image as an array.

A render is every pixel's spp samples cut into passes of about ``pass_samples`` samples
(``pass_plan``: slices of each pixel's samples times runs of pixels), so memory stays flat as
resolution and spp grow; passes are numbered in progressive order, so an interrupted render is a
whole noisy frame. Passes run on worker threads in this process, one per core
(``thread_count.default_threads``: embree's queries, the kernels and most numpy loops release the
GIL, so one thread's ray generation overlaps another's intersection), or, given a Dask ``client``,
as tasks of a few passes each on its workers (``farm``). The main thread adds pass sums to the film
in pass-index order (``film.PassFilm``), so the image is bit-identical whatever ran where. Ctrl-C
stops submitting passes, lets the passes in flight finish, and returns what has accumulated
(``RenderResult.interrupted``). With a ``checkpoint`` path the film is saved there every
``checkpoint_every`` seconds and on interrupt, and ``resume`` continues from it (``checkpoint``).
"""

from __future__ import annotations

import dataclasses
import queue
import sys
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera, SampleBlock
from realistic.core import affinity, validation
from realistic.core.spectrum import rgb_response
from realistic.errors import UserError
from realistic.renderer.checkpoint import RenderIdentity, load_checkpoint, save_checkpoint
from realistic.renderer.film import Film, PassFilm, pass_sums
from realistic.renderer.integrators import make_integrator
from realistic.renderer.memory import check_memory
from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES, default_pass_samples, plan_passes
from realistic.renderer.thread_count import default_threads
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Intersector
from realistic.scene.model import Scene

__all__ = ["DEFAULT_PASS_SAMPLES", "RenderResult", "default_pass_samples", "default_threads", "render", "render_frames",
           "render_passes"]


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
    passes_done: int = 0
    passes_total: int = 0


@dataclass(frozen=True)
class PassResult:
    """One pass's per-pixel sums (``film.pass_sums``) and ray counts; ``index`` is its plan index."""

    index: int
    first_pixel: int
    sums: np.ndarray
    count: int
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


def gather_rows(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """points[rows] as a contiguous (len(rows), 3) float32 array. The kernel's rays are transposed
    views of its (rows, n) output: gathering from each coordinate's contiguous row straight into the
    result's column takes 0.9 ms per 97k rays, ``np.take`` along the strided axis 1.4-1.6 ms."""
    if points.strides[0] < points.strides[1] and points.dtype == np.float32:  # coordinates are contiguous rows
        gathered = np.empty((len(rows), points.shape[1]), np.float32)
        for column in range(points.shape[1]):
            np.take(points[:, column], rows, out=gathered[:, column])
        return gathered
    return np.take(points, rows, axis=0).astype(np.float32, copy=False)


class PassRunner:
    """Runs passes of sample ids: rays, hits, shading, per-pixel sums. Built once per camera (and
    per worker process on a farm); ``intersector`` shares one scene's embree BVH between cameras."""

    def __init__(self, scene: Scene, camera: Camera, backend: str, seed: int, cl_device: str | None,
                 light_samples: int, morton: bool, clock: StageClock, intersector: Intersector | None = None):
        self.camera, self.morton, self.clock = camera, morton, clock
        self.generate = camera.ray_generator(backend, seed, cl_device)
        self.integrator = make_integrator(scene, intersector or Intersector(scene), light_samples, seed,
                                          camera.pixel_spread_radians(), backend=backend, cl_device=cl_device)

    def run(self, passes: list[tuple[int, SampleBlock]]) -> list[PassResult]:
        """The results of passes given as (plan index, sample block)."""
        return [self(index, block) for index, block in passes]

    def __call__(self, index: int, block: SampleBlock) -> PassResult:
        with self.clock("ray generation"):
            rays = self.generate(block)
        with self.clock("shading"):
            # a spectral camera's K rays per sample (its wavelengths) come consecutively, sample-major
            rays_per_sample, rest = divmod(len(rays.weight), block.count)
            if rest or not rays_per_sample:
                raise RuntimeError(f"{len(rays.weight)} camera rays for {block.count} samples")
            sample = block.sample_ids()
            if rays_per_sample > 1:  # the K rays share the sample id, so the integrator's light samples
                sample = np.repeat(sample, rays_per_sample)
            alive = np.flatnonzero(rays.weight != 0)  # a negative filter lobe gives negative weights
            if self.morton:
                alive = alive[morton_order(rays.pixel[alive], self.camera.width)]
            pixel = rays.pixel[alive]
            origin, direction = gather_rows(rays.origin, alive), gather_rows(rays.direction, alive)
            wavelength = None if rays.wavelength_nm is None else rays.wavelength_nm[alive]
        radiance, shadow_rays = self.integrator.radiance(origin, direction, pixel, sample[alive],
                                                         self.clock, wavelength)
        with self.clock("accumulation"):
            first_pixel, pixel_count = block.first_pixel, block.pixel_count
            value = radiance  # the integrator's own array: weighted in place, no second (N, 3) array
            value *= rays.weight[alive, None].astype(np.float32, copy=False)
            if wavelength is not None:
                response = rgb_response(wavelength)
                if rays_per_sample > 1:  # each of a sample's K wavelengths is 1/K of its estimate
                    response /= np.float32(rays_per_sample)
                value *= response
            sums = pass_sums(pixel, value, first_pixel, pixel_count)
        return PassResult(index, first_pixel, sums, block.count, len(alive), shadow_rays)


class _ThreadPasses:
    """Passes on threads of this process, one pass per task, one runner per camera (built on first use).
    ``pin_threads``: each worker on its own CPU (``core.affinity``)."""

    def __init__(self, scene: Scene, cameras: list[Camera], settings: dict, threads: int, clock: StageClock,
                 pin_threads: bool = True):
        self.scene, self.cameras, self.settings, self.clock = scene, cameras, settings, clock
        self.runners: dict[int, PassRunner] = {}
        self.intersector: Intersector | None = None
        self.capacity = max(1, threads)
        self.passes_per_task = 1
        self.pool = ThreadPoolExecutor(max_workers=self.capacity,
                                       initializer=affinity.worker_pinner() if pin_threads else None)
        self.finished: queue.SimpleQueue = queue.SimpleQueue()  # futures, as they finish

    def runner(self, frame: int) -> PassRunner:
        if frame not in self.runners:
            with self.clock("setup"):  # ray generator, BVH build, shading tables
                self.intersector = self.intersector or Intersector(self.scene)
                self.runners[frame] = PassRunner(self.scene, self.cameras[frame], clock=self.clock,
                                                 intersector=self.intersector, **self.settings)
        return self.runners[frame]

    def submit(self, frame: int, passes: list[tuple[int, SampleBlock]]):
        future = self.pool.submit(self.runner(frame).run, passes)
        future.add_done_callback(self.finished.put)
        return future

    def wait_first(self, pending: set) -> set:
        """The tasks finished since the last call (at least one), waited for in ``SimpleQueue.get``.

        Not ``concurrent.futures.wait``: a Ctrl-C (KeyboardInterrupt) landing in its Event.wait can
        leave the waiter's lock held by this thread (a ``with`` interrupted between acquire and its
        body), and the workers then block for ever in ``set_result`` while the render waits to
        finish the passes in flight (seen as a hung SIGTERM test; py-spy showed both workers in
        ``_FirstCompletedWaiter.add_result``). SimpleQueue's get holds no Python lock when a signal
        interrupts it, and its put never blocks."""
        done = {self.finished.get()}
        while not self.finished.empty():
            done.add(self.finished.get())
        return done & pending

    def finish_in_flight(self, pending: dict) -> list[tuple[int, list[PassResult]]]:
        """(frame, results) of the tasks already running (``pending``: future -> frame); those not
        started are cancelled."""
        return [(frame, future.result()) for future, frame in pending.items() if not future.cancel()]

    def close(self, finished: bool) -> None:
        # a second interrupt while passes finish leaves them running: the caller stops at once
        self.pool.shutdown(wait=finished, cancel_futures=not finished)


@dataclass
class _Frame:
    """One image of a job: its plan, film and statistics."""

    camera: Camera
    plan: list[SampleBlock]
    film: PassFilm
    result: RenderResult

    @property
    def complete(self) -> bool:
        return self.film.next_pass == len(self.plan)


@dataclass
class Checkpointing:
    """Where and how often a single-image render saves its film, and whether it starts from there."""

    path: Path
    every_seconds: float | None = 60.0  # None: only on interrupt
    resume: bool = False


def render_frames(scene: Scene, cameras: list[Camera], backend: str = "opencl", seed: int = 0,
                  cl_device: str | None = None, light_samples: int = 1, *,
                  pass_samples: int | None = None, threads: int | None = None, morton: bool = False,
                  progress: bool = False, on_pass: Callable[[RenderResult], None] | None = None,
                  on_frame: Callable[[int, RenderResult], None] | None = None,
                  max_memory_bytes: int | None = None, client=None, task_samples: int | None = None,
                  checkpoint: Checkpointing | None = None,
                  preview: Callable[[np.ndarray], None] | None = None,
                  preview_every: float | None = None, pin_threads: bool = False) -> list[RenderResult]:
    """Render one image per camera as one job (on a farm every frame's passes are in one graph, so
    workers stay busy across frame boundaries); ``on_frame(i, result)`` is called as frame i
    completes. Other options as ``render_passes``; ``checkpoint`` needs exactly one camera."""
    validation.seed(seed)
    if not cameras:
        raise UserError("nothing to render: no cameras")
    if pass_samples is None:
        pass_samples = default_pass_samples(cameras[0].rays_per_sample, light_samples)
    validation.pass_samples(pass_samples)
    if checkpoint is not None and len(cameras) != 1:
        raise UserError("checkpoints are for single images, not sequences")
    if threads is None:
        threads = default_threads()
    if client is None:
        for camera in cameras:
            check_memory(scene, camera, pass_samples, threads, max_memory_bytes)
    start = time.perf_counter()
    clock = StageClock()
    with clock("exit pupil"):  # the lens's sampling tables (``Camera.prepare``)
        for camera in cameras:
            camera.prepare()
    frames = []
    for camera in cameras:
        plan = plan_passes(camera.width * camera.height, camera.spp, pass_samples)
        result = RenderResult(np.zeros((camera.height, camera.width, 3), np.float32), 0, camera.sample_count,
                              0, 0, 0.0, False, passes_total=len(plan))
        frames.append(_Frame(camera, plan, PassFilm(Film(camera.width, camera.height, camera.spp), plan), result))
    identity = None
    if checkpoint is not None:
        identity = RenderIdentity.of(scene, cameras[0], seed, pass_samples, backend, light_samples)
        if checkpoint.resume:
            frame = frames[0]
            frame.film = load_checkpoint(checkpoint.path, identity, frame.plan)
            frame.result.samples_done = int(frame.film.film.samples.sum())
            frame.result.passes_done = frame.film.passes_taken
    settings = {"backend": backend, "seed": seed, "cl_device": cl_device, "light_samples": light_samples,
                "morton": morton}
    if client is None:
        executor = _ThreadPasses(scene, cameras, settings, threads, clock, pin_threads)
    else:
        from realistic.renderer.farm import DaskPasses  # imports dask: only for farm renders

        executor = DaskPasses(client, scene, cameras, settings, pass_samples, task_samples)
    tasks = deque()
    for index, frame in enumerate(frames):
        todo = [i for i in range(len(frame.plan)) if not frame.film.has(i)]
        for lo in range(0, len(todo), executor.passes_per_task):
            tasks.append((index, todo[lo:lo + executor.passes_per_task]))
    bar = _progress_bar(sum(f.result.passes_total for f in frames), sum(f.result.passes_done for f in frames)) \
        if progress else None
    state = {"checkpoint": time.monotonic(), "preview": time.monotonic()}

    def take(index: int, results: list[PassResult]) -> None:
        frame = frames[index]
        for done in results:
            if frame.film.has(done.index):
                continue  # a retried task's duplicate
            frame.film.add(done.index, done.first_pixel, done.sums)
            frame.result.samples_done += done.count
            frame.result.primary_rays += done.primary_rays
            frame.result.shadow_rays += done.shadow_rays
            frame.result.passes_done += 1
            if bar is not None:
                samples = sum(f.result.samples_done for f in frames)
                bar.set_postfix_str(f"{samples / max(time.perf_counter() - start, 1e-9) / 1e6:.2f} M samples/s",
                                    refresh=False)
                bar.update(1)
        if on_pass is not None:
            on_pass(frame.result)
        if frame.complete and on_frame is not None:
            on_frame(index, _finish(frame, start, clock))

    def periodic() -> None:
        now = time.monotonic()
        if checkpoint is not None and checkpoint.every_seconds is not None \
                and now - state["checkpoint"] >= checkpoint.every_seconds:
            save_checkpoint(checkpoint.path, identity, frames[0].film)
            state["checkpoint"] = now
        if preview is not None and preview_every is not None and now - state["preview"] >= preview_every:
            preview(frames[_current(frames)].film.image())
            state["preview"] = now

    pending: dict = {}  # future -> frame
    in_flight: dict = {}  # future -> passes it holds
    finished = False
    interrupted = False
    try:
        try:
            while tasks or pending:
                while tasks and len(pending) < executor.capacity:
                    index, chunk = tasks.popleft()
                    plan = frames[index].plan
                    future = executor.submit(index, [(i, plan[i]) for i in chunk])
                    pending[future], in_flight[future] = index, len(chunk)
                for future in executor.wait_first(set(pending)):
                    in_flight.pop(future)
                    take(pending.pop(future), future.result())
                periodic()
        except KeyboardInterrupt:
            interrupted = True
            if progress:
                print(f"\nrealistic: interrupted: finishing the {sum(in_flight.values())} passes in flight, then "
                      "writing what is done (interrupt again to stop at once and keep nothing)", file=sys.stderr)
            for index, results in executor.finish_in_flight(pending):
                take(index, results)
            if checkpoint is not None:
                save_checkpoint(checkpoint.path, identity, frames[0].film)
        finished = True
    finally:
        executor.close(finished)
    if bar is not None:
        bar.close()
    if checkpoint is not None and not interrupted and frames[0].complete:
        checkpoint.path.unlink(missing_ok=True)
    results = []
    for frame in frames:
        frame.result.interrupted = interrupted or not frame.complete
        results.append(_finish(frame, start, clock))
    return results


def _current(frames: list[_Frame]) -> int:
    """The first frame not yet complete (the last one when all are)."""
    return next((i for i, frame in enumerate(frames) if not frame.complete), len(frames) - 1)


def _finish(frame: _Frame, start: float, clock: StageClock) -> RenderResult:
    result = frame.result
    result.image = frame.film.image()
    result.seconds = time.perf_counter() - start
    result.stage_seconds = dict(clock.seconds)
    return result


def render_passes(scene: Scene, camera: Camera, backend: str = "opencl", seed: int = 0,
                  cl_device: str | None = None, light_samples: int = 1,
                  pass_samples: int | None = None, threads: int | None = None, morton: bool = False,
                  progress: bool = False, on_pass: Callable[[RenderResult], None] | None = None,
                  max_memory_bytes: int | None = None, *, client=None, task_samples: int | None = None,
                  checkpoint: Checkpointing | None = None, preview: Callable[[np.ndarray], None] | None = None,
                  preview_every: float | None = None, pin_threads: bool = False) -> RenderResult:
    """Render and return the image with statistics; ``on_pass`` is called after each pass is added.
    ``pass_samples`` None sizes passes by rays (``pass_plan.default_pass_samples``), ``threads``
    None runs ``default_threads()``; ``pin_threads`` keeps each render thread on one CPU (Linux;
    ``core.affinity``: without it the scheduler queued workers behind each other while a CPU idled).

    Before any work, a render whose estimated peak memory exceeds ``max_memory_bytes`` (None: what
    the system has available) is refused with a UserError (``realistic.renderer.memory``). A first
    KeyboardInterrupt finishes the passes in flight and returns what has accumulated
    (``RenderResult.interrupted``); a second one while they finish propagates at once. ``client``
    (a ``dask.distributed.Client``) runs the passes on its workers in tasks of about
    ``task_samples`` samples (``farm``); the image is bit-identical to a render on threads.
    ``checkpoint`` saves and resumes the film; ``preview(image)`` is called every ``preview_every`` s.
    """
    return render_frames(scene, [camera], backend, seed, cl_device, light_samples, pass_samples=pass_samples,
                         threads=threads, morton=morton, progress=progress, on_pass=on_pass,
                         max_memory_bytes=max_memory_bytes, client=client, task_samples=task_samples,
                         checkpoint=checkpoint, preview=preview, preview_every=preview_every,
                         pin_threads=pin_threads)[0]


def render(scene: Scene, camera: Camera | None = None, backend: str = "opencl", seed: int = 0, *,
           spp: int | None = None, client=None, **options) -> np.ndarray:
    """The film image (H, W, 3) float32: film irradiance per pixel in units of scene radiance.

    ``camera`` None renders through the scene's own camera (``Scene.camera``: a pbrt file's, or the
    framing of a loaded mesh); ``spp`` overrides the camera's samples per pixel; ``client`` (a
    ``dask.distributed.Client``) renders on its workers, bit-identically. ``options`` are those of
    ``render_passes`` (``light_samples`` defaults to the scene's). A spectral camera renders through
    the colour matching functions to linear sRGB (``realistic.core.spectrum``), each sample the mean
    of its ``wavelengths_per_sample`` rays; others render RGB directly.
    """
    camera = camera if camera is not None else scene.camera
    if camera is None:
        raise UserError("no camera: pass one, or load a scene that brings its own")
    if spp is not None:
        camera = dataclasses.replace(camera, spp=spp)
    options.setdefault("light_samples", scene.light_samples)
    return render_passes(scene, camera, backend, seed, client=client, **options).image


def _progress_bar(passes: int, done: int):
    from tqdm import tqdm

    return tqdm(total=passes, initial=done, unit="pass", desc="render", leave=False, dynamic_ncols=True)
