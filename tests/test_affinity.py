"""CPU placement of render threads (realistic.core.affinity): workers one per CPU, the OpenCL
runtime's pool spread while a render runs and restored after, and images unchanged by either."""

import json
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

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
    monkeypatch.setattr(affinity, "_runtime_threads", {threading.get_native_id()})
    refused = render(job, ThreadPasses(2, pin_threads=True))[0].image
    assert np.array_equal(refused, free)


def test_a_runtime_thread_that_has_ended_is_forgotten(monkeypatch):
    """An id that is no longer one of this process's threads is dropped rather than pinned (the
    system may have given it to another process)."""
    ended = max(affinity.native_threads()) + 10**6  # no thread of this process has it
    monkeypatch.setattr(affinity, "_runtime_threads", {ended})
    with affinity.runtime_threads_spread():
        pass
    assert affinity._runtime_threads == (set() if len(CPUS) >= 2 else {ended})


def test_python_threads_are_not_taken_for_the_runtimes():
    release = threading.Event()
    before = set(affinity._runtime_threads)
    started = []

    def start():
        thread = threading.Thread(target=release.wait)
        thread.start()
        started.append(thread)

    affinity.record_runtime_threads(start)
    release.set()
    started[0].join()
    assert affinity._runtime_threads == before


def test_without_a_way_to_pin_placement_is_left_alone(monkeypatch):
    monkeypatch.delattr(os, "sched_setaffinity", raising=False)
    assert affinity.allowed_cpus() == []
    assert affinity.worker_pinner() is None
    with affinity.runtime_threads_spread():
        pass  # nothing to do, nothing raised


_CHILD = """
import json, os
from realistic.device.opencl import Device
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.core import affinity
device = Device.for_spec().devices[0]
pool = sorted(affinity._runtime_threads)
before = {t: sorted(os.sched_getaffinity(t)) for t in pool}
with affinity.runtime_threads_spread():
    with affinity.runtime_threads_spread():
        inner = {t: sorted(os.sched_getaffinity(t)) for t in pool}
    outer = {t: sorted(os.sched_getaffinity(t)) for t in pool}
after = {t: sorted(os.sched_getaffinity(t)) for t in pool}
print(json.dumps({"units": device.max_compute_units, "platform": device.platform.name, "pool": pool,
                  "before": before, "inner": inner, "outer": outer, "after": after}))
"""


@needs_two_cpus
@pytest.mark.usefixtures("opencl_platform")
def test_pocl_pool_is_recorded_spread_and_restored():
    """In a fresh process, listing the devices starts PoCL's pool (one thread per compute unit): it
    is recorded, pinned one thread per CPU inside the spreading (which nests), and given back its
    CPU set after."""
    found = json.loads(run_fresh(_CHILD, timeout=300).stdout.strip().splitlines()[-1])
    if "Portable Computing Language" not in found["platform"]:
        pytest.skip(f"the pool checked here is PoCL's, not {found['platform']}'s")
    assert len(found["pool"]) == found["units"]
    round_robin = [[CPUS[k % len(CPUS)]] for k in range(len(found["pool"]))]
    for inside in (found["inner"], found["outer"]):
        assert [inside[str(tid)] for tid in found["pool"]] == round_robin
    assert found["after"] == found["before"]


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_pinning_leaves_the_image_bit_identical(backend, tiny):
    if backend == "opencl":
        pytest.importorskip("pyopencl")
    scene, camera = tiny
    job = RenderJob(scene, (camera,), backend, pass_samples=256)
    pinned = render(job, ThreadPasses(2, pin_threads=True))[0].image
    free = render(job, ThreadPasses(2, pin_threads=False))[0].image
    assert np.array_equal(pinned, free)
    assert pinned.max() > 0
