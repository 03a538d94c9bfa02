"""How many threads a render runs in this process when none are asked for (the CLI's --threads
help shows it, so this module stays free of the renderer's imports)."""

from __future__ import annotations

import os


def default_threads() -> int:
    """Render threads when none are asked for: one per core this process may run on. (A thread more
    than the cores fills some idle CPU time but, in bench/render.py, renders no faster, and it
    costs a pass of memory.)"""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
