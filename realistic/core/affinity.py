"""CPU placement of a render's own worker threads (Linux): each worker on its own CPU, on request.

Why: a worker woken by another thread (a GIL hand-over, a kernel that finished) is queued on a CPU
the scheduler picks at wake-up. On a busy last-level cache Linux skips its search for an idle CPU
(the SIS_UTIL heuristic), so the woken thread can queue behind a running one while another CPU
idles until the next load balance. Pinned, a worker always runs on its own CPU.

Only threads this process creates are placed (the render's ``ThreadPoolExecutor``). The OpenCL
runtime's thread pool belongs to PoCL, which documents one way to place it: ``POCL_AFFINITY=1`` in
the environment before PoCL loads pins each of its threads to the CPU of its index, for the life of
the process; a user who wants that sets it (``bench/render.py``'s "free" row measures pinning). Unpinned
threads keep the process's CPU set. Where threads cannot be pinned (not Linux), or the process may
run on a single CPU, placement is left to the system.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable


def allowed_cpus() -> list[int]:
    """The CPUs this process may run on, ascending; empty where threads cannot be pinned."""
    if not hasattr(os, "sched_setaffinity"):
        return []
    return sorted(os.sched_getaffinity(0))


def worker_pinner() -> Callable[[], None] | None:
    """A ``ThreadPoolExecutor`` initializer that pins the pool's k-th thread to the k-th allowed CPU
    (round robin); None where pinning cannot help (one CPU, or no way to pin)."""
    cpus = allowed_cpus()
    if len(cpus) < 2:
        return None
    order = itertools.count()

    def pin() -> None:
        try:
            os.sched_setaffinity(0, {cpus[next(order) % len(cpus)]})
        except OSError:  # a sandbox that forbids it: the thread runs where the system puts it
            pass

    return pin
