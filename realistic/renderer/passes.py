"""Pass scheduling: ``render(job, executor)`` returns one film image with statistics per frame.

A render is every pixel's spp samples cut into passes of about ``pass_samples`` samples
(``pass_plan``: slices of each pixel's samples times runs of pixels), so memory stays flat as
resolution and spp grow; passes are numbered in progressive order, so an interrupted render is a
whole noisy frame. Passes run on an executor (``job.PassExecutor``): ``ThreadPasses``, worker threads
in this process, one per core (``thread_count.default_threads``: embree's queries, the kernels and
most numpy loops release the GIL, so one thread's ray generation overlaps another's intersection),
or ``farm.DaskPasses``, tasks of a few passes each on a Dask cluster's workers. The main thread adds
pass sums to the film in pass-index order (``film.PassFilm``), so the image is bit-identical
whatever ran where. Ctrl-C stops submitting passes, lets the passes in flight finish, and returns
what has accumulated (``RenderResult.interrupted``). With a checkpoint (``job.Checkpointing``) the
film is saved there every ``every_seconds``, on interrupt and when the passes are done (a save that
fails, on a full disk say, is reported and the render goes on), and ``resume`` continues from it;
``output.save`` removes it once the complete image is written, and a render without ``resume``
refuses to replace one.

A sequence (several cameras, e.g. ``--sweep``) streams: a frame's camera is prepared (its exit-pupil
table) and its film allocated when its first pass is submitted, its film is released once it is
complete and handed to ``observer.on_frame``, and with ``job.keep_images`` False its image is not
kept either, so a long sequence starts at once and holds a frame or two at a time.
"""

from __future__ import annotations

import queue
import sys
import threading
import time
import weakref
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from realistic.camera.base import Camera, SampleBlock
from realistic.core import affinity, validation
from realistic.errors import UserError
from realistic.renderer.aov import AovLayout, CameraFrame
from realistic.renderer.backends import backend_for
from realistic.renderer.checkpoint import RenderIdentity, load_checkpoint, refuse_unless_resuming, save_checkpoint
from realistic.renderer.crop import PixelBounds
from realistic.renderer.film import Film, PassFilm
from realistic.renderer.job import (
    PassExecutor,
    PassResult,
    PassSettings,
    RenderJob,
    RenderObserver,
    RenderResult,
    TaskHandle,
)
from realistic.renderer.memory import check_job_memory
from realistic.renderer.pass_plan import plan_passes
from realistic.renderer.runner import PassRunner, choose_loops, compile_pass_loops, repays_compiling
from realistic.renderer.starburst import starburst
from realistic.renderer.thread_count import default_threads
from realistic.renderer.timing import StageClock
from realistic.scene.embree import compile_trace_loops
from realistic.scene.intersect import Intersector
from realistic.scene.model import Scene

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["ThreadPasses", "render", "scene_intersector"]

#: The image of a result not (or no longer) held: a frame streamed away (``RenderJob.keep_images``).
_EMPTY = np.zeros((0, 0, 3), np.float32)
_EMPTY.flags.writeable = False


#: Per live Scene object (by id): its geometry's signature, the objects named there (held so that
#: their ids stay theirs), and the Intersector built for it. Entries go when their Scene does.
_intersectors: dict[int, tuple[tuple, list, Intersector]] = {}
_intersectors_lock = threading.Lock()


def _geometry_signature(scene: Scene) -> tuple[tuple, list]:
    """What an Intersector is built from, by identity: each instance, its transform and mesh, each
    mesh's arrays, each light; and those objects."""
    held: list = [*scene.instances, *scene.meshes, *scene.lights]
    held += [inst.transform for inst in scene.instances] + [array for mesh in scene.meshes
                                                           for array in (mesh.vertices, mesh.faces)]
    return (tuple(inst.mesh for inst in scene.instances), tuple(map(id, held))), held


def scene_intersector(scene: Scene) -> Intersector:
    """The embree scene of ``scene``, built by its first render and reused by every later render of
    the same Scene object, so that a re-render after ``camera.with_focus`` or ``with_stop``
    rebuilds no BVH. Kept beside the Scene (weakly: dropped with it), never on it, since a Scene
    pickles to farm workers. Rebuilt when an instance, mesh array or light was added, removed or
    replaced; arrays edited in place are not noticed (replace them instead)."""
    signature, held = _geometry_signature(scene)
    with _intersectors_lock:
        known = _intersectors.get(id(scene))
        if known is not None and known[0] == signature:
            return known[2]
        intersector = Intersector(scene)
        if known is None:
            weakref.finalize(scene, _intersectors.pop, id(scene), None)
        _intersectors[id(scene)] = (signature, held, intersector)
        return intersector


class ThreadPasses:
    """Passes on ``threads`` threads of this process (None: ``default_threads()``), one pass per task,
    one runner per frame (built as the frame starts), all sharing one embree scene: ``intersector`` when
    given (one already built for the scene of the jobs it runs, e.g. by autofocus), else the
    scene's own (``scene_intersector``: built once per Scene object, reused by later renders).
    ``pin_threads``: each worker on its own CPU (Linux, ``core.affinity``; threads this process did
    not create, such as the OpenCL runtime's, are left where the system puts them). ``open``
    refuses a job whose estimated peak memory exceeds ``job.max_memory_bytes``
    (``renderer.memory``). Reusable: one job at a time."""

    def __init__(self, threads: int | None = None, pin_threads: bool = False,
                 intersector: Intersector | None = None) -> None:
        if threads is not None:
            validation.threads(threads)
        self.threads = default_threads() if threads is None else threads
        self.pin_threads = pin_threads
        self.given_intersector = intersector
        self.capacity = self.threads
        self.passes_per_task = 1

    def open(self, job: RenderJob, clock: StageClock) -> None:
        frames = len(job.cameras)
        check_job_memory(job, self.threads, job.max_memory_bytes, frames, frames if job.keep_images else 0)
        self.job, self.clock = job, clock
        self.intersector = self.given_intersector
        self.runners: dict[int, PassRunner] = {}
        self.pool = ThreadPoolExecutor(max_workers=self.threads,
                                       initializer=affinity.worker_pinner() if self.pin_threads else None)
        self.finished: queue.SimpleQueue[Future] = queue.SimpleQueue()  # futures, as they finish
        # on the render threads while the exit-pupil table is made: the first camera's programs (PoCL
        # builds them without the GIL), the embree packet loops and the pass's own loops (numba, with
        # it); a loop's error recurs in the first pass, which reports it
        self.ahead = self.pool.submit(_build_ahead, job.settings, job.cameras[0], repays_compiling(job))
        if choose_loops(job):  # numba's, where the render repays compiling them
            self.pool.submit(compile_trace_loops)
            self.pool.submit(compile_pass_loops)

    def runner(self, frame: int) -> PassRunner:
        """Frame ``frame``'s runner, its camera prepared now. ``render`` submits frames in order, so
        the runners of earlier frames get no more tasks: they are dropped (tasks running keep theirs)."""
        if frame not in self.runners:
            camera = self.job.cameras[frame]
            with self.clock("exit pupil"):  # the lens's sampling tables (``Camera.prepare``)
                camera.prepare()
            with self.clock("setup"):  # ray generator, BVH build, shading tables
                self.intersector = self.intersector or scene_intersector(self.job.scene)
                self.runners = {frame: PassRunner(self.job.scene, camera, self.job.settings, self.clock,
                                                  self.intersector)}
                self.ahead.result()
        return self.runners[frame]

    def submit(self, frame: int, passes: list[tuple[int, SampleBlock]]) -> Future:
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
        self.runners = {}


def _build_ahead(settings: PassSettings, camera: Camera, time_choices: bool) -> None:
    """The programs ``camera``'s ray generator will use, built (``Backend.build_ahead``), choices
    timed where the render repays it."""
    backend_for(settings.backend, settings.cl_device).build_ahead(camera, time_choices)


@dataclass
class _Frame:
    """One image of a job: its plan, statistics, and its film from its first pass until it is
    finished (``_finish``)."""

    camera: Camera
    plan: list[SampleBlock]
    result: RenderResult
    layout: AovLayout
    crop: PixelBounds | None = None
    film: PassFilm | None = None
    flare: bool = False  # the film holds lens flare (``RenderJob.flare``)
    starburst: bool = False  # the finished image gets the stop's starburst (``RenderJob.starburst``)

    @property
    def complete(self) -> bool:
        return self.result.passes_done == len(self.plan)

    def started(self) -> PassFilm:
        """The film, allocated on first use."""
        if self.film is None:
            self.film = PassFilm(Film(self.camera.width, self.camera.height, self.camera.spp, bounds=self.crop,
                                      columns=self.layout.columns, flare=self.flare), self.plan)
        return self.film


def render(job: RenderJob, executor: PassExecutor | None = None,
           observer: RenderObserver | None = None) -> list[RenderResult]:
    """Render every frame of ``job`` on ``executor`` (None: ``ThreadPasses()``, one thread per core,
    unpinned); one result per camera, in order. ``observer`` is told of passes, frames and previews.

    A first KeyboardInterrupt finishes the passes in flight and returns what has accumulated
    (``RenderResult.interrupted``); a second one while they finish propagates at once. A job with a
    checkpoint saves it every ``every_seconds``, on interrupt and at the end, starts from it when ``resume``
    (without it, an existing checkpoint is refused rather than replaced), and leaves it for
    ``output.save`` to remove once the complete image is written.
    """
    if job.checkpoint is not None and not job.checkpoint.resume:
        refuse_unless_resuming(job.checkpoint.path)
    executor = executor if executor is not None else ThreadPasses()
    observer = observer if observer is not None else RenderObserver()
    start = time.perf_counter()
    clock = StageClock()
    executor.open(job, clock)  # refuses what will not fit before any work
    finished = False
    try:
        with clock("exit pupil"):  # the first frame's lens tables, as set-up: an interrupt here writes nothing
            job.cameras[0].prepare()  # (later frames' as they start: ``ThreadPasses.runner``, ``farm._runner``)
        frames, interrupted = _run(job, executor, observer, clock, start)
        finished = True
    finally:
        executor.close(finished)
    results = []
    for frame in frames:
        frame.result.interrupted = interrupted or not frame.complete
        results.append(_finish(frame, start, clock, job.keep_images))
    return results


def _frames(job: RenderJob) -> tuple[list[_Frame], RenderIdentity | None]:
    """Each camera's plan and result (the first one's film from its checkpoint when resuming), and
    the identity its checkpoint carries. Cameras are prepared as their frames start (``ThreadPasses.
    runner``, ``farm._runner``), not here: a long sweep would build every exit-pupil table first."""
    plans: dict[tuple[int, int, int], list[SampleBlock]] = {}  # the frames of a sweep share one plan
    frames = []
    for index, camera in enumerate(job.cameras):
        key = (camera.width, camera.height, camera.spp)
        if key not in plans:
            plans[key] = plan_passes(camera.width * camera.height, camera.spp, job.pass_size)
            if job.crop is not None:
                plans[key] = job.crop.passes(plans[key], camera.width)
        plan = plans[key]
        samples = job.crop.width * job.crop.height * camera.spp if job.crop is not None else camera.sample_count
        result = RenderResult(_EMPTY, 0, samples, 0, 0, 0.0, False, passes_total=len(plan), job=job, frame=index)
        frames.append(_Frame(camera, plan, result, AovLayout(job.settings.aovs), job.crop, flare=job.flare,
                             starburst=job.starburst))
    if job.checkpoint is None:
        return frames, None
    identity = RenderIdentity.of(job.scene, job.cameras[0], job.seed, job.pass_size, job.backend,
                                 job.settings.light_samples, job.crop, job.settings.aovs, job.settings.flare_threshold)
    frame = frames[0]
    if job.checkpoint.resume:
        frame.film = load_checkpoint(job.checkpoint.path, identity, frame.plan, crop=job.crop,
                                     columns=frame.layout.columns, flare=job.flare)
        frame.result.samples_done = sum(_samples_of(job, frame.plan[i], frame.camera)
                                        for i in range(frame.film.next_pass)) \
            + sum(_samples_of(job, frame.plan[i], frame.camera) for i in frame.film.waiting)
        frame.result.passes_done = frame.film.passes_taken
    frame.started()  # saved on interrupt even before its first pass
    return frames, identity


def _samples_of(job: RenderJob, block: SampleBlock, camera: Camera) -> int:
    """The samples a pass takes: all of its block's, or in a crop those of the crop's pixels."""
    return block.count if job.crop is None else job.crop.samples_in(block, camera.width)


def _tasks(frames: list[_Frame], passes_per_task: int) -> Iterator[tuple[int, list[int]]]:
    """(frame, plan indices) of every task still to run, frame by frame, made as they are taken."""
    for index, frame in enumerate(frames):
        todo = [i for i in range(len(frame.plan)) if frame.film is None or not frame.film.has(i)]
        for lo in range(0, len(todo), passes_per_task):
            yield index, todo[lo:lo + passes_per_task]


def _run(job: RenderJob, executor: PassExecutor, observer: RenderObserver, clock: StageClock,
         start: float) -> tuple[list[_Frame], bool]:
    """The frames with every pass the executor ran added, and whether an interrupt stopped them."""
    frames, identity = _frames(job)
    checkpoint = job.checkpoint
    tasks = _tasks(frames, executor.passes_per_task)
    bar = _progress_bar(sum(f.result.passes_total for f in frames), sum(f.result.passes_done for f in frames)) \
        if observer.progress else None
    state = {"checkpoint": time.monotonic(), "preview": time.monotonic()}
    failing = {"checkpoint": False}  # a failing checkpoint is reported once, until a save succeeds

    def save(path: Path, identity: RenderIdentity) -> None:
        frame = frames[0]
        if frame.film is None and frame.complete:
            return  # saved as it completed, before its film was released
        try:
            save_checkpoint(path, identity, frame.started())
        except UserError as err:
            if not failing["checkpoint"]:
                print(f"realistic: warning: checkpoint not saved ({err}); rendering on", file=sys.stderr)
            failing["checkpoint"] = True
        else:
            failing["checkpoint"] = False

    def take(index: int, results: list[PassResult]) -> None:
        frame = frames[index]
        film = frame.film
        if film is None:
            return  # a retried task's duplicate of a frame already finished
        for done in results:
            if film.has(done.index):
                continue  # a retried task's duplicate
            film.add(done.index, done.first_pixel, done.sums, done.flare)
            frame.result.samples_done += done.count
            frame.result.primary_rays += done.primary_rays
            frame.result.shadow_rays += done.shadow_rays
            frame.result.passes_done += 1
            if bar is not None:
                samples = sum(f.result.samples_done for f in frames)
                bar.set_postfix_str(f"{samples / max(time.perf_counter() - start, 1e-9) / 1e6:.2f} M samples/s",
                                    refresh=False)
                bar.update(1)
        if observer.on_pass is not None:
            observer.on_pass(frame.result)
        if frame.complete and frame.film is not None:
            if checkpoint is not None and identity is not None:
                save(checkpoint.path, identity)  # it stays until ``output.save`` has written the image
            finished = _finish(frame, start, clock, True)  # the film released
            if observer.on_frame is not None:
                observer.on_frame(finished)
            if not job.keep_images:
                finished.image, finished.aovs = _EMPTY, {}

    def periodic() -> None:
        now = time.monotonic()
        if checkpoint is not None and identity is not None and checkpoint.every_seconds is not None \
                and now - state["checkpoint"] >= checkpoint.every_seconds:
            save(checkpoint.path, identity)
            state["checkpoint"] = now
        if observer.preview is not None and observer.preview_every is not None \
                and now - state["preview"] >= observer.preview_every:
            frame = frames[_current(frames)]  # its film, or once finished its image (empty if not kept)
            image = frame.film.image() if frame.film is not None else frame.result.image
            if image.size:
                observer.preview(image)
            state["preview"] = now

    pending: dict[TaskHandle, int] = {}  # task -> frame
    in_flight: dict[TaskHandle, int] = {}  # task -> passes it holds
    interrupted = False
    try:
        while True:
            while len(pending) < executor.capacity and (next_task := next(tasks, None)) is not None:
                index, chunk = next_task
                frames[index].started()
                plan = frames[index].plan
                task = executor.submit(index, [(i, plan[i]) for i in chunk])
                pending[task], in_flight[task] = index, len(chunk)
            if not pending:
                break
            for task in executor.wait_first(set(pending)):
                in_flight.pop(task)
                take(pending.pop(task), task.result())
            periodic()
    except KeyboardInterrupt:
        interrupted = True
        if observer.progress:
            print(f"\nrealistic: interrupted: finishing the {sum(in_flight.values())} passes in flight, then "
                  "writing what is done (interrupt again to stop at once and write no image)", file=sys.stderr)
        for index, results in executor.finish_in_flight(pending):
            take(index, results)
    if checkpoint is not None and identity is not None:
        save(checkpoint.path, identity)  # an unfinished film (a finished one was saved as it completed)
    if bar is not None:
        bar.close()
    return frames, interrupted


def _current(frames: list[_Frame]) -> int:
    """The first frame not yet complete (the last one when all are)."""
    return next((i for i, frame in enumerate(frames) if not frame.complete), len(frames) - 1)


def _finish(frame: _Frame, start: float, clock: StageClock, keep_images: bool) -> RenderResult:
    """The frame's result with its image and times; a complete frame's film is released. A frame
    never started gets a black image when ``keep_images`` (else it stays empty)."""
    result = frame.result
    bounds = frame.crop or PixelBounds.whole(frame.camera.width, frame.camera.height)
    if frame.film is not None:
        result.image = frame.film.image()
        if frame.starburst:  # on the image only: the film (and a checkpoint) keeps the raw sums
            result.image = starburst(result.image, frame.camera)
        aovs = frame.layout.images(frame.film.sums(), frame.camera.width, frame.camera.height,
                                   CameraFrame.of(frame.camera.world_from_camera))
        result.aovs = {name: image[bounds.y0:bounds.y1, bounds.x0:bounds.x1] for name, image in aovs.items()}
        if frame.complete:
            frame.film = None
    elif result.image is _EMPTY and keep_images and not frame.complete:
        result.image = np.zeros((bounds.height, bounds.width, 3), np.float32)
    result.seconds = time.perf_counter() - start
    result.stage_seconds = dict(clock.seconds)
    result.stage_cpu_seconds = dict(clock.cpu_seconds)
    return result


def _progress_bar(passes: int, done: int) -> tqdm:
    from tqdm import tqdm  # imported by renders that show a bar only

    return tqdm(total=passes, initial=done, unit="pass", desc="render", leave=False, dynamic_ncols=True)
