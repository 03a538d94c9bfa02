"""PoCL's work-group vectoriser asked to interleave: several independent SIMD vectors in flight.

PoCL turns a kernel's loop over work items into SIMD code with LLVM's loop vectoriser. Its cost
model interleaves a loop whose body is as large as the lens kernel's just once, so one vector of
16 rays at a time goes through the chain of dependent square roots and divisions, surface after
surface, and the next vector's chain starts only when the processor's out-of-order window reaches
it: the kernel is bound by latency, not throughput. LLVM's option ``-force-vector-interleave=N``
makes the vectoriser emit N independent vectors per loop iteration, instruction by instruction, so
their latencies overlap. On Zen 5 with 16 lanes (``pocl_cpu.WIDE_AMD_CPU``) the lens kernel makes
1.6x the rays per second at N = 2, 1.9x at N = 4 and 1.7x at N = 8 (dgauss and wide, 1M rays per
launch): ``INTERLEAVE`` is 4.

PoCL 3.0 refuses ``-mllvm`` among build options ("Invalid build option") and has no setting of its
own for LLVM's options, but its LLVM is in this process, and LLVM reads options from
``LLVMParseCommandLineOptions`` (``llvm-c/Support.h``), once, before PoCL's first build. The PoCL
that pip installs links LLVM statically and does not export that function: ``function_values``
finds it in the library's ELF symbol table (``.symtab``), and its address is its value there
relative to an exported function's, whose address the dynamic linker gives. A PoCL built against a
shared libLLVM exports it, and the dynamic linker finds it directly.

Interleaving changes the order instructions run in, not any lane's arithmetic (LLVM reorders no
floating-point sum without fast-math, which no kernel asks for), so images stay bit for bit the
same (tests/test_pocl_interleave.py). ``build_options`` marks builds made so, which keeps them
apart in PoCL's kernel cache and in ours.
"""

from __future__ import annotations

import ctypes
import platform
import struct
import threading
from pathlib import Path

import numpy as np

#: Vectors of work items interleaved per iteration of PoCL's work-item loop.
INTERLEAVE = 4
#: The LLVM C API function that parses LLVM's command-line options.
PARSE_OPTIONS = "LLVMParseCommandLineOptions"
#: A function every PoCL exports (the ICD loader asks it for the others), whose address anchors the
#: symbol table's values to where the library is loaded.
ANCHOR = "clGetExtensionFunctionAddress"

_ELF_SYMBOL = np.dtype([("name", "<u4"), ("info", "u1"), ("other", "u1"), ("section", "<u2"),
                        ("value", "<u8"), ("size", "<u8")])
_SYMTAB, _DYNSYM, _FUNCTION = 2, 11, 2  # section types; symbol type (the low four bits of info)
_lock = threading.Lock()
_applied: int | None = None  # the interleave count set in this process, once set
_tried = False


def function_values(path: Path, names: list[str]) -> dict[str, int]:
    """The values (offsets from the load address) of the functions ``names`` defined in the ELF64
    little-endian shared library at ``path``, from its symbol tables (``.symtab`` and ``.dynsym``);
    names it does not define are left out, and a file that is not such a library gives {}."""
    try:
        with open(path, "rb") as file:
            return _function_values(file, names)
    except (OSError, ValueError, struct.error):
        return {}


def _function_values(file, names: list[str]) -> dict[str, int]:
    header = file.read(64)
    if len(header) < 64 or header[:6] != b"\x7fELF\x02\x01":  # ELF, 64-bit, little-endian
        return {}
    (section_table,) = struct.unpack_from("<Q", header, 0x28)
    entry_size, sections = struct.unpack_from("<HH", header, 0x3A)
    if entry_size < 64 or sections == 0:
        return {}
    file.seek(section_table)
    table = file.read(entry_size * sections)
    headers = [struct.unpack_from("<IIQQQQII", table, i * entry_size)
               for i in range(len(table) // entry_size)]  # name, type, flags, addr, offset, size, link, info
    found: dict[str, int] = {}
    for _, kind, _, _, offset, size, link, _ in headers:
        if kind not in (_SYMTAB, _DYNSYM) or link >= len(headers):
            continue
        file.seek(offset)
        data = file.read(size)
        symbols = np.frombuffer(data, _ELF_SYMBOL, len(data) // _ELF_SYMBOL.itemsize)
        file.seek(headers[link][4])
        strings = file.read(headers[link][5])
        defined = symbols[((symbols["info"] & 0xF) == _FUNCTION) & (symbols["section"] != 0)]
        for name in names:
            if name in found:
                continue
            starts = _string_offsets(strings, name.encode("ascii"))
            hits = defined["value"][np.isin(defined["name"], starts)]
            if len(hits):
                found[name] = int(hits[0])
    return found


def _string_offsets(strings: bytes, name: bytes) -> list[int]:
    """Offsets in a string table where the string ``name`` starts: wherever it ends a string, since
    linkers store a name that is another's tail ("cl..." inside "POcl...") as that tail."""
    offsets, at = [], strings.find(name + b"\0")
    while at >= 0:
        offsets.append(at)
        at = strings.find(name + b"\0", at + 1)
    return offsets


def loaded_pocl() -> Path | None:
    """The PoCL library this process has loaded (``/proc/self/maps``), if any."""
    try:
        lines = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        fields = line.split(maxsplit=5)
        if len(fields) == 6 and Path(fields[5]).name.startswith("libpocl"):
            return Path(fields[5])
    return None


def parse_options_function(library: Path):
    """``LLVMParseCommandLineOptions`` of the LLVM that ``library`` (loaded) uses, or None."""
    loaded = ctypes.CDLL(str(library))
    try:
        address = ctypes.cast(getattr(loaded, PARSE_OPTIONS), ctypes.c_void_p).value
    except AttributeError:
        values = function_values(library, [PARSE_OPTIONS, ANCHOR])
        if len(values) < 2 or not hasattr(loaded, ANCHOR):
            return None
        anchor = ctypes.cast(getattr(loaded, ANCHOR), ctypes.c_void_p).value
        address = anchor - values[ANCHOR] + values[PARSE_OPTIONS]
    prototype = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.POINTER(ctypes.c_char_p), ctypes.c_char_p)
    return prototype(address)


def interleave_work_items(device) -> int | None:
    """Set PoCL's LLVM to interleave ``INTERLEAVE`` vectors, once per process, before any build
    for ``device`` (a PoCL CPU device on Linux x86-64); the count in force, None where it is not set."""
    global _applied, _tried
    if (platform.system() != "Linux" or platform.machine() not in ("x86_64", "AMD64")
            or "portable computing language" not in device.platform.name.lower()):
        return None
    with _lock:
        if not _tried:
            _tried = True
            library = loaded_pocl()
            parse = parse_options_function(library) if library is not None else None
            if parse is None:
                return None
            arguments = [b"realistic", f"-force-vector-interleave={INTERLEAVE}".encode()]
            parse(len(arguments), (ctypes.c_char_p * len(arguments))(*arguments), b"")
            _applied = INTERLEAVE
        return _applied


def build_options() -> tuple[str, ...]:
    """Build options that mark a program built with interleaving on (none when it is off): PoCL's
    kernel cache and ours key on the options, not on LLVM's settings."""
    return () if _applied is None else (f"-DREALISTIC_INTERLEAVE={_applied}",)
