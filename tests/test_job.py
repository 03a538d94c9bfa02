"""RenderJob is checked as it is made, and any executor keeping the PassExecutor protocol renders the same bits."""

import dataclasses

import numpy as np
import pytest

from realistic import load_scene
from realistic.camera.base import Camera, SampleBlock
from realistic.errors import UserError
from realistic.renderer.job import Checkpointing, PassExecutor, PassResult, RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.runner import PassRunner, morton_order
from realistic.renderer.timing import StageClock
from realistic.scene.model import Scene


def _scene() -> tuple[Scene, Camera]:
    scene = load_scene(resolution=(12, 10), spp=6, lens_sampling="rear", dispersion=False)
    return scene, scene.camera


class _Finished:
    """A task run as it was submitted: its results, each pass twice (a retry) and in reverse order."""

    def __init__(self, results: list[PassResult]) -> None:
        self.results = results[::-1] + results

    def result(self) -> list[PassResult]:
        return self.results


class NewestFirstWithRetries:
    """A PassExecutor that hands finished tasks back newest first, one at a time, with duplicates."""

    capacity = 3
    passes_per_task = 2

    def open(self, job: RenderJob, clock: StageClock) -> None:
        self.job, self.clock, self.runners, self.order = job, clock, {}, []

    def submit(self, frame: int, passes: list[tuple[int, SampleBlock]]) -> _Finished:
        if frame not in self.runners:
            self.runners[frame] = PassRunner(self.job.scene, self.job.cameras[frame], self.job.settings, self.clock)
        task = _Finished(self.runners[frame].run(passes))
        self.order.append(task)
        return task

    def wait_first(self, pending: set) -> set:
        return {next(task for task in reversed(self.order) if task in pending)}

    def finish_in_flight(self, pending: dict) -> list[tuple[int, list[PassResult]]]:
        return [(frame, task.result()) for task, frame in pending.items()]

    def close(self, finished: bool) -> None:
        self.runners = {}


class InterruptedAfterThirdTask(ThreadPasses):
    """ThreadPasses that interrupts the render (as Ctrl-C would) when it waits for its third task:
    a checkpoint holds the first tasks, for the resume tests."""

    def wait_first(self, pending: set) -> set:
        self.waited = getattr(self, "waited", 0) + 1
        if self.waited == 3:
            raise KeyboardInterrupt
        return super().wait_first(pending)


def test_any_executor_keeping_the_protocol_renders_the_same_bits():
    scene, camera = _scene()
    job = RenderJob(scene, (camera, dataclasses.replace(camera, spp=3)), "numpy", seed=4, pass_samples=17)
    executor: PassExecutor = NewestFirstWithRetries()
    odd = render(job, executor)
    threads = render(job, ThreadPasses(3))
    for a, b in zip(odd, threads, strict=True):
        assert a.image.max() > 0 and not a.interrupted and a.passes_done == a.passes_total
        np.testing.assert_array_equal(a.image, b.image)
        assert (a.samples_done, a.primary_rays, a.shadow_rays) == (b.samples_done, b.primary_rays, b.shadow_rays)


def test_a_job_is_checked_as_it_is_made(tmp_path):
    scene, camera = _scene()
    with pytest.raises(UserError, match="no cameras"):
        RenderJob(scene, ())
    with pytest.raises(UserError, match="single images"):
        RenderJob(scene, (camera, camera), checkpoint=Checkpointing(tmp_path / "x.partial"))
    with pytest.raises(UserError):
        RenderJob(scene, (camera,), seed=-1)
    with pytest.raises(UserError):
        RenderJob(scene, (camera,), pass_samples=0)
    with pytest.raises(UserError):
        ThreadPasses(0)
    scene.light_samples = 3
    assert RenderJob(scene, [camera]).settings.light_samples == 3  # None: the scene's
    assert RenderJob(scene, [camera], light_samples=2).settings.light_samples == 2
    assert RenderJob(scene, [camera]).cameras == (camera,)


def _element_morton_order(pixel: np.ndarray, width: int) -> np.ndarray:
    """The reference: each ray's Morton code (x and y's 16 low bits interleaved, x in the even
    bits), stably argsorted ray by ray."""
    def spread(v: np.ndarray) -> np.ndarray:
        bits = np.zeros(len(v), np.uint64)
        for b in range(16):
            bits |= ((v.astype(np.uint64) >> np.uint64(b)) & np.uint64(1)) << np.uint64(2 * b)
        return bits
    return np.argsort(spread(pixel % width) | (spread(pixel // width) << np.uint64(1)), kind="stable")


@pytest.mark.parametrize("layout", ["runs", "shuffled", "wide"])
def test_morton_order_is_the_stable_sort_of_every_rays_code(layout):
    """``morton_order`` sorts runs of equal pixels by one code each: the permutation is still the
    stable argsort of every ray's code, whether a pixel's rays are adjacent (a pass), scattered
    (runs of one pixel apart, kept in their order), or past 16 bits (codes that collide)."""
    rng = np.random.default_rng(7)
    width = 37
    pixel = np.repeat(rng.integers(0, width * 40, 300), rng.integers(1, 6, 300))
    if layout == "runs":
        pixel = np.sort(pixel)
    elif layout == "wide":
        width, pixel = 3, pixel * 70001
    for rays in (pixel, pixel[:1], pixel[:0]):
        assert np.array_equal(morton_order(rays, width), _element_morton_order(rays, width))
