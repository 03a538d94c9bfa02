"""How many threads a render runs in this process when none are asked for (the CLI's --threads
help shows it, so this module stays free of the renderer's imports)."""

from __future__ import annotations

import os


def default_threads() -> int:
    """Render threads when none are asked for: one per core this process may run on. (Two cores
    keep two threads: a third cut the idle CPU from 10-11 % to 7 % of the dragons' render, but
    bench/render.py made 4.00 and 4.14 M samples/s with it against 4.00 and 4.21 without, and it
    cost a pass of memory.)"""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
