"""A render job (what to render, as data) and the executor protocol that runs its passes.

``RenderJob`` holds everything a render needs that is data: the scene, one camera per frame, the
backend and OpenCL device by name, seed, light samples, pass size, Morton order, the memory limit,
checkpointing, the sweep that made the frames, and the crop. What happens while it runs (progress, previews,
callbacks) is a ``RenderObserver``; where its passes run is a ``PassExecutor``
(``passes.ThreadPasses`` in this process, ``farm.DaskPasses`` on a Dask cluster). ``passes.render``
runs a job on an executor and returns one ``RenderResult`` per frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from realistic.camera.base import Camera, SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.ghosts import DEFAULT_THRESHOLD
from realistic.renderer.crop import PixelBounds
from realistic.renderer.film import Splats
from realistic.renderer.pass_plan import default_pass_samples
from realistic.renderer.starburst import STARBURST_NEEDS_LENS
from realistic.renderer.timing import StageClock
from realistic.scene.model import Scene


@dataclass(frozen=True)
class PassSettings:
    """What a runner needs of a render job besides the scene and camera (``RenderJob.settings``)."""

    backend: str = "opencl"
    cl_device: str | None = None
    seed: int = 0
    light_samples: int = 1
    morton: bool = False
    crop: PixelBounds | None = None  # trace only these pixels' rays (None: all)
    aovs: tuple[str, ...] = ()  # ``renderer.aov`` names, in ``validation.AOV_NAMES`` order
    flare_threshold: float | None = None  # lens flare through the ghosts this bright (``renderer.flare``); None: none


@dataclass(frozen=True)
class PassResult:
    """One pass's per-pixel sums (``film.pass_sums``: the radiance's 3 columns, then the AOVs'
    (``aov.AovLayout``)), its lens flare (``film.Splats``, when the job renders flare) and ray
    counts; ``index`` is its plan index."""

    index: int
    first_pixel: int
    sums: np.ndarray
    count: int
    primary_rays: int
    shadow_rays: int
    flare: Splats | None = None


@dataclass(frozen=True)
class Checkpointing:
    """Where and how often a single-image render saves its film, and whether it starts from there."""

    path: Path
    every_seconds: float | None = 60.0  # None: only on interrupt
    resume: bool = False


@dataclass(frozen=True)
class RenderJob:
    """One render: an image per camera, as one job (on a farm every frame's passes are in one graph,
    so workers stay busy across frame boundaries). Checked as it is made (one-line UserErrors)."""

    scene: Scene
    cameras: tuple[Camera, ...]
    backend: str = "opencl"  # "opencl" or "numpy": kernels or their numpy references
    seed: int = 0
    cl_device: str | None = None  # the OpenCL device by name (None: the first)
    light_samples: int | None = None  # light samples per hit (None: the scene's)
    pass_samples: int | None = None  # sample ids per pass (None: about 2^19 rays' worth)
    morton: bool = False  # shade each pass's rays in Z order over the film
    max_memory_bytes: int | None = None  # refuse a render estimated above this (None: what is available)
    checkpoint: Checkpointing | None = None  # single images only
    sweep: str | None = None  # the sweep that made the cameras, as the image header names it
    # False: a complete frame's image is dropped once ``RenderObserver.on_frame`` has had it (its
    # result comes back with a 0x0 image), so a long sequence holds no finished frames
    keep_images: bool = True
    # only these pixels of each frame (``crop.PixelBounds``; None: all): the image holds them alone
    crop: PixelBounds | None = None
    # first-hit outputs written beside the image (``renderer.aov``): names or "depth,normal"
    aovs: tuple[str, ...] | str = ()
    # lens flare: light traced from the lights through the lens's ghost paths (``renderer.flare``),
    # those whose on-axis throughput is at least ``flare_threshold`` (``optics.ghosts.ghost_paths``)
    flare: bool = False
    flare_threshold: float = DEFAULT_THRESHOLD
    # the stop's diffraction starburst around each finished image's brightest pixels (``renderer.starburst``)
    starburst: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "cameras", tuple(self.cameras))
        object.__setattr__(self, "aovs", validation.aovs(self.aovs))
        if not self.cameras:
            raise UserError("nothing to render: no cameras")
        validation.seed(self.seed)
        if self.light_samples is not None:
            validation.light_samples(self.light_samples)
        if self.pass_samples is not None:
            validation.pass_samples(self.pass_samples)
        if self.crop is not None:
            for camera in self.cameras:
                self.crop.within(camera.width, camera.height)
        if self.checkpoint is not None and len(self.cameras) != 1:
            raise UserError("checkpoints are for single images, not sequences")
        validation.ghost_threshold(self.flare_threshold)
        if self.flare and not all(isinstance(camera, LensCamera) for camera in self.cameras):
            raise UserError("--flare on needs a real lens (--lens): a thin-lens or perspective camera has no ghosts")
        if self.starburst and not all(isinstance(camera, LensCamera) for camera in self.cameras):
            raise UserError(STARBURST_NEEDS_LENS)

    @property
    def settings(self) -> PassSettings:
        """What each pass runner needs besides the scene and camera."""
        light_samples = self.scene.light_samples if self.light_samples is None else self.light_samples
        return PassSettings(self.backend, self.cl_device, self.seed, light_samples, self.morton, self.crop,
                            validation.aovs(self.aovs), self.flare_threshold if self.flare else None)

    @property
    def pass_size(self) -> int:
        """Sample ids per pass: ``pass_samples``, else ``pass_plan.default_pass_samples``."""
        if self.pass_samples is not None:
            return self.pass_samples
        return default_pass_samples(self.cameras[0].rays_per_sample, self.settings.light_samples)


@dataclass
class RenderResult:
    """The film image and how it was made: frame ``frame`` of ``job``."""

    image: np.ndarray  # (H, W, 3) float32 film irradiance
    samples_done: int
    samples_total: int
    primary_rays: int  # camera rays that left the lens (traced by embree)
    shadow_rays: int
    seconds: float
    interrupted: bool
    stage_seconds: dict[str, float] = field(default_factory=dict)
    stage_cpu_seconds: dict[str, float] = field(default_factory=dict)  # the stages' threads' own CPU time
    passes_done: int = 0
    passes_total: int = 0
    job: RenderJob | None = None
    frame: int = 0
    # the AOVs' EXR channels (``aov.AovLayout.images``): name -> (H, W) float32
    aovs: dict[str, np.ndarray] = field(default_factory=dict)
    # the film image when ``image`` holds its denoised version (``renderer.denoise``), else None
    noisy: np.ndarray | None = None

    def __repr__(self) -> str:
        """One line, no arrays."""
        done = ("complete" if self.samples_done == self.samples_total
                else f"{self.samples_done} of {self.samples_total} samples")
        return (f"RenderResult(frame {self.frame}, {self.image.shape[1]}x{self.image.shape[0]}, {done}, "
                f"{self.seconds:.3g} s{', interrupted' if self.interrupted else ''})")

    @property
    def camera(self) -> Camera:
        """The camera this frame was rendered through."""
        if self.job is None:
            raise UserError("this result carries no render job: it does not say how it was made")
        return self.job.cameras[self.frame]


@dataclass(frozen=True)
class RenderObserver:
    """What a run reports as it goes: ``on_pass(result)`` after each task's passes are added,
    ``on_frame(result)`` as a frame completes, ``preview(image)`` every ``preview_every`` seconds
    (the first frame not yet complete), and a progress bar on stderr when ``progress``."""

    on_pass: Callable[[RenderResult], None] | None = None
    on_frame: Callable[[RenderResult], None] | None = None
    preview: Callable[[np.ndarray], None] | None = None
    preview_every: float | None = None
    progress: bool = False


class TaskHandle(Protocol):
    """A submitted task (a ``concurrent.futures`` or Dask future): hashable, with its result."""

    def __hash__(self) -> int: ...

    def result(self) -> list[PassResult]: ...


class PassExecutor(Protocol):
    """Where a job's passes run.

    ``passes.render`` calls ``open(job, clock)`` once, then submits tasks, at most ``capacity`` in
    flight: a task is some consecutive passes of one frame (at most ``passes_per_task``), given as
    (plan index, ``SampleBlock``) pairs, and its result is one ``PassResult`` (per-pixel sums and ray
    counts) per pass. An executor may run tasks in any order, on any worker, and more than once
    (a retry after a worker died): each pass depends only on its sample ids and the job
    (``core.rng``), and ``render`` adds each pass's sums once, in plan order, in float64
    (``film.PassFilm``), so the image is bit-identical whatever the executor, worker count, order
    or retries. ``close(finished)`` is called once, also after an error or interrupt
    (``finished`` False: stop at once, keep nothing running).
    """

    capacity: int  # tasks in flight at once (valid after open)
    passes_per_task: int  # passes a task holds at most (valid after open)

    def open(self, job: RenderJob, clock: StageClock) -> None:
        """Get ready to run ``job``'s passes (refuse, as a UserError, what cannot run here);
        ``clock`` gathers the stage times of passes run in this process."""

    def submit(self, frame: int, passes: list[tuple[int, SampleBlock]]) -> TaskHandle:
        """Start a task: these passes of frame ``frame`` (index into ``job.cameras``)."""

    def wait_first(self, pending: set[TaskHandle]) -> set[TaskHandle]:
        """Wait until at least one of ``pending`` is done; those done."""

    def finish_in_flight(self, pending: dict[TaskHandle, int]) -> list[tuple[int, list[PassResult]]]:
        """After an interrupt: (frame, results) of the tasks of ``pending`` (task -> frame) that run on;
        those not started may be dropped."""

    def close(self, finished: bool) -> None:
        """Release what ``open`` took (threads, pinning, the scene on the cluster)."""
