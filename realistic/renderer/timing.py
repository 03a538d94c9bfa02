"""Per-stage accounting shared by the render's worker threads: wall seconds, and the calling thread's
CPU seconds.

A stage's wall seconds count time its thread waits (for a core, for the GIL, for a kernel launch's
PoCL workers); its CPU seconds count only what the thread itself ran. For embree, which traces on the
calling thread, the two differ by how long the thread waited: ``bench/render.py`` compares embree's
CPU seconds in the render with its CPU seconds alone, so that sharing the cores is not mistaken for
slower traversal. Kernels run on PoCL's own threads, so a shading stage's CPU seconds leave them out."""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager

STAGES = ("setup", "exit pupil", "ray generation", "embree", "shading", "accumulation")


class StageClock:
    """Sums the seconds each thread spends in each named stage (thread-seconds, not wall time), and
    the CPU seconds those threads ran in it (``time.thread_time``)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.cpu_seconds: dict[str, float] = defaultdict(float)
        self._lock = threading.Lock()

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        start, cpu_start = time.perf_counter(), time.thread_time()
        try:
            yield
        finally:
            elapsed, cpu = time.perf_counter() - start, time.thread_time() - cpu_start
            with self._lock:
                self.seconds[stage] += elapsed
                self.cpu_seconds[stage] += cpu
