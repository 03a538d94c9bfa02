"""StageClock: a stage's wall seconds count waiting, its CPU seconds only what its thread ran, so
bench/render.py can tell slower traversal from a thread that waited for a core."""

from __future__ import annotations

import threading
import time

from realistic import load_scene
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.timing import StageClock


def _spin(seconds: float) -> None:
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def test_a_waiting_stage_costs_wall_time_but_no_cpu_time():
    clock = StageClock()
    with clock("embree"):
        time.sleep(0.2)
    assert clock.seconds["embree"] >= 0.2
    assert clock.cpu_seconds["embree"] < 0.05


def test_a_busy_stage_costs_its_cpu_time_and_other_threads_work_is_not_counted():
    clock = StageClock()
    stop = threading.Event()

    def other() -> None:  # runs beside the stage; its CPU time is not the stage thread's
        while not stop.is_set():
            _spin(0.001)

    beside = threading.Thread(target=other)
    beside.start()
    try:
        with clock("shading"):
            _spin(0.15)
    finally:
        stop.set()
        beside.join()
    assert 0.15 <= clock.cpu_seconds["shading"] < 0.2
    assert clock.seconds["shading"] >= clock.cpu_seconds["shading"]


def test_stages_sum_over_threads():
    clock = StageClock()

    def stage() -> None:
        with clock("embree"):
            _spin(0.05)

    workers = [threading.Thread(target=stage) for _ in range(3)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert 0.15 <= clock.cpu_seconds["embree"] < 0.2
    assert set(clock.cpu_seconds) == {"embree"}


def test_a_render_reports_each_stage_cpu_seconds_within_its_wall_seconds():
    scene = load_scene(resolution=(24, 16), spp=2, lens_sampling="rear", dispersion=False)
    result = render(RenderJob(scene, (scene.camera,), "numpy", seed=1), ThreadPasses(1))[0]
    assert result.stage_cpu_seconds["embree"] > 0
    for stage, cpu in result.stage_cpu_seconds.items():
        assert cpu <= result.stage_seconds[stage] + 1e-3, stage
