"""The processor a bench ran on, for its table and JSON: figures from different machines do not compare."""

from __future__ import annotations

import os
import platform
from pathlib import Path


def describe(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The CPU's model name, family and model (from /proc/cpuinfo where there is one) and the cores usable."""
    fields = {}
    try:
        for line in cpuinfo.read_text(encoding="ascii", errors="replace").splitlines():
            key, _, value = line.partition(":")
            if not key.strip():
                break  # the first processor's block ends at its blank line
            fields.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    name = fields.get("model name") or platform.processor() or platform.machine()
    family = f", family {fields['cpu family']} model {fields.get('model', '?')}" if "cpu family" in fields else ""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{name}{family}, {cores} cores"
