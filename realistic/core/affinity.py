"""CPU placement of a render's threads (Linux): each worker on its own CPU, and the OpenCL
runtime's thread pool spread one per CPU while a render runs.

Why: a worker woken by another thread (a GIL hand-over, a kernel that finished) is queued on a CPU
the scheduler picks at wake-up. On a busy last-level cache Linux skips its search for an idle CPU
(the SIS_UTIL heuristic), so the woken thread queues behind a running one while another CPU idles
until the next load balance. sched_switch traces of the dragons render on two CPUs showed both
workers runnable on one CPU, taking turns every 4 ms, with the other CPU idle for 8-11 ms at a
time: 7-13 % of the render's CPU time was idle. Pinned, a worker always runs on its own CPU, and
PoCL's pool threads, pinned one per CPU, cannot queue behind each other either.

Unpinned threads keep the process's CPU set. Where threads cannot be pinned (not Linux), or the
process may run on a single CPU, every function here leaves placement to the system.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

Result = TypeVar("Result")

#: Native thread ids the OpenCL runtime started (``record_runtime_threads``): PoCL's CPU pool.
_runtime_threads: set[int] = set()
_lock = threading.Lock()
_spreads = 0  # renders inside ``runtime_threads_spread``
_saved: dict[int, set[int]] = {}  # the runtime threads' CPU sets from before the first of them


def allowed_cpus() -> list[int]:
    """The CPUs this process may run on, ascending; empty where threads cannot be pinned."""
    if not hasattr(os, "sched_setaffinity"):
        return []
    return sorted(os.sched_getaffinity(0))


def native_threads() -> set[int]:
    """Native ids of this process's threads (empty where /proc cannot list them)."""
    try:
        return {int(name) for name in os.listdir("/proc/self/task")}
    except OSError:
        return set()


def record_runtime_threads(start: Callable[[], Result]) -> Result:
    """``start()``'s result; the native threads it started, other than Python's, are remembered
    as the OpenCL runtime's (call it around the first platform enumeration, which starts PoCL's pool)."""
    before = native_threads()
    result = start()
    started = native_threads() - before - {thread.native_id for thread in threading.enumerate()}
    with _lock:
        _runtime_threads.update(started)
    return result


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


@contextmanager
def runtime_threads_spread() -> Iterator[None]:
    """While inside, the OpenCL runtime's threads are pinned one per allowed CPU (round robin);
    afterwards their CPU sets are restored. Nested or concurrent renders share one spreading."""
    global _spreads
    cpus = allowed_cpus()
    if len(cpus) < 2:
        yield
        return
    with _lock:
        if _spreads == 0:
            _runtime_threads.intersection_update(native_threads())  # ended ones: their ids may be reused
            for k, tid in enumerate(sorted(_runtime_threads)):
                try:
                    _saved[tid] = os.sched_getaffinity(tid)
                    os.sched_setaffinity(tid, {cpus[k % len(cpus)]})
                except OSError:  # it ended meanwhile, or may not be moved
                    _saved.pop(tid, None)
        _spreads += 1
    try:
        yield
    finally:
        with _lock:
            _spreads -= 1
            if _spreads == 0:
                for tid, cpu_set in _saved.items():
                    try:
                        os.sched_setaffinity(tid, cpu_set)
                    except OSError:
                        pass
                _saved.clear()
