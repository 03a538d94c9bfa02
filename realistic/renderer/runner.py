"""One pass task's work, the same on a thread and on a farm worker: sample ids in, per-pixel sums out.

``PassRunner`` turns a pass (a ``SampleBlock`` of sample ids) into rays, embree hits, radiance and
per-pixel sums (``film.pass_sums``). Both executors (``passes.ThreadPasses`` and
``farm.DaskPasses``) build their runners here, so neither imports the other.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from realistic.camera.base import Camera, RayBatch, SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core.jit import compiled, compiled_loops, use_compiled_loops
from realistic.renderer.aov import AovLayout
from realistic.renderer.backends import backend_for
from realistic.renderer.direct_lighting import compile_shading_loops
from realistic.renderer.film import pass_sums
from realistic.renderer.flare import FlareEstimator, ghost_paths
from realistic.renderer.footprint import differential_scale
from realistic.renderer.integrators import make_integrator
from realistic.renderer.job import PassResult, PassSettings, RenderJob
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Intersector, compile_intersect_loops
from realistic.scene.model import Scene


def morton_order(pixel: np.ndarray, width: int) -> np.ndarray:
    """Permutation that visits pixels along a Z-order (Morton) curve over (x, y): the stable argsort
    of the rays' Morton codes, taken over runs of equal pixels (a pass's rays come pixel by pixel,
    so a run per pixel, a sort of one code per pixel rather than per ray): the runs in stable order
    of their codes, each run's rays in their order, which is the same permutation."""
    def spread(v: np.ndarray) -> np.ndarray:
        v = v.astype(np.uint64) & np.uint64(0xFFFF)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        return v
    pixel = np.asarray(pixel)
    starts = np.flatnonzero(np.concatenate([np.ones(min(len(pixel), 1), bool), pixel[1:] != pixel[:-1]]))
    first = pixel[starts]
    code = spread(first % width) | (spread(first // width) << np.uint64(1))
    order = np.argsort(code, kind="stable")
    lengths = np.diff(np.append(starts, len(pixel)))[order]
    # the ray at position j of run m (in order) is starts[m] + j: shift each position by its run's
    return np.arange(len(pixel)) + np.repeat(starts[order] - (np.cumsum(lengths) - lengths), lengths)


def _gather(points: np.ndarray, rows: np.ndarray, gathered: np.ndarray) -> bool:
    """gathered[j] = points[rows[j]] of (n, 3) points (a numba loop, ``core.jit``: one pass writing
    the result's rows in order, whatever ``points``' layout, its three columns spelt out, which the
    compiler keeps apart where a loop over the columns cost half as much again); False, with
    nothing written, at a row out of range."""
    for j in range(rows.shape[0]):
        if rows[j] < 0 or rows[j] >= points.shape[0]:
            return False
    for j in range(rows.shape[0]):
        r = rows[j]
        gathered[j, 0], gathered[j, 1], gathered[j, 2] = points[r, 0], points[r, 1], points[r, 2]
    return True


#: ``_gather``'s one signature: any layout of points, so that the kernel's rays, strided or
#: contiguous views (a launch with no padding), do not compile it twice.
GATHER_SIGNATURE = "boolean(float32[:, :], int64[:], float32[:, ::1])"


def gather_rows(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """points[rows] of (n, 3) points (non-negative ``rows``) as a contiguous (len(rows), 3) float32
    array. The kernel's rays are transposed views of its (columns, n) output, which the loop reads
    in place; other points (the numpy references' float64) are rounded to float32 first."""
    points, rows = np.asarray(points, np.float32), np.asarray(rows, np.int64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"gather_rows: points of shape {points.shape}, not (n, 3)")
    if not compiled_loops():  # numpy's form (``core.jit.use_compiled_loops``)
        if len(rows) and (rows.min() < 0 or rows.max() >= len(points)):
            raise IndexError(f"gather_rows: a row outside 0 .. {len(points) - 1}")
        return np.ascontiguousarray(points[rows])
    gathered = np.empty((len(rows), 3), np.float32)
    if not compiled(_gather, GATHER_SIGNATURE)(points, rows, gathered):
        raise IndexError(f"gather_rows: a row outside 0 .. {len(points) - 1}")
    return gathered


def _copy(points: np.ndarray, copied: np.ndarray) -> None:
    """copied[j] = points[j] of (n, 3) points (a numba loop, ``core.jit``), whatever ``points``'
    layout, its columns spelt out as ``_gather``'s."""
    for j in range(points.shape[0]):
        copied[j, 0], copied[j, 1], copied[j, 2] = points[j, 0], points[j, 1], points[j, 2]


#: ``_copy``'s one signature, as ``GATHER_SIGNATURE``.
COPY_SIGNATURE = "void(float32[:, :], float32[:, ::1])"


def contiguous_rows(points: np.ndarray) -> np.ndarray:
    """``gather_rows`` of every row in order: the kernel's float32 rays, transposed views of its
    (3, n) output, copied to a contiguous (n, 3) array without reading a row number per row
    (numpy's copy of such a view is slower than the loop's)."""
    points = np.asarray(points, np.float32)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"contiguous_rows: points of shape {points.shape}, not (n, 3)")
    if not compiled_loops():
        return np.ascontiguousarray(points)
    copied = np.empty(points.shape, np.float32)
    compiled(_copy, COPY_SIGNATURE)(points, copied)
    return copied


def _pick_live(origin: np.ndarray, direction: np.ndarray, weight: np.ndarray, pixel: np.ndarray,
               wavelength: np.ndarray, first: int, samples: int, first_sample: int, rays_per_sample: int,
               out_origin: np.ndarray, out_direction: np.ndarray, out_pixel: np.ndarray, out_weight: np.ndarray,
               out_wavelength: np.ndarray, out_sample: np.ndarray) -> int:
    """The live rays (weight != 0) of a ``SampleBlock(first, ., samples, first_sample)``'s kernel
    rays, ``rays_per_sample`` a sample, written in order to the ``out_`` arrays' first rows, their
    number returned (a numba loop, ``core.jit``: one pass over the rays where numpy's picks made
    one per array). The arrays have a row more than the live rays, which each dead ray after the
    last live one is written to; -1, with the rows written so far, where there are more live rays.
    A ray's sample id is derived, not read: ray r is of the block's pair r // rays_per_sample,
    sample ``first_sample + (first + r // rays_per_sample) % samples`` (``SampleBlock.sample_ids``),
    counted up here. An empty ``wavelength``: none written."""
    spectral = wavelength.shape[0] > 0
    slot, ray_of_sample, count = first % samples, 0, 0
    for r in range(weight.shape[0]):
        if count == out_weight.shape[0]:
            return -1
        # every ray written at the next free row, which only a live one keeps: no branch per ray to
        # mispredict where a lens vignettes a third of its rays at random
        out_origin[count, 0], out_origin[count, 1], out_origin[count, 2] = origin[r, 0], origin[r, 1], origin[r, 2]
        out_direction[count, 0], out_direction[count, 1], out_direction[count, 2] = \
            direction[r, 0], direction[r, 1], direction[r, 2]
        out_pixel[count], out_weight[count], out_sample[count] = pixel[r], weight[r], first_sample + slot
        if spectral:
            out_wavelength[count] = wavelength[r]
        count += weight[r] != 0
        ray_of_sample += 1
        if ray_of_sample == rays_per_sample:
            ray_of_sample, slot = 0, slot + 1
            if slot == samples:
                slot = 0
    return count


#: ``_pick_live``'s one signature: the kernel's rays in any layout (views of its output), as
#: ``GATHER_SIGNATURE``.
PICK_SIGNATURE = ("int64(float32[:, :], float32[:, :], float32[:], int32[:], float32[:], int64, int64, int64, int64, "
                  "float32[:, ::1], float32[:, ::1], int32[::1], float32[::1], float32[::1], int64[::1])")


@dataclass(frozen=True)
class LiveRays:
    """A pass's camera rays that are traced, in tracing order: origin and direction contiguous
    (m, 3) float32 (what embree and the integrator read), each ray's pixel, weight, sample id and,
    for a spectral camera, wavelength. (``every_ray``'s are the kernel's views, contiguous once
    picked by ``rows``.)"""

    origin: np.ndarray
    direction: np.ndarray
    pixel: np.ndarray
    weight: np.ndarray
    sample: np.ndarray
    wavelength: np.ndarray | None

    def rows(self, rows: np.ndarray) -> LiveRays:
        """These rays' ``rows`` (non-negative indices), in that order."""
        wavelength = None if self.wavelength is None else self.wavelength[rows]
        return LiveRays(gather_rows(self.origin, rows), gather_rows(self.direction, rows), self.pixel[rows],
                        self.weight[rows], self.sample[rows], wavelength)


def every_ray(rays: RayBatch, block: SampleBlock, rays_per_sample: int) -> LiveRays:
    """All of ``rays``, as the kernel gave them (not copied), with their sample ids: ``block``'s,
    ``rays_per_sample`` consecutive rays a sample (a spectral camera's wavelengths, which share the
    sample id, so the integrator's light samples). Pick the traced ones with ``rows``."""
    sample = block.sample_ids()
    if rays_per_sample > 1:
        sample = np.repeat(sample, rays_per_sample)
    return LiveRays(rays.origin, rays.direction, rays.pixel, rays.weight, sample, rays.wavelength_nm)


def live_rays(rays: RayBatch, block: SampleBlock, rays_per_sample: int) -> LiveRays:
    """``rays``' live ones (weight != 0: a vignetted ray has weight 0, a negative filter lobe a
    negative weight), in order, of ``block``'s samples, ``rays_per_sample`` consecutive rays a sample
    (a spectral camera's wavelengths, which share the sample id, so the integrator's light samples):
    the kernel's rays in one compiled loop (``_pick_live``); every ray where all are live (a thin
    lens's), copied without a row number per ray, the per-ray arrays as they are; other rays (the
    numpy references') and the numpy form (``core.jit.use_compiled_loops``) by numpy's picks, the
    same bits."""
    wavelength = rays.wavelength_nm
    kernel_types = (rays.weight.dtype == np.float32 and rays.pixel.dtype == np.int32
                    and rays.origin.dtype == rays.direction.dtype == np.float32
                    and (wavelength is None or wavelength.dtype == np.float32))
    n, is_live = len(rays.weight), rays.weight != 0
    live = int(np.count_nonzero(is_live))
    every = live == n
    if every or not (compiled_loops() and kernel_types):
        rays_as_given = every_ray(rays, block, rays_per_sample)
        if every:
            return dataclasses.replace(rays_as_given, origin=contiguous_rows(rays.origin),
                                       direction=contiguous_rows(rays.direction))
        return rays_as_given.rows(np.flatnonzero(is_live))
    if rays.origin.shape != (n, 3) or rays.direction.shape != (n, 3) or len(rays.pixel) != n \
            or (wavelength is not None and len(wavelength) != n) or n != block.count * rays_per_sample:
        raise ValueError(f"live_rays: rays of unequal lengths for {block.count} samples of {rays_per_sample} rays")
    # sized to the live rays (and the loop's spare row), not to every ray: arrays a third larger
    # than used grew the heap each pass, whose fresh (huge) pages the kernel then zeroed
    rows = live + 1
    origin, direction = np.empty((rows, 3), np.float32), np.empty((rows, 3), np.float32)
    pixel, weight, sample = np.empty(rows, np.int32), np.empty(rows, np.float32), np.empty(rows, np.int64)
    wavelengths, picked_wavelength = (np.empty(0, np.float32),) * 2 if wavelength is None else \
        (wavelength, np.empty(rows, np.float32))
    count = compiled(_pick_live, PICK_SIGNATURE)(
        rays.origin, rays.direction, rays.weight, rays.pixel, wavelengths, block.first, block.samples,
        block.first_sample, rays_per_sample, origin, direction, pixel, weight, picked_wavelength, sample)
    if count != live:
        raise RuntimeError(f"live_rays: the loop found {count} live rays of {n}, numpy {live}")
    return LiveRays(origin[:live], direction[:live], pixel[:live], weight[:live], sample[:live],
                    None if wavelength is None else picked_wavelength[:live])


def compile_pass_loops() -> None:
    """Compile (or load from numba's cache) a pass's own numba loops, the pick of the kernel's live
    rays, the gather and copy of rows (for their one signature each), the closest hits' instance normals,
    the film's sums and the shading sums, for the argument types a pass passes, on no rows: a render
    does this on a render thread as it starts (``ThreadPasses.open``), beside its OpenCL builds, not
    in its first pass."""
    compiled(_gather, GATHER_SIGNATURE)
    compiled(_copy, COPY_SIGNATURE)
    compiled(_pick_live, PICK_SIGNATURE)
    compile_intersect_loops()
    pass_sums(np.empty(0, np.int32), np.empty((0, 3), np.float32), 0, 0, np.empty(0, np.float32))
    compile_shading_loops()


#: Rays (camera and shadow rays) from which a render repays one-off compiles (``repays_compiling``):
#: numba's import and first compiles take a second or so of one core, holding the GIL, which the
#: numpy forms and embree's packets called from Python repay only over about this many rays; timing
#: the lens program's choice of rays per work item costs about as much.
COMPILED_LOOPS_RAYS = 8_000_000


def repays_compiling(job: RenderJob) -> bool:
    """Whether ``job`` has at least ``COMPILED_LOOPS_RAYS`` rays, estimated as each camera's samples
    times its rays per sample and one more than the light samples."""
    rays = sum(camera.width * camera.height * camera.spp * camera.rays_per_sample for camera in job.cameras)
    return rays * (1 + job.settings.light_samples) >= COMPILED_LOOPS_RAYS


def choose_loops(job: RenderJob) -> bool:
    """Whether ``job``'s passes run numba's loops, set for the process (``core.jit.use_compiled_loops``):
    only for a render that repays compiling them (``repays_compiling``), or where they are made
    already."""
    use_compiled_loops(repays_compiling(job))
    return compiled_loops()


class PassRunner:
    """Runs passes of sample ids: rays, hits, shading, per-pixel sums. Built once per camera (and
    per worker process on a farm); ``intersector`` shares one scene's embree BVH between cameras."""

    def __init__(self, scene: Scene, camera: Camera, settings: PassSettings, clock: StageClock,
                 intersector: Intersector | None = None):
        self.camera, self.morton, self.clock, self.crop = camera, settings.morton, clock, settings.crop
        kernels = backend_for(settings.backend, settings.cl_device)  # this process's, made once: jobs carry strings
        self.generate = kernels.ray_generator(camera, settings.seed)
        spread = camera.pixel_spread_radians() * differential_scale(camera.spp, scene.differential_floor)
        self.integrator = make_integrator(scene, intersector or Intersector(scene), settings.light_samples,
                                          settings.seed, spread, backend=kernels,
                                          spectral=isinstance(camera, LensCamera) and camera.spectral)
        self.aovs = AovLayout(settings.aovs)
        self.flare = None
        if settings.flare_threshold is not None and isinstance(camera, LensCamera):  # RenderJob refuses other cameras
            paths = ghost_paths(camera, settings.flare_threshold, kernels.ghost_tracer(camera.lens))
            self.flare = FlareEstimator(scene, camera, self.integrator.intersector, settings.seed, paths)

    def run(self, passes: list[tuple[int, SampleBlock]]) -> list[PassResult]:
        """The results of passes given as (plan index, sample block)."""
        return [self(index, block) for index, block in passes]

    def __call__(self, index: int, block: SampleBlock) -> PassResult:
        with self.clock("ray generation"):
            rays = self.generate(block)
        with self.clock("shading"):
            # a spectral camera's K rays per sample (its wavelengths) come consecutively, sample-major
            rays_per_sample, rest = divmod(len(rays.weight), block.count)
            if rest or not rays_per_sample:
                raise RuntimeError(f"{len(rays.weight)} camera rays for {block.count} samples")
            if self.crop is None and not self.morton:
                live = live_rays(rays, block, rays_per_sample)
            else:  # the traced rows chosen first, so that only they are copied, once
                every = every_ray(rays, block, rays_per_sample)
                rows = np.flatnonzero(every.weight != 0)
                if self.crop is not None:  # a crop's pixels only: the pass's other rays are made, not traced
                    rows = rows[self.crop.contains(every.pixel[rows], self.camera.width)]
                if self.morton:
                    rows = rows[morton_order(every.pixel[rows], self.camera.width)]
                live = every.rows(rows)
            origin, direction, pixel = live.origin, live.direction, live.pixel
        hits, albedo, aov_values = None, None, None
        if self.aovs.aovs:  # the camera rays' hits and albedo, found once for the AOVs and the integrator
            with self.clock("embree"):
                hits = self.integrator.intersector.closest(origin, direction, coherent=True)
            with self.clock("first hits"):
                with_albedo = "albedo" in self.aovs.quantities
                first = self.integrator.first_hits(origin, direction, hits, with_albedo)
                albedo = first.albedo if with_albedo else None
                aov_values = self.aovs.values(first, np.sign(live.weight))
        radiance, shadow_rays = self.integrator.radiance(origin, direction, pixel, live.sample, self.clock,
                                                         live.wavelength, hits, albedo)
        with self.clock("accumulation"):
            first_pixel, pixel_count = block.first_pixel, block.pixel_count
            # a spectral ray's radiance comes weighted by the film's response at its wavelength
            weight = live.weight.astype(np.float32, copy=False)
            if rays_per_sample > 1:  # each of a sample's K wavelengths is 1/K of its estimate
                weight = weight / np.float32(rays_per_sample)
            sums = pass_sums(pixel, radiance, first_pixel, pixel_count, weight)
            if aov_values is not None:
                sums = np.column_stack([sums, pass_sums(pixel, aov_values, first_pixel, pixel_count)])
        flare = None
        if self.flare is not None:
            with self.clock("flare"):
                flare = self.flare.splats(block)
        count = block.count if self.crop is None else self.crop.samples_in(block, self.camera.width)
        return PassResult(index, first_pixel, sums, count, len(pixel), shadow_rays, flare)
