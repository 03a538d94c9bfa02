"""Path tracing and MIS direct lighting over any lights and BSDFs, wavefront style.

Each bounce is one batch: every live path's ray goes through embree together, then numpy shades the
hits grouped by material (``realistic.renderer.bsdf.bsdf_for``). At each surface vertex:

- next-event estimation: ``light_samples`` light samples at the first vertex, one beyond
  (``LightSampler``), each weighted by the power heuristic against the BSDF's density (Veach 1997;
  pbrt's ``EstimateDirect``): w_l = (n p_l)^2 / ((n p_l)^2 + p_f^2), deltas weight 1;
- one BSDF sample continues the path; when it reaches an emitter (area light, emitting instance or,
  on a miss, the infinite lights) that emission is weighted w_f = p_f^2 / ((n p_l)^2 + p_f^2), or 1
  after a specular bounce or for camera rays. An area light with a material (``AreaLight.material``:
  pbrt's shape keeps the material in effect) is also a surface: the path adds its emission and goes
  on from it with that material's BSDF, as pbrt's does; one without ends the path.

``mode`` "path": every BSDF sample continues, up to ``max_depth`` bounces, with Russian roulette
after the third (pbrt-v3 ``PathIntegrator``: q = max(0.05, 1 - max throughput)). "direct" (pbrt's
``directlighting``): the first hit is always lit; non-specular BSDF samples only collect the
emission they reach, specular ones continue while depth + 1 < ``max_depth`` (pbrt-v3
``DirectLightingIntegrator``). ``mis`` False keeps light sampling alone (BSDF-sampled emission only
after specular bounces), for tests.

Backends: on "opencl", RGB rays at hits whose material ``kernels/bsdf.cl`` covers (constant
parameters, the diffuse-like colour of Lambertian, Oren-Nayar, plastic, coated diffuse and substrate
under a grid or checker texture, or under an image texture, which ``EwaKernel.at_hits`` filters
on the device before the launch; any other textured parameter, such as roughness, Ks or a mix's
amount or second material, looked up per hit with ``_hit_parameters``, its image textures filtered on
the device too by the backend's ``image_lookup``; a mix holding a mix, its whole tree looked up per hit
likewise, or once where nothing in it is textured, for RGB rays) take the whole bounce in one launch of
``kernels/bounce.cl`` (``renderer.bounce_kernel``: surface point, normals, light samples, MIS weights,
shadow rays, BSDF sample, beta, roulette), with the same random numbers; so do spectral rays (a
dispersive camera's) at the same hits, in the kernel's spectral build. The host keeps embree,
emission and the compaction of live paths. Other hits (a mix tree of more than
``bsdf_kernel.MAX_LOBES`` lobes) have the numpy bounce (``_shade``), with their BSDFs evaluated and
sampled in ``kernels/bsdf.cl`` where it covers the material (the backend's ``bsdf_kernel``:
its ``rows`` say which), in one launch per bounce with the same random numbers; every other
material and the "numpy" backend use the numpy BSDFs of ``bsdf_factory``, the reference.

Random numbers: the first vertex's light sample k uses ``rng.light_uniforms`` (the pixel's
stratified light samples) as ``DirectLighting`` does; bounce b's BSDF sample, lobe choice,
roulette and its light sample use ``BOUNCE_DIMENSION + 8 b + (0 .. 6)``, so results do not depend
on pass size.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import nullcontext
from typing import TYPE_CHECKING

import numpy as np

from realistic.core import rng
from realistic.core.spectrum import rgb_basis, rgb_response
from realistic.core.validation import MAX_LIGHT_SAMPLES
from realistic.core.vectors import dot, normalise
from realistic.renderer.area_lights import light_outward_flipped
from realistic.renderer.backends import Backend, backend_for
from realistic.renderer.bsdf import BSDF, BSDFSample, HitParameters, ShadingFrame, bsdf_for
from realistic.renderer.direct_lighting import SHADOW_OFFSET, DirectLighting, _rows, interpolated
from realistic.renderer.light_sampler import FAR, SHADOW_LENGTH, LightSampler
from realistic.renderer.surface_parameters import SurfaceParameters, directional_albedo
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Hits, Intersector
from realistic.scene.lights import EmissiveInstance
from realistic.scene.materials import SurfaceMaterial
from realistic.scene.model import Scene
from realistic.scene.shapes import light_mesh
from realistic.scene.textures import Footprint

if TYPE_CHECKING:  # pyopencl is imported only when the "opencl" backend is chosen
    from realistic.renderer.bounce_kernel import BounceKernel

BOUNCE_DIMENSION = 4 + 3 * MAX_LIGHT_SAMPLES
MODES = ("direct", "path")
#: Bounces after which Russian roulette may end a path (pbrt-v3 ``PathIntegrator``: bounces > 3).
ROULETTE_AFTER = 3
def _add_rows(out: np.ndarray, rows: np.ndarray, value: np.ndarray) -> None:
    """out[rows] += value for distinct ``rows`` of a C-contiguous (N, C) ``out``: the rows gathered
    with ``np.take`` and put back as single items (``np.put`` on a void view of the rows), the same
    sums several times faster than fancy indexing of a 2-D array."""
    item = np.dtype((np.void, out.dtype.itemsize * out.shape[1]))
    total = np.take(out, rows, axis=0)
    total += value
    np.put(out.view(item).reshape(len(out)), rows, total.view(item).reshape(len(rows)))


def power_heuristic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a^2 / (a^2 + b^2), 0 where both are 0."""
    a2, b2 = np.square(a, dtype=np.float64), np.square(b, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a2 + b2 > 0, a2 / (a2 + b2), 0.0)


class PathIntegrator(DirectLighting):
    """Radiance along camera rays by path tracing (``mode`` "path") or MIS direct lighting ("direct")."""

    def __init__(self, scene: Scene, intersector: Intersector, light_samples: int = 1, seed: int = 0,
                 pixel_spread_radians: float = 0.0, max_depth: int = 5, mode: str = "path", mis: bool = True,
                 bsdf_factory: Callable[[SurfaceMaterial, HitParameters], BSDF] = bsdf_for, *,
                 backend: Backend | str = "numpy"):
        """An "opencl" ``backend`` evaluates and samples the BSDFs it covers in ``kernels/bsdf.cl``
        (with ``bsdf_for``, whose materials it mirrors); the rest of the integrator is numpy."""
        chosen = backend_for(backend) if isinstance(backend, str) else backend
        # the camera hits' footprints (``_footprint``) and the image textures of ``SurfaceParameters``
        # (``_shade``, the per-hit rows, albedo) on the backend, the ``DirectLighting`` part's
        super().__init__(scene, intersector, light_samples, seed, pixel_spread_radians, backend=chosen)
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}")
        if max_depth < 0:
            raise ValueError("max_depth must be at least 0")
        self.max_depth, self.mode, self.mis, self.bsdf_factory = max_depth, mode, mis, bsdf_factory
        self._bsdf_kernel = chosen.bsdf_kernel() if bsdf_factory is bsdf_for else None
        self.lights = LightSampler(scene, intersector.extent)
        self._add_light_surfaces(scene)
        self._bounce = self._build_bounce(chosen) if self._bsdf_kernel is not None else None
        #: per geometry, whether the fused bounce shades its material (RGB and spectral rays alike)
        self._bounce_covers = None if self._bounce is None else self._bounce.covered[self._geom_material]
        self._instance_light = np.full(max(self.instance_count, 1), -1, np.int64)
        for i, light in enumerate(scene.lights):
            if isinstance(light, EmissiveInstance):
                self._instance_light[light.instance] = i

    def _add_light_surfaces(self, scene: Scene) -> None:
        """Extend the per-geometry tables past the instances by the area lights' tessellations
        (geometry ``instance_count + j``, as ``scene.intersect`` builds them), so that a path reflects
        off an area light that has a material, as pbrt's paths do: pbrt gives the shape the material
        in effect (pbrt-v3 ``pbrtShape``, pbrt-v4 ``BasicScene::CreateAggregate``) and its path
        integrator adds the emission at the hit and goes on with that material's BSDF (pbrt-v3
        ``PathIntegrator::Li``, pbrt-v4 ``PathIntegrator::Li``). ``_shaded[g]``: whether hits on
        geometry g are shaded (every instance; the lights with a material), with a False last entry
        for misses (geometry -1). ``_geom_swaps[g]``: whether geometry g's outside is opposite its
        world winding (``_outward_normals``): an instance's under a mirroring transform (the pbrt
        importer winds ReverseOrientation into the mesh) unless it emits, a light's by
        ``light_outward_flipped``, so that a light's glass has the inside and outside the same shape
        has without the light. An emitting instance's outside is its front, the side it emits from
        (``EmissiveInstance``), as a pbrt shape's normal is both (``DiffuseAreaLight::L``, pbrt-v3
        ``src/lights/diffuse.h``, pbrt-v4 ``src/pbrt/lights.h``, emits on its side, and the BSDF's
        frame is built on it): the importer's ``_face_front`` winds that front to the shape's normal."""
        lights = scene.area_lights
        reflecting = np.array([light.material is not None for light in lights], bool)
        self._shaded = np.concatenate([np.ones(self.instance_count, bool), reflecting, [False]])
        self._geom_swaps = np.linalg.det(self._geom_linear) < 0 if len(self._geom_linear) else np.zeros(0, bool)
        self._geom_swaps[[light.instance for light in scene.lights if isinstance(light, EmissiveInstance)]] = False
        if not reflecting.any():
            return
        material_index = {id(material): index for index, material in enumerate(self._materials)}
        faces, normals, uv, vertices, offsets, linear, material_of = [], [], [], [], [], [], []
        vertex_count, face_count = len(self._vertices), len(self._faces)
        for light in lights:
            mesh = light_mesh(light)
            if light.material is not None and id(light.material) not in material_index:
                material_index[id(light.material)] = len(self._materials)
                self._materials.append(light.material)
            faces.append(mesh.faces + vertex_count)
            vertices.append(mesh.vertices)
            normals.append(np.zeros((len(mesh.vertices), 3)))  # flat: never interpolated
            uv.append(np.zeros((len(mesh.vertices), 2)) if mesh.uv is None else mesh.uv)
            offsets.append(face_count)
            linear.append(np.asarray(light.transform, np.float64)[:3, :3])
            material_of.append(-1 if light.material is None else material_index[id(light.material)])
            vertex_count, face_count = vertex_count + len(mesh.vertices), face_count + len(mesh.faces)
        self._faces = np.concatenate([self._faces, *faces]).astype(self._faces.dtype)
        self._vertices = np.concatenate([self._vertices, *vertices])
        self._normals = np.concatenate([self._normals, *normals]).astype(np.float32)
        self._uv = np.concatenate([self._uv, *uv]).astype(np.float32)
        self._geom_face_offset = np.concatenate([self._geom_face_offset, offsets]).astype(np.int64)
        self._geom_smooth = np.concatenate([self._geom_smooth, np.zeros(len(lights), bool)])
        self._geom_linear = np.concatenate([self._geom_linear, np.array(linear).reshape(-1, 3, 3)])
        self._geom_normal_matrix = np.concatenate(
            [self._geom_normal_matrix, np.linalg.inv(np.array(linear).reshape(-1, 3, 3)).transpose(0, 2, 1)]
        ).astype(np.float32)
        self._geom_material = np.concatenate([self._geom_material, material_of]).astype(np.int64)
        self._geom_swaps = np.concatenate([self._geom_swaps, [light_outward_flipped(light) for light in lights]])

    def radiance(self, origin: np.ndarray, direction: np.ndarray, pixel: np.ndarray, sample: np.ndarray,
                 clock: StageClock | None = None, wavelength_nm: np.ndarray | None = None,
                 hits: Hits | None = None, albedo: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """RGB radiance (N, 3) float32 (with ``wavelength_nm``, spectral values times ``rgb_response``) and the
        number of shadow rays traced; ``hits``: the camera rays' closest hits when already traced
        (``albedo``, the shading kernel's input in ``DirectLighting``, has no use here: BSDFs are
        evaluated at every hit)."""
        camera_hits = hits
        timed = clock or (lambda _stage: nullcontext())
        n = len(origin)
        basis_all = None if wavelength_nm is None else rgb_basis(wavelength_nm)
        channels = 3 if basis_all is None else 1
        out = np.zeros((n, channels), np.float32)
        beta = np.ones((n, channels), np.float32)
        path = np.arange(n, dtype=np.int32)  # int32: the bounce kernel's rows, read without a copy
        o = np.ascontiguousarray(origin, np.float32)
        d = np.ascontiguousarray(direction, np.float32)
        specular = np.ones(n, bool)
        shade = np.ones(n, bool)
        prev_pdf = np.zeros(n)
        prev_point = o.astype(np.float64)
        shadow_rays = 0
        if self._bounce is not None:  # the fused bounce's random-number keys
            pixel_key, sample_key = pixel.astype(np.uint32), np.broadcast_to(sample, (n,)).astype(np.uint32)
        # "direct" shades the first hit whatever max_depth is (its MIS rays are traced one step more)
        last = max(self.max_depth, 1) if self.mode == "direct" else self.max_depth
        for depth in range(last + 1):
            if len(path) == 0:
                break
            if depth == 0 and camera_hits is not None:
                hits = camera_hits
            else:
                with timed("embree"):
                    hits = self.intersector.closest(o, d, coherent=depth == 0)  # camera rays at 0
            with timed("shading"):
                basis = None if basis_all is None else basis_all[path]
                prev_lights = self.light_samples if depth == 1 else 1
                self._emission(hits, path, o, d, beta, basis, specular, prev_pdf, prev_point, prev_lights,
                               depth, out)
                surface = np.flatnonzero(self._shaded[hits.geom] & shade)
                if depth == last or len(surface) == 0:
                    break
                if self._bounce is not None:
                    state = self._shade_on_device(hits, surface, path, o, d, beta, basis, basis_all, pixel, sample,
                                                  pixel_key, sample_key, depth)
                else:
                    state = self._shade(hits, surface, path, o, d, beta, basis, pixel, sample, depth)
            shadow = state["shadow"]
            if shadow["rows"] is not None and len(shadow["rows"]):
                with timed("embree"):  # every light sample's shadow ray of this bounce in one batch
                    blocked = self.intersector.occluded(shadow["start"], shadow["vector"], shadow["length"])
                with timed("shading"):
                    free = ~blocked
                    rows, value = shadow["rows"][free], np.compress(free, shadow["contribution"], axis=0)
                    if depth > 0 or self.light_samples == 1:  # one light sample per ray: rows are distinct
                        _add_rows(out, rows, value)
                    else:
                        for c in range(channels):  # rows repeat with several light samples per hit
                            out[:, c] += np.bincount(rows, value[:, c], minlength=n).astype(np.float32)
                    # the fused bounce's dead light samples have length -1 (embree skips them)
                    shadow_rays += int(np.count_nonzero(shadow["length"] > 0))
            path, o, d, beta = state["path"], state["origin"], state["direction"], state["beta"]
            specular, shade, prev_pdf, prev_point = state["specular"], state["shade"], state["pdf"], state["point"]
        result = np.empty((n, 3), np.float32)
        result[:] = out
        if wavelength_nm is not None:  # the film's weight at each ray's wavelength, as DirectLighting's
            result *= rgb_response(wavelength_nm)
        return result, shadow_rays

    def _build_kernel(self) -> None:
        """No shading kernel (``DirectLighting``'s, ``kernels/shade.cl``): paths are shaded by the
        bounce (``_build_bounce``) and ``_shade``, with the BSDFs of every material, where the
        shading kernel takes matte and measured ones alone."""
        return None

    def _build_bounce(self, backend: Backend) -> BounceKernel | None:
        """The fused bounce kernel on ``backend``'s device (imports pyopencl only here); None on the
        "numpy" backend."""
        if backend.name != "opencl":
            return None
        from realistic.renderer import bounce_kernel
        from realistic.renderer.opencl_backend import OpenCLBackend

        if not isinstance(backend, OpenCLBackend):
            raise TypeError(f"the bounce kernel runs on an OpenCL backend, not {backend!r}")
        self._bounce_flags = (bounce_kernel.MIS if self.mis else 0) | (
            bounce_kernel.DIRECT | (bounce_kernel.EMISSION_AFTER_DIFFUSE if self.mis and self.lights.hittable else 0)
            if self.mode == "direct" else 0)
        return backend.bounce_kernel(faces=self._faces, normals=self._normals, uv=self._uv,
                                     geom_face_offset=self._geom_face_offset, geom_material=self._geom_material,
                                     geom_smooth=self._geom_smooth, geom_swaps=self._geom_swaps,
                                     geom_normal_matrix=self._geom_normal_matrix, materials=self._materials,
                                     lights=self.lights, extent=self.intersector.extent,
                                     dimension=BOUNCE_DIMENSION, roulette_after=ROULETTE_AFTER,
                                     vertices=self._vertices, geom_linear=self._geom_linear,
                                     pixel_spread_radians=self.pixel_spread_radians, ewa_kernel=backend.ewa_kernel)

    def _shade_on_device(self, hits: Hits, surface: np.ndarray, path: np.ndarray, o: np.ndarray, d: np.ndarray,
                         beta: np.ndarray, basis: np.ndarray | None, basis_all: np.ndarray | None, pixel: np.ndarray,
                         sample: np.ndarray, pixel_key: np.ndarray, sample_key: np.ndarray, depth: int) -> dict:
        """``_shade`` by the fused bounce kernel (``renderer.bounce_kernel``) at the hits whose
        material it covers (RGB or spectral rays: ``basis`` the batch's ``rgb_basis`` rows,
        ``basis_all`` the camera rays'), and by ``_shade`` at the others; ``pixel_key`` and
        ``sample_key``: ``pixel`` and ``sample`` as uint32, the kernel's random-number keys. The
        shadow rays include the kernel's dead light samples (length -1, contribution 0)."""
        assert self._bounce is not None and self._bounce_covers is not None
        covered = self._bounce_covers[hits.geom[surface]]
        if not covered.any():  # nothing for the kernel
            return self._shade(hits, surface, path, o, d, beta, basis, pixel, sample, depth)
        rows = (surface if covered.all() else surface[covered]).astype(np.int32)  # the kernel's, converted once
        result = self._bounce(rows, path, pixel_key, sample_key, o, d, hits, beta, depth=depth,
                              light_samples=self.light_samples if depth == 0 else 1, seed=self.seed,
                              mode_flags=self._bounce_flags, max_depth=self.max_depth, basis=basis_all,
                              hit_parameters=self._hit_parameters(hits, rows, d, basis, depth))
        ray = path[rows]
        keep, specular, shade = result.going_on()
        state = {"path": ray[keep], "origin": _rows(result.origin, keep), "direction": _rows(result.direction, keep),
                 "beta": _rows(result.beta, keep), "specular": specular, "shade": shade,
                 "pdf": result.pdf[keep], "point": _rows(result.point, keep),  # float32: read in float64 as gathered
                 "shadow": {"start": result.shadow_origin, "vector": result.shadow_vector,
                            "length": result.shadow_length,
                            "rows": ray if len(result.shadow_length) == len(rows) else  # one light sample each
                            np.tile(ray, len(result.shadow_length) // max(len(rows), 1)),
                            "contribution": result.contribution}}
        if len(rows) == len(surface):
            return state
        rest = self._shade(hits, surface[~covered], path, o, d, beta, basis, pixel, sample, depth)
        joined: dict = {key: np.concatenate([state[key], rest[key]]) for key in state if key != "shadow"}
        joined["shadow"] = {key: value if rest["shadow"][key] is None else np.concatenate([value, rest["shadow"][key]])
                            for key, value in state["shadow"].items()}
        return joined

    def _parameters_at(self, face: np.ndarray, bary: np.ndarray, depth: int, footprint: Callable[[], Footprint],
                       basis: np.ndarray | None) -> SurfaceParameters:
        """The ``HitParameters`` of hits at ``depth`` on triangles ``face`` at barycentrics ``bary``
        (``basis``: spectral rays' ``rgb_basis`` rows): textures at their uv, image textures filtered
        over ``footprint()`` for camera rays with a pixel spread, deeper bounces having none here
        (level 0), with the backend's ``image_lookup`` (on the device for "opencl"). ``_shade`` and the fused
        bounce's per-hit rows (``_hit_parameters``) both look up with it."""
        def uv() -> np.ndarray:
            return interpolated(self._uv, face, bary)

        def camera_footprint() -> Footprint | None:
            return footprint() if depth == 0 and self.pixel_spread_radians > 0 else None

        return SurfaceParameters(len(face), uv, camera_footprint, basis, self.backend.image_lookup)

    def _hit_parameters(self, hits: Hits, rows: np.ndarray, d: np.ndarray, basis: np.ndarray | None, depth: int
                        ) -> Callable[[np.ndarray], SurfaceParameters]:
        """The fused bounce's ``hit_parameters`` at its hits ``rows`` of a batch of rays (directions
        ``d``, ``basis`` their ``rgb_basis`` rows or None) at ``depth``: the ``HitParameters`` that
        ``_shade`` would look the hits rows[picked] up with."""
        def at(picked: np.ndarray) -> SurfaceParameters:
            surface = rows[picked]
            face, bary = self._triangles(hits, surface)

            def footprint() -> Footprint:
                ng = self._outward_normals(hits, surface, face, bary)[0]
                return self._footprint(face, hits.geom[surface], _rows(d, surface), ng, hits.t[surface])

            return self._parameters_at(face, bary, depth, footprint, None if basis is None else _rows(basis, surface))
        return at

    def first_albedo(self, hits: Hits, surface: np.ndarray, direction: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """Albedo (n, 3) of the camera-ray hits ``surface``: each material's BSDF's directional
        albedo rho(wo) = E[f |cos wi| / pdf], estimated with the ``RHO_SAMPLES`` fixed samples
        (pbrt-v4 ``BSDF::rho`` as its integrators fill a ``VisibleSurface``); a Lambertian gives its
        reflectance exactly."""
        geom, t = hits.geom[surface], hits.t[surface]
        face, bary = self._triangles(hits, surface)
        frame = ShadingFrame(self._outward_normals(hits, surface, face, bary)[1])
        wo = frame.to_local(-direction)
        rho = np.zeros((len(surface), 3), np.float32)
        material_of = self._geom_material[geom]
        for index in np.unique(material_of):
            rows = np.flatnonzero(material_of == index)

            def footprint(rows: np.ndarray = rows) -> Footprint:
                return self._footprint(face[rows], geom[rows], direction[rows], ng[rows], t[rows])

            parameters = self._parameters_at(face[rows], bary[rows], 0, footprint, None)
            bsdf = self.bsdf_factory(self._materials[index], parameters)
            rho[rows] = directional_albedo(bsdf, wo[rows])
        return rho

    def _light_albedo(self, hits: Hits, lit: np.ndarray, direction: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """``first_albedo``: the per-geometry tables hold the lights' surfaces (``_add_light_surfaces``),
        so a light's material is looked up, oriented and filtered as an instance's is."""
        return self.first_albedo(hits, lit, direction, ng)

    def _outward_normals(self, hits: Hits, surface: np.ndarray, face: np.ndarray, bary: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Geometric and shading normals (n, 3) of the hits ``surface`` on the surface's outer side,
        not turned toward the ray: glass tells entering from leaving by the side of wo (pbrt-v3
        ``FresnelSpecular``/``MicrofacetTransmission`` in ``src/core/reflection.cpp``, pbrt-v4
        ``DielectricBxDF`` in ``src/pbrt/bxdfs.h``/``.cpp`` take the sign of cos(theta_o) in the
        shading frame), and the reflection lobes are two-sided (``renderer.bsdf``).

        Orientation as pbrt gives a triangle's (pbrt-v3 ``src/shapes/triangle.cpp``, pbrt-v4
        ``src/pbrt/shapes.h``): the world winding's normal (embree's), reversed under a mirroring
        transform (``transformSwapsHandedness``); where the mesh has vertex normals, the geometric
        normal is turned to the interpolated one instead, which is the shading normal
        (``SetShadingGeometry`` with ``orientationIsAuthoritative``, pbrt-v3
        ``src/core/interaction.cpp``)."""
        geom = hits.geom[surface]
        ng = normalise(_rows(hits.normal, surface).astype(np.float32))
        ng[self._geom_swaps[geom]] *= -1
        shading = ng.copy()
        rows, n = self._vertex_normals(face, bary, geom)
        ng[rows[dot(ng[rows], n) < 0]] *= -1
        shading[rows] = n
        return ng, shading

    def _mis(self, weight_rows: np.ndarray, specular: np.ndarray, prev_pdf: np.ndarray, light_pdf: np.ndarray,
             prev_lights: int) -> np.ndarray:
        """Weights of BSDF-sampled emission: 1 after specular bounces (and camera rays), else the power
        heuristic (or 0 without MIS)."""
        if not self.mis:
            return specular[weight_rows].astype(np.float64)
        return np.where(specular[weight_rows], 1.0,
                        power_heuristic(prev_pdf[weight_rows], prev_lights * light_pdf))

    def _emission(self, hits: Hits, path: np.ndarray, o: np.ndarray, d: np.ndarray, beta: np.ndarray,
                  basis: np.ndarray | None, specular: np.ndarray, prev_pdf: np.ndarray, prev_point: np.ndarray,
                  prev_lights: int, depth: int, out: np.ndarray) -> None:
        """Add what the rays see of emitters, MIS-weighted against the light samples that could find it."""
        pick = (lambda rows: None) if basis is None else (lambda rows: basis[rows])
        # misses see the infinite lights, or the background from camera rays (else nothing to add: a
        # black background adds zeros)
        seen = self.lights.environments or depth == 0 and self.lights.background.any()
        miss = np.flatnonzero(hits.geom < 0) if seen else np.zeros(0, np.int64)
        if len(miss):
            # weights only after a non-specular bounce (camera rays and specular ones weigh 1), and the
            # light sampler's density only where the power heuristic reads it
            weighted = bool(self.lights.environments) and not specular[miss].all()
            le, pdf = self.lights.escaping(_rows(d, miss), pick(miss), depth == 0, weighted and self.mis)
            arriving = _rows(beta, miss) * le
            if weighted:
                arriving *= self._mis(miss, specular, prev_pdf, pdf, prev_lights)[:, None].astype(np.float32)
            _add_rows(out, path[miss], arriving)
        lit = np.flatnonzero(hits.geom >= self.instance_count)
        if len(lit):
            slot = hits.geom[lit] - self.instance_count
            d_lit = _rows(d, lit)
            point = _rows(o, lit) + hits.t[lit, None] * d_lit
            arriving = _rows(beta, lit) * self.lights.area_emission(slot, d_lit, pick(lit))
            if not specular[lit].all():
                arriving *= self._mis(lit, specular, prev_pdf, self.lights.pdf_area(slot, prev_point[lit], point),
                                      prev_lights)[:, None].astype(np.float32)
            _add_rows(out, path[lit], arriving)
        if self.lights.emitters:
            instance = (hits.geom >= 0) & (hits.geom < self.instance_count)
            which = self._instance_light[np.where(instance, hits.geom, 0)]
            hit = np.flatnonzero(instance & (which >= 0))
            # the hits grouped by light in one sort (stable: each group's rows stay ascending)
            hit = hit[np.argsort(which[hit], kind="stable")]
            for rows in np.split(hit, np.flatnonzero(np.diff(which[hit])) + 1) if len(hit) else ():
                light = int(which[rows[0]])
                normal = hits.normal[rows].astype(np.float32)
                arriving = _rows(beta, rows) * self.lights.instance_emission(light, d[rows], normal, pick(rows))
                if not specular[rows].all():
                    point = o[rows] + hits.t[rows, None] * d[rows]
                    density = self.lights.pdf_instance(light, prev_point[rows], point, normal)
                    arriving *= self._mis(rows, specular, prev_pdf, density, prev_lights)[:, None].astype(np.float32)
                _add_rows(out, path[rows], arriving)

    def _shade(self, hits: Hits, surface: np.ndarray, path: np.ndarray, o: np.ndarray, d: np.ndarray,
               beta: np.ndarray, basis: np.ndarray | None, pixel: np.ndarray, sample: np.ndarray, depth: int
               ) -> dict:
        """Next-event estimation and one BSDF sample at the surface hits ``surface``: the next bounce,
        and the shadow rays (``shadow``: starts, vectors, lengths, ray rows, contributions if free)."""
        ray = path[surface]
        px, sx = pixel[ray], sample[ray]
        sb = None if basis is None else _rows(basis, surface)
        ds = _rows(d, surface)
        geom = hits.geom[surface]
        t = hits.t[surface]
        point = _rows(o, surface) + t[:, None] * ds
        face, bary = self._triangles(hits, surface)
        ng, shading = self._outward_normals(hits, surface, face, bary)
        frame = ShadingFrame(shading)
        wo = frame.to_local(-ds)
        magnitude = np.abs(point).max(axis=1)
        eps = (SHADOW_OFFSET * (magnitude + 1e-2 * self.intersector.extent)).astype(np.float32)[:, None]
        m = len(surface)
        base = BOUNCE_DIMENSION + 8 * depth
        light_count = self.light_samples if depth == 0 else 1
        samples = []
        if depth == 0 and self.lights.has_lights:  # every light sample's numbers in one compiled loop
            first_light = rng.all_light_uniforms(px, sx, self.light_samples, self.seed)
        for k in range(light_count if self.lights.has_lights else 0):
            if depth == 0:
                u_light = list(first_light[:, k])
            else:
                u_light = [rng.uniform(px, sx, dim, self.seed) for dim in (base + 4, base + 5, base + 6)]
            u_pick, u1, u2 = u_light
            ls = self.lights.sample(point, u_pick, u1, u2, sb)
            samples.append((ls, frame.to_local(ls.wi)))
        u_bsdf = np.column_stack([rng.uniform(px, sx, base, self.seed), rng.uniform(px, sx, base + 1, self.seed)])
        u_lobe = rng.uniform(px, sx, base + 2, self.seed)
        channels = beta.shape[1]
        light_f = [np.zeros((m, channels), np.float32) for _ in samples]
        light_bsdf_pdf = [np.zeros(m) for _ in samples]
        wi = np.zeros((m, 3), np.float32)
        throughput = np.zeros((m, channels), np.float32)
        pdf = np.zeros(m)
        is_specular = np.zeros(m, bool)
        valid = np.zeros(m, bool)

        def store(rows: slice | np.ndarray, s: BSDFSample, f: list[np.ndarray], f_pdf: list[np.ndarray]) -> None:
            """The BSDF's values at the light samples and its sample at the hits ``rows``."""
            for k in range(len(samples)):
                light_f[k][rows], light_bsdf_pdf[k][rows] = f[k], f_pdf[k]
            wi[rows], pdf[rows], is_specular[rows] = s.wi, s.pdf, s.specular
            ok = s.valid & (s.pdf > 0)
            valid[rows] = ok
            with np.errstate(divide="ignore", invalid="ignore"):
                throughput[rows] = np.where(ok[:, None], s.value * (np.abs(s.wi[:, 2]) / np.where(ok, s.pdf, 1.0))
                                            [:, None], 0.0)

        kernel = self._bsdf_kernel
        on_device: list[tuple[slice | np.ndarray, np.ndarray]] = []
        material_of = self._geom_material[geom]
        groups = np.unique(material_of)
        for index in groups:
            # one material over every hit (the common case): slices, not gathers and scatters
            rows = slice(None) if len(groups) == 1 else np.flatnonzero(material_of == index)
            material = self._materials[index]
            f = face[rows]

            def footprint(rows: slice | np.ndarray = rows) -> Footprint:
                return self._footprint(face[rows], geom[rows], ds[rows], ng[rows], t[rows])

            params = self._parameters_at(f, bary[rows], depth, footprint, None if sb is None else sb[rows])
            table = None if kernel is None else kernel.rows(material, params, len(f))
            if table is not None:
                on_device.append((rows, table))
                continue
            bsdf = self.bsdf_factory(material, params)
            store(rows, bsdf.sample(wo[rows], u_bsdf[rows], u_lobe[rows]),
                  [bsdf.evaluate(wo[rows], local[rows]) for _, local in samples],
                  [bsdf.pdf(wo[rows], local[rows]) for _, local in samples])
        if kernel is not None and on_device:  # every covered hit in one launch
            if len(on_device) == 1:
                hit_rows, table = on_device[0]
            else:
                hit_rows = np.concatenate([np.arange(m)[r] for r, _ in on_device])
                width = max(t.shape[1] for _, t in on_device)  # a mix tree's rows are wider (``BsdfKernel.rows``)
                table = np.concatenate([t if t.shape[1] == width else np.pad(t, ((0, 0), (0, width - t.shape[1])))
                                        for _, t in on_device])
            hit_wo = wo[hit_rows]
            light_wi = np.stack([local[hit_rows] for _, local in samples]) if samples else \
                np.zeros((0, len(hit_wo), 3), np.float32)
            f_light, pdf_light, s = kernel(table, hit_wo, light_wi, u_bsdf[hit_rows], u_lobe[hit_rows], channels)
            store(hit_rows, s, list(f_light), list(pdf_light))
        beta_s = beta[surface]
        shadow: dict[str, list[np.ndarray]] = {"start": [], "vector": [], "length": [], "rows": [],
                                               "contribution": []}
        for k, (ls, local) in enumerate(samples):
            side_g = dot(ls.wi, ng)
            usable = ls.valid & (side_g * local[:, 2] > 0)
            weight = np.where(ls.delta | (not self.mis), 1.0,
                              power_heuristic(light_count * ls.pdf, light_bsdf_pdf[k]))
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = np.where(usable, np.abs(local[:, 2]) * weight / (np.where(usable, ls.pdf, 1.0) * light_count),
                                 0.0).astype(np.float32)
            contribution = beta_s * light_f[k] * ls.radiance * scale[:, None]
            live = np.flatnonzero(np.any(contribution > 0, axis=1) | np.any(contribution < 0, axis=1))
            start = point[live] + ng[live] * eps[live] * np.sign(side_g[live]).astype(np.float32)[:, None]
            # toward a point: the vector from the offset start to it, traced to 1 - 1e-4 of its length
            # (as DirectLighting does, so the light's own surface never shadows it); else a far ray
            far = ls.distance[live] >= FAR
            target = ls.target[live]
            shadow["start"].append(start)
            shadow["vector"].append(np.where(far[:, None], ls.wi[live], target - start))
            shadow["length"].append(np.where(far, FAR, SHADOW_LENGTH).astype(np.float32))
            shadow["rows"].append(ray[live])
            shadow["contribution"].append(contribution[live])
        # the next bounce
        world_wi = frame.to_world(wi)
        side = dot(world_wi, ng)
        go = valid & (side * wi[:, 2] > 0)
        new_beta = beta_s * throughput
        shade = np.ones(m, bool)
        if self.mode == "direct":
            # pbrt-v3 DirectLightingIntegrator: specular reflection while depth + 1 < maxdepth
            follow = is_specular & (depth + 1 < self.max_depth)
            shade = follow
            # a non-specular sample's ray only looks for emission: none to find with delta lights alone
            go &= follow | (~is_specular if self.mis and self.lights.hittable else False)
        elif depth >= ROULETTE_AFTER:
            q = np.maximum(0.05, 1.0 - new_beta.max(axis=1))
            survive = rng.uniform(px, sx, base + 3, self.seed) >= q
            go &= survive
            new_beta /= np.maximum(1.0 - q, 1e-6).astype(np.float32)[:, None]
        go &= np.any(new_beta != 0, axis=1)
        keep = np.flatnonzero(go)
        start = point[keep] + ng[keep] * eps[keep] * np.sign(side[keep]).astype(np.float32)[:, None]
        return {"path": ray[keep], "origin": np.ascontiguousarray(start, np.float32),
                "direction": np.ascontiguousarray(world_wi[keep], np.float32), "beta": new_beta[keep],
                "specular": is_specular[keep], "shade": shade[keep], "pdf": pdf[keep],
                "point": point[keep].astype(np.float64),
                "shadow": {key: np.concatenate(parts) if parts else None for key, parts in shadow.items()}}
