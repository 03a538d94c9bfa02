"""The processor a bench ran on, for its table and JSON: figures from different machines do not compare."""

from __future__ import annotations

import platform
from pathlib import Path

from realistic.device.pocl_cpu import cpuinfo_fields
from realistic.renderer.thread_count import default_threads


def describe(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The CPU's model name, family and model (from /proc/cpuinfo where there is one) and the cores usable."""
    fields = cpuinfo_fields(cpuinfo)
    name = fields.get("model name") or platform.processor() or platform.machine()
    family = f", family {fields['cpu family']} model {fields.get('model', '?')}" if "cpu family" in fields else ""
    return f"{name}{family}, {default_threads()} cores"
