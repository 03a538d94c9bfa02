"""A native loop over embree's 16-ray packets, compiled once per process with llvmlite.

embree 4 traces at most 16 rays per call (``rtcIntersect16``, ``rtcOccluded16``). Called per packet
from Python through ctypes, the calls cost about as much as the traversal and, worse, release and
take back the GIL every 16 rays: beside a thread running Python, tracing fell from 2.0 to 0.9 M
rays/s (the other thread slowed as well). This loop makes a whole batch one ctypes call, which
releases the GIL once for the batch. Its LLVM IR is portable; llvmlite compiles it for the host in
about 50 ms, the first time a scene is traced.
"""

from __future__ import annotations

import ctypes
import functools
import threading

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

_lock = threading.Lock()
_vp = ctypes.c_void_p
PacketLoop = ctypes.CFUNCTYPE(None, _vp, _vp, _vp, _vp, ctypes.c_int64, ctypes.c_int64)


@functools.cache
def _compiled() -> tuple[object, PacketLoop]:
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    module = llvm.parse_assembly(_IR)
    module.verify()
    engine = llvm.create_mcjit_compiler(module, llvm.Target.from_default_triple().create_target_machine())
    engine.finalize_object()
    return engine, PacketLoop(engine.get_function_address("trace"))  # the engine owns the machine code


def packet_loop() -> PacketLoop:
    """The compiled loop (a ctypes function: calling it releases the GIL)."""
    with _lock:
        return _compiled()[1]
