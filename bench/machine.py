"""The processor a bench ran on, for its table and JSON: figures from different machines do not compare."""

from __future__ import annotations

import platform
from pathlib import Path

from realistic.renderer.thread_count import default_threads


def cpuinfo_fields(cpuinfo: Path = Path("/proc/cpuinfo")) -> dict[str, str]:
    """The first processor's fields in ``/proc/cpuinfo`` ("model name", "cpu family", ...; empty where
    there is no such file)."""
    fields: dict[str, str] = {}
    try:
        text = cpuinfo.read_text(encoding="ascii", errors="replace")
    except OSError:
        return fields
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if not key.strip():
            break  # the first processor's block ends at its blank line
        fields.setdefault(key.strip(), value.strip())
    return fields


def describe(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The CPU's model name, family and model (from /proc/cpuinfo where there is one) and the cores usable."""
    fields = cpuinfo_fields(cpuinfo)
    name = fields.get("model name") or platform.processor() or platform.machine()
    family = f", family {fields['cpu family']} model {fields.get('model', '?')}" if "cpu family" in fields else ""
    return f"{name}{family}, {default_threads()} cores"
