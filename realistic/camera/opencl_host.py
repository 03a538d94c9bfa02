"""OpenCL host of ray generation: ``kernels/lens.cl`` built for a ``LensCamera`` on a ``Device``.

The lens surfaces, film geometry's constants and sampler are compiled in as constants (so PoCL
vectorises the kernel); the focus and a round stop's diameter are the ``settings`` argument. A
``LensKernel`` keeps its device buffers across launches and copies the rays back into numpy arrays.
The device, its context and the program cache are ``realistic.device.opencl``'s.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from realistic.camera.base import RayBatch, SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import disk_cache
from realistic.core.pixel_filter import TABLE_BINS, PixelFilter
from realistic.core.rng import wavelength_step
from realistic.core.spectrum import WAVELENGTH_CDF, WAVELENGTH_DENSITY, WAVELENGTH_INTERVALS, WAVELENGTH_NODES_NM
from realistic.device.opencl import (
    LOCAL_SIZE,
    Device,
    OutputBlock,
    TypedKernel,
    cl,
    kernel_source,
    leave_binaries_unstored,
    whole_groups,
)
from realistic.device.tables import Table
from realistic.optics.coating import BARE, DESIGN_WAVELENGTH_NM, LAYER, MGF2, MGF2_INDEX, mgf2_index
from realistic.optics.dispersion import D_LINE_NM, GlassFormula, cauchy_coefficients
from realistic.optics.lens import LensSystem
from realistic.optics.sampling import PUPIL_INTERVALS, rear_element_sampler

KERNEL_FILE = "lens.cl"
#: Output rows of ``generate_rays``: origin xyz, direction xyz, weight (and wavelength when spectral).
#: A spectral camera's launch has one work item per ray: ``rays_per_sample`` per sample.
ROWS = 7
#: ``lens.cl``'s ``settings`` argument (float32), declared once for the kernel's SET_* offsets and
#: ``setting_values``: the sampling plane's z (lens frame: film at z = 0, +z to the scene) and its
#: square, the front vertex's z, the film's z relative to the rear vertex (-film distance), the
#: sampling's three constants (pupil: PUPIL_INTERVALS / film radius, 0, 0; rear-element disk: 1 -
#: t_far, clear radius * t_far, clear radius), a round stop's squared radius (mm^2); then, from
#: SET_PUPIL, the exit-pupil boxes (x0, x1, y0, y1) per interval and their areas (mm^2).
SETTINGS = Table("SET", np.float32, (("plane_z", 1), ("plane_z2", 1), ("front_vertex_z", 1), ("rear_w", 1),
                                     ("sampling", 3), ("stop_r2", 1)), tail="pupil")


def _c_float(value: float) -> str:
    """A float32 C literal holding exactly np.float32(value)."""
    return repr(float(np.float32(value))) + "f"


def _index_ratios(camera: LensCamera) -> list[tuple[str, str, str]]:
    """Per surface, rear first, the index ratio (incident over transmitted) and the incident and
    transmitted media's indices, as C expressions of ``il2`` (1 / lambda^2, um^-2), the macro
    parameter of the ray's wavelength.

    A ratio between media of constant index (no V number, or a non-spectral camera) is a literal
    computed in float64, as at the d line; otherwise it is n_i * (1 / n_(i-1)) per ray, a dispersive
    glass's index n = A + B il2 (Cauchy) or its catalogue formula (``_glass_index``) computed where it
    is used (the compiler computes it once per ray).
    """
    lens = camera.lens
    index = lens.index_at(D_LINE_NM)
    a, b = cauchy_coefficients(lens.index_d, lens.abbe_v)
    catalogue = np.array([g is not None for g in lens.glass])
    dispersive = ((b != 0) | catalogue) & camera.spectral

    def n(k: int) -> str:
        if k < 0:
            return "1.0f"
        glass = lens.glass[k]
        if dispersive[k] and glass is not None:
            return _glass_index(glass)
        return f"({_c_float(a[k])} + {_c_float(b[k])} * (il2))" if dispersive[k] else _c_float(index[k])

    def inv(k: int) -> str:
        return f"(1.0f / {n(k)})" if k >= 0 and dispersive[k] else _c_float(1.0 / (index[k] if k >= 0 else 1.0))

    ratios = []
    for i in range(lens.surface_count - 1, -1, -1):
        if dispersive[i] or (i > 0 and dispersive[i - 1]):
            ratio = f"{n(i)} * {inv(i - 1)}"
        else:
            ratio = _c_float(index[i] / (index[i - 1] if i > 0 else 1.0))
        ratios.append((ratio, n(i), n(i - 1)))
    return ratios


def _transmission(camera: LensCamera, i: int, eta: str, n_in: str, n_out: str) -> str:
    """The call after surface ``i``'s that multiplies the ray's transmittance by its coating's
    (``realistic.optics.coating``), or nothing where it transmits all."""
    model = camera.lens.interface_models[i]
    if model == BARE:
        return f" transmit_bare(r, {eta});"
    if model == LAYER:
        # pi (lambda0 / lambda) n(lambda) / n(lambda0): 1 / lambda is sqrt(il2) / 1000 per ray, or the d line's
        factor = np.pi * DESIGN_WAVELENGTH_NM / MGF2_INDEX
        if camera.spectral:
            layer = _glass_index(MGF2)
            phase = f"({_c_float(factor * 1e-3)} * __builtin_sqrtf(il2) * {layer})"
        else:
            layer = _c_float(float(mgf2_index(D_LINE_NM)))
            phase = _c_float(factor * float(mgf2_index(D_LINE_NM)) / D_LINE_NM)
        return f" transmit_layer(r, {n_in}, {n_out}, {phase}, {layer});"
    return ""


def _glass_index(glass: GlassFormula) -> str:
    """A catalogue glass's index as a C expression of ``il2``: the formula of
    ``realistic.optics.dispersion.GlassFormula.index`` in float32. Sellmeier's three terms
    B / (1 - C il2) are summed as one fraction 1 + P(il2) / Q(il2), Q the product of their
    denominators (coefficients in float64 here): written as three like terms, LLVM's SLP vectoriser
    packed them into a vector, which stops PoCL's work-group vectoriser (the whole kernel ran
    scalar; see the header of ``kernels/lens.cl``)."""
    k = glass.coefficients
    if glass.formula == "sellmeier":
        factors = [np.array([1.0, -k[3 + i]]) for i in range(3)]  # 1 - C_i il2, lowest power first
        q = np.polynomial.polynomial.polymul(np.polynomial.polynomial.polymul(factors[0], factors[1]), factors[2])
        p = sum(k[i] * np.polynomial.polynomial.polymul(*(factors[j] for j in range(3) if j != i)) for i in range(3))
        pc, qc = [_c_float(v) for v in p], [_c_float(v) for v in q]
        return (f"__builtin_sqrtf(1.0f + ({pc[0]} + (il2) * ({pc[1]} + (il2) * {pc[2]})) / "
                f"(1.0f + (il2) * ({qc[1]} + (il2) * ({qc[2]} + (il2) * {qc[3]}))))")
    c = [_c_float(v) for v in k]
    return (f"__builtin_sqrtf({c[0]} + {c[1]} / (il2) + (il2) * ({c[2]} + (il2) * ({c[3]} + (il2) * "
            f"({c[4]} + (il2) * {c[5]}))))")


def stop_lines(lens: LensSystem) -> list[str]:
    """``STOP_INSIDE(x, y)`` (and a mask table) for the lens's stop, as realistic.optics.stop_shape defines it."""
    diameter = float(lens.aperture_mm[lens.stop])
    shape = lens.stop_shape
    if shape is None:  # round: its squared radius is a setting (``setting_values``)
        return ["#define STOP_INSIDE(x, y) ((x) * (x) + (y) * (y) <= STOP_R2)", "#define STOP_MASKED 0"]
    if shape.mask is not None:
        rows, cols = shape.mask.shape
        table = ", ".join("1" if v else "0" for v in shape.mask.ravel())
        return ["#define STOP_MASKED 1", f"#define STOP_MASK_W {cols}", f"#define STOP_MASK_H {rows}",
                f"#define STOP_DIAMETER_MM {_c_float(diameter)}",
                f"__constant uchar STOP_MASK[{rows * cols}] = {{{table}}};",
                "#define STOP_INSIDE(x, y) stop_mask((x), (y))"]
    terms = []
    for nx, ny, a, rho in shape.edges(diameter):
        if rho == 0:  # a straight side: the half-plane x nx + y ny <= a
            terms.append(f"((x) * {_c_float(nx)} + (y) * {_c_float(ny)} <= {_c_float(a)})")
        else:  # an arc: |p - a n|^2 <= rho^2, written so float32 keeps precision when rho is huge
            terms.append(f"((x) * (x) + (y) * (y) - {_c_float(2 * a * nx)} * (x) - {_c_float(2 * a * ny)} * (y) <= "
                         f"{_c_float((rho - a) * (rho + a))})")
    return ["#define STOP_MASKED 0", "#define STOP_INSIDE(x, y) (" + " & ".join(terms) + ")"]


def _wavelength_lines(camera: LensCamera) -> list[str]:
    """A spectral camera's wavelength density table (``realistic.core.spectrum.wavelengths_nm``) and
    its wavelengths per sample with the fixed-point width of their strata (``realistic.core.rng.spectral_rays``)."""
    if not camera.spectral:
        return []
    def table(name: str, values: np.ndarray) -> str:
        return f"__constant float {name}[{len(values)}] = {{{', '.join(_c_float(v) for v in values)}}};"
    return [f"#define WAVELENGTHS_PER_SAMPLE {camera.wavelengths_per_sample}u",
            f"#define LAMBDA_STRATUM_STEP {wavelength_step(camera.wavelengths_per_sample)}u",
            f"#define LAMBDA_INTERVALS {WAVELENGTH_INTERVALS}",
            f"#define LAMBDA_MIN_NM {_c_float(WAVELENGTH_NODES_NM[0])}",
            f"#define LAMBDA_STEP_NM {_c_float(WAVELENGTH_NODES_NM[1] - WAVELENGTH_NODES_NM[0])}",
            table("LAMBDA_DENSITY", WAVELENGTH_DENSITY), table("LAMBDA_CDF", WAVELENGTH_CDF)]


def filter_lines(pixel_filter: PixelFilter) -> list[str]:
    """The pixel filter's ``FILTER_*`` defines and tables (see ``kernels/lens.cl``; also
    ``kernels/thin_lens.cl``'s)."""
    kind = 2 if pixel_filter.tabulated else ("box", "triangle").index(pixel_filter.name)
    lines = [f"#define FILTER_KIND {kind}", f"#define FILTER_RX {_c_float(pixel_filter.radius_x)}",
             f"#define FILTER_RY {_c_float(pixel_filter.radius_y)}"]
    if kind == 2:
        lines.append(f"#define FILTER_BINS {TABLE_BINS}")
        for axis, table in (("X", pixel_filter.x_table), ("Y", pixel_filter.y_table)):
            cdf = ", ".join(_c_float(v) for v in table.cdf)
            weight = ", ".join(_c_float(v) for v in table.sign * table.ratio)
            lines += [f"__constant float FILTER_CDF_{axis}[{TABLE_BINS + 1}] = {{{cdf}}};",
                      f"__constant float FILTER_WEIGHT_{axis}[{TABLE_BINS}] = {{{weight}}};"]
    return lines


#: Rays each work item of the lens kernel may trace side by side (``kernels/lens.cl``, "several rays
#: per work item"), for a lens of spheres and planes and for one with aspheres (whose kernel is three
#: times as long); the other choice is 1 (``LensKernel``).
RAYS_PER_ITEM = 4
ASPHERIC_RAYS_PER_ITEM = 2
#: The most wavelengths per sample whose rays one work item traces together (``shares_samples``): a
#: work item's four consecutive stores of four rays' values LLVM's SLP vectoriser packs into vectors,
#: and PoCL's work-group vectoriser then leaves the kernel scalar (K = 4 on the dgauss lens).
MAX_SAMPLE_RAYS = 3


def rays_per_item_choices(camera: LensCamera) -> tuple[int, int]:
    """The rays per work item ``LensKernel`` chooses between for ``camera``: several, or one. A
    spectral camera's several are its K wavelengths per sample where 2 <= K <= ``MAX_SAMPLE_RAYS``
    and the several an RGB camera of its lens would trace: each work item then traces one sample's
    rays (``shares_samples``)."""
    several = ASPHERIC_RAYS_PER_ITEM if camera.lens.asphere_count else RAYS_PER_ITEM
    if camera.spectral and 2 <= camera.rays_per_sample <= min(several, MAX_SAMPLE_RAYS):
        return camera.rays_per_sample, 1
    return several, 1


def shares_samples(camera: LensCamera, rays_per_item: int) -> bool:
    """Whether the lens kernel tracing ``rays_per_item`` rays per work item for ``camera`` traces
    one spectral sample's K rays per work item (``kernels/lens.cl``'s SAMPLE_RAYS), which share the
    sample's film and lens point, rather than rays i, i + n, ... of the launch: where K is
    ``rays_per_item``, 2 to ``MAX_SAMPLE_RAYS``."""
    return camera.spectral and rays_per_item == camera.rays_per_sample and 2 <= rays_per_item <= MAX_SAMPLE_RAYS


def camera_header(camera: LensCamera) -> str:
    """The generated ``#define`` block that specialises ``lens.cl`` to one lens and camera (see its
    header); the focus and a round stop's diameter are ``setting_values`` instead, so a camera
    refocused or stopped down reuses the build."""
    lens = camera.lens
    calls = []
    for (eta, n_in, n_out), i in zip(_index_ratios(camera), range(lens.surface_count - 1, -1, -1)):
        gap = lens.thickness_mm[i - 1] if i > 0 else 0.0
        ahead = int(i == lens.surface_count - 1 or lens.thickness_mm[i] != 0)
        ap2 = (lens.aperture_mm[i] / 2) ** 2
        radius = lens.radius_mm[i]
        refracts = int(eta != "1.0f")
        if lens.paraxial[i]:
            px, py = (_c_float(p) for p in lens.paraxial_power_per_mm[i])
            clear = "settings[SET_STOP_R2]" if i == lens.stop else _c_float(ap2)
            calls.append(f"paraxial(r, {clear}, {px}, {py}, {_c_float(gap)}, {ahead});")
        elif i == lens.stop and not lens.stop_is_flat_in_air:  # a round stop (``with_stop_shape``) on its surface
            kind = "plane" if radius == 0 else "sphere"
            shape = "" if radius == 0 else f"{_c_float(radius)}, "
            calls.append(f"{kind}(r, {shape}settings[SET_STOP_R2], {eta}, {refracts}, {_c_float(gap)}, {ahead});")
        elif i == lens.stop:
            calls.append(f"stop(r, {_c_float(gap)}, settings[SET_STOP_R2], {ahead});")
        elif lens.aspheric[i]:
            c = 1.0 / radius if radius != 0 and np.isfinite(radius) else 0.0
            shape = ", ".join(_c_float(v) for v in (c, lens.conic[i], *lens.aspheric_coefficients[i]))
            calls.append(f"asphere(r, {shape}, {_c_float(ap2)}, {eta}, {refracts}, {_c_float(gap)}, {ahead});")
        elif radius == 0 or not np.isfinite(radius):
            calls.append(f"plane(r, {_c_float(ap2)}, {eta}, 1, {_c_float(gap)}, {ahead});")
        else:
            calls.append(f"sphere(r, {_c_float(radius)}, {_c_float(ap2)}, {eta}, {refracts}, {_c_float(gap)}, "
                         f"{ahead});")
        if refracts and not (i == lens.stop and lens.stop_is_flat_in_air) and not lens.paraxial[i]:
            calls[-1] += _transmission(camera, i, eta, n_in, n_out)
    lines = [
        SETTINGS.defines().rstrip("\n"),
        f"#define SPECTRAL {int(camera.spectral)}",
        f"#define COATED {int(bool(lens.interface_models.any()))}",
        *(f"#define SURFACE_{k}(r, il2) {call}" for k, call in enumerate(calls)),
        "#define TRACE_SURFACES(EACH) " + " ".join(f"EACH(SURFACE_{k})" for k in range(len(calls))),
        *stop_lines(lens),
        *_wavelength_lines(camera),
        *filter_lines(camera.pixel_filter),
    ]
    if camera.lens_sampling == "pupil":
        # the count ``LensCamera.pupil`` builds its table with: the header needs no table, so the
        # program can build while the table is made (``build_ahead``)
        lines += ["#define LENS_SAMPLING_PUPIL 1", f"#define PUPIL_INTERVALS {PUPIL_INTERVALS}"]
    else:
        lines += ["#define LENS_SAMPLING_PUPIL 0"]
    return "\n".join(lines) + "\n"


def setting_values(camera: LensCamera) -> np.ndarray:
    """``lens.cl``'s ``settings`` argument (``SETTINGS``, float32). Each value is rounded to float32
    before the products and quotients are taken in float32, as the compiler once folded them from
    literals."""
    f = np.float32
    lens = camera.lens
    vertex_z = lens.vertex_z_mm(camera.film_distance_mm)
    if camera.lens_sampling == "pupil":
        table = camera.pupil
        plane_z = f(table.plane_z_mm)
        sampling = [f(len(table.bounds)) / f(table.film_radius_mm), f(0), f(0)]
        tables = [np.asarray(table.bounds, np.float32).ravel(), np.asarray(table.area_mm2(), np.float32)]
    else:
        rear = rear_element_sampler(lens, camera.film_distance_mm)
        plane_z, t_far, clear = f(rear.plane_z_mm), f(rear.plane_z_mm / rear.far_z_mm), f(rear.clear_radius_mm)
        sampling = [f(1) - t_far, clear * t_far, clear]
        tables = []
    stop_r2 = f((float(lens.aperture_mm[lens.stop]) / 2) ** 2)
    head = SETTINGS.pack(1, plane_z=plane_z, plane_z2=plane_z * plane_z, front_vertex_z=f(vertex_z[0]),
                         rear_w=f(-camera.film_distance_mm), sampling=np.array(sampling, np.float32),
                         stop_r2=stop_r2)[0]
    return np.concatenate([head, *tables])  # float32 throughout


#: PoCL 3.0 compiles a kernel apart for launches of fewer work items than this (its "smallgrid"
#: variant) and for the others (32768 work items take the first, 65536 the second), each at its
#: first launch. A camera kernel object's launches keep to the variant of its first launch
#: (``LaunchSizes``): after a first launch of at least this many work items, smaller ones are padded
#: up to it (the padding rays compute as much as real ones); after a smaller first launch none is
#: padded beyond whole work groups. So a render compiles one variant, and one whose passes are
#: small (the lens kernel's, four rays a work item: fewer than 2^18 rays a pass) pays for no
#: padding rays. The shading and EWA kernels are not padded: a pass's hits can number far fewer,
#: and their padding would cost more than a second compile saves.
SMALL_GRID_LIMIT = 65536


def launch_size(rays: int, per_item: int = 1, pad: bool = True) -> int:
    """Rays to launch the lens kernel for ``rays``, ``per_item`` rays per work item: whole groups
    of work items, at least ``SMALL_GRID_LIMIT`` of them where ``pad``."""
    items = whole_groups(-(-rays // per_item))
    return per_item * (max(SMALL_GRID_LIMIT, items) if pad else items)


def launch_layout(block: SampleBlock, rays_per_sample: int = 1, per_item: int = 1, pad: bool = True
                  ) -> tuple[tuple[np.uint32, ...], int]:
    """A camera kernel's (first pixel, offset, slice start, slice width) arguments for ``block`` and
    the launch's rays (``rays_per_sample`` per sample, ``per_item`` per work item, padded as
    ``launch_size`` pads), checking the uint32 limits for the rays up to the last work group's end
    (those padded beyond it compute rays nobody reads)."""
    used = whole_groups(block.count * rays_per_sample)
    first_pixel, offset = divmod(block.first, block.samples)
    if offset + used >= 2**32 or first_pixel + (offset + used) // block.samples >= 2**31 \
            or block.first_sample + block.samples >= 2**32:
        raise ValueError(f"sample block {block} exceeds the kernel's 32-bit indices")
    return tuple(np.uint32(v) for v in (first_pixel, offset, block.first_sample, block.samples)), \
        launch_size(used, per_item, pad)


class LaunchSizes:
    """The launch sizes of one camera kernel object's program (``SMALL_GRID_LIMIT``): its first
    launch decides whether later ones are padded up to the limit (it had at least that many work
    items: PoCL compiled the large-grid variant) or not. Callers serialise ``layout`` with their
    launches (the kernel's lock)."""

    def __init__(self) -> None:
        self.pad: bool | None = None

    def layout(self, block: SampleBlock, rays_per_sample: int = 1, per_item: int = 1
               ) -> tuple[tuple[np.uint32, ...], int]:
        """``launch_layout`` of ``block``, padded as this kernel's first launch decided."""
        address, unpadded = launch_layout(block, rays_per_sample, per_item, pad=False)
        if self.pad is None:
            self.pad = unpadded // per_item >= SMALL_GRID_LIMIT
        return address, launch_size(unpadded, per_item, self.pad)


def lens_program(camera: LensCamera, rays_per_item: int) -> tuple[str, str]:
    """``Device.build_program``'s source and name for the camera's lens kernel, tracing
    ``rays_per_item`` rays per work item."""
    return (f"#define RAYS_PER_ITEM {rays_per_item}\n#define SAMPLE_RAYS {int(shares_samples(camera, rays_per_item))}\n"
            + camera_header(camera) + kernel_source(KERNEL_FILE), KERNEL_FILE)


#: Rounds of timed launches, one per choice of rays per work item each, taken in turn (the fastest
#: of each choice's counts), and the rays each launch makes.
TIMED_ROUNDS = 5
TIMED_RAYS = 4 * SMALL_GRID_LIMIT
#: One ray per work item is chosen only where its fastest launch takes less than this fraction of
#: the other's: where SLP packed the rays it takes about a third, and a busy machine's noise in
#: launches of a few milliseconds does not flip the choice.
ONE_RAY_MARGIN = 0.8
#: Rays per work item chosen in this process, by disk-cache key (a refocused camera asks again).
_chosen: dict[str, int] = {}
_choosing = threading.Lock()  # ``build_ahead`` on a render thread and ``LensKernel`` decide alike
#: Whether a choice not yet timed is timed now (``time_choices``).
_timing = [True]


def time_choices(wanted: bool) -> None:
    """Whether this process's ``LensKernel``s time a choice of rays per work item that is still
    untimed (building and compiling both programs: about a second, which a small render never
    repays) or run one ray per item untimed, leaving the choice to a render that repays timing it
    (``renderer.runner.repays_compiling``). A stored choice is used either way."""
    _timing[0] = wanted


def _seconds(run: Callable[[], object]) -> float:
    """Wall-clock seconds ``run()`` takes."""
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


#: A lens program as ``LensKernel._build`` makes it: its rays per work item, the program, and its
#: ``generate_rays`` and ``sample_bits`` kernels.
_Built = tuple[int, "cl.Program", TypedKernel, TypedKernel]


def _choice_key(camera: LensCamera, device: Device) -> str:
    """The disk-cache key of the camera's choice of rays per work item on ``device``."""
    source = camera_header(camera) + kernel_source(KERNEL_FILE)
    return disk_cache.cache_key("lens-rays-per-item", device.identity(), source)


def _stored_choice(key: str, choices: tuple[int, int]) -> int | None:
    """The rays per work item the disk cache holds for ``key`` (``_choice_key``), or None: no
    entry, or one that is not a single integer among ``choices`` (a cache entry is never an error)."""
    stored = disk_cache.load_arrays(key)
    if stored is None or list(stored) != ["rays_per_item"]:
        return None
    value = stored["rays_per_item"]
    if value.shape != (1,) or value.dtype.kind not in "iu" or int(value[0]) not in choices:
        return None
    return int(value[0])


def _untimed_choice(key: str, choices: tuple[int, int]) -> int | None:
    """The rays per work item ``LensKernel`` runs without timing them for ``key`` (``_choice_key``;
    ``choices``: several, one): the one chosen in this process (``_chosen``) or stored in the disk
    cache; else None where the choice is to be timed now, or one ray, untimed, where this process's
    renders do not repay timing it (``time_choices``)."""
    with _choosing:
        if key in _chosen:
            return _chosen[key]
        stored = _stored_choice(key, choices)
        if stored is not None:
            return _chosen.setdefault(key, stored)
        return None if _timing[0] else choices[1]


def build_ahead(camera: LensCamera, device: Device) -> None:
    """Build the lens programs ``LensKernel(camera, device)`` will use, before it is made: the
    choice of rays per work item it runs untimed, or both choices where it will time them. A render
    calls this on a thread of its own while the exit-pupil table is made (the programs need no
    table; ``Device.build_program`` hands a program being built to whoever asks next)."""
    choices = rays_per_item_choices(camera)
    untimed = _untimed_choice(_choice_key(camera, device), choices)
    for rays_per_item in choices if untimed is None else (untimed,):
        device.build_program(*lens_program(camera, rays_per_item))


class LensKernel:
    """``lens.cl`` built for one camera; each launch writes straight into the arrays it returns.

    Each work item traces ``rays_per_item`` rays: given, or else the faster of
    ``rays_per_item_choices`` as timed on this device by the first render of this lens, camera and
    kernel source that repays timing it (a smaller one uses one, untimed: ``_fastest_rays_per_item``),
    then kept in the disk cache. Several rays per work item are what let PoCL's
    vectoriser overlap their latencies (``kernels/lens.cl``), but LLVM's SLP vectoriser, which PoCL
    3.0 runs before it, sometimes packs the rays into short vectors instead, and then the kernel
    runs at a third of the speed of one ray per work item: which happens depends on the kernel's
    variant and on the processor. Every ray is computed the same either way, and so are a spectral
    sample's K rays traced by one work item (``shares_samples``).

    Safe to call from several threads: launches are serialised on one lock (the kernel object's
    arguments are shared; PoCL spreads one launch over every core anyway).
    """

    def __init__(self, camera: LensCamera, device: Device | None = None, rays_per_item: int | None = None):
        """``device``: where to build and launch (None: ``Device.for_spec()``, the default device)."""
        device = device or Device.for_spec()
        self.camera, self.device = camera, device
        self.context = device.context
        self.queue = device.queue()
        self._lock = threading.Lock()
        self._rows = ROWS + int(camera.spectral)
        self._world = device.copied_buffer(camera.world_from_lens[:3, :4], np.float32)
        self._settings = device.copied_buffer(setting_values(camera), np.float32)
        w_mm, h_mm = camera.film_size_mm
        # the values the compiler folded when they were literals: 1.0f / WIDTH rounds as float32 does
        self._film = (np.uint32(camera.width), np.float64(1) / np.float64(camera.width),
                      np.float32(1) / np.float32(camera.width),
                      np.float32(1) / np.float32(camera.height), np.float32(w_mm), np.float32(h_mm))
        self._use(self._build(rays_per_item or self._fastest_rays_per_item()))

    def _build(self, rays_per_item: int) -> _Built:
        """The program tracing ``rays_per_item`` rays per work item (built, or from the caches) and
        its two kernels."""
        program = self.device.build_program(*lens_program(self.camera, rays_per_item))
        return rays_per_item, program, TypedKernel(program, "generate_rays"), TypedKernel(program, "sample_bits")

    def _use(self, built: _Built) -> None:
        """Launch the program ``_build`` made from now on, its launch sizes decided by its next launch."""
        self.rays_per_item, self.program, self._generate, self._bits = built
        self._sizes = LaunchSizes()

    def _fastest_rays_per_item(self) -> int:
        """The faster of ``rays_per_item_choices`` for this camera on this device (see
        ``ONE_RAY_MARGIN``): from the disk cache, or timed on launches of equal work, taken in turn
        (PoCL compiles each at its first launch, untimed).

        Only a render that repays it times the choice (``time_choices``): timing builds and
        compiles both programs, about a second, while the choice changes only the camera rays'
        speed (every ray is the same either way); a smaller render uses one ray per work item,
        untimed, whose program PoCL compiles in a fraction of the several-ray one's time. The choice
        timed is stored, keyed by the device, the lens, camera and kernel source (``_choice_key``),
        so a later process reads it back and builds the chosen program alone (its binaries stored
        at this one's exit: ``opencl.keep_first_builds``); with the disk cache off every process
        that repays it times its choice. The program not chosen leaves no binaries to store at exit
        (``leave_binaries_unstored``)."""
        key = _choice_key(self.camera, self.device)
        several, one = rays_per_item_choices(self.camera)
        untimed = _untimed_choice(key, (several, one))
        if untimed is not None:
            return untimed
        block = SampleBlock(0, TIMED_RAYS // self.camera.rays_per_sample, self.camera.spp)
        built = {choice: self._build(choice) for choice in (several, one)}  # each built once
        fastest = {several: np.inf, one: np.inf}
        for choice in fastest:
            self._use(built[choice])
            self.generate(block)
        for _ in range(TIMED_ROUNDS):
            for choice in fastest:
                self._use(built[choice])
                fastest[choice] = min(fastest[choice], _seconds(lambda: self.generate(block)))
        chosen = _chosen[key] = one if fastest[one] < ONE_RAY_MARGIN * fastest[several] else several
        disk_cache.store_arrays(key, {"rays_per_item": np.array([chosen])})
        leave_binaries_unstored(built[several if chosen == one else one][1])
        return chosen

    def generate(self, block: SampleBlock, seed: int = 0) -> RayBatch:
        """Rays of the block's samples, as ``LensCamera.generate_rays`` makes them (float32): a
        spectral camera's ``rays_per_sample`` rays of each sample consecutively."""
        per_item = self.rays_per_item
        count = block.count * self.camera.rays_per_sample
        with self._lock:  # the kernel writes into the result's own arrays, read back at once (Device.run_into)
            address, padded = self._sizes.layout(block, self.camera.rays_per_sample, per_item)
            outputs = OutputBlock(self.device, (((self._rows, padded), np.float32), ((padded,), np.int32)))
            out, pixels = outputs.arrays
            self.device.run_into(self.queue, self._generate, (padded // per_item,), (LOCAL_SIZE,),
                                 (*address, np.uint32(seed & 0xFFFFFFFF), self._world, self._settings, *self._film,
                                  np.uint32(padded)), outputs)
        return RayBatch(origin=out[0:3, :count].T, direction=out[3:6, :count].T, weight=out[6, :count],
                        pixel=pixels[:count], wavelength_nm=out[7, :count] if self.camera.spectral else None)

    def sample_bits(self, block: SampleBlock, seed: int = 0) -> np.ndarray:
        """The kernel's stratified uint32 values per sample: R4's four, or for a spectral camera R5's
        five (the wavelength's last): shape (4 or 5, count) (for tests)."""
        address, padded = launch_layout(block)
        count = block.count
        rows = 4 + int(self.camera.spectral)
        bits = cl.Buffer(self.context, cl.mem_flags.WRITE_ONLY, rows * padded * 4)
        host = np.empty((rows, padded), dtype=np.uint32)
        with self._lock:
            self._bits(self.queue, (padded,), (LOCAL_SIZE,), *address,
                       np.uint32(seed & 0xFFFFFFFF), np.uint32(padded), bits)
            cl.enqueue_copy(self.queue, host, bits)
        return host[:, :count]
