"""A native loop over embree's 16-ray packets: a whole batch in one ctypes call.

embree 4 traces at most 16 rays per call (``rtcIntersect16``, ``rtcOccluded16``). Called per packet
from Python through ctypes, the calls cost about as much as the traversal and, worse, release and
take back the GIL every 16 rays: beside a thread running Python, tracing fell from 2.0 to 0.9 M
rays/s (the other thread slowed as well). This loop makes a batch one ctypes call, which releases
the GIL once.

The loop is ``_IR``. On Linux x86-64 it runs as ``X86_64_SYSV_CODE``, the IR compiled by llvmlite
for generic x86-64 (95 bytes, position independent, no relocations), copied to a page mapped
read+execute; ``tests/test_embree.py`` compiles the IR again and checks the bytes. Loading
llvmlite's LLVM costs 70 MiB of resident memory, so it is imported only on other platforms, where
it compiles the IR for the host in about 50 ms.
"""

from __future__ import annotations

import ctypes
import functools
import mmap
import platform
import sys
import threading

from realistic.errors import UserError

#: trace(function, valid, scene, packets, packet_stride, count): for i < count,
#: function(valid + 64 i, scene, packets + packet_stride i, NULL)
_IR = r"""
define void @trace(ptr %function, ptr %valid, ptr %scene, ptr %packets, i64 %stride, i64 %count) {
entry:
  %empty = icmp eq i64 %count, 0
  br i1 %empty, label %done, label %loop
loop:
  %i = phi i64 [0, %entry], [%next, %loop]
  %valid_offset = mul i64 %i, 64
  %valid_i = getelementptr i8, ptr %valid, i64 %valid_offset
  %packet_offset = mul i64 %i, %stride
  %packet_i = getelementptr i8, ptr %packets, i64 %packet_offset
  call void %function(ptr %valid_i, ptr %scene, ptr %packet_i, ptr null)
  %next = add i64 %i, 1
  %more = icmp ult i64 %next, %count
  br i1 %more, label %loop, label %done
done:
  ret void
}
"""

#: ``_IR``'s .text as llvmlite 0.50 compiles it for x86_64-unknown-linux-gnu, cpu "x86-64", PIC.
X86_64_SYSV_CODE = bytes.fromhex(
    "4d85c9745955415741564155415453504d89cc4c89c34989cf4989f54889fd4531f648891424662e0f1f8400000000"
    "004c89ef4889d64c89fa31c9ffd5488b142449ffc64901df4983c5404d39e672e04883c4085b415c415d415e415f5d"
    "c3")

_lock = threading.Lock()
_vp = ctypes.c_void_p
PacketLoop = ctypes.CFUNCTYPE(None, _vp, _vp, _vp, _vp, ctypes.c_int64, ctypes.c_int64)


def packet_loop() -> PacketLoop:
    """The loop, as a ctypes function (calling it releases the GIL)."""
    with _lock:
        return _loaded()[-1]


@functools.cache
def _loaded() -> tuple:
    if sys.platform == "linux" and platform.machine() == "x86_64":
        return executable_code(X86_64_SYSV_CODE)
    return compiled_for_host()


def executable_code(code: bytes) -> tuple:
    """``code`` copied to a fresh page that is then made read+execute (never writable and
    executable at once); returns the page and the loop (the page must outlive the loop)."""
    page = mmap.mmap(-1, mmap.PAGESIZE, prot=mmap.PROT_READ | mmap.PROT_WRITE)
    page.write(code)
    start = ctypes.c_char.from_buffer(page)
    address = ctypes.addressof(start)
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [_vp, ctypes.c_size_t, ctypes.c_int]
    if libc.mprotect(address, mmap.PAGESIZE, mmap.PROT_READ | mmap.PROT_EXEC) != 0:
        raise UserError(f"this system refuses executable memory (mprotect: errno {ctypes.get_errno()}); "
                        "the renderer's ray tracing loop needs one page of it")
    return page, start, PacketLoop(address)


def compiled_for_host() -> tuple:
    """``_IR`` compiled for this machine by llvmlite; returns its engine (which owns the code) and the loop."""
    try:
        import llvmlite.binding as llvm
    except ImportError as error:
        raise UserError("this platform needs llvmlite for the ray tracing loop: pip install llvmlite "
                        f"({error})") from None
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    module = llvm.parse_assembly(_IR)
    module.verify()
    engine = llvm.create_mcjit_compiler(module, llvm.Target.from_default_triple().create_target_machine())
    engine.finalize_object()
    return engine, PacketLoop(engine.get_function_address("trace"))
