"""CPU placement of render threads (realistic.core.affinity): the render's own workers one per CPU
when asked (not by default from Python), threads the process did not create never moved, and
images unchanged."""

import json
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import realistic
from conftest import run_fresh
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.core import affinity
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.renderer.timing import StageClock
from realistic.scene.staging import default_setup

CPUS = affinity.allowed_cpus()
needs_two_cpus = pytest.mark.skipif(len(CPUS) < 2, reason="pinning needs a process allowed on two or more CPUs")


@pytest.fixture(scope="module")
def tiny():
    """The default scene through dgauss at 24x16, 4 spp."""
    setup = default_setup()
    return setup.scene, LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 24, 16, 4)


def _cpu_sets_of_pool(pool: ThreadPoolExecutor, threads: int) -> list[set[int]]:
    """Each pool thread's CPU set, asked from inside it (a barrier makes every thread take one task)."""
    barrier = threading.Barrier(threads)

    def report() -> set[int]:
        barrier.wait(timeout=30)
        return os.sched_getaffinity(0)

    return [future.result() for future in [pool.submit(report) for _ in range(threads)]]


@needs_two_cpus
def test_pool_threads_are_pinned_one_per_cpu():
    with ThreadPoolExecutor(max_workers=len(CPUS), initializer=affinity.worker_pinner()) as pool:
        sets = _cpu_sets_of_pool(pool, len(CPUS))
    assert sorted(sets, key=min) == [{cpu} for cpu in CPUS]


@needs_two_cpus
def test_more_workers_than_cpus_go_round_robin():
    threads = 2 * len(CPUS)
    with ThreadPoolExecutor(max_workers=threads, initializer=affinity.worker_pinner()) as pool:
        sets = _cpu_sets_of_pool(pool, threads)
    assert all(len(s) == 1 for s in sets)
    assert sorted(min(s) for s in sets) == sorted(CPUS * 2)


@needs_two_cpus
@pytest.mark.parametrize("pin", [True, False])
def test_render_workers_follow_pin_threads(pin, tiny):
    """The renderer's own pool (``ThreadPasses``) pins when asked, and leaves the process's CPU set when not."""
    scene, camera = tiny
    passes = ThreadPasses(len(CPUS), pin)
    passes.open(RenderJob(scene, (camera,), "numpy"), StageClock())
    try:
        sets = _cpu_sets_of_pool(passes.pool, len(CPUS))
    finally:
        passes.close(True)
    expected = [{cpu} for cpu in CPUS] if pin else [set(CPUS)] * len(CPUS)
    assert sorted(sets, key=min) == expected


@needs_two_cpus
def test_a_system_that_refuses_pinning_still_renders(monkeypatch, tiny):
    """Where setting a CPU set is forbidden (a sandbox), workers and the runtime's pool run unpinned:
    the render completes, with the same image."""
    def refuse(*_args):
        raise PermissionError("not permitted")

    scene, camera = tiny
    job = RenderJob(scene, (camera,), "numpy", pass_samples=256)
    free = render(job, ThreadPasses(2, pin_threads=False))[0].image
    monkeypatch.setattr(os, "sched_setaffinity", refuse)
    refused = render(job, ThreadPasses(2, pin_threads=True))[0].image
    assert np.array_equal(refused, free)


def test_without_a_way_to_pin_placement_is_left_alone(monkeypatch):
    monkeypatch.delattr(os, "sched_setaffinity", raising=False)
    assert affinity.allowed_cpus() == []
    assert affinity.worker_pinner() is None


def test_python_api_renders_leave_placement_to_the_system_by_default(thread_pools, tiny):
    scene, camera = tiny
    realistic.render(scene, camera, "numpy", threads=2, pass_samples=256)
    render(RenderJob(scene, (camera,), "numpy", pass_samples=256))
    assert [pin for _, pin in thread_pools] == [False, False]


_CHILD = """
import json, os, threading
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.renderer.job import RenderJob, RenderObserver
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.staging import default_setup

def cpu_sets(tids):
    found = {}
    for tid in tids:
        try:
            found[tid] = sorted(os.sched_getaffinity(tid))
        except OSError:  # ended meanwhile
            pass
    return found

setup = default_setup()
camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 24, 16, 4)
render(RenderJob(setup.scene, (camera,), "opencl", pass_samples=256), ThreadPasses(2))  # starts OpenCL's threads
foreign = sorted({int(t) for t in os.listdir("/proc/self/task")} - {t.native_id for t in threading.enumerate()})
before = cpu_sets(foreign)
during = []
render(RenderJob(setup.scene, (camera,), "opencl", pass_samples=128), ThreadPasses(2, pin_threads=True),
       RenderObserver(on_pass=lambda result: during.append(cpu_sets(foreign))))
print(json.dumps({"foreign": foreign, "before": before, "during": during}))
"""


@needs_two_cpus
@pytest.mark.usefixtures("opencl_platform")
def test_a_pinned_render_moves_no_thread_it_did_not_create():
    """In a fresh process, the threads Python did not start (the OpenCL runtime's pool among them)
    keep their CPU sets through a render that pins its own workers."""
    found = json.loads(run_fresh(_CHILD, timeout=300).stdout.strip().splitlines()[-1])
    assert found["during"]
    for seen in found["during"]:
        kept = seen.keys() & found["before"].keys()  # threads that lived through the render
        assert kept
        assert {tid: seen[tid] for tid in kept} == {tid: found["before"][tid] for tid in kept}


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_pinning_leaves_the_image_bit_identical(backend, tiny):
    if backend == "opencl":
        pytest.importorskip("pyopencl")
    scene, camera = tiny
    job = RenderJob(scene, (camera,), backend, pass_samples=256)
    pinned = render(job, ThreadPasses(2, pin_threads=True))[0].image
    free = render(job, ThreadPasses(2))[0].image
    assert np.array_equal(pinned, free)
    assert pinned.max() > 0
