"""OpenCL host side of direct-lighting shading: ``kernels/shade.cl`` on PoCL, one launch per pass.

``DirectLighting`` (``renderer/direct_lighting.py``) uses this module when the render's backend is
"opencl" (``PassRunner`` passes it on); its numpy code stays the reference, and the tests compare
the two per hit (``tests/test_shade_kernel.py``). For each camera ray of a pass the kernel computes
the hit point, the geometric and shading normals, the albedo (constant, grid and checker materials;
image-textured rows come from the host: ``DirectLighting._host_albedo``) and, for every light
sample, the light point, the shadow ray and its contribution. It writes them in lanes, 16 rays' of
each light sample and component side by side (``packet_loop.LANE_DEFINES``: neighbouring work
items' values adjacent, so that each store is a vector store), and embree traces all of a launch's
shadow rays in one ``occluded_lanes`` call, each hit point's one after another (coherent); dead
samples have length -1, which embree skips. Measured materials
(pbrt-v2's irregular ``.brdf`` files, their tables from ``renderer.bsdf.measured.irregular_table``
one after another in one buffer) build the ``MEASURED`` variant: each light sample is paired with a
cosine-weighted BSDF sample, both weighted by the power heuristic as pbrt-v2's ``directlighting``
does (``EstimateDirect``), the k-th light sample a ray's shadow ray 2 k and its BSDF sample 2 k + 1.

The program source does not depend on the scene: the scene's tables (faces, vertex normals, uvs,
per-instance normal matrices and materials, lights and their CDF) are device buffers made once per
integrator. Four build options leave out what a scene never needs (every table read is a vector
gather on the CPU, the kernel's main cost): the light search's depth, smooth normals, procedural
textures, host albedos, measured materials. Another, the light samples per launch, lets each work item do a hit's work
once for all of them (the loop unrolled); the last, ``SPECTRAL``, shades rays of one wavelength each
(a spectral camera's K per sample, all in the one launch): albedo and radiance as spectra at the
ray's wavelength (one contribution column), and each ray's film weight and basis row, from
``SPECTRUM``, a table of the numpy path's own ``rgb_basis``, ``cie_rgb`` and ``wavelength_pdf``, so
that a spectral ray costs the host nothing an RGB ray does not (``rgb_response`` in numpy cost
several times an RGB ray's whole shading). PoCL builds each variant once per process and caches the
build on disk across processes. Inputs are wrapped without copying (``USE_HOST_PTR``: PoCL on the
CPU reads the numpy arrays in place); outputs are numpy arrays kept per thread and reused across
passes while they are large enough, all in one block read back by one call (``_ThreadState``).
Each thread has its own queue and kernel object, so the renderer's worker threads launch
independently; PoCL spreads each launch over every core.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from realistic.core.spectrum import (
    LAMBDA_MAX_NM,
    LAMBDA_MIN_NM,
    WAVELENGTH_INTERVALS,
    cie_rgb,
    rgb_basis,
    wavelength_pdf,
)
from realistic.device.opencl import LOCAL_SIZE, Device, OutputBlock, TypedKernel, cl, kernel_source, whole_groups
from realistic.device.tables import Table, constant_defines
from realistic.renderer.bsdf.measured import TABLE_NODES
from realistic.renderer.light_sampler import SHADOW_DEFINES
from realistic.scene.materials import Measured
from realistic.scene.model import CheckerTexture, GridTexture, Material
from realistic.scene.packet_loop import LANE_DEFINES, PACKET, shadow_lanes

KERNEL_FILE = "shade.cl"
#: The tables ``kernels/shade.cl`` reads, declared once: their ``#define``s head the kernel source.
#: Per instance (embree geometry id): its first face, material index, smooth flag and whether its
#: transform mirrors (0 or 1; read by the path tracer's ``bounce.cl``, which shares this layout, and
#: left 0 here: shade.cl faces the geometric normal to the ray instead).
GEOM_INTS = Table("GEOM_INT", np.int32, (("face_offset", 1), ("material", 1), ("smooth", 1), ("swaps", 1)))
#: Per instance: the normal matrix (inverse transpose of the linear map), row major (``bounce.cl`` too).
GEOM_FLOATS = Table("GEOM_FLOAT", np.float32, (("normal_matrix", 9),))
#: Per material: its kind (``KINDS``), diffuse colour, and a grid's or checker's cells, line bounds
#: (low, high: line_width / 2 and 1 - line_width / 2) and colours (a: line or even, b: base or odd);
#: a measured material's table (its index among the kernel's ``measured_tables``).
MATERIALS = Table("MATERIAL", np.float32, (("kind", 1), ("diffuse", 3), ("cells", 1), ("low", 1), ("high", 1),
                                           ("colour_a", 3), ("colour_b", 3), ("table", 1), ("unused", 2)))
#: Per area light: centre and half-axes a, b (a point is centre + a x + b y), normal, radiance, the
#: contribution's scale (area / probability / pi), whether a disk, whether two-sided (0 or 1); for
#: measured materials' BSDF samples its area and the dual axes of a and b
#: (``direct_lighting.dual_axes``).
LIGHTS = Table("LIGHT", np.float32, (("centre", 3), ("a", 3), ("b", 3), ("normal", 3), ("radiance", 3),
                                     ("scale", 1), ("disk", 1), ("two_sided", 1), ("area", 1), ("dual_a", 3),
                                     ("dual_b", 3), ("unused", 3)))
#: Per wavelength node (``SPECTRUM_INTERVALS`` + 1 of them, equally spaced over 380-780 nm): the
#: RGB-to-spectrum basis (``rgb_basis``), and the film's weight ``rgb_response`` as its two factors,
#: ``cie_rgb`` and the wavelength density ``wavelength_pdf``, which spectral rays interpolate linearly
#: (the weight is their quotient: 1 / pdf bends too sharply in the blue to interpolate as closely).
SPECTRUM = Table("SPECTRUM", np.float32, (("basis", 3), ("cie", 3), ("pdf", 1)))
#: Intervals of ``SPECTRUM``: 128 per interval of the wavelength density, whose nodes are then table
#: nodes (the density is exactly linear between them); the interpolated basis and weight are within
#: 3e-7 and 5e-6 of the closed forms' largest values (``tests/test_shade_kernel.py``).
SPECTRUM_INTERVALS = 128 * WAVELENGTH_INTERVALS
#: Material kinds: constant colour, grid and checker textures (in the kernel), host albedo, and a
#: measured BRDF's table (``realistic.renderer.bsdf.measured``), shaded with BSDF samples too.
KINDS = ("constant", "grid", "checker", "host", "measured")
KIND_CONSTANT, KIND_GRID, KIND_CHECKER, KIND_HOST, KIND_MEASURED = range(len(KINDS))
#: The generated head of ``shade.cl``'s source: every table's defines and the kinds.
HEADER = "".join(table.defines() for table in (GEOM_INTS, GEOM_FLOATS, MATERIALS, LIGHTS, SPECTRUM)) + \
    constant_defines("KIND", KINDS) + \
    (f"#define SPECTRUM_INTERVALS {SPECTRUM_INTERVALS}\n#define SPECTRUM_MIN_NM {LAMBDA_MIN_NM!r}f\n"
     f"#define SPECTRUM_PER_NM {SPECTRUM_INTERVALS / (LAMBDA_MAX_NM - LAMBDA_MIN_NM)!r}f\n"
     f"#define TABLE_NODES {TABLE_NODES}\n") + SHADOW_DEFINES + LANE_DEFINES
#: The kernel's light search is written out for at most this many lights.
MAX_LIGHTS = 65535
#: Shadow rays per launch (and per embree call) at most: a pass's light samples go in groups of
#: about this many rays, so memory stays flat in the light-sample count (40 bytes per row here,
#: about as much again in embree's ray structs).
MAX_SHADOW_ROWS = 1 << 19
#: Light samples per launch at most: a work item's loop over them is unrolled when the program is
#: built, and PoCL's uncached build grows with every light sample unrolled.
MAX_LAUNCH_SAMPLES = 4


def rounded_up_cdf(cdf: np.ndarray) -> np.ndarray:
    """float32 values c' >= c, each the smallest such: for a float32 u, c' <= u exactly when c <= u,
    so the kernel's float32 search picks the lights numpy's float64 ``searchsorted`` picks."""
    c32 = np.asarray(cdf, np.float64).astype(np.float32)
    low = c32.astype(np.float64) < cdf
    c32[low] = np.nextafter(c32[low], np.float32(np.inf))
    return c32


def table_records(table: np.ndarray) -> np.ndarray:
    """A measured table (n, n, n, 3) of bfloat16 values in float32 (``direct_lighting.bfloat16``) as
    ``kernels/shade.cl`` reads it: uint32 (n, n, n, 3), record (x, y, z) the six values r, g, b at
    (x, y, z) and at (x + 1, y, z) (0 past the last x) as their upper 16 bits, two to a uint, low half first."""
    bits = np.asarray(table, np.float32).view(np.uint32) >> np.uint32(16)
    upper = np.zeros_like(bits)
    upper[:-1] = bits[1:]
    halves = np.concatenate([bits, upper], axis=3)  # r, g, b at x, then at x + 1
    return halves[..., 0::2] | (halves[..., 1::2] << np.uint32(16))


def spectrum_rows() -> np.ndarray:
    """The ``SPECTRUM`` table: ``rgb_basis``, ``cie_rgb`` and ``wavelength_pdf`` at its equally
    spaced wavelengths (``rgb_response`` is ``cie_rgb / wavelength_pdf``)."""
    nodes = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, SPECTRUM_INTERVALS + 1)
    return SPECTRUM.pack(len(nodes), basis=rgb_basis(nodes), cie=cie_rgb(nodes), pdf=wavelength_pdf(nodes))


def material_row(material: Material | Measured, table: int = 0) -> np.ndarray:
    """A material's ``MATERIALS`` row; a measured one's table is ``table``."""
    if isinstance(material, Measured):
        return MATERIALS.pack(1, kind=KIND_MEASURED, table=table)[0]
    diffuse = np.asarray(material.diffuse, np.float32)
    texture = material.texture
    if texture is None:
        return MATERIALS.pack(1, kind=KIND_CONSTANT, diffuse=diffuse)[0]
    if isinstance(texture, GridTexture):
        half = texture.line_width / 2
        # float32, as numpy compares float32 uvs with them
        return MATERIALS.pack(1, kind=KIND_GRID, diffuse=diffuse, cells=texture.cells, low=half, high=1 - half,
                              colour_a=texture.line, colour_b=texture.base)[0]
    if isinstance(texture, CheckerTexture):
        return MATERIALS.pack(1, kind=KIND_CHECKER, diffuse=diffuse, cells=texture.cells, colour_a=texture.even,
                              colour_b=texture.odd)[0]
    return MATERIALS.pack(1, kind=KIND_HOST, diffuse=diffuse)[0]


@dataclass
class ShadowBatch:
    """One launch's outputs in lanes (``packet_loop.LANE_DEFINES``): ``per`` shadow rays for each of
    ``stride`` rays, [i // 16, k, c, i % 16] value c of ray i's k-th: the launch's k-th light sample,
    or with measured materials its k / 2-th's (even k) and the paired BSDF sample's (odd k); those of
    rays i >= n (padding) are dead."""

    origin: np.ndarray  # (stride / 16, per, 3, 16) float32
    vector: np.ndarray  # (stride / 16, per, 3, 16) float32: to the light point
    length: np.ndarray  # (stride / 16, per, 16) float32: 1 - 1e-4 (in units of vector), -1 for a dead sample
    contribution: np.ndarray  # (stride / 16, per, 3, 16) float32 (spectral rays: channels 1), 0 for a dead sample
    stride: int
    response: np.ndarray | None = None  # spectral rays: (stride, 3) float32 view, each ray's ``rgb_response``
    basis: np.ndarray | None = None  # spectral rays: (stride, 3) float32 view, each ray's ``rgb_basis`` row


#: The kernel's outputs in the order they lie in a thread's one block: name, floats per row, and
#: whether a row is a shadow ray's (else a camera ray's: spectral launches' ``response`` and ``basis``).
OUTPUTS = (("origin", 3, True), ("vector", 3, True), ("length", 1, True), ("contribution", 3, True),
           ("response", 3, False), ("basis", 3, False))


class _ThreadState:
    """A thread's queue, kernel object and reusable output arrays: one ``OutputBlock`` holding every
    output, wrapped by one buffer with a sub-buffer per output, so that a launch's outputs come
    back by one read (each read, like each wait, releases the GIL, and taking it back while the
    other render threads run Python cost more than the reads themselves)."""

    def __init__(self, device: Device):
        self.queue = device.queue()
        self.shade: dict[tuple[int, bool], TypedKernel] = {}  # (light samples per launch, spectral) -> kernel
        self.rows = {True: 0, False: 0}  # rows the block holds: of shadow rays, of camera rays
        self.block: OutputBlock | None = None

    def outputs(self, device: Device, rows: int, rays: int) -> OutputBlock:
        """The block of output arrays (``OUTPUTS``, in order), of at least ``rows`` shadow-ray rows
        and, for spectral launches (``rays`` not 0), ``rays`` per-ray rows (an eighth more, so passes
        of varying size settle on one allocation; a launch of RGB rays has a one-element placeholder
        there), kept for the thread's later launches."""
        wanted = {True: rows, False: max(rays, 1)}
        if self.block is not None and all(wanted[kind] <= self.rows[kind] for kind in wanted):
            return self.block
        for kind, count in wanted.items():
            if count > self.rows[kind]:
                self.rows[kind] = count + count // 8
        self.block = OutputBlock(device, [((self.rows[shadow] * width,), np.float32) for _, width, shadow in OUTPUTS])
        return self.block
        for kind, count in wanted.items():
            if count > self.rows[kind]:
                self.rows[kind] = count + count // 8
        # each output starts at the device's sub-buffer alignment (in floats)
        align = max(device.context.devices[0].mem_base_addr_align // 32, 1)
        starts, end = [], 0
        for _, width, shadow in OUTPUTS:
            starts.append(end)
            end += -(-self.rows[shadow] * width // align) * align
        self.block = np.empty(end, np.float32)
        self.parent = device.host_buffer(self.block, cl.mem_flags.WRITE_ONLY)
        for (name, width, shadow), start in zip(OUTPUTS, starts):
            size = self.rows[shadow] * width
            self.arrays[name] = self.block[start:start + size]
            self.buffers[name] = self.parent.get_sub_region(4 * start, 4 * size)
        return self.block, self.parent


class ShadeKernel:
    """``shade.cl`` with one scene's tables on the device."""

    def __init__(self, *, faces: np.ndarray, normals: np.ndarray, uv: np.ndarray, geom_face_offset: np.ndarray,
                 geom_material: np.ndarray, geom_smooth: np.ndarray, geom_normal_matrix: np.ndarray,
                 materials: list[Material | Measured], light_rows: np.ndarray, light_cdf: np.ndarray, extent: float,
                 device: Device, launch_samples: int = 1, spectral: bool = False,
                 measured_tables: dict[str, np.ndarray] | None = None):
        """``launch_samples``: the light samples per launch a render will ask for (at most
        ``MAX_LAUNCH_SAMPLES``), and ``spectral``: whether its rays are spectral; that program
        variant is built here rather than in its first pass (others are built on first use).
        ``measured_tables``: each ``Measured`` material's file's table (``irregular_table``,
        rounded to bfloat16: ``direct_lighting.bfloat16``) by path, which a measured
        material's row names; with any, every light sample has a BSDF
        sample's row too (``rows_per_sample`` 2), and rays must be RGB. Without, a measured
        material's row reflects nothing (its hits are for the measured variant to shade)."""
        self.device = device
        self.context = device.context
        if not 0 < len(light_cdf) <= MAX_LIGHTS:
            raise ValueError(f"the shading kernel handles 1 to {MAX_LIGHTS} area lights, not {len(light_cdf)}")
        self.instance_count = len(geom_face_offset)
        self.light_count = len(light_cdf)
        self.offset_base = np.float32(1e-2 * extent)  # numpy adds the float64 1e-2 extent to float32 as float32
        rows = max(self.instance_count, 1)  # a zero row where there are no instances
        geom_ints = GEOM_INTS.pack(rows)
        geom_ints[:self.instance_count] = GEOM_INTS.pack(self.instance_count, face_offset=geom_face_offset,
                                                         material=geom_material, smooth=geom_smooth)
        geom_floats = GEOM_FLOATS.pack(rows)
        geom_floats[:self.instance_count] = GEOM_FLOATS.pack(
            self.instance_count, normal_matrix=np.asarray(geom_normal_matrix, np.float32).reshape(-1, 9))
        tables = measured_tables or {}
        order = {path: index for index, path in enumerate(tables)}
        material_rows = np.array([material_row(m, order.get(m.path, 0) if isinstance(m, Measured) else 0)
                                  for m in materials] or [MATERIALS.pack(1)[0]], np.float32)
        kinds = material_rows[:, MATERIALS.offset("kind")]
        self.host_albedo = kinds == KIND_HOST
        # the program variant this scene needs: work no instance or material asks for is compiled out
        self.options = (f"-DPICK_BITS={(len(light_cdf) - 1).bit_length()}",
                        f"-DSMOOTH={int(np.any(geom_smooth))}",
                        f"-DTEXTURED={int(np.any(np.isin(kinds, (KIND_GRID, KIND_CHECKER))))}",
                        f"-DHOST_ALBEDO={int(self.host_albedo.any())}",
                        f"-DMEASURED={int(bool(tables))}")
        #: Shadow-ray rows per light sample: a measured scene's BSDF sample has the second.
        self.rows_per_sample = 2 if tables else 1
        if tables and spectral:
            raise ValueError("measured materials shade RGB rays only")
        self.program = self._program(min(launch_samples, MAX_LAUNCH_SAMPLES), spectral)
        self._tables = [device.wrapped_buffer(array, dtype) for array, dtype in (
            (faces, np.int32), (normals, np.float32), (uv, np.float32), (geom_ints, np.int32),
            (geom_floats, np.float32), (material_rows, np.float32), (light_rows, np.float32),
            (rounded_up_cdf(light_cdf), np.float32),
            (np.concatenate([table_records(t).ravel() for t in tables.values()]) if tables else np.zeros(4),
             np.uint32))]
        self._spectrum = device.wrapped_buffer(spectrum_rows(), np.float32)
        self._dummy_albedo = np.zeros(3, np.float32)
        self._local = threading.local()
        self._states: list[_ThreadState] = []  # keeps every thread's buffers alive with the kernel

    def _program(self, launch_samples: int, spectral: bool = False) -> cl.Program:
        """The scene's program variant whose work items make ``launch_samples`` light samples each, of
        RGB or (``spectral``) one-wavelength rays (built once per process and variant: a render needs
        one, or two with a remainder)."""
        return self.device.build_program(HEADER + kernel_source(KERNEL_FILE), KERNEL_FILE,
                                         (*self.options, f"-DLAUNCH_SAMPLES={launch_samples}",
                                          f"-DSPECTRAL={int(spectral)}"))

    def _state(self) -> _ThreadState:
        state = getattr(self._local, "state", None)
        if state is None:
            state = self._local.state = _ThreadState(self.device)
            self._states.append(state)
        return state

    def shade(self, origin: np.ndarray, direction: np.ndarray, t: np.ndarray, u: np.ndarray, v: np.ndarray,
              prim: np.ndarray, geom: np.ndarray, normal: np.ndarray, pixel: np.ndarray, sample: np.ndarray,
              albedo: np.ndarray | None, light_samples: int, seed: int, first_sample: int = 0,
              total_samples: int | None = None, wavelength_nm: np.ndarray | None = None) -> ShadowBatch:
        """Shadow rays and contributions of N camera rays and their closest hits (embree's t, u, v,
        prim, geom and unnormalised Ng) for light samples ``first_sample`` .. ``first_sample +
        light_samples - 1`` of ``total_samples`` per camera sample (default: up to the last of these,
        which the random numbers depend on: ``rng.light_bits``); ``albedo`` (N, 3) the numpy albedo
        where a material's row is KIND_HOST (None when no material is). ``wavelength_nm``: for
        spectral rays, each ray's wavelength (N,): the contributions are then spectral values (one
        column), and the batch's ``response`` and ``basis`` each ray's ``rgb_response`` and ``rgb_basis``
        row. The arrays returned are this thread's, valid until its next call."""
        if not 0 < light_samples <= MAX_LAUNCH_SAMPLES:
            raise ValueError(f"a launch makes 1 to {MAX_LAUNCH_SAMPLES} light samples per ray, not {light_samples}")
        total = first_sample + light_samples if total_samples is None else total_samples
        n = len(origin)
        stride = whole_groups(n)
        per = light_samples * self.rows_per_sample  # shadow rays per ray
        rows = stride * per
        if n == 0:
            empty = np.zeros((0, per, 3, PACKET), np.float32)
            return ShadowBatch(empty, empty, np.zeros((0, per, PACKET), np.float32), empty, 0)
        state = self._state()
        outputs = state.outputs(self.device, rows, 0 if wavelength_nm is None else stride)
        mf = cl.mem_flags
        inputs = [np.ascontiguousarray(origin, np.float32), np.ascontiguousarray(direction, np.float32),
                  np.ascontiguousarray(t, np.float32), np.ascontiguousarray(u, np.float32),
                  np.ascontiguousarray(v, np.float32), np.ascontiguousarray(prim, np.int32),
                  np.ascontiguousarray(geom, np.int32), np.ascontiguousarray(normal, np.float32),
                  _as_uint32(pixel), _as_uint32(sample),
                  self._dummy_albedo if albedo is None else np.ascontiguousarray(albedo, np.float32),
                  self._dummy_albedo if wavelength_nm is None else np.ascontiguousarray(wavelength_nm, np.float32)]
        buffers = [cl.Buffer(self.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=a) for a in inputs]
        variant = (light_samples, wavelength_nm is not None)
        kernel = state.shade.get(variant)
        if kernel is None:
            kernel = state.shade[variant] = TypedKernel(self._program(*variant), "shade")
        # work groups of PACKET: shade.cl's work group is a group of lanes (``LANE_DEFINES``)
        kernel(state.queue, (stride,), (PACKET,), np.uint32(n), np.uint32(first_sample), np.uint32(total),
               np.uint32(seed & 0xFFFFFFFF), np.uint32(1), np.int32(self.instance_count), self.offset_base,
               np.int32(self.light_count), *buffers, self._spectrum, *self._tables, *outputs.parts)
        # one blocking read of the whole block, after the launch (and a first launch's compile),
        # without the GIL (``Device.run_into``): PoCL copies nothing (a platform that kept its own
        # memory would copy)
        outputs.read(state.queue)
        spectral = wavelength_nm is not None
        channels = 1 if spectral else 3
        for buffer in buffers:
            buffer.release()
        arrays = dict(zip((name for name, _, _ in OUTPUTS), outputs.arrays))
        return ShadowBatch(shadow_lanes(arrays["origin"], per, 3, stride),
                           shadow_lanes(arrays["vector"], per, 3, stride),
                           shadow_lanes(arrays["length"], per, 1, stride)[:, :, 0],
                           shadow_lanes(arrays["contribution"], per, channels, stride), stride,
                           _per_ray(arrays["response"], stride) if spectral else None,
                           _per_ray(arrays["basis"], stride) if spectral else None)

    def light_uniforms(self, pixel: np.ndarray, sample: np.ndarray, light_samples: int, seed: int) -> np.ndarray:
        """The kernel's light-sample random numbers (3 * light_samples, N): u_pick, u1, u2 per light
        sample of ``light_samples`` per camera sample (for tests against ``realistic.core.rng.light_uniforms``)."""
        n = len(pixel)
        stride = max(LOCAL_SIZE, whole_groups(n))
        state = self._state()
        out = np.empty((3 * light_samples, stride), np.float32)
        mf = cl.mem_flags
        inputs = [cl.Buffer(self.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=_as_uint32(a))
                  for a in (pixel, sample)]
        out_buffer = cl.Buffer(self.context, mf.WRITE_ONLY, out.nbytes)
        cl.Kernel(self.program, "light_uniforms")(state.queue, (stride, light_samples), (LOCAL_SIZE, 1), np.uint32(n),
                                                  np.uint32(stride), np.uint32(seed & 0xFFFFFFFF), *inputs, out_buffer)
        cl.enqueue_copy(state.queue, out, out_buffer)
        return out[:, :n]

    def disk_points(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The kernel's concentric map of float32 (u1, u2) (for tests against ``core.warp``)."""
        state = self._state()
        mf = cl.mem_flags
        a, b = (np.ascontiguousarray(x, np.float32) for x in (u1, u2))
        x, y = np.empty_like(a), np.empty_like(a)
        bx, by = (cl.Buffer(self.context, mf.WRITE_ONLY, a.nbytes) for _ in range(2))
        ins = [cl.Buffer(self.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=c) for c in (a, b)]
        cl.Kernel(self.program, "disk_points")(state.queue, (len(a),), None, *ins, bx, by)
        cl.enqueue_copy(state.queue, x, bx)
        cl.enqueue_copy(state.queue, y, by)
        return x, y


def _per_ray(values: np.ndarray, stride: int) -> np.ndarray:
    """A per-ray output of three values (``response``, ``basis``: three rows of ``stride`` rays) as
    (stride, 3) rows, a view: a copy out of lanes, for two outputs per launch, cost a spectral pass
    more than the products that read them."""
    return values[:3 * stride].reshape(3, stride).T


def _as_uint32(a: np.ndarray) -> np.ndarray:
    """uint32 bits of integer rows (int32 viewed in place, wider types converted modulo 2^32)."""
    a = np.asarray(a)
    if a.dtype == np.int32 or a.dtype == np.uint32:
        return np.ascontiguousarray(a).view(np.uint32)
    return np.ascontiguousarray(a.astype(np.uint32))
