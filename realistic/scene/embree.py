"""Embree 4 through its C API (ctypes), on the library the embreex wheel ships.

embreex 4.4's own binding copies triangle meshes into embree element by element, answers
single-ray queries, and binds no instancing. The C API of the same library has what the renderer
needs: meshes built from our float32 arrays without a copy (``rtcSetSharedGeometryBuffer``),
instances of one mesh's scene under several transforms (embree's two-level BVH), and packets of 16
rays per call, which ``scene/packet_loop`` packs, traces and unpacks over a whole batch in one call
(the GIL released), so several threads trace at once.

The packet loops are written for one layout of ``RTCRayHit16``, which depends on how embree was
built (``RTC_MAX_INSTANCE_LEVEL_COUNT``, instance arrays), and no device property reports it. So a
library is used only after a check (``configuration_problems``): its version is the tested one
(``rtcGetDeviceProperty``), it culls no back faces and has triangles, and a probe ray traced
through an instance, in a packet with sentinel rows far past the assumed ones, comes back with its
hit in the assumed rows and nothing written beyond them. A library that fails is refused with one
line naming it, its version and what differs; embreex's library is tried first, then a system-wide
``libembree4``, which is used only if it passes the same check.

A hit in an instanced scene reports the instance's id in instID and its normal in the instanced
mesh's object space.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import importlib.util
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.core.jit import compiled_loops
from realistic.errors import UserError
from realistic.scene import packet_loop
from realistic.scene.packet_loop import GEOM, INST, INST_PRIM, PRIM, RAY_ROWS, ROWS, TFAR, PacketFunction

_TRIANGLE, _INSTANCE = 0, 121  # RTCGeometryType
_INDEX_BUFFER, _VERTEX_BUFFER = 0, 1  # RTCBufferType
_UINT3, _FLOAT3, _FLOAT3X4_ROW_MAJOR = 0x5003, 0x9003, 0x9134  # RTCFormat
_OUT_OF_MEMORY, _UNSUPPORTED_CPU = 4, 5  # RTCError

_VERSION, _VERSION_MAJOR, _VERSION_MINOR, _VERSION_PATCH = 0, 1, 2, 3  # RTCDeviceProperty
_BACKFACE_CULLING_ENABLED, _TRIANGLE_GEOMETRY_SUPPORTED = 65, 96
_RAY_QUERY_FLAG_COHERENT, _FEATURE_FLAG_ALL = 1 << 16, 0xFFFFFFFF  # RTCRayQueryFlags, RTCFeatureFlags


class _IntersectArguments(ctypes.Structure):
    """RTCIntersectArguments (``embree4/rtcore_scene.h``): what ``rtcInitIntersectArguments``, an
    inline function of the header and so not in the library, sets, with the caller's flags. The last
    field is there only in an embree built with ``RTC_MIN_WIDTH``; it is 0 (the default) either way."""

    _fields_ = [("flags", ctypes.c_uint), ("feature_mask", ctypes.c_uint), ("context", ctypes.c_void_p),
                ("filter", ctypes.c_void_p), ("intersect", ctypes.c_void_p),
                ("min_width_distance_factor", ctypes.c_float)]


#: Closest-hit queries for coherent rays (camera rays, neighbours in a packet start together and
#: point nearly alike): embree's traversal for them, RTC_RAY_QUERY_FLAG_COHERENT, which the
#: documentation of rtcInitIntersectArguments recommends for primary rays (scattered rays, and the
#: shadow rays as the packet loops pack them, trace slower with it, so they keep the default)
_COHERENT = _IntersectArguments(_RAY_QUERY_FLAG_COHERENT, _FEATURE_FLAG_ALL, None, None, None, 0.0)

#: RTC_DEVICE_PROPERTY_VERSION (major * 10000 + minor * 100 + patch) of the embree releases the loops
#: are tested with: 4.4.x, as embreex 4.4 ships
TESTED_VERSIONS = range(40400, 40500)

_vp, _uint, _size = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
_SIGNATURES = {
    "rtcNewDevice": (_vp, [ctypes.c_char_p]),
    "rtcReleaseDevice": (None, [_vp]),
    "rtcGetDeviceProperty": (ctypes.c_ssize_t, [_vp, ctypes.c_int]),
    "rtcGetDeviceError": (ctypes.c_int, [_vp]),
    "rtcNewScene": (_vp, [_vp]),
    "rtcReleaseScene": (None, [_vp]),
    "rtcCommitScene": (None, [_vp]),
    "rtcNewGeometry": (_vp, [_vp, ctypes.c_int]),
    "rtcSetSharedGeometryBuffer": (None, [_vp, ctypes.c_int, _uint, ctypes.c_int, _vp, _size, _size, _size]),
    "rtcSetGeometryInstancedScene": (None, [_vp, _vp]),
    "rtcSetGeometryTransform": (None, [_vp, _uint, ctypes.c_int, _vp]),
    "rtcCommitGeometry": (None, [_vp]),
    "rtcAttachGeometryByID": (None, [_vp, _vp, _uint]),
    "rtcReleaseGeometry": (None, [_vp]),
}


def library_candidates() -> Iterator[Path]:
    """Where embree 4 may be: the libraries vendored in the embreex wheel (``embreex.libs`` on
    Linux and Windows, ``embreex/.dylibs`` on macOS), then a system-wide install, looked for only
    when asked for: ``ctypes.util.find_library`` runs ldconfig, gcc and ld on Linux, three
    processes at every start-up, where the wheel's library is the one used."""
    spec = importlib.util.find_spec("embreex")
    if spec is not None and spec.origin:
        package = Path(spec.origin).parent
        for folder in (package.parent / "embreex.libs", package / ".dylibs", package):
            yield from sorted(p for p in folder.glob("*embree4*") if p.is_file())
    system = ctypes.util.find_library("embree4")
    if system:
        yield Path(system)


@dataclass(frozen=True)
class Library:
    """A loaded embree 4 library, the device made on it (it lives as long as the process), and its
    packet functions as ctypes function objects, which the packet loops call."""

    path: Path
    lib: ctypes.CDLL
    device: int
    intersect16: Callable[..., None]
    occluded16: Callable[..., None]

    def version(self) -> str:
        """The library's version, as "major.minor.patch"."""
        return ".".join(str(self.lib.rtcGetDeviceProperty(self.device, p))
                        for p in (_VERSION_MAJOR, _VERSION_MINOR, _VERSION_PATCH))


def open_library(path: Path) -> Library:
    """The library at ``path`` with its signatures declared and a device made (not yet checked);
    OSError or AttributeError if it does not load or lacks a function."""
    lib = ctypes.CDLL(str(path))
    for name, (restype, argtypes) in _SIGNATURES.items():
        function = getattr(lib, name)
        function.restype, function.argtypes = restype, argtypes
    intersect16, occluded16 = (PacketFunction((name, lib)) for name in ("rtcIntersect16", "rtcOccluded16"))
    device = lib.rtcNewDevice(None)
    if not device:
        raise UserError(f"embree could not start on this machine (rtcNewDevice failed, {path})")
    return Library(path, lib, device, intersect16, occluded16)


@functools.cache
def embree_library() -> Library:
    """The process's embree: the first candidate that loads and passes ``configuration_problems``."""
    unloadable, refused = [], []
    for path in library_candidates():
        try:
            library = open_library(path)
        except (OSError, AttributeError) as error:
            unloadable.append(f"{path}: {error}")
            continue
        problems = configuration_problems(library)
        if not problems:
            return library
        library.lib.rtcReleaseDevice(library.device)
        refused.append(mismatch(library, problems))
    if refused:
        raise UserError("; ".join(refused))
    raise UserError("embree 4 was not found: install embreex (`pip install embreex`), whose wheel ships it"
                    + (f" ({'; '.join(unloadable)})" if unloadable else ""))


def mismatch(library: Library, problems: list[str]) -> str:
    """One line: the library, its version, and what differs from what the packet loops are written for."""
    return (f"embree {library.version()} at {library.path} is not the build the ray loops are written for "
            f"(embree 4.4.x, one instance level, instance arrays): {'; '.join(problems)}")


#: The probe: a triangle (geometry PROBE_GEOM) placed by an identity instance (PROBE_INSTANCE), hit
#: by lane 0 of a packet from above at t = 1, barycentrics (0.25, 0.25)
PROBE_GEOM, PROBE_INSTANCE = 5, 3
#: Instance levels the probe packet has rows for (instID and instPrimID each), so that an embree built
#: with up to this many cannot write past it
PROBE_LEVELS = 256
PROBE_ROWS = RAY_ROWS + packet_loop.HIT_ROWS + 2 * PROBE_LEVELS
SENTINEL = 0x5EE0F00D


def probe_packet(library: Library) -> np.ndarray:
    """The probe ray traced by ``library``'s rtcIntersect16 in a (PROBE_ROWS, 16) int32 packet whose
    rows past the ray hold SENTINEL except lane 0's hit rows, cleared (Ng, u, v 0; ids -1); lane 0
    alone is valid."""
    inner = EmbreeScene(library)
    inner.add_triangles(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]), PROBE_GEOM)
    inner.commit()
    top = EmbreeScene(library)
    top.add_instance(inner, np.eye(4), PROBE_INSTANCE)
    top.commit()
    buffer = packet_loop.packet_buffer(PROBE_ROWS + 1)
    packet, valid = buffer[:PROBE_ROWS], buffer[PROBE_ROWS]
    floats = packet.view(np.float32)
    packet[RAY_ROWS:] = SENTINEL
    floats[:7, 0] = 0.25, 0.25, 1, 0, 0, 0, -1
    floats[TFAR] = 10
    floats[RAY_ROWS:PRIM, 0] = 0
    packet[[PRIM, GEOM, INST], 0] = -1
    valid[:] = 0
    valid[0] = -1
    library.intersect16(valid.ctypes.data, top._handle, packet.ctypes.data, None)
    return packet


def configuration_problems(library: Library) -> list[str]:
    """What differs between ``library`` and the embree the packet loops are written for (nothing
    when it is that one): the version, back-face culling, triangle support, and the probe's packet
    (``probe_packet``): lane 0's hit in RTCRayHit16's rows (tfar, geomID, primID, instID, and
    instPrimID 0, a plain instance's, in the row after instID), and every other word as it was."""
    lib, device = library.lib, library.device
    version = lib.rtcGetDeviceProperty(device, _VERSION)
    if version not in TESTED_VERSIONS:
        return [f"version {library.version()}, where 4.4.x is tested"]
    problems = []
    if lib.rtcGetDeviceProperty(device, _BACKFACE_CULLING_ENABLED):
        problems.append("it is built to cull back faces")
    if not lib.rtcGetDeviceProperty(device, _TRIANGLE_GEOMETRY_SUPPORTED):
        problems.append("it is built without triangles")
    if problems:
        return problems
    packet = probe_packet(library)
    hit = [float(packet.view(np.float32)[TFAR, 0]), *(int(x) for x in packet[[GEOM, PRIM, INST], 0])]
    if hit != [1.0, PROBE_GEOM, 0, PROBE_INSTANCE]:
        problems.append(f"the probe's hit came back as tfar, geomID, primID, instID {hit} where "
                        f"{[1.0, PROBE_GEOM, 0, PROBE_INSTANCE]} are expected")
    instance_prim = int(packet[INST_PRIM, 0])
    if instance_prim == SENTINEL:
        problems.append(f"it wrote no instPrimID row (row {INST_PRIM}): built without instance arrays")
    elif instance_prim != 0:
        problems.append(f"row {INST_PRIM} came back {instance_prim} where instPrimID 0 is expected "
                        "(RTC_MAX_INSTANCE_LEVEL_COUNT > 1)")
    beyond = np.flatnonzero(np.any(packet[ROWS:] != SENTINEL, axis=1))
    if len(beyond):
        problems.append(f"it wrote row {ROWS + beyond[-1]} of the packet, past RTCRayHit16's {ROWS} rows "
                        "(RTC_MAX_INSTANCE_LEVEL_COUNT > 1)")
    if np.any(packet[RAY_ROWS:ROWS, 1:] != SENTINEL):
        problems.append("it wrote hit rows of lanes that were not valid")
    return problems


def _check(library: Library, what: str) -> None:
    code = library.lib.rtcGetDeviceError(library.device)
    if code == _OUT_OF_MEMORY:
        raise UserError(f"embree ran out of memory {what}")
    if code == _UNSUPPORTED_CPU:
        raise UserError("embree does not support this CPU")
    if code:
        raise RuntimeError(f"embree reported error {code} {what}")


@dataclass(frozen=True)
class RayHits:
    """Closest hits: ``geom`` the hit geometry's id in its own scene and ``instance`` the id of the
    instance it was reached through (both -1 where absent; ``geom`` -1 means a miss, whose ``t``
    is the tfar it was given); ``normal`` is embree's unnormalised Ng in the hit mesh's space."""

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    prim: np.ndarray
    geom: np.ndarray
    instance: np.ndarray
    normal: np.ndarray


class EmbreeScene:
    """One embree scene of triangle meshes and instances of other scenes, each under a caller's id.
    Add geometry, ``commit`` once (builds the BVH), then query from any number of threads. It is
    made on ``library``, by default the process's checked embree (``embree_library``)."""

    def __init__(self, library: Library | None = None) -> None:
        self._embree = library or embree_library()
        self._lib = self._embree.lib
        self._handle = self._lib.rtcNewScene(self._embree.device)
        self._keep: list = []  # embree reads these arrays and scenes for the scene's lifetime
        self.committed = False

    def __del__(self) -> None:
        if getattr(self, "_handle", None):
            self._lib.rtcReleaseScene(self._handle)

    def _attach(self, geometry: int, geom_id: int) -> None:
        self._lib.rtcCommitGeometry(geometry)
        self._lib.rtcAttachGeometryByID(self._handle, geometry, geom_id)
        self._lib.rtcReleaseGeometry(geometry)

    def add_triangles(self, vertices: np.ndarray, faces: np.ndarray, geom_id: int) -> None:
        """A triangle mesh ((V, 3) vertices, (F, 3) vertex indices), shared with embree, not copied
        again: the vertices are held as float32 with the one spare row embree's 16-byte reads need."""
        faces = np.ascontiguousarray(faces, np.uint32).reshape(-1, 3)
        if len(faces) and int(faces.max()) >= len(vertices):
            raise ValueError(f"a face names vertex {int(faces.max())} of {len(vertices)}")
        padded = np.zeros((len(vertices) + 1, 3), np.float32)
        padded[:-1] = vertices
        geometry = self._lib.rtcNewGeometry(self._embree.device, _TRIANGLE)
        self._lib.rtcSetSharedGeometryBuffer(geometry, _INDEX_BUFFER, 0, _UINT3, faces.ctypes.data, 0, 12, len(faces))
        self._lib.rtcSetSharedGeometryBuffer(geometry, _VERTEX_BUFFER, 0, _FLOAT3, padded.ctypes.data, 0, 12,
                                             len(vertices))
        self._attach(geometry, geom_id)
        self._keep += [faces, padded]

    def add_instance(self, scene: EmbreeScene, transform: np.ndarray, geom_id: int) -> None:
        """``scene`` (committed) placed by the affine ``transform`` (its top 3x4: object to this scene)."""
        matrix = np.ascontiguousarray(np.asarray(transform)[:3, :4], np.float32)
        geometry = self._lib.rtcNewGeometry(self._embree.device, _INSTANCE)
        self._lib.rtcSetGeometryInstancedScene(geometry, scene._handle)
        self._lib.rtcSetGeometryTransform(geometry, 0, _FLOAT3X4_ROW_MAJOR, matrix.ctypes.data)
        self._attach(geometry, geom_id)
        self._keep += [scene, matrix]

    def commit(self) -> None:
        self._lib.rtcCommitScene(self._handle)
        _check(self._embree, "building the scene")
        self.committed = True

    def intersect(self, origin: np.ndarray, direction: np.ndarray, tfar: float = 1e37,
                  coherent: bool = False) -> RayHits:
        """Closest hit of each ray (float32 (N, 3) origins and directions, t in [0, tfar]);
        ``coherent`` rays (camera rays) take embree's traversal for them (``_COHERENT``)."""
        origin, direction = _rays(origin, direction)
        self._require_committed()
        n = len(origin)
        hits = RayHits(t=np.empty(n, np.float32), u=np.empty(n, np.float32), v=np.empty(n, np.float32),
                       prim=np.empty(n, np.int32), geom=np.empty(n, np.int32), instance=np.empty(n, np.int32),
                       normal=np.empty((n, 3), np.float32))
        arrays = (hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.instance, hits.normal)
        arguments = ctypes.addressof(_COHERENT) if coherent else 0
        if compiled_loops():
            packet_loop.closest_loop()(self._embree.intersect16, self._handle, *packet_loop.packet_arguments(),
                                       arguments, origin, direction, np.float32(tfar), *arrays)
        else:
            packet_loop.trace_closest(self._embree.intersect16, self._handle, arguments, origin, direction,
                                      np.float32(tfar), *arrays)
        return hits

    def occluded(self, origin: np.ndarray, direction: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """True where something lies within [0, distance] of the ray, and where the distance is
        negative (embreex answered so; callers keep that); False where it is NaN."""
        origin, direction = _rays(origin, direction)
        distance = np.ascontiguousarray(distance, np.float32).reshape(-1)
        if len(distance) != len(origin):
            raise ValueError(f"{len(distance)} distances for {len(origin)} rays")
        self._require_committed()
        blocked = np.empty(len(origin), np.bool_)
        if compiled_loops():
            packet_loop.occluded_loop()(self._embree.occluded16, self._handle, *packet_loop.packet_arguments(),
                                        np.empty(packet_loop.PACKET, np.int64), origin, direction, distance, blocked)
        else:
            packet_loop.trace_occluded(self._embree.occluded16, self._handle, origin, direction, distance, blocked)
        return blocked

    def occluded_lanes(self, origin: np.ndarray, vector: np.ndarray, length: np.ndarray) -> np.ndarray:
        """``occluded`` for shadow rays in lanes (``packet_loop.LANE_DEFINES``): origin and vector
        (hits / 16, per, 3, 16) float32, length (hits / 16, per, 16) float32, traced hit by hit;
        the answers in length's shape."""
        groups, per, lanes = length.shape
        if origin.shape != (groups, per, 3, lanes) or vector.shape != origin.shape or lanes != packet_loop.PACKET:
            raise ValueError(f"shadow rays in lanes {origin.shape}, {vector.shape} for lengths {length.shape}")
        self._require_committed()
        blocked = np.empty(length.shape, np.bool_)
        origin, vector, length = (np.ascontiguousarray(a, np.float32) for a in (origin, vector, length))
        if compiled_loops():
            packet_loop.occluded_lanes_loop()(self._embree.occluded16, self._handle, *packet_loop.packet_arguments(),
                                              np.empty(packet_loop.PACKET, np.int64), origin.reshape(-1),
                                              vector.reshape(-1), length.reshape(-1), per, blocked.reshape(-1))
        else:
            packet_loop.trace_occluded_lanes(self._embree.occluded16, self._handle, origin, vector, length, blocked)
        return blocked

    def _require_committed(self) -> None:
        if not self.committed:
            raise RuntimeError("commit the embree scene before tracing it")


def _rays(origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions as contiguous float32 (N, 3) arrays, as the loops read them."""
    origin = np.ascontiguousarray(origin, np.float32).reshape(-1, 3)
    direction = np.ascontiguousarray(direction, np.float32).reshape(-1, 3)
    if len(origin) != len(direction):
        raise ValueError(f"{len(origin)} origins and {len(direction)} directions")
    return origin, direction


def compile_trace_loops() -> None:
    """Trace no rays through an empty scene. The process's first trace compiles the packet loops
    (``scene/packet_loop``: numba's import and its compile or cache load, Python that holds the GIL
    for half a second to a second); a render does this on a thread of its own as it starts, beside
    its OpenCL builds (which run without the GIL), not in its first pass after them. The arrays are
    of the types every trace passes (``_rays``), so nothing is compiled twice."""
    scene = EmbreeScene()
    scene.commit()
    none = np.empty((0, 3), np.float32)
    scene.intersect(none, none)
    scene.occluded(none, none, np.empty(0, np.float32))
    lanes = np.empty((0, 1, 3, packet_loop.PACKET), np.float32)
    scene.occluded_lanes(lanes, lanes, np.empty((0, 1, packet_loop.PACKET), np.float32))
