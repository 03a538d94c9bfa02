"""Loops that trace a whole batch of rays through embree's 16-ray packets in one call, the GIL released.

embree 4 traces at most 16 rays per call (``rtcIntersect16``, ``rtcOccluded16``) and wants each
packet as rows of 16 lanes. Called per packet from Python, the calls cost about as much as the
traversal and released and took back the GIL every 16 rays, which convoyed the render threads;
packing the rows in numpy cost much of the traversal again. These loops read the caller's (N, 3)
float32 origins and directions, fill one packet at a time, call embree, and write the hits to the
caller's arrays: a batch is one call, with the GIL released throughout, so several render threads
trace at once.

They are numba functions (``njit(nogil=True, cache=True)``), compiled on the first trace of a
process; numba is imported then, not with the package, so ``import realistic`` and ``--help`` stay
quick. embree's packet function reaches them as an argument, a ctypes function object whose address
numba reads at each call, so the compiled code holds no address of the process that compiled it and
numba can cache it on disk: in ``$NUMBA_CACHE_DIR`` if set, else in ``__pycache__`` beside this
file where that is writable, else (an installed, read-only package) in the user's cache directory
(``~/.cache/numba`` on Linux); where none is writable the loops are compiled in every process,
uncached. That first trace is the loops' start-up cost: numba's import, and its
first compile or cache load, which imports numba's own typing and lowering modules (and scipy's
linalg, when installed, for its BLAS check); ``bench/embree_loop.py`` measures it, cold and warm.
A render too small to repay that (``renderer.runner.choose_loops``) never imports numba: there
``trace_closest`` and ``trace_occluded`` make every packet in numpy at once and call embree once
per packet from Python, with the same packets lane for lane, so the same answers.

Packet rows (``embree4/rtcore_ray.h``, ``RTCRayHit16``): org_x, org_y, org_z, tnear, dir_x, dir_y,
dir_z, time, tfar, mask, id, flags (``RTCRay16`` ends here), then the hit's Ng_x, Ng_y, Ng_z, u, v,
primID, geomID, ``RTC_MAX_INSTANCE_LEVEL_COUNT`` rows of instID and, when embree is built with
instance arrays, as many rows of instPrimID. ``ROWS`` is that count for the configuration embree
4.4 is built with by default and as the embreex wheel ships it (one instance level, instance
arrays on); ``scene/embree`` checks the library it loads against it before any loop runs.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable

import numpy as np

from realistic.core.jit import compiled

PACKET = 16  # rays per rtcIntersect16 / rtcOccluded16 call
RAY_ROWS = 12  # rows of RTCRay16
HIT_ROWS = 7  # RTCHit16's rows before instID: Ng_x, Ng_y, Ng_z, u, v, primID, geomID
INSTANCE_LEVELS = 1  # RTC_MAX_INSTANCE_LEVEL_COUNT the loops are written for
ROWS = RAY_ROWS + HIT_ROWS + 2 * INSTANCE_LEVELS  # RTCRayHit16 with instID and instPrimID rows
TNEAR, TIME, TFAR, MASK, ID, FLAGS = 3, 7, 8, 9, 10, 11  # row numbers
NG, U, V, PRIM, GEOM, INST = 12, 15, 16, 17, 18, 19
INST_PRIM = INST + INSTANCE_LEVELS
VALID = ROWS  # the packet buffer's row after RTCRayHit16: the valid mask (-1 traced, 0 not)
ALIGNMENT = 64  # bytes: RTCRayHit16 is RTC_ALIGN(64), and embree loads the valid mask as one vector

#: Shadow rays in lanes, as ``kernels/shade.cl`` writes them (these defines head its source) and
#: ``_occluded_lanes`` reads them: hits in groups of ``PACKET`` (``LANES``, the kernel's work-group
#: size), and in a group, for each of the ``per`` rays per hit and each of an output's ``width``
#: values, the group's hits side by side: value c of hit i's k-th ray at ((i / 16 per + k) width +
#: c) 16 + i % 16, numpy's (hits / 16, per, width, 16) array ``[i // 16, k, c, i % 16]``
#: (``shadow_lanes``). Neighbouring work items' values are adjacent, so the kernel stores a vector of
#: them at once, where (N, width) rows made each store a scatter; a group's rays lie together, so
#: the packet loop reads each output as one stream (planes of one value across all hits, per k and
#: c, cost it more: 28 streams).
LANE_DEFINES = (f"#define LANES {PACKET}\n#define LANE_AT(a, per, width, k, c, group, lane) "
                "((a)[(((group) * (per) + (k)) * (width) + (c)) * LANES + (lane)])\n")

#: rtcIntersect16 and rtcOccluded16: (const int* valid, RTCScene, RTCRayHit16* or RTCRay16*, arguments*)
PacketFunction = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)


def shadow_lanes(values: np.ndarray, per: int, width: int, hits: int) -> np.ndarray:
    """The first hits per width of flat ``values`` (``hits`` a multiple of ``PACKET``) as
    (hits / 16, per, width, 16) lanes (``LANE_DEFINES``)."""
    return values[:hits * per * width].reshape(hits // PACKET, per, width, PACKET)


def lane_rows(lanes: np.ndarray) -> np.ndarray:
    """Lanes ((hits / 16, per, width, 16), or a length's (hits / 16, per, 16)) as rows per hit:
    (hits, per, width), or (hits, per), hit i's k-th ray at [i, k] (``shadow_lanes``' inverse): a
    copy, never a view of the lanes (the shading kernel's outputs are reused by its next launch)."""
    return np.array(np.moveaxis(lanes, -1, 1)).reshape(-1, *lanes.shape[1:-1])


def _aligned_packets(count: int, rows: int) -> np.ndarray:
    """(count, rows, 16) int32 packets in one 64-byte aligned block (a row is 64 bytes, so each
    packet is aligned), zero but for every mask bit: the ray rows that no trace changes (tnear,
    time, mask, id, flags) are set."""
    raw = np.zeros(count * rows * PACKET + ALIGNMENT // 4, np.int32)
    start = (-raw.ctypes.data % ALIGNMENT) // 4
    block = raw[start:start + count * rows * PACKET].reshape(count, rows, PACKET)
    block[:, MASK] = -1
    return block


def packet_buffer(rows: int = ROWS + 1) -> np.ndarray:
    """A (rows, 16) int32 packet, 64-byte aligned, its ray rows that no trace changes already set:
    tnear and time 0, every mask bit, id and flags 0. The loops take ``ROWS + 1`` rows (the last
    is the valid mask); each call gets its own, so threads share none."""
    return _aligned_packets(1, rows)[0]


def packet_arguments() -> tuple[np.ndarray, np.ndarray, int, int]:
    """A new ``packet_buffer`` for one call of a loop, with what the loops take beside it: its
    float32 view and the addresses of its valid mask and of its RTCRayHit16. Made here, not in the
    loops: numba compiles a view or a slice's address in a loop as code of its own (a fifth of a
    loop's first compile, which a first render waits for)."""
    packet = packet_buffer()
    return packet, packet.view(np.float32), packet[VALID:].ctypes.data, packet.ctypes.data


def _closest(function: Callable[..., None], scene: int, packet: np.ndarray, floats: np.ndarray, valid: int,
             rayhit: int, arguments: int, origin: np.ndarray, direction: np.ndarray, tfar: np.float32, t: np.ndarray,
             u: np.ndarray, v: np.ndarray, prim: np.ndarray, geom: np.ndarray, instance: np.ndarray,
             normal: np.ndarray) -> None:
    """Closest hits of ``origin``/``direction`` ((N, 3) float32) within [0, tfar], copied to t, u,
    v, prim, geom, instance ((N,) arrays) and normal ((N, 3)). Each lane's geomID and instID are
    set invalid (-1) before the call, as embree asks; a hit writes every hit row, so a miss (geomID
    still -1) is copied as Ng, u, v 0 and primID -1, without clearing those rows per lane (a
    quarter of the loop's own time); it keeps tfar as t. The packet, its float32 view and the
    addresses embree takes come from ``packet_arguments``; ``arguments`` is the address of the
    calls' RTCIntersectArguments, or 0 for embree's defaults."""
    count = origin.shape[0]
    for base in range(0, count, PACKET):
        lanes = count - base if count - base < PACKET else PACKET
        for lane in range(PACKET):
            packet[VALID, lane] = -1 if lane < lanes else 0
        for lane in range(lanes):
            i = base + lane
            for axis in range(3):
                floats[axis, lane] = origin[i, axis]
                floats[4 + axis, lane] = direction[i, axis]
            floats[TFAR, lane] = tfar
            packet[GEOM, lane] = -1
            packet[INST, lane] = -1
        function(valid, scene, rayhit, arguments)
        for lane in range(lanes):
            i = base + lane
            t[i] = floats[TFAR, lane]
            hit = packet[GEOM, lane]
            geom[i] = hit
            instance[i] = packet[INST, lane]
            if hit == -1:
                u[i] = 0.0
                v[i] = 0.0
                prim[i] = -1
                for axis in range(3):
                    normal[i, axis] = 0.0
            else:
                u[i] = floats[U, lane]
                v[i] = floats[V, lane]
                prim[i] = packet[PRIM, lane]
                for axis in range(3):
                    normal[i, axis] = floats[NG + axis, lane]


def _occluded(function: Callable[..., None], scene: int, packet: np.ndarray, floats: np.ndarray, valid: int,
              rayhit: int, rows: np.ndarray, origin: np.ndarray, direction: np.ndarray, distance: np.ndarray,
              blocked: np.ndarray) -> None:
    """Occlusion of each ray within [0, distance]: a ray whose distance is not >= 0 is not traced.
    ``blocked`` is True where tfar ends negative: embree's -inf for an occluded ray, or a negative
    distance (a NaN distance stays unblocked). The rays traced fill each packet's lanes in their
    order, the others skipped (a packet costs embree about as much with idle lanes as full); ``rows``
    (``PACKET`` int64) holds the lanes' ray numbers."""
    count = origin.shape[0]
    lanes = 0
    for i in range(count + 1):
        if i < count:
            if not distance[i] >= 0:
                blocked[i] = distance[i] < 0
                continue
            for axis in range(3):
                floats[axis, lanes] = origin[i, axis]
                floats[4 + axis, lanes] = direction[i, axis]
            floats[TFAR, lanes] = distance[i]
            rows[lanes] = i
            lanes += 1
            if lanes < PACKET:
                continue
        elif lanes == 0:
            break
        for lane in range(PACKET):
            packet[VALID, lane] = -1 if lane < lanes else 0
        function(valid, scene, rayhit, 0)
        for lane in range(lanes):
            blocked[rows[lane]] = floats[TFAR, lane] < 0
        lanes = 0


def _occluded_lanes(function: Callable[..., None], scene: int, packet: np.ndarray, floats: np.ndarray, valid: int,
                    rayhit: int, rows: np.ndarray, origin: np.ndarray, vector: np.ndarray, length: np.ndarray,
                    per: int, blocked: np.ndarray) -> None:
    """``_occluded`` for shadow rays in lanes (``LANE_DEFINES``), ``per`` per hit, each output flat:
    origin and vector of (hits / 16, per, 3, 16), length and ``blocked`` of (hits / 16, per, 16).
    Each hit's rays fill the packets' lanes one after another, hit by hit (as ``_occluded`` traces
    point-major rows), so embree traces a hit's shadow rays together; ``rows`` (``PACKET`` int64)
    holds the lanes' places in ``length``."""
    lanes = 0
    for lane in range(PACKET):
        packet[VALID, lane] = -1
    for group in range(len(length) // (per * PACKET)):
        for hit in range(PACKET):
            at = group * per * PACKET + hit  # the hit's k-th ray's length, (group per + k) 16 + hit
            ray = 3 * group * per * PACKET + hit  # its origin's and vector's x, ((group per + k) 3 + axis) 16 + hit
            for _ in range(per):
                distance = length[at]
                if distance >= 0:
                    for axis in range(3):
                        floats[axis, lanes] = origin[ray + axis * PACKET]
                        floats[4 + axis, lanes] = vector[ray + axis * PACKET]
                    floats[TFAR, lanes] = distance
                    rows[lanes] = at
                    lanes += 1
                    if lanes == PACKET:
                        function(valid, scene, rayhit, 0)
                        for lane in range(PACKET):
                            blocked[rows[lane]] = floats[TFAR, lane] < 0
                        lanes = 0
                else:
                    blocked[at] = distance < 0
                at += PACKET
                ray += 3 * PACKET
    if lanes:
        for lane in range(PACKET):
            packet[VALID, lane] = -1 if lane < lanes else 0
        function(valid, scene, rayhit, 0)
        for lane in range(lanes):
            blocked[rows[lane]] = floats[TFAR, lane] < 0


def closest_loop() -> Callable[..., None]:
    """``_closest`` compiled (``realistic.core.jit``): (function, scene, *``packet_arguments()``,
    arguments, origin, direction, tfar, t, u, v, prim, geom, instance, normal); it runs with the GIL released."""
    return compiled(_closest)


def occluded_loop() -> Callable[..., None]:
    """``_occluded`` compiled: (function, scene, *``packet_arguments()``, rows, origin, direction,
    distance, blocked), ``rows`` an empty (``PACKET``,) int64 array."""
    return compiled(_occluded)


def occluded_lanes_loop() -> Callable[..., None]:
    """``_occluded_lanes`` compiled: (function, scene, *``packet_arguments()``, rows, origin, vector,
    length, per, blocked), ``rows`` an empty (``PACKET``,) int64 array."""
    return compiled(_occluded_lanes)


def _packets(count: int) -> np.ndarray:
    """(count / 16 rounded up, ``ROWS + 1``, 16) int32 packets in one 64-byte aligned block, each
    set as ``packet_buffer`` sets one, its hit rows cleared (Ng, u, v 0; ids -1: a miss's rows as
    ``_closest`` copies them), its lanes from ``count`` on not valid."""
    block = _aligned_packets(-(-count // PACKET), ROWS + 1)
    block[:, PRIM:INST + 1] = -1
    _set_lanes(block[:, VALID:VALID + 1], np.full((count, 1), -1, np.int32))
    return block


def _set_lanes(lanes: np.ndarray, values: np.ndarray) -> None:
    """Rows (N, k) into the block's (packets, k, 16) ``lanes``, in order (the last packet's spare
    lanes left as they are)."""
    full, rest = divmod(len(values), PACKET)
    spread = lanes.transpose(0, 2, 1)  # (packets, 16, k)
    spread[:full] = values[:full * PACKET].reshape(full, PACKET, values.shape[1])
    if rest:
        spread[full, :rest] = values[full * PACKET:]


def _call_each(function: Callable[..., None], scene: int, block: np.ndarray, arguments: int = 0) -> None:
    """``function`` (rtcIntersect16 or rtcOccluded16) on each packet of ``block`` in turn, with the
    arguments struct at address ``arguments`` (0: none, embree's defaults)."""
    stride, valid = block.strides[0], VALID * block.strides[1]
    for address in range(block.ctypes.data, block.ctypes.data + len(block) * stride, stride):
        function(address + valid, scene, address, arguments or None)


def trace_closest(function: Callable[..., None], scene: int, arguments: int, origin: np.ndarray,
                  direction: np.ndarray, tfar: np.float32, t: np.ndarray, u: np.ndarray, v: np.ndarray,
                  prim: np.ndarray, geom: np.ndarray, instance: np.ndarray, normal: np.ndarray) -> None:
    """``_closest`` without numba: every packet made by numpy at once, then one call from Python
    per packet (a render too small to repay compiling the loop, ``core.jit.compiled_loops``). The
    packets are ``_closest``'s, lane for lane, so the hits are the same."""
    count = len(origin)
    block = _packets(count)
    floats = block.view(np.float32)
    _set_lanes(floats[:, 0:3], origin)
    _set_lanes(floats[:, 4:7], direction)
    floats[:, TFAR] = tfar
    _call_each(function, scene, block, arguments)
    t[:] = floats[:, TFAR].reshape(-1)[:count]
    u[:] = floats[:, U].reshape(-1)[:count]
    v[:] = floats[:, V].reshape(-1)[:count]
    prim[:] = block[:, PRIM].reshape(-1)[:count]
    geom[:] = block[:, GEOM].reshape(-1)[:count]
    instance[:] = block[:, INST].reshape(-1)[:count]
    normal[:] = floats[:, NG:NG + 3].transpose(0, 2, 1).reshape(-1, 3)[:count]


def trace_occluded(function: Callable[..., None], scene: int, origin: np.ndarray, direction: np.ndarray,
                   distance: np.ndarray, blocked: np.ndarray) -> None:
    """``_occluded`` without numba (see ``trace_closest``): the rays traced fill the packets' lanes in
    their order, as there, so the answers are the same."""
    blocked[:] = distance < 0
    traced = np.flatnonzero(distance >= 0)
    block = _packets(len(traced))
    floats = block.view(np.float32)
    _set_lanes(floats[:, 0:3], origin[traced])
    _set_lanes(floats[:, 4:7], direction[traced])
    _set_lanes(floats[:, TFAR:TFAR + 1], distance[traced, None])
    _call_each(function, scene, block)
    blocked[traced] = floats[:, TFAR].reshape(-1)[:len(traced)] < 0


def trace_occluded_lanes(function: Callable[..., None], scene: int, origin: np.ndarray, vector: np.ndarray,
                         length: np.ndarray, blocked: np.ndarray) -> None:
    """``_occluded_lanes`` without numba, on the (hits / 16, per, ...) lanes: the rays as point-major
    rows (hit i's k-th at i per + k), traced by ``trace_occluded``, whose lanes take them in that
    order, as there."""
    groups, per = length.shape[:2]
    rows = np.empty(groups * PACKET * per, np.bool_)
    trace_occluded(function, scene, lane_rows(origin).reshape(-1, 3), lane_rows(vector).reshape(-1, 3),
                   lane_rows(length).reshape(-1), rows)
    blocked[:] = rows.reshape(groups, PACKET, per).transpose(0, 2, 1)
