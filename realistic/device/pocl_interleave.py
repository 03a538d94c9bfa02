"""PoCL's work-group vectoriser asked to interleave: several independent SIMD vectors in flight.

PoCL turns a kernel's loop over work items into SIMD code with LLVM's loop vectoriser. Its cost
model interleaves a loop whose body is as large as the lens kernel's just once, so one vector of
16 rays at a time goes through the chain of dependent square roots and divisions, surface after
surface, and the next vector's chain starts only when the processor's out-of-order window reaches
it: the kernel is bound by latency, not throughput. LLVM's option ``-force-vector-interleave=N``
makes the vectoriser emit N independent vectors per loop iteration, instruction by instruction, so
their latencies overlap. On Zen 5 with 16 lanes (``pocl_cpu.WIDE_AMD_CPU``) the lens kernel makes
1.6x the rays per second at N = 2, 1.9x at N = 4 and 1.7x at N = 8 (dgauss and wide, 1M rays per
launch): ``INTERLEAVE`` is 4. A lens with aspheres makes a kernel three times as long (six
Newton steps a surface), whose first build takes 1-1.8 s longer at 4 and 0.3-0.5 s at 2, for 2.3x
and 1.7x the rays per second: such kernels are interleaved ``ASPHERIC_INTERLEAVE`` times. The
shading kernel, bound by its table gathers, gains nothing and takes 0.8 s longer to compile so, so
only kernels compiled inside ``interleaved()`` (the lens kernel's first launch, where PoCL compiles
it) are interleaved; elsewhere LLVM's cost model decides.

PoCL 3.0 refuses ``-mllvm`` among build options ("Invalid build option") and has no setting of its
own for LLVM's options, but its LLVM is in this process, and LLVM reads options from
``LLVMParseCommandLineOptions`` (``llvm-c/Support.h``), called once, before PoCL's first build.
The option then counts as given, and the vectoriser reads its value from the variable
``llvm::VectorizerParams::VectorizationInterleave`` each time it runs: 0 leaves the count to the
cost model, and ``interleaved(count)`` sets it for a while. The PoCL that pip installs
links LLVM statically and exports neither: ``symbol_values`` finds them in the library's ELF symbol
table (``.symtab``), and their addresses are their values there relative to an exported
function's, whose address the dynamic linker gives. A PoCL built against a shared libLLVM has them
exported, and the dynamic linker finds them directly.

Interleaving changes the order instructions run in, not any lane's arithmetic (LLVM reorders no
floating-point sum without fast-math, which no kernel asks for), so images stay bit for bit the
same (tests/test_pocl_interleave.py). ``build_options`` marks programs built to be interleaved,
which keeps them apart in PoCL's kernel cache and in ours.
"""

from __future__ import annotations

import ctypes
import struct
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from realistic.device import pocl_cpu

#: Vectors of work items interleaved per iteration of PoCL's work-item loop, and for the longer
#: kernels of lenses with aspheres.
INTERLEAVE = 4
ASPHERIC_INTERLEAVE = 2
#: The LLVM C API function that parses LLVM's command-line options.
PARSE_OPTIONS = "LLVMParseCommandLineOptions"
#: Where the loop vectoriser reads the interleave count of ``-force-vector-interleave``
#: (``llvm::VectorizerParams::VectorizationInterleave``, an unsigned; LLVM's LoopAccessAnalysis.cpp).
INTERLEAVE_COUNT = "_ZN4llvm16VectorizerParams23VectorizationInterleaveE"
#: A function every PoCL exports (the ICD loader asks it for the others), whose address anchors the
#: symbol table's values to where the library is loaded.
ANCHOR = "clGetExtensionFunctionAddress"

_ELF_SYMBOL = np.dtype([("name", "<u4"), ("info", "u1"), ("other", "u1"), ("section", "<u2"),
                        ("value", "<u8"), ("size", "<u8")])
_SYMTAB, _DYNSYM = 2, 11  # section types
_OBJECT, _FUNCTION = 1, 2  # symbol types (the low four bits of info)
_lock = threading.Lock()
_count: ctypes.c_uint | None = None  # LLVM's interleave count, once the option is given
_tried = False


def symbol_values(path: Path, names: list[str]) -> dict[str, int]:
    """The values (offsets from the load address) of the functions and variables ``names`` defined in the ELF64
    little-endian shared library at ``path``, from its symbol tables (``.symtab`` and ``.dynsym``);
    names it does not define are left out, and a file that is not such a library gives {}."""
    try:
        with open(path, "rb") as file:
            return _symbol_values(file, names)
    except (OSError, ValueError, struct.error):
        return {}


def _symbol_values(file, names: list[str]) -> dict[str, int]:
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
        kind = symbols["info"] & 0xF
        defined = symbols[((kind == _FUNCTION) | (kind == _OBJECT)) & (symbols["section"] != 0)]
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


def loaded_library(prefix: str) -> Path | None:
    """The library whose file name starts with ``prefix`` that this process has loaded
    (``/proc/self/maps``), if any."""
    try:
        lines = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        fields = line.split(maxsplit=5)
        if len(fields) == 6 and Path(fields[5]).name.startswith(prefix):
            return Path(fields[5])
    return None


def _addresses(library: Path, names: list[str]) -> dict[str, int]:
    """Where the functions and variables ``names`` of ``library`` (loaded) or its LLVM are: all of
    them, or {}."""
    loaded = ctypes.CDLL(str(library))
    found = {}
    for name in names:
        try:
            found[name] = ctypes.addressof(ctypes.c_char.in_dll(loaded, name))
        except ValueError:  # not exported: from the symbol table, relative to the anchor
            break
    else:
        return found
    values = symbol_values(library, [*names, ANCHOR])
    if len(values) < len(names) + 1 or not hasattr(loaded, ANCHOR):
        return {}
    base = ctypes.cast(getattr(loaded, ANCHOR), ctypes.c_void_p).value - values[ANCHOR]
    return {name: base + values[name] for name in names}


def interleave_work_items(device) -> bool:
    """Give LLVM's ``-force-vector-interleave`` once per process, before any build for ``device``
    (a PoCL CPU device on Linux x86-64), with the count left to the cost model until
    ``interleaved()``; whether ``interleaved()`` can now interleave."""
    global _count, _tried
    if not pocl_cpu.pocl_on_linux_x86_64(device):
        return False
    with _lock:
        if not _tried:
            _tried = True
            library = loaded_library("libpocl")
            found = _addresses(library, [PARSE_OPTIONS, INTERLEAVE_COUNT]) if library is not None else {}
            if not found:
                return False
            prototype = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.POINTER(ctypes.c_char_p), ctypes.c_char_p)
            arguments = [b"realistic", f"-force-vector-interleave={INTERLEAVE}".encode()]
            prototype(found[PARSE_OPTIONS])(len(arguments), (ctypes.c_char_p * len(arguments))(*arguments), b"")
            count = ctypes.c_uint.from_address(found[INTERLEAVE_COUNT])
            if count.value == INTERLEAVE:  # the option took: hand the count back to the cost model
                count.value = 0
                _count = count
        return _count is not None


@contextmanager
def interleaved(count: int = INTERLEAVE) -> Iterator[None]:
    """Kernels that PoCL compiles while this is open (on any thread) interleave ``count`` vectors;
    one caller at a time."""
    with _lock:
        if _count is None:
            yield
            return
        _count.value = count
        try:
            yield
        finally:
            _count.value = 0


def build_options(count: int = INTERLEAVE) -> tuple[str, ...]:
    """Build options that mark a program whose kernels are compiled ``interleaved(count)`` (none
    where interleaving is off): PoCL's kernel cache and ours key on the options, not on LLVM's settings."""
    return () if _count is None else (f"-DREALISTIC_INTERLEAVE={count}",)
