"""PoCL's CPU device on processors newer than its LLVM: name the CPU by the x86-64 level it supports.

The PoCL that pip installs (pyopencl's wheels: PoCL 3.0 linked with LLVM 14) asks LLVM for the host
CPU's name (``llvm::sys::getHostCPUName``). LLVM 14 does not know processors released after it (AMD
family 1Ah, Zen 5, for one) and answers "generic", which PoCL passes to clang as ``-target-cpu``;
clang rejects that name for x86-64, so every kernel build fails with "unknown target CPU 'generic'"
(pocl/pocl#1049). Later PoCLs read ``POCL_LLVM_CPU_NAME`` instead (``lib/CL/pocl_llvm_utils.cc``,
``pocl_get_llvm_cpu_name``), and this one has no setting for it: ``name_unknown_cpu`` rewrites the
name where the device keeps it (its ``llvm_cpu`` string, heap memory PoCL allocated) to the x86-64
micro-architecture level (v2, v3, v4) the host's CPU flags show, a name LLVM 14 knows, or on an AMD
processor with AVX-512 to ``WIDE_AMD_CPU``, whose tuning lets the kernels use 512-bit vectors.
"""

from __future__ import annotations

import ctypes
import platform
from pathlib import Path

#: The name LLVM gives a CPU it does not recognise.
UNKNOWN_CPU = b"generic"
#: The device struct's first bytes, searched for the pointer to its CPU name (PoCL 3.0 keeps it
#: 640 bytes in).
DEVICE_STRUCT_BYTES = 4096
#: x86-64 micro-architecture levels (the x86-64 psABI), each with the Linux CPU flags it adds to
#: the one before; LLVM 12 and later accept each as a CPU name.
X86_64_LEVELS = (
    ("x86-64-v2", {"cx16", "lahf_lm", "popcnt", "pni", "sse4_1", "sse4_2", "ssse3"}),
    ("x86-64-v3", {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "abm", "movbe", "xsave"}),
    ("x86-64-v4", {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}),
)

#: The name given to an AMD processor at x86-64-v4. LLVM 14's tuning for x86-64-v4, like that of every
#: Intel AVX-512 processor it knows, has TuningPrefer256Bit, so PoCL's work-group vectoriser makes
#: kernels 8 float lanes wide; LLVM's tunings for AMD's AVX-512 processors (znver4 and later, which
#: LLVM 14 does not know) leave it out, and of the AVX-512 processors LLVM 14 knows, only Knights
#: Landing's does (llvm/lib/Target/X86/X86.td). Named so, the kernels are 16 lanes wide: on Zen 5 the
#: lens kernel makes the same rays 1.8x as fast (bench/lens_kernel.py), their chain of dependent
#: square roots and divisions surface by surface being latency-bound at 8 lanes. Knights Landing's
#: own instructions (AVX512ER, AVX512PF, PREFETCHWT1), which AMD lacks, are emitted only for their
#: intrinsics, which no kernel uses: tests/test_pocl_cpu.py disassembles kernels built so and looks.
WIDE_AMD_CPU = "knl"
#: Names given by ``name_unknown_cpu``, per device (``int_ptr``): a program's binaries depend on them.
_given: dict[int, str] = {}


def cpu_name(fields: dict[str, str]) -> str:
    """The name to give a CPU that LLVM 14 calls "generic", from its ``/proc/cpuinfo`` fields: its
    x86-64 level, or ``WIDE_AMD_CPU`` for an AMD processor at x86-64-v4."""
    level = x86_64_level(set(fields.get("flags", "").split()))
    return WIDE_AMD_CPU if level == "x86-64-v4" and fields.get("vendor_id") == "AuthenticAMD" else level


def x86_64_level(flags: set[str]) -> str:
    """The highest x86-64 level whose flags (and every lower level's) are all in ``flags``."""
    level, needed = "x86-64", set()
    for name, added in X86_64_LEVELS:
        needed |= added
        if not needed <= flags:
            break
        level = name
    return level


def cpuinfo_fields(cpuinfo: Path = Path("/proc/cpuinfo")) -> dict[str, str]:
    """The first processor's fields in ``/proc/cpuinfo`` ("flags", "model name", ...; empty where
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


def _mapped_regions() -> list[tuple[int, int, bool]]:
    """This process's readable memory from ``/proc/self/maps``: (start, end, heap), heap where
    malloc may have allocated it (writable, and the heap or an anonymous mapping)."""
    regions = []
    for line in Path("/proc/self/maps").read_text().splitlines():
        fields = line.split()
        start, end = (int(bound, 16) for bound in fields[0].split("-"))
        if fields[1][0] == "r":
            regions.append((start, end, fields[1][1] == "w" and (len(fields) < 6 or fields[5] == "[heap]")))
    return regions


def _region(regions: list[tuple[int, int, bool]], address: int, size: int) -> tuple[int, int, bool] | None:
    return next((r for r in regions if r[0] <= address and address + size <= r[1]), None)


def rewrite_cpu_name(struct_address: int, struct_bytes: int, name: str) -> bool:
    """Overwrite in place the heap string "generic" that a pointer in the struct at ``struct_address``
    points to with ``name``; True when one was found and rewritten.

    Only memory the process maps readable is read, and only a string on the heap whose allocation
    (``malloc_usable_size``) holds ``name`` is written, so a struct without such a pointer is left
    as it is."""
    encoded = name.encode("ascii") + b"\0"
    try:
        regions = _mapped_regions()
    except OSError:  # no /proc: nothing can be read safely
        return False
    libc = ctypes.CDLL(None)
    libc.malloc_usable_size.restype = ctypes.c_size_t
    libc.malloc_usable_size.argtypes = [ctypes.c_void_p]
    for offset in range(0, struct_bytes, 8):
        if _region(regions, struct_address + offset, 8) is None:
            break
        pointer = ctypes.c_uint64.from_address(struct_address + offset).value
        target = _region(regions, pointer, len(UNKNOWN_CPU) + 1) if pointer else None
        if target is None or ctypes.string_at(pointer, len(UNKNOWN_CPU) + 1) != UNKNOWN_CPU + b"\0":
            continue
        if not target[2] or libc.malloc_usable_size(pointer) < len(encoded):
            return False
        ctypes.memmove(pointer, encoded, len(encoded))
        return True
    return False


def is_pocl(platform_name: str) -> bool:
    """Whether an OpenCL platform of this name is PoCL."""
    return "portable computing language" in platform_name.lower()


def pocl_on_linux_x86_64(device) -> bool:
    """Whether ``device`` is PoCL's, in this process on Linux x86-64: where this module and
    ``pocl_interleave`` reach into PoCL's memory."""
    return (platform.system() == "Linux" and platform.machine() in ("x86_64", "AMD64")
            and is_pocl(device.platform.name))


def name_unknown_cpu(device) -> str | None:
    """Give a PoCL CPU device that LLVM named "generic" a name LLVM knows (``cpu_name``), so its
    kernels build; the name given, or None where nothing needed it (another driver or processor, a
    CPU LLVM knows, or a device already named)."""
    if not pocl_on_linux_x86_64(device):
        return None
    name = cpu_name(cpuinfo_fields())
    if not rewrite_cpu_name(device.int_ptr, DEVICE_STRUCT_BYTES, name):
        return None
    _given[device.int_ptr] = name
    return name


def given_name(device) -> str | None:
    """The CPU name ``name_unknown_cpu`` gave ``device`` in this process, None if it gave none."""
    return _given.get(device.int_ptr)
