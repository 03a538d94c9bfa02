"""Native loops that trace a whole batch of rays through embree's 16-ray packets in one ctypes call.

embree 4 traces at most 16 rays per call (``rtcIntersect16``, ``rtcOccluded16``) and wants each
packet as rows of 16 lanes. Called per packet from Python, the calls cost about as much as the
traversal and released and took back the GIL every 16 rays: beside a thread running Python,
tracing fell from 2.0 to 0.9 M rays/s (the other thread slowed as well). Packing the rows in numpy
cost another 40 % of the traversal. These loops read the caller's (N, 3) float32 origins and
directions, fill one packet at a time on the stack, call embree, and write the hits to the
caller's arrays; a batch is one ctypes call, which releases the GIL once.

The loops are LLVM IR (``closest_ir``, ``occluded_ir``, written out by the functions below). On
Linux x86-64 they run as ``SHIPPED``, the IR compiled by llvmlite 0.50 for generic x86-64 (position
independent, no relocations), copied to a page mapped read+execute; ``tests/test_embree.py``
compiles the IR again and checks the bytes. Loading llvmlite's LLVM costs 70 MiB of resident
memory, so it is imported only on other platforms, where it compiles the IR for the host at start-up.

Packet rows (``embree4/rtcore_ray.h``, ``RTCRayHit16``): org_x, org_y, org_z, tnear, dir_x, dir_y,
dir_z, time, tfar, mask, id, flags, then the hit's Ng_x, Ng_y, Ng_z, u, v, primID, geomID, instID
(and instPrimID); ``RTCRay16`` is the first twelve.
"""

from __future__ import annotations

import ctypes
import functools
import mmap
import platform
import sys
import threading

from realistic.errors import UserError

PACKET = 16  # rays per rtcIntersect16 / rtcOccluded16 call
ROWS = 21  # rows of RTCRayHit16; RTCRay16 is the first twelve
TFAR, NG, U, V, PRIM, GEOM, INST = 8, 12, 15, 16, 17, 18, 19  # row numbers

_vp, _i64 = ctypes.c_void_p, ctypes.c_int64
#: closest(function, scene, origin, direction, count, tfar, t, u, v, prim, geom, instance, normal)
ClosestLoop = ctypes.CFUNCTYPE(None, _vp, _vp, _vp, _vp, _i64, ctypes.c_float, _vp, _vp, _vp, _vp, _vp, _vp, _vp)
#: occluded(function, scene, origin, direction, count, distance, blocked)
OccludedLoop = ctypes.CFUNCTYPE(None, _vp, _vp, _vp, _vp, _i64, _vp, _vp)


def _store(row: int, value: str, kind: str, tag: str) -> str:
    """packet[row][lane] = value (kind "float" or "i32")."""
    return (f"  %{tag}_k = add i64 %lane, {row * PACKET}\n"
            f"  %{tag}_p = getelementptr {kind}, ptr %packet, i64 %{tag}_k\n"
            f"  store {kind} {value}, ptr %{tag}_p\n")


def _copy_in(array: str, index: str, row: int, tag: str) -> str:
    """packet[row][lane] = array[index] (32-bit words)."""
    return (f"  %{tag}_a = getelementptr i32, ptr {array}, i64 {index}\n"
            f"  %{tag}_x = load i32, ptr %{tag}_a\n" + _store(row, f"%{tag}_x", "i32", tag))


def _copy_out(row: int, array: str, index: str, tag: str) -> str:
    """array[index] = packet[row][out_lane] (32-bit words)."""
    return (f"  %{tag}_k = add i64 %out_lane, {row * PACKET}\n"
            f"  %{tag}_p = getelementptr i32, ptr %packet, i64 %{tag}_k\n"
            f"  %{tag}_x = load i32, ptr %{tag}_p\n"
            f"  %{tag}_a = getelementptr i32, ptr {array}, i64 {index}\n"
            f"  store i32 %{tag}_x, ptr %{tag}_a\n")


def _ray_in() -> str:
    """A lane's ray: origin and direction from the caller's (N, 3) arrays, tnear and time 0, every
    mask bit, id and flags 0."""
    lines = "  %i3 = mul i64 %i, 3\n  %i3y = add i64 %i3, 1\n  %i3z = add i64 %i3, 2\n"
    for axis, index in enumerate(("%i3", "%i3y", "%i3z")):
        lines += _copy_in("%origin", index, axis, f"origin{axis}") + _copy_in("%direction", index, 4 + axis,
                                                                              f"direction{axis}")
    return (lines + _store(3, "0.0", "float", "tnear") + _store(7, "0.0", "float", "time")
            + _store(9, "-1", "i32", "mask") + _store(10, "0", "i32", "id") + _store(11, "0", "i32", "flags"))


def _loop(name: str, parameters: str, pack_lane: str, unpack_lane: str) -> str:
    """For each packet of 16 rays: pack the lanes below ``count`` (``pack_lane`` sets ``%active``,
    the lane's valid flag), call embree's ``function`` on the packet, unpack the same lanes."""
    return f"""define void @{name}(ptr %function, ptr %scene, ptr %origin, ptr %direction, i64 %count{parameters}) {{
entry:
  %packet = alloca [{ROWS * PACKET} x float], align 64
  %valid = alloca [{PACKET} x i32], align 64
  %empty = icmp eq i64 %count, 0
  br i1 %empty, label %done, label %packets
packets:
  %base = phi i64 [0, %entry], [%next_base, %unpacked]
  br label %pack
pack:
  %lane = phi i64 [0, %packets], [%next_lane, %pack_next]
  %i = add i64 %base, %lane
  %in_range = icmp ult i64 %i, %count
  br i1 %in_range, label %pack_lane, label %pack_idle
pack_idle:
  %idle_valid = getelementptr i32, ptr %valid, i64 %lane
  store i32 0, ptr %idle_valid
  br label %pack_next
pack_lane:
{pack_lane}  %mask = select i1 %active, i32 -1, i32 0
  %lane_valid = getelementptr i32, ptr %valid, i64 %lane
  store i32 %mask, ptr %lane_valid
  br label %pack_next
pack_next:
  %next_lane = add i64 %lane, 1
  %more_lanes = icmp ult i64 %next_lane, {PACKET}
  br i1 %more_lanes, label %pack, label %trace
trace:
  call void %function(ptr %valid, ptr %scene, ptr %packet, ptr null)
  br label %unpack
unpack:
  %out_lane = phi i64 [0, %trace], [%next_out_lane, %unpack_next]
  %j = add i64 %base, %out_lane
  %written = icmp ult i64 %j, %count
  br i1 %written, label %unpack_lane, label %unpack_next
unpack_lane:
{unpack_lane}  br label %unpack_next
unpack_next:
  %next_out_lane = add i64 %out_lane, 1
  %more_out = icmp ult i64 %next_out_lane, {PACKET}
  br i1 %more_out, label %unpack, label %unpacked
unpacked:
  %next_base = add i64 %base, {PACKET}
  %more = icmp ult i64 %next_base, %count
  br i1 %more, label %packets, label %done
done:
  ret void
}}
"""


def closest_ir() -> str:
    """``closest``: tfar the same for every ray, the hit rows cleared (ids invalid) before the call;
    afterwards t, u, v, prim, geom, instance ((N,) arrays) and normal ((N, 3)) per ray."""
    pack = _ray_in() + _store(TFAR, "%tfar", "float", "tfar") + "  %active = icmp eq i64 0, 0\n"
    for row in range(NG, V + 1):
        pack += _store(row, "0.0", "float", f"hit{row}")
    for row in (PRIM, GEOM, INST):
        pack += _store(row, "-1", "i32", f"id{row}")
    unpack = "".join(_copy_out(row, array, "%j", f"out{row}") for row, array in
                     ((TFAR, "%t"), (U, "%u"), (V, "%v"), (PRIM, "%prim"), (GEOM, "%geom"), (INST, "%instance")))
    unpack += "  %j3 = mul i64 %j, 3\n  %j3y = add i64 %j3, 1\n  %j3z = add i64 %j3, 2\n"
    unpack += "".join(_copy_out(NG + axis, "%normal", index, f"normal{axis}")
                      for axis, index in enumerate(("%j3", "%j3y", "%j3z")))
    return _loop("closest", ", float %tfar, ptr %t, ptr %u, ptr %v, ptr %prim, ptr %geom, ptr %instance, ptr %normal",
                 pack, unpack)


def occluded_ir() -> str:
    """``occluded``: tfar per ray from ``distance``; a lane whose distance is not >= 0 is not traced.
    ``blocked`` (N bytes) is 1 where tfar ends negative: embree's -inf for an occluded ray, or a
    negative distance (NaN stays unblocked)."""
    pack = (_ray_in() + "  %distance_i = getelementptr float, ptr %distance, i64 %i\n"
            "  %tfar = load float, ptr %distance_i\n" + _store(TFAR, "%tfar", "float", "tfar")
            + "  %active = fcmp oge float %tfar, 0.0\n")
    unpack = (f"  %end_k = add i64 %out_lane, {TFAR * PACKET}\n"
              "  %end_p = getelementptr float, ptr %packet, i64 %end_k\n"
              "  %end = load float, ptr %end_p\n"
              "  %blocked_i1 = fcmp olt float %end, 0.0\n"
              "  %blocked_i8 = zext i1 %blocked_i1 to i8\n"
              "  %blocked_j = getelementptr i8, ptr %blocked, i64 %j\n"
              "  store i8 %blocked_i8, ptr %blocked_j\n")
    return _loop("occluded", ", ptr %distance, ptr %blocked", pack, unpack)


#: Each loop's IR compiled alone by llvmlite 0.50 for x86_64-unknown-linux-gnu, cpu "x86-64", PIC:
#: its object file's .text (the function at offset 0).
SHIPPED = {
    "closest": bytes.fromhex(
        "554889e54157415641554154534883e4c04881ec40060000488974244848897c24404d85c00f84900200004d89c64989"
        "cf4989d4488b7538488b7d304c8b45284c8b55204c8b5d184c8b6d104983c7084983c4084883c60831dbf30f1144243c"
        "eb4866666666662e0f1f8400000000004883c3104981c7c00000004981c4c00000004881c6c00000004883c7404983c0"
        "404983c2404983c3404983c5404983c1404c39f30f83110200004c895c24504c895424584c8944246048897c24684889"
        "7424704c894c247831c031c9e9050100006666666666662e0f1f840000000000418b5404f889948cc0000000418b5407"
        "f889948cc0010000418b5404fc89948c00010000418b5407fc89948c00020000418b140489948c40010000418b140789"
        "948c40020000c7848c8001000000000000c7848c8002000000000000c7848c00030000ffffffffc7848c400300000000"
        "0000c7848c8003000000000000f30f11848cc0020000c7848cc003000000000000c7848c0004000000000000c7848c40"
        "04000000000000c7848c8004000000000000c7848cc004000000000000c7848c00050000ffffffffc7848c40050000ff"
        "ffffffc7848c80050000ffffffffc7848c80000000ffffffff48ffc14883c00c4883f910731a488d140b4c39f20f82fd"
        "feffffc7848c8000000000000000ebd9488dbc2480000000488b742448488d9424c000000031c9ff542440f30f104424"
        "3c488b7424704889f031c94c8b4c2478488b7c24684c8b4424604c8b5424584c8b5c2450eb1b662e0f1f840000000000"
        "48ffc14883c00c4883f9100f831ffeffff488d140b4c39f273e68b948cc0020000418914898b948c800400004189548d"
        "008b948cc00400004189148b8b948c000500004189148a8b948c40050000418914888b948c8005000089148f8b948cc0"
        "0300008950f88b948c000400008950fc8b948c400400008910eb85488d65d85b415c415d415e415f5dc3"),
    "occluded": bytes.fromhex(
        "554889e54157415641554154534883e4c04881ec00060000488974243048897c24284d85c00f846b0100004d89c64989"
        "cf4989d44c8b6d104983c7084983c40831db0f57c9eb2c660f1f8400000000004883c3104983c1404981c7c000000049"
        "81c4c00000004983c5104c39f30f832301000031c031c9e9ac0000000f1f4000418b5404f889948c80000000418b5407"
        "f889948c80010000418b5404fc89948cc0000000418b5407fc89948cc0010000418b140489948c00010000418b140789"
        "948c00020000c7848c4001000000000000c7848c4002000000000000c7848cc0020000ffffffffc7848c000300000000"
        "0000c7848c4003000000000000f3410f100489f30f11848c800200000f2ec1ba0000000083d2ff89548c4048ffc14883"
        "c00c4883f9107318488d140b4c39f20f824bffffffc7448c4000000000ebdc90488d7c2440488b742430488d94248000"
        "000031c94c894c2438ff5424280f57c94c8b4c243831c0eb140f1f800000000048ffc04883f8100f83d3feffff488d0c"
        "034c39f173ea0f2e8c8480020000410f97440500ebda488d65d85b415c415d415e415f5dc3"),
}
_IR = {"closest": closest_ir, "occluded": occluded_ir}
_TYPES = {"closest": ClosestLoop, "occluded": OccludedLoop}
_lock = threading.Lock()


def closest_loop() -> ClosestLoop:
    """The closest-hit loop, as a ctypes function (calling it releases the GIL)."""
    return _loop_function("closest")


def occluded_loop() -> OccludedLoop:
    """The occlusion loop, as a ctypes function (calling it releases the GIL)."""
    return _loop_function("occluded")


def _loop_function(name: str):
    with _lock:
        return _loaded(name)[-1]


@functools.cache
def _loaded(name: str) -> tuple:
    if sys.platform == "linux" and platform.machine() == "x86_64":
        return executable_code(SHIPPED[name], _TYPES[name])
    return compiled_for_host(name)


def executable_code(code: bytes, function_type) -> tuple:
    """``code`` copied to fresh pages that are then made read+execute (never writable and
    executable at once); returns the pages and the function (the pages must outlive it)."""
    size = -(-len(code) // mmap.PAGESIZE) * mmap.PAGESIZE
    pages = mmap.mmap(-1, size, prot=mmap.PROT_READ | mmap.PROT_WRITE)
    pages.write(code)
    start = ctypes.c_char.from_buffer(pages)
    address = ctypes.addressof(start)
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [_vp, ctypes.c_size_t, ctypes.c_int]
    if libc.mprotect(address, size, mmap.PROT_READ | mmap.PROT_EXEC) != 0:
        raise UserError(f"this system refuses executable memory (mprotect: errno {ctypes.get_errno()}); "
                        "the renderer's ray tracing loop needs one page of it")
    return pages, start, function_type(address)


def compiled_for_host(name: str) -> tuple:
    """Loop ``name`` compiled for this machine by llvmlite; returns its engine (which owns the
    code) and the function."""
    try:
        import llvmlite.binding as llvm
    except ImportError as error:
        raise UserError("this platform needs llvmlite for the ray tracing loop: pip install llvmlite "
                        f"({error})") from None
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    module = llvm.parse_assembly(_IR[name]())
    module.verify()
    engine = llvm.create_mcjit_compiler(module, llvm.Target.from_default_triple().create_target_machine())
    engine.finalize_object()
    return engine, _TYPES[name](engine.get_function_address(name))
