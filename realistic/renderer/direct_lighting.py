"""Direct lighting in numpy: closest hits, area-light samples, shadow rays, Lambertian reflection.

For a hit point p with albedo rho and shading normal n, one light sample picks light j with
probability P_j (proportional to its power), a point q uniformly on its area A_j, and gives

    L = rho / pi * L_j * cos(theta_p) * cos(theta_q) / |q - p|^2 * A_j / P_j * V(p, q),

the area-sampling estimator (pdf in solid angle A_j^-1 |q - p|^2 / cos(theta_q)), averaged over
``light_samples`` samples. Camera rays that hit an emitter's front side see its radiance; rays
that miss everything see the background colour. Random numbers: ``realistic.core.rng.light_uniforms``
for light sample k of camera sample s, a per-pixel scrambled Sobol' sequence over s L + k (L light
samples), so a pixel's spp L light samples are stratified together and a render does not depend on
pass size.
Image textures are filtered over each camera ray's pixel footprint (``renderer.footprint``) when
the camera's ``pixel_spread_radians`` is given.

Measured BRDFs of irregular samples (pbrt-v2's ``.brdf`` files, shaded from their tables,
``renderer.bsdf.measured.irregular_table``) take pbrt-v2 ``directlighting``'s estimator for a
non-specular BSDF (``UniformSampleAllLights``/``EstimateDirect``, ``src/core/integrator.cpp``): each
light sample (light j, picked with probability P_j, point q) is paired with a BSDF sample, a
cosine-weighted direction about the shading normal (pbrt-v2 ``BxDF::Sample_f``'s default,
``src/core/reflection.cpp``; numbers ``rng.light_bsdf_uniforms``), which counts where it meets light
j's disk or quad from its emitting side; each is weighted by the power heuristic between the light's
solid-angle density |q - p|^2 / (cos_q A_j) and the BSDF's cos / pi, divided by P_j, and traces its
own shadow ray. RGB rays only (``integrators.make_integrator`` sends spectral ones to the path
integrator).

Spectral rays (one wavelength each) evaluate every RGB albedo, light radiance and background as a
spectrum at the ray's wavelength (``realistic.core.spectrum.rgb_basis``), multiply spectra, and return
the spectral radiance weighted by the film's ``rgb_response`` at that wavelength (RGB).

Backends: the numpy code here is the reference and shades with backend "numpy". With backend
"opencl" RGB rays are shaded by ``kernels/shade.cl`` (``renderer.shade_kernel``): one launch per pass
computes every surface hit's normals and albedo and every light sample's shadow ray and
contribution, embree traces all the shadow rays in one ``occluded_lanes`` call, and a loop (``_visible_sums``) sums the
unblocked contributions; camera rays that miss or see an emitter keep the numpy code. The albedo of
EWA-filtered image textures comes from ``kernels/ewa.cl`` (``EwaKernel.at_hits``: hit records to albedo, bit
for bit the numpy ``_albedo`` here: ``tests/test_ewa_hits.py``), other image textures' from ``_albedo``. Spectral rays
shade in the kernel too (its ``SPECTRAL`` variant, which weights by ``rgb_response`` itself). The two
agree to float32 rounding, shadow-ray origins bit for bit (``tests/test_shade_kernel.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from realistic.core import rng
from realistic.core.jit import compiled, compiled_loops
from realistic.core.spectrum import rgb_basis, rgb_response, spectral_value
from realistic.core.vectors import dot, normalise
from realistic.core.warp import concentric_disk
from realistic.renderer.aov import FirstHits
from realistic.renderer.area_lights import AreaLightTable, light_outward_flipped
from realistic.renderer.backends import Backend, backend_for
from realistic.renderer.bsdf import ShadingFrame, bsdf_for
from realistic.renderer.bsdf.lambertian import cosine_hemisphere
from realistic.renderer.bsdf.measured import irregular_table, table_lookup
from realistic.renderer.hit_rows import compile_row_loops, place_rows, rows_on_material
from realistic.renderer.light_sampler import SHADOW_LENGTH
from realistic.renderer.surface_parameters import RHO_U, SurfaceParameters, directional_albedo
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Hits, Intersector
from realistic.scene.materials import Measured, SurfaceMaterial
from realistic.scene.measured import IrregularSamples, load_measured
from realistic.scene.model import AreaLight, ImageTexture, Material, Scene
from realistic.scene.packet_loop import PACKET, lane_rows
from realistic.scene.shapes import light_mesh
from realistic.scene.textures import Footprint, albedo, numpy_lookup

if TYPE_CHECKING:  # pyopencl is imported only when the "opencl" backend is chosen
    from realistic.renderer.opencl_backend import OpenCLBackend
    from realistic.renderer.shade_kernel import ShadeKernel

SHADOW_OFFSET = 1e-4  # relative to the hit point's magnitude (float32 precision of embree)


def _rows(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    """a[index] for row gathers (np.take: faster than fancy indexing on (N, 3) arrays)."""
    return np.take(a, index, axis=0)


def interpolated(table: np.ndarray, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Per-vertex rows of ``table`` (normals, uv) at hits: the rows of each hit triangle's vertices
    ``face`` (n, 3) weighted by its barycentrics ``bary`` (n, 3)."""
    return (_rows(table, face[:, 0]) * bary[:, :1] + _rows(table, face[:, 1]) * bary[:, 1:2]
            + _rows(table, face[:, 2]) * bary[:, 2:])


#: The directions of a measured material's albedo estimate (``first_hits``): ``RHO_U`` cosine-weighted.
_RHO_DIRECTIONS = cosine_hemisphere(RHO_U)


def _matte(material: SurfaceMaterial) -> Material:
    """``material``, which ``DirectLighting``'s own shading needs matte where it reads an albedo
    (``integrators.make_integrator`` gives scenes of other materials, but for measured ones, to
    ``PathIntegrator``, which shades them by their BSDFs)."""
    if not isinstance(material, Material):
        raise TypeError(f"DirectLighting shades matte materials only, not {type(material).__name__}")
    return material


def tabulated_samples(material: SurfaceMaterial) -> IrregularSamples | None:
    """The samples of ``material`` when it is a measured BRDF of irregular samples (a ``.brdf``
    file), which ``DirectLighting`` shades from its table (``renderer.bsdf.measured.irregular_table``)."""
    if isinstance(material, Measured):
        data = load_measured(material.path)
        if isinstance(data, IrregularSamples):
            return data
    return None


def is_tabulated(material: SurfaceMaterial) -> bool:
    """Whether ``DirectLighting`` shades ``material`` from a measured table (``tabulated_samples``)."""
    return tabulated_samples(material) is not None


def bfloat16(table: np.ndarray) -> np.ndarray:
    """A measured table (float32) rounded to bfloat16 (a float's upper 16 bits, to nearest, ties to
    even; relative error at most 2^-8) as the shading kernel holds it: half the memory, and so
    fewer cache misses, which are most of its lookups' cost."""
    bits = np.ascontiguousarray(table, np.float32).view(np.uint32)
    rounded = (bits + np.uint32(0x7FFF) + ((bits >> np.uint32(16)) & np.uint32(1))) & np.uint32(0xFFFF0000)
    return rounded.view(np.float32)


def dual_axes(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 vectors a*, b* (L, 3) with a* . (x a + y b) = x and b* . (x a + y b) = y (in the
    plane of a and b): a point's coordinates on a light (``AreaLightTable``), from float64 a and b."""
    a64, b64 = np.asarray(a, np.float64), np.asarray(b, np.float64)
    aa, bb, ab = (np.einsum("ij,ij->i", p, q)[:, None] for p, q in ((a64, a64), (b64, b64), (a64, b64)))
    det = aa * bb - ab * ab
    return ((bb * a64 - ab * b64) / det).astype(np.float32), ((aa * b64 - ab * a64) / det).astype(np.float32)


@dataclass(frozen=True)
class _MeasuredHits:
    """Surface hits' measured materials (numpy's MIS reference): each row's table (an index into
    ``tables``, -1 for the other materials), its shading normal n, wo = -d, cos_o = wo . n, and
    n x wo, from which a direction's azimuth about n relative to wo follows without a local frame
    (as ``kernels/shade.cl`` computes it)."""

    table: np.ndarray
    tables: list[np.ndarray]
    normal: np.ndarray
    wo: np.ndarray
    cos_o: np.ndarray
    n_cross_wo: np.ndarray

    def lookup(self, rows: np.ndarray, wi: np.ndarray, cos_i: np.ndarray) -> np.ndarray:
        """f(wo, wi) RGB (n, 3) float32 of the measured hits ``rows`` for world directions ``wi``
        (n, 3) with cos_i = wi . n: ``table_lookup`` of the pair given as (1, 0, cos_o) and
        (along, cross, cos_i), along = wo . wi - cos_o cos_i and cross = n . (wo x wi): projected
        onto the tangent plane, wo and wi are then sin_o (1, 0) and sin_i sin_o (cos phi, sin phi)
        scaled by 1 / sin_o, at the same azimuths (the lookup reads the pair through cos_o,
        cos_i and the angle between the projections alone)."""
        cos_o = self.cos_o[rows]
        wo = np.column_stack([np.ones(len(rows), np.float32), np.zeros(len(rows), np.float32), cos_o])
        local = np.column_stack([dot(wi, self.wo[rows]) - cos_o * cos_i, dot(wi, self.n_cross_wo[rows]), cos_i])
        f = np.zeros((len(rows), 3), np.float32)
        for index, table in enumerate(self.tables):
            at = np.flatnonzero(self.table[rows] == index)
            if len(at):
                f[at] = table_lookup(table, wo[at], local[at]).astype(np.float32)
        return f


def _facing(normal: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """embree's geometric normals (N, 3), normalised in float32 and turned to face the rays."""
    ng = normalise(np.asarray(normal).astype(np.float32))
    ng *= np.where(dot(ng, direction) > 0, -1.0, 1.0).astype(np.float32)[:, None]
    return ng


def _visible_sums(contribution: np.ndarray, blocked: np.ndarray, length: np.ndarray, n: int, fresh: bool,
                  out: np.ndarray) -> int:
    """Add to ``out`` (n, channels) float32 each ray's unblocked contributions: of a launch's lanes
    (``ShadowBatch``: contribution (hits / 16, per, channels, 16), length and ``blocked`` (hits / 16,
    per, 16), the latter from ``occluded_lanes``), ray i's shadow rays k = 0 .. per - 1 in order, as
    contribution times 1 or 0 in float32 (``fresh``: ``out`` starts as the first product, not 0
    plus it, as numpy's reduction starts); the shadow rays traced (length > 0) are returned. A dead
    one (length not > 0: the kernel writes its contribution 0, and embree reports it blocked) adds
    +0, whatever its contribution and answer hold.

    A numba loop (``core.jit``), the GIL released, that LLVM vectorises across a group's 16 lanes:
    each channel's running totals are a row of 16, summed two shadow rays (rows k, k + 1) per pass
    over it (with one row a pass, LLVM's 8-wide loop wanted 32 iterations and its 4-wide remainder
    loop ran), and stored to ``out`` once per group. A pair of rows with no live lane below n adds
    +0 once, without reading its contributions (about half a launch's rays are dead: points facing
    away from the light, padding): after x + 0 a sum is never -0, so a second +0 would change
    nothing. A fresh sum starts at -0 (the first pass reads -0, not the totals: setting them first
    cost a sixth of the loop with one shadow ray per hit), and an odd ``per``'s last pass adds -0 for
    its missing second row: x + -0 == x for every float32 x, so neither changes a sum."""
    traced = 0
    zero, one, none = np.float32(0.0), np.float32(1.0), np.float32(-0.0)
    channels, per, width = out.shape[1], length.shape[1], length.shape[2]
    total = np.zeros((channels, width), np.float32)  # lanes past n (padding) are summed, never stored
    for group in range(-(-n // width)):
        base = group * width
        lanes = min(width, n - base)
        if not fresh:
            for c in range(channels):
                for j in range(lanes):
                    total[c, j] = out[base + j, c]
        for k in range(0, per, 2):
            after = min(k + 1, per - 1)
            pair = after > k
            start = fresh and k == 0  # the totals are -0, not what they hold
            live = 0
            for j in range(lanes):
                live += (length[group, k, j] > zero) + (pair and length[group, after, j] > zero)
            traced += live
            if live == 0:
                for c in range(channels):
                    for j in range(width):
                        total[c, j] = (none if start else total[c, j]) + zero
                continue
            for c in range(channels):
                for j in range(width):
                    first = contribution[group, k, c, j] * (zero if blocked[group, k, j] else one)
                    second = contribution[group, after, c, j] * (zero if blocked[group, after, j] else one)
                    total[c, j] = (((none if start else total[c, j]) + (first if length[group, k, j] > zero else zero))
                                   + (none if not pair else second if length[group, after, j] > zero else zero))
        if channels == 3:  # a lane's three stores, which LLVM interleaves (a loop over channels scattered)
            for j in range(lanes):
                out[base + j, 0], out[base + j, 1], out[base + j, 2] = total[0, j], total[1, j], total[2, j]
        else:
            for c in range(channels):
                for j in range(lanes):
                    out[base + j, c] = total[c, j]
    return traced


def visible_sums(contribution: np.ndarray, blocked: np.ndarray, length: np.ndarray, n: int, fresh: bool,
                 out: np.ndarray) -> int:
    """``_visible_sums``, compiled, or in numpy where the loops do not run compiled
    (``core.jit.use_compiled_loops``): the same products, added in the same order."""
    if compiled_loops():
        return int(compiled(_visible_sums)(contribution, blocked, length, n, fresh, out))
    per, channels = length.shape[1], out.shape[1]
    # (hits, per) and (hits, per, channels), ray i's rows at [i]
    length, blocked = (lane_rows(a)[:n] for a in (length, blocked))
    contribution = lane_rows(contribution[:, :, :channels])[:n]
    live = length > 0
    visible = np.where(blocked, np.float32(0.0), np.float32(1.0))
    products = np.where(live[:, :, None], contribution * visible[:, :, None], np.float32(0.0))
    for k in range(per):
        if fresh and k == 0:
            out[:n] = products[:, 0]
        else:
            out[:n] += products[:, k]
    return int(np.count_nonzero(live))


def compile_shading_loops() -> None:
    """Compile (or load from numba's cache) ``_visible_sums`` and the device textures' row loops
    (``hit_rows``) for the argument types every launch passes, on no rows: a render does this on a
    render thread as it starts (``runner.compile_pass_loops``)."""
    compiled(_visible_sums)(np.empty((0, 1, 3, PACKET), np.float32), np.empty((0, 1, PACKET), np.bool_),
                            np.empty((0, 1, PACKET), np.float32), 0, True, np.empty((0, 3), np.float32))
    compile_row_loops()


class DirectLighting:
    """Radiance arriving along camera rays, with direct illumination from the scene's area lights."""

    def __init__(self, scene: Scene, intersector: Intersector, light_samples: int = 1, seed: int = 0,
                 pixel_spread_radians: float = 0.0, *, backend: Backend | str = "numpy", spectral: bool = False):
        """``pixel_spread_radians``: the camera's (``Camera.pixel_spread_radians``); 0 point-samples
        image textures (bilinear on their finest level). An "opencl" ``backend`` (a
        ``renderer.backends`` object, or its name for the default device) shades RGB rays with
        ``kernels/shade.cl`` on its device (``renderer.shade_kernel``); "numpy" with the numpy code
        here, the reference. ``spectral``: whether the rays will be spectral (the kernel variant built first)."""
        if light_samples < 1:
            raise ValueError("light_samples must be at least 1")
        self.intersector, self.light_samples, self.seed = intersector, light_samples, seed
        self.pixel_spread_radians, self.spectral = pixel_spread_radians, spectral
        # also runs EWA texture lookups (``scene.ewa_kernel``) and the camera hits' footprints (``_footprint``)
        self.backend = backend_for(backend) if isinstance(backend, str) else backend
        self.background = np.asarray(scene.background, dtype=np.float32)
        self.instance_count = len(scene.instances)
        self._area_lights: list[AreaLight] = scene.area_lights
        self._light_reflects = np.array([light.material is not None for light in self._area_lights], bool)
        self._build_surfaces(scene)
        self._build_lights(scene)
        self._kernel: ShadeKernel | None = None
        self._measured_kernel: ShadeKernel | None = None  # the MEASURED variant, for hits on measured materials
        if self.backend.name == "opencl" and len(self._lights) and self._light_cdf[-1] > 0:
            self._kernel = self._build_kernel()

    def _build_surfaces(self, scene: Scene) -> None:
        """Per-mesh data concatenated once, and per-instance (geometry id) lookups into it."""
        vertex_offset = np.cumsum([0] + [len(m.vertices) for m in scene.meshes])
        face_offset = np.cumsum([0] + [len(m.faces) for m in scene.meshes])
        self._faces = np.concatenate([m.faces + o for m, o in zip(scene.meshes, vertex_offset)] or
                                     [np.zeros((0, 3), np.int64)])
        self._normals = np.concatenate([np.zeros((len(m.vertices), 3)) if m.normals is None else m.normals
                                        for m in scene.meshes] or [np.zeros((0, 3))]).astype(np.float32)
        self._vertices = np.concatenate([m.vertices for m in scene.meshes] or [np.zeros((0, 3))])
        self._uv = np.concatenate([np.zeros((len(m.vertices), 2)) if m.uv is None else m.uv
                                   for m in scene.meshes] or [np.zeros((0, 2))]).astype(np.float32)
        mesh_of = np.array([inst.mesh for inst in scene.instances], dtype=np.int64)
        self._geom_face_offset = face_offset[mesh_of] if len(mesh_of) else np.zeros(0, np.int64)
        # Smooth shading only where the vertex normals differ: a flat mesh (a floor quad, a disk) gets
        # the same normal from its faces without the per-hit interpolation.
        smooth = [m.normals is not None and bool(np.ptp(m.normals, axis=0).max() > 1e-6) for m in scene.meshes]
        self._geom_smooth = np.array([smooth[i] for i in mesh_of], dtype=bool)
        self._geom_linear = np.array([inst.transform[:3, :3] for inst in scene.instances]).reshape(-1, 3, 3)
        self._geom_normal_matrix = np.array([np.linalg.inv(inst.transform[:3, :3]).T for inst in scene.instances],
                                            dtype=np.float32).reshape(-1, 3, 3)
        self._materials: list[SurfaceMaterial] = []
        material_index: dict[int, int] = {}
        for inst in scene.instances:
            if id(inst.material) not in material_index:
                material_index[id(inst.material)] = len(self._materials)
                self._materials.append(inst.material)
        self._geom_material = np.array([material_index[id(inst.material)] for inst in scene.instances], np.int64)
        # measured materials' tables (in bfloat16, as the kernel holds them), one per file, and
        # each material's index among them (-1: matte)
        self._tables: dict[str, np.ndarray] = {}
        self._material_table = np.full(max(len(self._materials), 1), -1, np.int64)
        for index, material in enumerate(self._materials):
            data = tabulated_samples(material)
            if data is not None and isinstance(material, Measured):
                if material.path not in self._tables:
                    self._tables[material.path] = bfloat16(irregular_table(data))
                self._material_table[index] = list(self._tables).index(material.path)

    def _build_lights(self, scene: Scene) -> None:
        """The area lights' table, and each one's pick probability, proportional to its power."""
        self._lights = lights = AreaLightTable.of(scene.area_lights)
        sides = np.where(lights.two_sided, 2.0, 1.0)
        power = lights.area * sides * lights.radiance.astype(np.float64).mean(axis=1)
        self._light_probability = power / power.sum() if power.sum() > 0 else power
        self._light_cdf = np.cumsum(self._light_probability)
        self._dual_a, self._dual_b = dual_axes(lights.a, lights.b)

    def _build_kernel(self) -> ShadeKernel | None:
        """The scene's tables on the backend's OpenCL device (imports pyopencl only here); None (the
        numpy path) for more area lights than the kernel's light search reaches."""
        from realistic.renderer.opencl_backend import OpenCLBackend
        from realistic.renderer.shade_kernel import LIGHTS, MAX_LIGHTS

        backend = self.backend
        if not isinstance(backend, OpenCLBackend):
            raise TypeError(f"the shading kernel runs on an OpenCL backend, not {backend!r}")

        if len(self._lights) > MAX_LIGHTS:
            return None

        with np.errstate(divide="ignore"):
            light_scale = self._lights.area / self._light_probability / np.pi
        lights = self._lights
        rows = LIGHTS.pack(len(lights), centre=lights.centre, a=lights.a, b=lights.b, normal=lights.normal,
                           radiance=lights.radiance, scale=light_scale, disk=lights.disk, two_sided=lights.two_sided,
                           area=lights.area, dual_a=self._dual_a, dual_b=self._dual_b)
        tables = dict(faces=self._faces, normals=self._normals, uv=self._uv, geom_face_offset=self._geom_face_offset,
                      geom_material=self._geom_material, geom_smooth=self._geom_smooth,
                      geom_normal_matrix=self._geom_normal_matrix,
                      materials=[m if isinstance(m, Measured) and m.path in self._tables else _matte(m)
                                 for m in self._materials],
                      light_rows=rows, light_cdf=self._light_cdf, extent=self.intersector.extent,
                      launch_samples=self.light_samples)
        kernel = backend.shade_kernel(**tables, spectral=self.spectral)
        if self._tables:
            self._measured_kernel = backend.shade_kernel(**tables, measured_tables=self._tables)
        self._build_device_textures(backend, kernel.host_albedo)
        return kernel

    def _build_device_textures(self, backend: OpenCLBackend, host_albedo: np.ndarray) -> None:
        """Image textures filtered over pixel footprints with any filter the device has
        (``ewa_kernel.DEVICE_FILTERS``): their albedo is computed from the hit records on the device
        (``EwaKernel.at_hits``), the rest of the host's materials in numpy."""
        self._device_textures = []
        self._numpy_albedo = host_albedo.copy()  # materials left to ``_albedo``
        if self.pixel_spread_radians <= 0:
            return
        from realistic.scene.ewa_kernel import DEVICE_FILTERS, hit_mapping

        for index, material in enumerate(self._materials):
            if not isinstance(material, Material):
                continue
            texture = material.texture
            if host_albedo[index] and isinstance(texture, ImageTexture) and texture.filter in DEVICE_FILTERS:
                ewa = backend.ewa_kernel(texture.mipmap)
                self._device_textures.append((index, ewa, hit_mapping(texture, material.diffuse,
                                                                      self.pixel_spread_radians), texture.filter))
                self._numpy_albedo[index] = False
        if self._device_textures:
            self._surface_tables = backend.surface_tables(self._faces, self._vertices, self._uv,
                                                          self._geom_face_offset, self._geom_linear.reshape(-1, 9))

    def radiance(self, origin: np.ndarray, direction: np.ndarray, pixel: np.ndarray, sample: np.ndarray,
                 clock: StageClock | None = None, wavelength_nm: np.ndarray | None = None,
                 hits: Hits | None = None, albedo: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """RGB radiance (N, 3) float32 along unit-direction rays, and the number of shadow rays traced.

        With ``wavelength_nm`` (N,), the spectral radiance at each ray's wavelength times the film's
        ``rgb_response`` there.
        ``hits``: the rays' closest hits when already traced, else traced here; ``albedo``: their
        ``first_hits`` albedo (N, 3) when already computed, which the shading kernel then reads.
        """
        timed = clock or (lambda _stage: nullcontext())
        if hits is None:
            with timed("embree"):
                hits = self.intersector.closest(origin, direction, coherent=True)
        if self._kernel is not None:
            return self._radiance_kernel(self._kernel, origin, direction, pixel, sample, hits, timed, albedo,
                                         wavelength_nm)
        out, shadow_rays = self._radiance_numpy(origin, direction, pixel, sample, hits, timed, wavelength_nm)
        if wavelength_nm is not None:
            with timed("shading"):
                out *= rgb_response(wavelength_nm)
        return out, shadow_rays

    def _radiance_numpy(self, origin: np.ndarray, direction: np.ndarray, pixel: np.ndarray, sample: np.ndarray,
                        hits: Hits, timed: Callable[[str], AbstractContextManager[object]],
                        wavelength_nm: np.ndarray | None) -> tuple[np.ndarray, int]:
        """``radiance`` in numpy, the reference: spectral values in all three columns for spectral rays."""
        with timed("shading"):
            basis = None if wavelength_nm is None else rgb_basis(wavelength_nm)

            def colour(rgb: np.ndarray, rows: np.ndarray) -> np.ndarray:
                """RGB rows as they are, or as spectral values (n, 1) at the rays ``rows``' wavelengths."""
                return rgb if basis is None else spectral_value(rgb, _rows(basis, rows))[:, None]

            out = np.empty((len(origin), 3), np.float32)
            if basis is None:
                out[:] = self.background
            else:
                out[:] = spectral_value(np.broadcast_to(self.background, (len(origin), 3)), basis)[:, None]
            light_id = hits.geom - self.instance_count
            seen = np.flatnonzero(light_id >= 0)
            if len(seen):
                j = light_id[seen]
                front = (dot(_rows(direction, seen), _rows(self._lights.normal, j)) < 0) | self._lights.two_sided[j]
                out[seen] = colour(_rows(self._lights.radiance, j), seen) * front[:, None]
            surface = np.flatnonzero((hits.geom >= 0) & (light_id < 0))
            out[surface] = 0.0
            if len(surface) == 0 or len(self._lights) == 0 or self._light_cdf[-1] <= 0:
                return out, 0
            point, shadow_origin, shading, ng, rho = self._surface_points(origin, direction, hits, surface, basis)
            measured = self._measured_hits(direction, hits, surface, shading)
            if measured is not None and basis is not None:
                raise ValueError("DirectLighting shades measured materials with RGB rays only")
        total = np.zeros((len(surface), 3 if basis is None else 1), np.float32)

        def add(contribution: np.ndarray, to_light: np.ndarray, live: np.ndarray) -> int:
            """Trace the shadow rays of the rows ``live`` and add their unblocked contributions."""
            with timed("embree"):
                blocked = self.intersector.occluded(_rows(shadow_origin, live), to_light,
                                                    np.full(len(live), SHADOW_LENGTH, np.float32))
            with timed("shading"):
                total[live[~blocked]] += contribution[~blocked]
            return len(live)

        shadow_rays = 0
        for k in range(self.light_samples):
            with timed("shading"):
                light = self._light_sample(point, shadow_origin, shading, ng, rho, pixel[surface], sample[surface], k,
                                           None if basis is None else _rows(basis, surface), measured)
            shadow_rays += add(*light)
            if measured is not None:  # its BSDF sample, added after it (the kernel's row order)
                with timed("shading"):
                    paired = self._bsdf_sample(point, shadow_origin, ng, measured, pixel[surface], sample[surface], k)
                shadow_rays += add(*paired)
        with timed("shading"):
            out[surface] = total / np.float32(self.light_samples)
        return out, shadow_rays

    def first_hits(self, origin: np.ndarray, direction: np.ndarray, hits: Hits, with_albedo: bool = True
                   ) -> FirstHits:
        """What the camera rays, whose closest ``hits`` are traced, hit first (``renderer.aov``):
        points, normals facing the rays, and albedo (0 everywhere unless ``with_albedo``).
        With the shading kernel, image-textured materials' albedo is ``_host_albedo``'s, which
        ``radiance`` then takes instead of computing it again; the others' is ``first_albedo``'s.

        On an area light with a material the albedo is that material's (``_light_albedo``), as on any
        surface: pbrt-v4's ``PathIntegrator::Li`` (``src/pbrt/cpu/integrators.cpp``) adds an emitter's
        Le, then fills the ``VisibleSurface`` of the first hit with ``bsdf.rho`` of the shape's
        material, emitting or not. A pure emitter (no material) keeps albedo 0, with its point and
        normal: it reflects nothing and paths end at it. pbrt-v4 has no such surface (an area light
        on an "interface" shape is dropped, ``BasicScene::CreateLights``, and camera rays pass through
        that shape), so 0, the reflectance of a surface without a BSDF, is ours to choose."""
        n = len(origin)
        hit = hits.geom >= 0
        point, normal, rho = (np.zeros((n, 3), np.float32) for _ in range(3))
        rows = np.flatnonzero(hit)
        d = _rows(np.asarray(direction, np.float32), rows)
        point[rows] = _rows(np.asarray(origin, np.float32), rows) + hits.t[rows, None] * d
        normal[rows] = _facing(_rows(hits.normal, rows), d)
        surface = np.flatnonzero(hit & (hits.geom < self.instance_count)) if with_albedo else rows[:0]
        lit = np.flatnonzero(hits.geom >= self.instance_count) if with_albedo else rows[:0]
        lit = lit[self._light_reflects[hits.geom[lit] - self.instance_count]]
        if self._kernel is not None and self._kernel.host_albedo.any() and len(surface):
            rho[:] = self._host_albedo(origin, direction, hits)
            surface = surface[~self._kernel.host_albedo[self._geom_material[hits.geom[surface]]]]
        for at, albedo_of in ((surface, self.first_albedo), (lit, self._light_albedo)):
            if len(at):
                rho[at] = albedo_of(hits, at, _rows(np.asarray(direction, np.float32), at), _rows(normal, at))
        return FirstHits(hit, point, normal, rho)

    def first_albedo(self, hits: Hits, surface: np.ndarray, direction: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """Albedo (n, 3) of the camera-ray hits ``surface`` (rows of ``hits`` on instances): the matte
        materials' reflectance, image textures filtered over the rays' footprints as when shading."""
        face, bary = self._triangles(hits, surface)
        return self._albedo(face, bary, hits.geom[surface], direction, ng, hits.t[surface])

    def _light_albedo(self, hits: Hits, lit: np.ndarray, direction: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """Albedo (n, 3) of the camera-ray hits ``lit`` on area lights that have a material: its
        BSDF's ``directional_albedo`` in the frame of the light's outside (``light_outward_flipped``),
        its textures at the tessellation's uv, image textures filtered over the rays' footprints on
        the light's triangles (``ng``: the normals facing the rays), as ``PathIntegrator.first_albedo``
        filters them from its per-geometry tables, which hold the lights (these hold instances only)."""
        rho = np.empty((len(lit), 3), np.float32)
        slot = hits.geom[lit] - self.instance_count
        outward = normalise(_rows(hits.normal, lit).astype(np.float32))
        for j in np.unique(slot):
            rows = np.flatnonzero(slot == j)
            light, at = self._area_lights[j], lit[rows]
            material, mesh = light.material, light_mesh(light)
            assert material is not None and mesh.uv is not None  # ``first_hits`` picks lights with a material
            face, u, v = mesh.faces[hits.prim[at]], hits.u[at], hits.v[at]
            uv = interpolated(mesh.uv, face, np.column_stack([1 - u - v, u, v])).astype(np.float32)

            def at_uv(uv: np.ndarray = uv) -> np.ndarray:
                return uv

            def footprint(face: np.ndarray = face, rows: np.ndarray = rows, at: np.ndarray = at,
                          transform: np.ndarray = light.transform, vertices: np.ndarray = mesh.vertices,
                          uv_table: np.ndarray = mesh.uv) -> Footprint | None:
                if self.pixel_spread_radians <= 0:
                    return None
                return self.backend.triangle_footprint(vertices, uv_table, np.asarray(transform)[None, :3, :3], face,
                                                       np.zeros(len(face), np.int32), direction[rows], ng[rows],
                                                       hits.t[at], self.pixel_spread_radians)

            side = np.float32(-1.0 if light_outward_flipped(light) else 1.0)
            bsdf = bsdf_for(material, SurfaceParameters(len(rows), at_uv, footprint, None))
            rho[rows] = directional_albedo(bsdf, ShadingFrame(outward[rows] * side).to_local(-direction[rows]))
        return rho

    def _surface_points(self, origin: np.ndarray, direction: np.ndarray, hits: Hits, surface: np.ndarray,
                        basis: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Of the rays ``surface``, which hit instances: hit points, shadow-ray origins, shading and
        geometric normals (facing the rays), and albedos (spectral values at ``basis``'s rows, if given)."""
        o = _rows(np.asarray(origin, np.float32), surface)
        d = _rows(np.asarray(direction, np.float32), surface)
        geom = hits.geom[surface]
        point = o + hits.t[surface, None] * d
        ng = _facing(_rows(hits.normal, surface), d)
        face, bary = self._triangles(hits, surface)
        shading = self._shading_normal(face, bary, geom, ng)
        rho = self._albedo(face, bary, geom, d, ng, hits.t[surface])
        if basis is not None:
            rho = spectral_value(rho, _rows(basis, surface))[:, None]
        magnitude = np.maximum(np.maximum(np.abs(point[:, 0]), np.abs(point[:, 1])), np.abs(point[:, 2]))
        eps = SHADOW_OFFSET * (magnitude + 1e-2 * self.intersector.extent)
        shadow_origin = point + ng * eps[:, None].astype(np.float32)
        return point, shadow_origin, shading, ng, rho

    def _radiance_kernel(self, kernel: ShadeKernel, origin: np.ndarray, direction: np.ndarray, pixel: np.ndarray,
                         sample: np.ndarray, hits: Hits, timed: Callable[[str], AbstractContextManager[object]],
                         albedo: np.ndarray | None = None, wavelength_nm: np.ndarray | None = None
                         ) -> tuple[np.ndarray, int]:
        """``radiance`` through ``kernels/shade.cl`` (``_radiance_launches``): the rays that hit a
        measured material through the measured kernel, the others through ``kernel``, which does no
        table lookups and writes no BSDF rows (every lane of a launch does a lane's whole work)."""
        if self._measured_kernel is None:
            return self._radiance_launches(kernel, origin, direction, pixel, sample, hits, timed, albedo, wavelength_nm)
        if wavelength_nm is not None:
            raise ValueError("DirectLighting shades measured materials with RGB rays only")
        with timed("shading"):
            on_instance = (hits.geom >= 0) & (hits.geom < self.instance_count)
            geom = np.where(on_instance, hits.geom, 0)
            measured = on_instance & (self._material_table[self._geom_material[geom]] >= 0)
            out = np.empty((len(origin), 3), np.float32)
        shadow_rays = 0
        for launched, rows in ((kernel, np.flatnonzero(~measured)), (self._measured_kernel, np.flatnonzero(measured))):
            if len(rows) == 0:
                continue
            with timed("shading"):
                part = Hits(*(_rows(a, rows) for a in (hits.t, hits.u, hits.v, hits.prim, hits.geom, hits.normal)))
            out[rows], traced = self._radiance_launches(launched, _rows(origin, rows), _rows(direction, rows),
                                                        pixel[rows], sample[rows], part, timed,
                                                        None if albedo is None else _rows(albedo, rows))
            shadow_rays += traced
        return out, shadow_rays

    def _radiance_launches(self, kernel: ShadeKernel, origin: np.ndarray, direction: np.ndarray, pixel: np.ndarray,
                           sample: np.ndarray, hits: Hits, timed: Callable[[str], AbstractContextManager[object]],
                           albedo: np.ndarray | None = None, wavelength_nm: np.ndarray | None = None
                           ) -> tuple[np.ndarray, int]:
        """The rays' radiance through one shading kernel: the kernel shades every surface hit and writes
        all light samples' shadow rays, embree traces them in one call, ``_visible_sums`` sums. ``albedo``: the
        rays' albedo from ``first_hits`` (its host rows are ``_host_albedo``'s); ``wavelength_nm``:
        spectral rays' wavelengths (None for RGB rays)."""
        from realistic.device.opencl import whole_groups
        from realistic.renderer.shade_kernel import MAX_LAUNCH_SAMPLES, MAX_SHADOW_ROWS

        n = len(origin)
        if n == 0:
            return np.zeros((0, 3), np.float32), 0
        with timed("shading"):
            if not kernel.host_albedo.any():
                albedo = None  # the kernel holds every material's albedo
            elif albedo is None:
                albedo = self._host_albedo(origin, direction, hits)
            channels = 3 if wavelength_nm is None else 1  # a spectral ray's sum is one spectral value
            out = np.empty((n, channels), np.float32)  # the first launch's sums write every row
            # light samples per launch (``rows_per_sample`` shadow rays each: a measured scene's BSDF samples)
            rows_per_sample = kernel.rows_per_sample
            group = max(1, min(MAX_LAUNCH_SAMPLES, MAX_SHADOW_ROWS // (whole_groups(n) * rows_per_sample)))
            shadow_rays = 0
            response: np.ndarray | None = None  # spectral rays' film weights and basis rows, which every
            basis: np.ndarray | None = None  # launch writes
        for first in range(0, self.light_samples, group):
            count = min(group, self.light_samples - first)
            with timed("shading"):
                batch = kernel.shade(origin, direction, hits.t, hits.u, hits.v, hits.prim, hits.geom,
                                           hits.normal, pixel, sample, albedo, count, self.seed, first,
                                           self.light_samples, wavelength_nm)
                response, basis = batch.response, batch.basis
            with timed("embree"):
                blocked = self.intersector.occluded_lanes(batch.origin, batch.vector, batch.length)
            with timed("shading"):
                shadow_rays += visible_sums(batch.contribution, blocked, batch.length, n, first == 0, out)
        with timed("shading"):
            if self.light_samples > 1:
                out /= np.float32(self.light_samples)
            if response is not None:  # the film's weight, after the sum, as the numpy path applies it
                out = out * response[:n]
            if self.background.any():  # misses are already zero: a black background needs no pass over them
                missed = np.flatnonzero(hits.geom < 0)  # twice as fast as a boolean-mask store
                out[missed] = self._seen(np.broadcast_to(self.background, (len(missed), 3)), missed, response, basis)
            seen = np.flatnonzero(hits.geom >= self.instance_count)
            if len(seen):
                j = hits.geom[seen] - self.instance_count
                front = (dot(_rows(direction, seen), _rows(self._lights.normal, j)) < 0) | self._lights.two_sided[j]
                out[seen] = self._seen(_rows(self._lights.radiance, j), seen, response, basis) * front[:, None]
        return out, shadow_rays

    @staticmethod
    def _seen(rgb: np.ndarray, rows: np.ndarray, response: np.ndarray | None, basis: np.ndarray | None
              ) -> np.ndarray:
        """Radiance ``rgb`` (n, 3) seen directly by the camera rays ``rows``: as it is (RGB rays), or
        for spectral rays its spectral value at each ray's wavelength (``basis``: every ray's
        ``rgb_basis`` row) times the ray's film weight (``response``), as ``radiance`` makes it on the
        numpy path. The kernel's ``basis`` and ``response`` are (stride, 3) views of three rows
        (``ShadeKernel.shade``), gathered along those rows: a row gather across them cost three times
        as much."""
        if response is None or basis is None:
            return rgb
        return (spectral_value(rgb, np.take(basis.T, rows, axis=1).T)[:, None]
                * np.take(response.T, rows, axis=1).T)

    def _host_albedo(self, origin: np.ndarray, direction: np.ndarray, hits: Hits) -> np.ndarray:
        """Albedo (N, 3) of the surface hits whose material the shading kernel leaves to the host
        (image textures): those the device filters on the device (``_build_device_textures``),
        the others by ``_albedo``; other rows are zero, unread by the kernel."""
        albedo = np.zeros((len(origin), 3), np.float32)
        if self._device_textures:
            picks = np.empty(len(origin), np.int32)
        for index, ewa, mapping, texture_filter in self._device_textures:
            picked = picks[:rows_on_material(hits.geom, self._geom_material, index, picks)]
            place_rows(ewa.at_hits(self._surface_tables, picked, mapping, direction, hits, texture_filter),
                       picked, albedo)
        if not self._numpy_albedo.any():
            return albedo
        surface = (hits.geom >= 0) & (hits.geom < self.instance_count)
        geom_all = np.where(surface, hits.geom, 0)
        rows = np.flatnonzero(surface & self._numpy_albedo[self._geom_material[geom_all]])
        if len(rows):
            d = _rows(np.asarray(direction, np.float32), rows)
            face, bary = self._triangles(hits, rows)
            albedo[rows] = self._albedo(face, bary, hits.geom[rows], d, _facing(_rows(hits.normal, rows), d),
                                        hits.t[rows])
        return albedo

    def _triangles(self, hits: Hits, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The hit triangles' vertex indices (n, 3) and barycentrics (n, 3) of the hits ``rows``."""
        u, v = hits.u[rows], hits.v[rows]
        face = _rows(self._faces, self._geom_face_offset[hits.geom[rows]] + hits.prim[rows])
        return face, np.column_stack([1.0 - u - v, u, v])

    def _shading_normal(self, face: np.ndarray, bary: np.ndarray, geom: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """Shading normals (N, 3): the interpolated vertex normals turned to ``ng``'s side, else ``ng``."""
        shading = ng.copy()
        rows, n = self._vertex_normals(face, bary, geom)
        n[dot(n, ng[rows]) < 0] *= -1
        shading[rows] = n
        return shading

    def _vertex_normals(self, face: np.ndarray, bary: np.ndarray, geom: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows on smooth meshes with a usable interpolated normal, and those unit world normals
        as the mesh orients them."""
        smooth = np.flatnonzero(self._geom_smooth[geom])
        n = interpolated(self._normals, face[smooth], bary[smooth])
        n = normalise(np.einsum("nij,nj->ni", self._geom_normal_matrix[geom[smooth]], n))
        good = dot(n, n) > 0.5
        return smooth[good], n[good]

    def _albedo(self, face: np.ndarray, bary: np.ndarray, geom: np.ndarray, direction: np.ndarray,
                normal: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """Albedo (N, 3) of camera-ray hits; image textures filtered over the rays' footprints."""
        rho = np.empty((len(face), 3), np.float32)
        material_of = self._geom_material[geom]
        for index, surface_material in enumerate(self._materials):
            rows = np.flatnonzero(material_of == index)
            if len(rows) == 0:
                continue
            if isinstance(surface_material, Measured):
                rho[rows] = self._measured_albedo(surface_material.path, direction[rows], normal[rows])
                continue
            material = _matte(surface_material)
            uv = None
            if material.texture is not None:
                uv = interpolated(self._uv, face[rows], bary[rows])
            footprint = None
            if isinstance(material.texture, ImageTexture) and self.pixel_spread_radians > 0:
                footprint = self._footprint(face[rows], geom[rows], direction[rows], normal[rows], distance[rows])
            # over a footprint on the backend's device; point-sampled (level 0) in numpy, which builds no ewa.cl
            lookup = numpy_lookup if footprint is None else self.backend.image_lookup
            rho[rows] = albedo(material, uv, len(rows), footprint, lookup)
        return rho

    def _measured_albedo(self, path: str, direction: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """A measured material's directional albedo (n, 3) seen along ``direction`` at normals
        ``normal``: the mean of f pi over ``_RHO_DIRECTIONS`` (cosine-weighted, so f cos / pdf = f pi)."""
        table = self._tables[path]
        wo = ShadingFrame(normal).to_local(-np.asarray(direction, np.float32))
        total = np.zeros((len(wo), 3), np.float64)
        for wi in _RHO_DIRECTIONS:
            total += table_lookup(table, wo, np.broadcast_to(wi, wo.shape))
        return (total * (np.pi / len(_RHO_DIRECTIONS))).astype(np.float32)

    def _footprint(self, face: np.ndarray, geom: np.ndarray, direction: np.ndarray, normal: np.ndarray,
                   distance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """uv axes of the pixel footprints of hits on triangles ``face`` of instances ``geom``, by the
        backend (``footprint.triangle_footprint`` in numpy, ``kernels/ewa.cl`` on "opencl")."""
        return self.backend.triangle_footprint(self._vertices, self._uv, self._geom_linear, face, geom,
                                               direction, normal, distance, self.pixel_spread_radians)

    def _pick(self, pixel: np.ndarray, sample: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Light sample ``k``'s light (picked by power) and its point numbers u1, u2 per point."""
        u_pick, u1, u2 = rng.light_uniforms(pixel, sample, k, self.light_samples, self.seed,
                                            pick=len(self._light_cdf) > 1)
        j = np.minimum(np.searchsorted(self._light_cdf, u_pick, side="right"), len(self._light_cdf) - 1)
        return j, u1, u2

    def _light_scale(self, j: np.ndarray) -> np.ndarray:
        """The kernel's float32 ``LIGHT_SCALE`` (area / probability / pi) of lights ``j``."""
        with np.errstate(divide="ignore"):
            return (self._lights.area[j] / self._light_probability[j] / np.pi).astype(np.float32)

    def _measured_hits(self, direction: np.ndarray, hits: Hits, surface: np.ndarray, shading: np.ndarray
                       ) -> _MeasuredHits | None:
        """The surface hits' measured materials (``_MeasuredHits``), or None where none is measured."""
        table = self._material_table[self._geom_material[hits.geom[surface]]]
        if not np.any(table >= 0):
            return None
        wo = -_rows(np.asarray(direction, np.float32), surface)
        return _MeasuredHits(table, list(self._tables.values()), shading, wo, dot(wo, shading),
                             np.cross(shading, wo).astype(np.float32))

    def _light_sample(self, point: np.ndarray, shadow_origin: np.ndarray, shading: np.ndarray, ng: np.ndarray,
                      rho: np.ndarray, pixel: np.ndarray, sample: np.ndarray, k: int, basis: np.ndarray | None,
                      measured: _MeasuredHits | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One light sample per point: (contribution of the unoccluded ones, shadow ray vector, their rows).

        ``basis`` (rows of ``rgb_basis`` per point) makes the light's radiance spectral, as ``rho`` is then.
        At ``measured`` hits, f(wo, wi) pi takes rho's place, times the power heuristic's weight
        against the BSDF sample (``_bsdf_sample``), as ``kernels/shade.cl`` computes it.
        """
        j, u1, u2 = self._pick(pixel, sample, k)
        q = self._lights.points(j, u1, u2)
        to_light = q - point
        dist2 = dot(to_light, to_light)
        wi = to_light / np.sqrt(dist2)[:, None]
        cos_p = dot(wi, shading)
        cos_q = -dot(wi, _rows(self._lights.normal, j))
        cos_q = np.where(self._lights.two_sided[j], np.abs(cos_q), cos_q)
        live = np.flatnonzero((cos_p > 0) & (cos_q > 0) & (dot(wi, ng) > 0) & (dist2 > 0))
        jl = j[live]
        scale = (cos_p[live] * cos_q[live] / dist2[live]
                 * (self._lights.area[jl] / self._light_probability[jl] / np.pi)).astype(np.float32)
        emitted = _rows(self._lights.radiance, jl)
        if basis is not None:
            emitted = spectral_value(emitted, _rows(basis, live))[:, None]
        reflectance = _rows(rho, live)
        if measured is not None:
            at = np.flatnonzero(measured.table[live] >= 0)
            rows = live[at]
            area = self._lights.area[j[rows]].astype(np.float32)
            ratio = cos_p[rows] * cos_q[rows] * area / (np.float32(np.pi) * dist2[rows])
            weight = np.float32(np.pi) / (np.float32(1) + ratio * ratio)
            reflectance[at] = measured.lookup(rows, wi[rows], cos_p[rows]) * weight[:, None]
        contribution = reflectance * emitted * scale[:, None]
        return contribution, _rows(q, live) - _rows(shadow_origin, live), live

    def _bsdf_sample(self, point: np.ndarray, shadow_origin: np.ndarray, ng: np.ndarray, measured: _MeasuredHits,
                     pixel: np.ndarray, sample: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The BSDF sample paired with light sample ``k`` at the ``measured`` hits (pbrt-v2
        ``EstimateDirect``'s second half, ``src/core/integrator.cpp``): a cosine-weighted direction
        (``rng.light_bsdf_uniforms``; n plus a uniform point on the unit sphere, normalised) that
        counts where it meets the light sample's light from its
        emitting side, weighted by the power heuristic against that light's density, over the
        light's pick probability. Returns as ``_light_sample``: contributions, shadow-ray vectors
        (to the point met), their rows."""
        j, _, _ = self._pick(pixel, sample, k)
        v1, v2 = rng.light_bsdf_uniforms(pixel, sample, k, self.light_samples, self.seed)
        x, y = (c.astype(np.float32) for c in concentric_disk(v1, v2))
        # n plus a uniform point on the sphere (the disk mapped by area), normalised: cosine-weighted about n
        r2 = np.maximum(np.abs(2 * v1 - 1), np.abs(2 * v2 - 1)) ** 2
        lift = 2 * np.sqrt(np.maximum(1 - r2, 0))
        wi = normalise(measured.normal + np.column_stack([x * lift, y * lift, 1 - 2 * r2]))
        cos_i = dot(wi, measured.normal)
        normal, centre = _rows(self._lights.normal, j), _rows(self._lights.centre, j)
        denom = dot(wi, normal)
        with np.errstate(divide="ignore", invalid="ignore"):
            th = dot(centre - point, normal) / denom
            hit = point + th[:, None] * wi
            r = hit - centre
            lu, lv = dot(r, _rows(self._dual_a, j)), dot(r, _rows(self._dual_b, j))
        inside = np.where(self._lights.disk[j], lu * lu <= 1 - lv * lv, (np.abs(lu) <= 1) & (np.abs(lv) <= 1))
        cos_h = np.where(self._lights.two_sided[j], np.abs(denom), -denom)
        live = np.flatnonzero((measured.table >= 0) & (cos_i > 0) & (dot(wi, ng) > 0) & (th > 0) & inside
                              & (cos_h > 0))
        jl = j[live]
        f = measured.lookup(live, wi[live], cos_i[live])
        area = self._lights.area[jl].astype(np.float32)
        pi = np.float32(np.pi)
        ratio = th[live] * th[live] * pi / (cos_h[live] * area * cos_i[live])
        scale = pi / (np.float32(1) + ratio * ratio) * (self._light_scale(jl) * pi / area)
        contribution = f * _rows(self._lights.radiance, jl) * scale[:, None]
        return contribution, _rows(hit, live) - _rows(shadow_origin, live), live
