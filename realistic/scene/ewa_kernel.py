"""MIP-map lookups (EWA, bilinear, point, trilinear) on the OpenCL device (``kernels/ewa.cl``), for the
"opencl" backend.

The numpy ``MipMap.ewa`` expands every (lookup, texel) tap into flat arrays: about 0.07 M lookups/s,
the largest cost of a homework render's floor. The kernel runs the same mathematics per lookup in
single precision, as pbrt-v3's ``Float`` and the reference do (one work-item loops over its ellipse),
so it agrees with the reference to the rounding of the level's log2; ``tests/test_ewa_kernel.py``
checks that. EWA's lookups are float32 rows (``lookup_dtype``), the other filters' float64.

Most of a render's lookups are magnified (the minor axis under a texel, so level 0 alone) over a
few texels: ``ewa_small`` does those vectorised over work items (``ewa``, a work item's loops over
its ellipse, runs scalar) and marks the others, which ``ewa`` does; the same bits either way.

``SurfaceTables`` and ``EwaKernel.at_hits`` go one step further for the renderer: from embree's hit
records to the albedo, with the uv, the pixel footprint and the st mapping computed on the device
too (``hit_lookups``, or ``hit_lookups_single`` for EWA's float32 rows, vectorised like
``ewa_small``, on the rows of the texture's material that the
renderer picks; numpy spent three times as long on those as on the lookups). Its reference is
``DirectLighting._albedo`` (``tests/test_ewa_hits.py``).

``bilinear_small`` and ``bilinear`` filter the same lookups with pbrt-v4's "bilinear" filter (one
bilinear lookup at the level the footprint's width picks: ``MipMap.bilinear_at_width``, bit for bit),
pbrt-v4's default and the filter Mitsuba's ``bitmap`` uses, split as EWA's are (level 0 vectorised,
the others scalar); ``point_small``/``point`` (pbrt-v4's nearest texel: ``MipMap.point``, bit for
bit) and ``trilinear_small``/``trilinear`` (``MipMap.trilinear``, to float32 rounding: its blend
weight comes from log2) likewise, the map's ``trilinear_blend_from`` (pbrt-v3's blend or pbrt-v4's)
their last argument. ``DEVICE_FILTERS`` names the filters done here. A lookup without a
footprint (a ``hit_mapping`` of spread 0: the path integrator's deeper bounces) is level 0 bilinear
whatever the filter, as ``textures.evaluate`` has it, so ``at_hits`` filters those with "bilinear", as
does ``lookup``, the ``textures.ImageLookup`` the "opencl" backend gives ``SurfaceParameters``.

``FootprintKernel`` (``triangle_footprints``) computes ``renderer.footprint.triangle_footprint``,
its numpy reference, on the device with ``hit_lookups``' own footprint code (one definition in
``ewa.cl``), for the image textures of ``SurfaceParameters`` (the path integrator's per-hit parameters
and albedo), which the host looks up over the footprints of camera-ray hits: to float64 rounding of
the reference (``tests/test_footprint_kernel.py``).

An ``EwaKernel`` is made for a MIP map on a ``Device`` and kept by the render backend that made it
(``realistic.renderer.backends``), keyed by the map: the map itself stays plain data. Each thread
launches on its own queue with its own kernel objects (``_ThreadKernels``: a kernel object's
arguments are its state), so a render's threads filter side by side, not one at a time.
"""

from __future__ import annotations

import threading

import numpy as np

from realistic.core.validation import TEXTURE_WRAPS
from realistic.device.opencl import LOCAL_SIZE, Device, OutputBlock, TypedKernel, cl, kernel_source, whole_groups
from realistic.device.tables import Table
from realistic.scene.intersect import Hits
from realistic.scene.mipmap import EWA_WEIGHTS, MipMap
from realistic.scene.model import ImageTexture
from realistic.scene.textures import Footprint, st_mapping

KERNEL_FILE = "ewa.cl"
#: ``hit_lookups``' MAPPING row (float64), declared once for the kernel and ``hit_mapping``: the camera's
#: spread (radians per pixel), st = (uv * st_scale + st_offset) * (1, t_flip) + (0, t_shift)
#: (``textures.st_mapping``), and the material's diffuse colour.
MAPPING = Table("MAPPING", np.float64, (("spread", 1), ("st_scale", 2), ("st_offset", 2), ("t_flip", 1),
                                        ("t_shift", 1), ("diffuse", 3)))
#: The image-texture filters (``validation.TEXTURE_FILTERS``) an ``EwaKernel`` runs on the device.
DEVICE_FILTERS = ("ewa", "bilinear", "point", "trilinear")
#: The generated head of ``ewa.cl``'s source: MAPPING's offsets and the weights table's size (an
#: ``EwaKernel`` adds its map's ``WRAP``).
HEADER = MAPPING.defines() + f"#define LUT_SIZE {len(EWA_WEIGHTS)}\n"


def lookup_dtype(texture_filter: str) -> type[np.floating]:
    """The type of a filter's lookup rows: float32 for EWA (``MipMap.ewa`` rounds its input to
    float32, as pbrt-v3's ``Float``), float64 for the others (their references read float64)."""
    return np.float32 if texture_filter == "ewa" else np.float64


def build_ewa_program(device: Device, wrap: str) -> cl.Program:
    """``ewa.cl`` built on ``device`` for the wrap mode ``wrap`` (``validation.TEXTURE_WRAPS``): one
    program per mode, built once per process (``Device.build_program``)."""
    source = HEADER + f"#define WRAP {TEXTURE_WRAPS.index(wrap)}\n" + kernel_source(KERNEL_FILE)
    # EWA's float32 divisions correctly rounded, as numpy's (OpenCL allows 2.5 ulps without it)
    return device.build_program(source, KERNEL_FILE, ("-cl-fp32-correctly-rounded-divide-sqrt",))


class SurfaceTables:
    """A scene's triangles as ``hit_lookups`` reads them, wrapped once per render: faces (F, 3) of
    concatenated vertex indices, float64 vertices (V, 3) in mesh space, float32 uvs (V, 2), and per
    instance (embree geometry id) its first face and linear map (3 x 3)."""

    def __init__(self, device: Device, faces: np.ndarray, vertices: np.ndarray, uv: np.ndarray,
                 geom_face_offset: np.ndarray, geom_linear: np.ndarray):
        self.buffers = [device.wrapped_buffer(a, dtype) for a, dtype in
                        ((faces, np.int32), (vertices, np.float64), (uv, np.float32), (geom_face_offset, np.int32),
                         (geom_linear, np.float64))]


def hit_mapping(texture: ImageTexture, diffuse: np.ndarray | tuple[float, float, float],
                spread_radians: float) -> np.ndarray:
    """``hit_lookups``' ``MAPPING`` row (the diffuse colour's float32 values, exact in float64)."""
    repeats, offset, flip, shift = st_mapping(texture)
    return MAPPING.pack(1, spread=spread_radians, st_scale=repeats, st_offset=offset, t_flip=flip[1],
                        t_shift=shift[1], diffuse=np.asarray(diffuse, np.float32))[0]


class _ThreadKernels:
    """One thread's command queue and kernel objects over an ``EwaKernel``'s program, each made on its
    first use (a texture has one filter: making all nine for every thread and map cost more than the
    lookups of a small render)."""

    def __init__(self, device: Device, program: cl.Program):
        self.queue = device.queue()
        self._program = program
        #: hit_lookups and hit_lookups_single (EWA's float32 lookups), each made on its first use
        self._hits: dict[bool, TypedKernel] = {}
        #: per filter, its kernel for the small lookups and the one for the lookups it leaves pending
        self._filters: dict[str, tuple[TypedKernel, TypedKernel]] = {}

    def hits(self, single: bool) -> TypedKernel:
        """``hit_lookups``, or ``hit_lookups_single`` (float32 lookups, EWA's) where ``single``."""
        kernel = self._hits.get(single)
        if kernel is None:
            kernel = self._hits[single] = TypedKernel(self._program, "hit_lookups_single" if single else "hit_lookups")
        return kernel

    def filter(self, name: str) -> tuple[TypedKernel, TypedKernel]:
        """The filter ``name``'s two kernels (``DEVICE_FILTERS``): ``{name}_small`` and ``{name}``."""
        kernels = self._filters.get(name)
        if kernels is None:
            kernels = self._filters[name] = (TypedKernel(self._program, f"{name}_small"),
                                             TypedKernel(self._program, name))
        return kernels


class EwaKernel:
    """One MIP map's texels on a device, and lookups over them with each of ``DEVICE_FILTERS``
    (thread-safe: a queue and kernel objects per calling thread)."""

    def __init__(self, mipmap: MipMap, device: Device | None = None):
        """``device``: where the texels go (None: ``Device.for_spec()``, the default device)."""
        sides = np.concatenate([mipmap.level_width, mipmap.level_height])
        if np.any(sides & (sides - 1)):  # the kernel wraps with x & (w - 1)
            raise ValueError(f"MIP map levels must have power-of-two sides, not {sides.tolist()}")
        device = device or Device.for_spec()
        self.device = device
        self.context = device.context
        self._program = build_ewa_program(device, mipmap.wrap)
        # the texels wrapped, not copied, so they are not held twice
        # the map's kernel arguments: its buffers, then its scalars
        self._map: list[cl.Buffer | np.generic] = [
            device.wrapped_buffer(mipmap.texels, np.float32),
            *(device.wrapped_buffer(a, np.int64) for a in (mipmap.level_base, mipmap.level_width, mipmap.level_height)),
            np.int32(mipmap.level_count),
            np.float64(mipmap.max_anisotropy), device.wrapped_buffer(EWA_WEIGHTS, np.float32)]
        #: per filter, the arguments its two kernels take after their common ones
        self._own: dict[str, tuple[np.generic, ...]] = {name: () for name in DEVICE_FILTERS}
        self._own["trilinear"] = (np.int32(mipmap.trilinear_blend_from),)
        self._local = threading.local()

    def _thread(self) -> _ThreadKernels:
        """The calling thread's queue and kernels, made on its first call."""
        kernels: _ThreadKernels | None = getattr(self._local, "kernels", None)
        if kernels is None:
            kernels = self._local.kernels = _ThreadKernels(self.device, self._program)
        return kernels

    def __call__(self, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray, texture_filter: str = "ewa") -> np.ndarray:
        """Colours (N, 3) float32 at (s, t) (N, 2) filtered (``DEVICE_FILTERS``) over footprints with
        axes (N, 2) each."""
        lookups = np.empty((len(st), 6), lookup_dtype(texture_filter))
        with np.errstate(over="ignore"):  # past float32's range: infinite, which EWA filters to 0
            for column, values in enumerate((st, axis0, axis1)):
                lookups[:, 2 * column:2 * column + 2] = values
        return self._filter(lookups, np.ones(3, np.float32), texture_filter)

    def lookup(self, texture_filter: str, st: np.ndarray, axes: Footprint | None) -> np.ndarray:
        """A ``textures.ImageLookup`` on this map: ``texture_filter`` over ``axes``, or without a
        footprint (None) "bilinear" over zero axes (width 0: level 0, as ``MipMap.bilinear``)."""
        if axes is None:
            zero = np.zeros_like(st)
            return self(st, zero, zero, "bilinear")
        return self(st, axes[0], axes[1], texture_filter)

    def _filter(self, lookups: np.ndarray, scale: np.ndarray, texture_filter: str,
                lookup_buffer: cl.Buffer | None = None) -> np.ndarray:
        """The filtered colours (N, 3) float32 times ``scale`` (3,) float32 of the lookups (s, t, axis0,
        axis1) (N, 6) of the filter's ``lookup_dtype`` (``lookup_buffer``: the buffer over them that a
        kernel queued before this writes; None: wrapped here): the filter's small kernel
        (``ewa_small``, ``bilinear_small``, ...) over all, then its other kernel (``ewa``,
        ``bilinear``, ...) over the rows it leaves, reading them from the same lookups and writing them
        into their rows of the colours (no gathered copies), each with the filter's own arguments
        last. The colours and the small kernel's marks of the rows it leaves are one ``OutputBlock``:
        one read brings both, and where no row is left nothing more is queued."""
        if texture_filter not in DEVICE_FILTERS:
            raise ValueError(f"the device filters with {' or '.join(DEVICE_FILTERS)}, not {texture_filter!r}")
        count = len(lookups)
        if count == 0:
            return np.empty((0, 3), np.float32)
        outputs = OutputBlock(self.device, (((count, 3), np.float32), ((count,), np.uint8)), cl.mem_flags.READ_WRITE)
        out, pending = outputs.arrays
        colours, marks = outputs.parts
        inputs = [self.device.wrapped_buffer(lookups, lookup_dtype(texture_filter)) if lookup_buffer is None
                  else lookup_buffer]
        scales = [np.float32(v) for v in scale]
        kernels = self._thread()
        small, other = kernels.filter(texture_filter)
        try:
            small(kernels.queue, (whole_groups(count),), (LOCAL_SIZE,), *self._map, *inputs, *scales, np.int32(count),
                  np.int32(1), marks, colours, *self._own[texture_filter])
            outputs.read(kernels.queue)
            rest = np.flatnonzero(pending)
            if len(rest):
                # kept until the blocking read below: the buffer holds the int32 rows' only reference
                inputs.append(self.device.wrapped_buffer(rest, np.int32))
                other(kernels.queue, (whole_groups(len(rest)),), (LOCAL_SIZE,), *self._map, *inputs, *scales,
                      np.int32(len(rest)), colours, *self._own[texture_filter])
                outputs.read(kernels.queue)
        finally:
            outputs.release()
        return out

    def at_hits(self, surfaces: SurfaceTables, rows: np.ndarray, mapping: np.ndarray, direction: np.ndarray,
                hits: Hits, texture_filter: str = "ewa") -> np.ndarray:
        """The albedo (len(rows), 3) float32 of the rays ``rows`` (int32) among those with unit
        ``direction`` (N, 3), whose closest hits (``scene.intersect.Hits``) are on instances of a
        material whose image texture this map is (``hit_mapping``), filtered with ``texture_filter``
        (``DEVICE_FILTERS``; with "bilinear" where ``mapping``'s spread is 0: no footprint, level 0):
        ``hit_lookups``' kernel makes their lookups and ``_filter`` filters them, times the diffuse
        colour, from the lookups' buffer: they are not read back between the two (the queue orders
        them). The caller picks the rows and places the colours (one pass each)."""
        launched = self._launch_hit_lookups(surfaces, rows, mapping, direction, hits, texture_filter)
        lookups, written, texture_filter, _inputs = launched  # the inputs held until the filter's reads
        diffuse = MAPPING.offset("diffuse")
        try:
            return self._filter(lookups, mapping[diffuse:diffuse + 3].astype(np.float32), texture_filter, written)
        finally:
            if written is not None:
                # waits for nothing after the filter's reads; for the kernel where the filter raised before them
                self._thread().queue.finish()
                written.release()

    def hit_lookups(self, surfaces: SurfaceTables, rows: np.ndarray, mapping: np.ndarray, direction: np.ndarray,
                    hits: Hits, texture_filter: str = "ewa") -> tuple[np.ndarray, str]:
        """``at_hits``' lookups (len(rows), 6) (s, t, axis0, axis1) of the filter's ``lookup_dtype``, made
        by the kernel ``hit_lookups`` (float64) or ``hit_lookups_single`` (float32, EWA's), and the
        filter they are for (``texture_filter``, or "bilinear" where ``mapping``'s spread is 0)."""
        lookups, written, texture_filter, _inputs = self._launch_hit_lookups(surfaces, rows, mapping, direction, hits,
                                                                             texture_filter)
        if written is not None:
            # a read into the buffer's own host pointer: PoCL copies nothing; it orders the read after the kernel
            cl.enqueue_copy(self._thread().queue, lookups, written)
            written.release()
        return lookups, texture_filter

    def _launch_hit_lookups(self, surfaces: SurfaceTables, rows: np.ndarray, mapping: np.ndarray,
                            direction: np.ndarray, hits: Hits, texture_filter: str
                            ) -> tuple[np.ndarray, cl.Buffer | None, str, list[cl.Buffer]]:
        """``hit_lookups``' kernel queued on this thread's queue, not waited for: the lookups' array,
        the buffer over it that the kernel writes (None for no rows: no launch), the filter, and the
        input buffers, which the caller holds until a blocking read or wait after the kernel."""
        if rows.dtype != np.int32:
            raise ValueError(f"at_hits reads int32 rows, not {rows.dtype}")
        footprint = mapping[MAPPING.offset("spread")] > 0
        texture_filter = texture_filter if footprint else "bilinear"
        lookups = np.empty((len(rows), 6), lookup_dtype(texture_filter))
        if len(rows) == 0:
            return lookups, None, texture_filter, []
        inputs = [self.device.wrapped_buffer(a, dtype)
                  for a, dtype in ((mapping, np.float64), (direction, np.float32), (hits.t, np.float32),
                                   (hits.u, np.float32), (hits.v, np.float32), (hits.prim, np.int32),
                                   (hits.geom, np.int32), (hits.normal, np.float32), (rows, np.int32))]
        written = self.device.host_buffer(lookups, cl.mem_flags.READ_WRITE)
        kernels = self._thread()
        kernels.hits(lookups.dtype == np.float32)(kernels.queue, (whole_groups(len(rows)),), (LOCAL_SIZE,),
                                                  *surfaces.buffers, *inputs, np.int32(len(rows)), np.int32(1), written)
        return lookups, written, texture_filter, inputs


class FootprintKernel:
    """``renderer.footprint.triangle_footprint`` on a device (``ewa.cl``'s ``triangle_footprints``,
    from the program a repeat-wrapped map's ``EwaKernel`` uses: no build of its own where a scene has
    one), thread-safe as ``EwaKernel`` is (a queue and kernel object per calling thread)."""

    def __init__(self, device: Device):
        self.device = device
        self._program = build_ewa_program(device, "repeat")
        self._local = threading.local()

    def _thread(self) -> tuple[cl.CommandQueue, TypedKernel]:
        """The calling thread's queue and kernel, made on its first call."""
        made: tuple[cl.CommandQueue, TypedKernel] | None = getattr(self._local, "made", None)
        if made is None:
            made = self._local.made = (self.device.queue(), TypedKernel(self._program, "triangle_footprints"))
        return made

    def __call__(self, vertices: np.ndarray, uv: np.ndarray, linear: np.ndarray, face: np.ndarray,
                 geom: np.ndarray, direction: np.ndarray, normal: np.ndarray, distance: np.ndarray,
                 spread_radians: float) -> Footprint:
        """The uv axes (N, 2) float64 of the pixel footprints of hits on triangles ``face`` (N, 3)
        (rows of a mesh's ``vertices`` (V, 3) and ``uv`` (V, 2), read as float64 and float32 as the
        reference reads them) placed in the world by ``linear[geom]`` (``linear`` (G, 3, 3), ``geom``
        (N,)), with unit ``direction`` and ``normal`` (N, 3) and hit ``distance`` (N,):
        ``triangle_footprint(vertices, uv, face, linear[geom], direction, normal, distance,
        spread_radians)`` to float64 rounding."""
        count = len(face)
        axes = np.empty((count, 2), np.float64), np.empty((count, 2), np.float64)
        if count == 0:
            return axes
        arguments = [self.device.wrapped_buffer(a, dtype) for a, dtype in
                     ((face, np.int32), (vertices, np.float64), (uv, np.float32), (linear, np.float64),
                      (geom, np.int32), (direction, np.float64), (normal, np.float64), (distance, np.float64))]
        queue, kernel = self._thread()
        self.device.run_into(queue, kernel, (whole_groups(count),), (LOCAL_SIZE,),
                             (*arguments, np.float64(spread_radians), np.int32(count), np.int32(1)), axes)
        return axes
