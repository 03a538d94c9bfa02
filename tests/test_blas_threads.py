"""A render wakes no OpenBLAS pool thread (issue 35).

numpy's and scipy's OpenBLAS each start a pool of threads when imported; a matrix product large
enough (``(N, 3) @ (3, 3)`` from about 10^5 rows) hands work to the pool, whose threads then spin
for a while on the cores the render's own threads need (commit 83a4100 replaced two such ``@``).
A process of its own imports numpy and scipy first, waits until their pools' start-up spin is
over (the threads present then are OpenBLAS's), and counts those threads' CPU time over renders
whose passes carry a few hundred thousand escaping rays through an environment map's rotation.
``python -m realistic render`` then asks OpenBLAS for one thread, so that no pool starts at all.
"""

import os
import subprocess
import sys

import pytest

from conftest import fresh_process_env

#: The environment variables OpenBLAS takes its thread count from.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def run_unlimited(script: str, *args: str, **env: str) -> subprocess.CompletedProcess:
    """``script`` in a process of its own whose OpenBLAS may start its pools: none of
    ``BLAS_THREAD_VARIABLES`` is passed on but those in ``env`` (importing dask.distributed, as
    other tests do, sets OMP_NUM_THREADS and OPENBLAS_NUM_THREADS to 1 in this process: its
    "pre-spawn-environ")."""
    base = {key: value for key, value in fresh_process_env().items() if key not in BLAS_THREAD_VARIABLES}
    run = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, timeout=600,
                         env={**base, **env})
    assert run.returncode == 0, run.stderr[-2000:]
    return run

SCRIPT = r"""
import os, sys, time

import numpy as np
import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS and its pool)


def pool_ticks(threads):
    '''User and system clock ticks the given threads of this process have run.'''
    total = 0
    for tid in threads:
        with open(f"/proc/self/task/{tid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])
    return total


pool = {int(tid) for tid in os.listdir("/proc/self/task")} - {os.getpid()}
settled, last = 0, -1
for _ in range(100):  # the pools spin a while after they start, then sleep
    time.sleep(0.05)
    now = pool_ticks(pool)
    settled, last = (settled + 1 if now == last else 0), now
    if settled == 4:
        break

from realistic.camera.thin_lens import ThinLensCamera
from realistic.core.transforms import rotate, translate
from realistic.renderer.job import RenderJob
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.lights import InfiniteLight
from realistic.scene.model import Material, Scene
from realistic.scene.shapes import sphere

image = (0.2 + np.random.default_rng(3).random((16, 32, 3))).astype(np.float32)
woken = []
for backend, integrator in (("opencl", "directlighting"), ("opencl", "path"), ("numpy", "directlighting")):
    scene = Scene()
    scene.add(sphere(1.0, 48), np.eye(4), Material((0.5, 0.5, 0.5)))
    scene.lights.append(InfiniteLight((1.0, 1.0, 1.0), image, "latlong", rotate(30.0, (1.0, 1.0, 0.0))))
    scene.integrator = integrator
    camera = ThinLensCamera(60.0, 0.05, 5.0, 192, 192, 8, translate(0, 0, -5.0))
    before = pool_ticks(pool)
    render(RenderJob(scene, (camera,), backend, seed=1), ThreadPasses())
    time.sleep(0.2)  # a woken pool spins on past the call
    woken.append(f"{backend}/{integrator}={pool_ticks(pool) - before}")
print(len(pool), " ".join(woken))
"""


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="needs Linux's /proc to read threads' CPU time")
def test_a_render_wakes_no_openblas_thread() -> None:
    """The pool threads run (at most) one clock tick over the renders; a pool woken by a product runs several."""
    pool, *woken = run_unlimited(SCRIPT).stdout.split()
    if int(pool) == 0:
        pytest.skip("OpenBLAS started no pool threads here (one core, or its thread count set to 1)")
    assert all(int(entry.split("=")[1]) <= 1 for entry in woken), woken


POOLS = r"""
import os, sys

from realistic.__main__ import one_blas_thread

one_blas_thread(sys.argv[1:])
import numpy  # noqa: F401
import scipy.linalg  # noqa: F401

print(len(os.listdir("/proc/self/task")) - 1, os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="needs Linux's /proc to count threads")
@pytest.mark.parametrize(("argv", "env", "one"), [
    (["render", "scene.pbrt"], {}, True),
    (["render", "scene.pbrt"], {"OPENBLAS_NUM_THREADS": "2"}, False),  # the user's choice stands
    (["lens", "info", "dgauss"], {}, False),
])
def test_the_render_command_starts_no_openblas_pool(argv: list[str], env: dict[str, str], one: bool) -> None:
    """``python -m realistic render`` asks OpenBLAS for one thread before numpy loads: numpy and
    scipy then start no pool threads; a value the user set, and the other commands, are left alone."""
    run = run_unlimited(POOLS, *argv, **env)
    threads, value = run.stdout.split()
    if one:
        assert (threads, value) == ("0", "1")
    else:
        assert value == env.get("OPENBLAS_NUM_THREADS", "None")
        if len(os.sched_getaffinity(0)) > 1:
            assert int(threads) > 0
