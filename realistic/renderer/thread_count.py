"""How many threads a render runs in this process when none are asked for (the CLI's --threads
help shows it, so this module stays free of the renderer's imports)."""

from __future__ import annotations

import os


def default_threads() -> int:
    """Render threads when none are asked for: one per core this process may run on. (Two cores
    kept two threads: a third cut the idle CPU from 10-11 % to 7 % of the dragons' render but made
    bench/render.py and bench/converge.py no faster, 4.00/4.21 against 4.00/4.14 M samples/s, and
    cost a pass of memory.)"""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
