"""Lens flare: light traced from the scene's lights through the lens's ghost paths to the film.

A ghost is light that reflects twice inside the lens (``realistic.optics.ghosts``) before it
reaches the film. Camera rays cannot find it efficiently: a camera ray would have to take a
reflection of a few tenths of a percent at two chosen surfaces and still hit a small light. Light
tracing from the light does it directly (Hullin et al. 2011 trace the ghost paths from a point light
as a 2-D overlay; here they start on the lights of a 3-D scene, with visibility):

Estimator. Each camera sample id (pixel, sample) of a pass also draws one light path from its own
counter-based numbers (``core.rng``, dimensions ``FLARE_KEY`` + 0 .. 6), so the number of light
paths is spp x pixels, every pass's splats depend only on its sample
ids and the seed, and passes stay bit-identical whatever the executor. A path picks

* a light l with probability P_l proportional to an estimate of the flux it sends into the lens
  (floored at ``LIGHT_FLOOR`` of the largest, so every light that can reach the lens is picked:
  unbiased whatever the estimate), and a point y on it uniformly by area (pdf 1 / A_l); a point or
  spot light is its position, a distant light a direction;
* a point x uniformly on a disk of area A_d in the plane z_p of the front surface's cap point
  nearest the scene, the disk holding every line from y to the cap (radius max(a, rho_y (1 - s) + a s),
  s = (y_z - z_p) / (y_z - z_far), a the clear radius: the cap lies between z_far and z_p), or for
  a distant light every parallel line to it (a + (z_p - z_far) tan theta);
* a lens path g (a ghost path) with probability P_g proportional to its throughput.

Lines from y to x, measured by cos_l cos_x / d^2 dA_l dA_d, are all the light from the light's
surface that reaches the front surface, so the flux that path g brings to the film point where the
line lands is, as a one-sample estimate,

    Phi = L(y -> x) cos_l cos_x / d^2 A_l A_d V(y, x) T_g / (P_l P_g)   (area light, radiance L)
    Phi = I(x - y) cos_x / d^2 A_d V(y, x) T_g / (P_l P_g)             (point or spot, intensity I)
    Phi = E cos_x A_d V(x) T_g / (P_l P_g)                             (distant light, irradiance E)

with T_g the path's Fresnel throughput from ``trace_ghost`` (0 where it is blocked) and V the
visibility of the light from the lens (a shadow ray from the light to x, world space: the camera's
``world_from_lens``). Adding Phi / A_pixel to the pixel where the path lands and dividing by the
number of paths makes each pixel's value the mean irradiance over the pixel due to the ghosts:
the expectation of each term is the flux through that pixel, exactly (every factor is the density
of what was drawn), so the estimate is unbiased and its variance falls as 1 / (spp x pixels).
That is the ordinary camera's pixel value: its weight cos^4 A / Z^2 makes a pixel
mean(w L) = integral L cos dw, the film irradiance, box-filtered over the pixel (the flare ignores
a wider pixel filter: ghosts are blurred far beyond a pixel). Lengths are mm in the lens frame, so
a point or spot light's intensity (radiance times a scene-unit area) is multiplied by the camera's
``mm_per_unit`` squared; radiance and irradiance need no conversion.

A spectral camera draws each path's wavelength as its own samples do (``core.spectrum``) and weights
it by ``rgb_response``, so ghosts take the coatings' colours; an RGB camera traces the d line, as
its camera rays do. Lights: area lights, emitting shapes (a pbrt AreaLightSource on a sphere or a
mesh: points uniform by area over its triangles, ``light_sampler.Emitter``), point, spot and distant
lights (the infinite light's texels are not traced). Light reaching the front surface from beside or behind
the plane z_p (a light touching the lens) is not counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.core import rng
from realistic.core.spectrum import rgb_basis, rgb_response, spectral_value, wavelengths_nm
from realistic.core.transforms import transform_points, transform_vectors
from realistic.core.warp import concentric_disk
from realistic.optics.asphere import sag_mm
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.ghosts import GhostPath, GhostTrace, GhostTracer
from realistic.optics.ghosts import ghost_paths as lens_ghost_paths
from realistic.renderer.direct_lighting import SHADOW_OFFSET
from realistic.renderer.film import Splats
from realistic.renderer.light_sampler import FAR, LUMINANCE, Emitter
from realistic.scene.intersect import Intersector
from realistic.scene.lights import DistantLight, EmissiveInstance, PointLight, SpotLight
from realistic.scene.model import AreaLight, Scene

#: First of the seven ``rng`` dimensions of a light path (light pick, light point u and v, lens
#: point u and v, lens path pick, wavelength): far from the camera's and the integrators'.
FLARE_KEY = 0xF1A2E000
#: A light's pick probability is at least this fraction of the likeliest light's.
LIGHT_FLOOR = 1e-3
#: Radii at which the front surface's sag is evaluated to bound its cap in z.
_CAP_RADII = 257


#: A way through the lens: (origins, directions (N, 3) lens frame mm, wavelengths (N,) nm) -> where rays land.
PathTracer = Callable[[np.ndarray, np.ndarray, np.ndarray], GhostTrace]


@dataclass(frozen=True)
class LensPath:
    """One way from the scene to the film through the lens, and its share of the light paths
    (any positive number: the shares are normalised)."""

    trace: PathTracer
    share: float


def ghost_paths(camera: LensCamera, threshold: float, tracer: GhostTracer) -> list[LensPath]:
    """The camera's ghost paths (``optics.ghosts.ghost_paths`` at ``threshold``), each with a share
    of the light paths proportional to its on-axis throughput, traced by ``tracer`` (a backend's)."""
    return [LensPath(_path_tracer(camera, path, tracer), path.throughput)
            for path in lens_ghost_paths(camera.lens, threshold=threshold)]


def direct_path(camera: LensCamera, tracer: GhostTracer) -> LensPath:
    """The ordinary way through the camera's lens (every surface refracting), as a ``LensPath``:
    light-traced, it renders what the camera's own rays render (the estimator's normalisation)."""
    return LensPath(_path_tracer(camera, None, tracer), 1.0)


def _path_tracer(camera: LensCamera, path: GhostPath | None, tracer: GhostTracer) -> PathTracer:
    """``path`` (None: direct) of the camera's lens as a ``PathTracer``, traced by ``tracer``: at the
    d line for an RGB camera, at each ray's own wavelength for a spectral one."""
    film = camera.film_distance_mm

    def trace(origins: np.ndarray, directions: np.ndarray, wavelength_nm: np.ndarray) -> GhostTrace:
        return tracer(film, path, origins, directions, wavelength_nm if camera.spectral else D_LINE_NM)
    return trace


def front_cap_z(camera: LensCamera) -> tuple[float, float]:
    """(z_p, z_far): the lens frame's largest and smallest z of the front surface's clear cap."""
    lens = camera.lens
    vertex = float(lens.vertex_z_mm(camera.film_distance_mm)[0])
    radius = float(lens.radius_mm[0])
    curvature = 1.0 / radius if radius != 0 and math.isfinite(radius) else 0.0
    rho2 = np.linspace(0.0, lens.aperture_mm[0] / 2, _CAP_RADII) ** 2
    z = vertex - sag_mm(rho2, curvature, float(lens.conic[0]), lens.aspheric_coefficients[0])
    return float(np.nanmax(z)), float(np.nanmin(z))


@dataclass(frozen=True)
class _Light:
    """A light in the lens frame (mm): kind, position or centre, axes, normal, colour, area; an
    emitting shape's triangles (``emitter``, world space) with the lens frame from the world."""

    light: object
    centre: np.ndarray  # point, spot, area: position (mm); distant: unit direction toward the light
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    colour: np.ndarray  # (3,) radiance, intensity or irradiance
    area_mm2: float
    emitter: Emitter | None = None
    lens_from_world: np.ndarray | None = None

    @property
    def has_surface(self) -> bool:
        """Whether the light emits from a surface (an area light or an emitting shape)."""
        return isinstance(self.light, (AreaLight, EmissiveInstance))

    @property
    def two_sided(self) -> bool:
        """Whether a surface light emits from both sides."""
        return bool(getattr(self.light, "two_sided", False))

    def points(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (N, 3) uniform by area for (u, v) uniform on [0, 1)^2 (the position of a point
        light), and the unit emitting normals there (the light's own normal; zero for a point)."""
        light = self.light
        if self.emitter is not None and self.lens_from_world is not None:
            points, normals = self.emitter.points(u, v)
            normals = transform_vectors(self.lens_from_world, normals)
            return (transform_points(self.lens_from_world, points),
                    normals / np.linalg.norm(normals, axis=1, keepdims=True))
        normals = np.broadcast_to(self.normal, (len(u), 3))
        if not isinstance(light, AreaLight):
            return np.broadcast_to(self.centre, (len(u), 3)).copy(), normals
        if light.shape == "disk":
            x, y = concentric_disk(u, v)
        else:
            x, y = 2.0 * u - 1.0, 2.0 * v - 1.0
        return (self.centre + self.a * x.astype(np.float64)[:, None] + self.b * y.astype(np.float64)[:, None],
                normals)


class FlareEstimator:
    """Light paths of the module docstring for one scene and ``LensCamera``, through ``paths``
    (the ghost paths, or any ``LensPath``s); ``splats(block)`` is one pass's flare."""

    def __init__(self, scene: Scene, camera: LensCamera, intersector: Intersector, seed: int,
                 paths: Sequence[LensPath]):
        self.camera, self.intersector, self.seed = camera, intersector, seed
        self.paths = [path for path in paths if path.share > 0]
        shares = np.array([path.share for path in self.paths], np.float64)
        self.path_cdf = np.cumsum(shares) / shares.sum() if len(shares) else shares
        self.path_p = shares / shares.sum() if len(shares) else shares
        self.world_from_lens = camera.world_from_lens
        self.lens_from_world = np.linalg.inv(self.world_from_lens)
        self.mm_per_unit = camera.mm_per_unit
        self.z_p, self.z_far = front_cap_z(camera)
        self.clear_radius = float(camera.lens.aperture_mm[0]) / 2
        w_mm, h_mm = camera.film_size_mm
        self.pixel_area_mm2 = (w_mm / camera.width) * (h_mm / camera.height)
        self.lights = [light for light in (self._in_lens_frame(light, scene) for light in scene.lights)
                       if light is not None]
        estimate = np.array([self._flux_estimate(light) for light in self.lights], np.float64)
        if len(estimate) and estimate.max() > 0:
            estimate = np.maximum(estimate, LIGHT_FLOOR * estimate.max())
        else:
            estimate = np.ones(len(self.lights))
        self.light_p = estimate / estimate.sum() if len(estimate) else estimate
        self.light_cdf = np.cumsum(self.light_p)
        self.colours = np.array([light.colour for light in self.lights], np.float64).reshape(-1, 3)
        # a spot light's frame from the lens frame, for its falloff
        self.spot_frames = {id(light): np.linalg.inv(np.asarray(light.light.light_to_world, np.float64))
                            @ self.world_from_lens for light in self.lights if isinstance(light.light, SpotLight)}

    def _in_lens_frame(self, light: object, scene: Scene) -> _Light | None:
        """A light this estimator traces, in the lens frame; None for others."""
        to_lens, mm2 = self.lens_from_world, self.mm_per_unit ** 2
        zero = np.zeros(3)
        if isinstance(light, EmissiveInstance):
            emitter = Emitter(light, scene)
            centre = transform_points(to_lens, (emitter.origin + (emitter.e1 + emitter.e2) / 3).mean(axis=0)[None])[0]
            return _Light(light, centre, zero, zero, zero, np.asarray(light.radiance, np.float64),
                          emitter.area * mm2, emitter, to_lens)
        if isinstance(light, AreaLight):
            centre, a, b, normal = light.frame()
            normal = transform_vectors(to_lens, normal[None])[0]
            return _Light(light, transform_points(to_lens, centre[None])[0], transform_vectors(to_lens, a[None])[0],
                          transform_vectors(to_lens, b[None])[0], normal / np.linalg.norm(normal),
                          np.asarray(light.radiance, np.float64), light.area() * mm2)
        if isinstance(light, (PointLight, SpotLight)):
            position = transform_points(to_lens, np.asarray(light.position, np.float64)[None])[0]
            return _Light(light, position, zero, zero, zero, np.asarray(light.intensity, np.float64) * mm2, 0.0)
        if isinstance(light, DistantLight):
            toward = transform_vectors(to_lens, np.asarray(light.direction, np.float64)[None])[0]
            return _Light(light, toward / np.linalg.norm(toward), zero, zero, zero,
                          np.asarray(light.radiance, np.float64), 0.0)
        return None

    def _flux_estimate(self, light: _Light) -> float:
        """Luminance flux the light sends into the front aperture, seen from its centre (a guess
        that only sets pick probabilities)."""
        lum = float(LUMINANCE @ light.colour)
        disk = math.pi * self.clear_radius ** 2
        axis = np.array([0.0, 0.0, self.z_p])
        if isinstance(light.light, DistantLight):
            return lum * max(light.centre[2], 0.0) * disk
        offset = axis - light.centre
        d2 = float(offset @ offset)
        if d2 == 0 or light.centre[2] <= self.z_p:
            return 0.0
        cos_x = -offset[2] / math.sqrt(d2)
        if isinstance(light.light, AreaLight):
            emitted = lum * light.area_mm2 * abs(float(light.normal @ offset)) / math.sqrt(d2)
        elif light.emitter is not None:  # a shape's mean projected area: a convex one's is a quarter of its area
            emitted = lum * light.area_mm2 / 4
        else:
            emitted = lum
        return emitted * cos_x * disk / d2

    def splats(self, block: SampleBlock) -> Splats:
        """The flare of ``block``'s light paths, one per sample id."""
        if not self.lights or not self.paths:
            return Splats.empty()
        pixel, sample = block.ids()
        keys = rng.hash_keys(pixel, sample, tuple(FLARE_KEY + k for k in range(7)), self.seed)
        u = [rng.to_unit_float(key).astype(np.float64) for key in keys]
        count = len(pixel)
        pick = np.minimum(np.searchsorted(self.light_cdf, u[0], side="right"), len(self.lights) - 1)
        origin = np.zeros((count, 3))
        target = np.zeros((count, 3))
        normal = np.zeros((count, 3))  # a surface light's emitting normal at the line's start
        flux = np.zeros(count)  # Phi / T_g before the path's pick, per unit of the light's colour
        for index, light in enumerate(self.lights):
            rows = np.flatnonzero(pick == index)
            if len(rows):
                origin[rows], target[rows], flux[rows], normal[rows] = self._light_rows(
                    light, u[1][rows], u[2][rows], u[3][rows], u[4][rows])
                flux[rows] /= self.light_p[index]
        spectral = self.camera.spectral
        wavelength = wavelengths_nm(u[6]).astype(np.float64) if spectral else np.full(count, D_LINE_NM)
        path = np.minimum(np.searchsorted(self.path_cdf, u[5], side="right"), len(self.paths) - 1)
        live = np.flatnonzero(flux != 0)
        by_path = live[np.argsort(path[live], kind="stable")]  # each path's rows, in order
        ends = np.searchsorted(path[by_path], np.arange(len(self.paths) + 1))
        landed, landed_pixel, landed_weight = [], [], []
        for g in range(len(self.paths)):
            rows = by_path[ends[g]:ends[g + 1]]
            if not len(rows):
                continue
            exit_ = self.paths[g].trace(origin[rows], target[rows] - origin[rows], wavelength[rows])
            weight = np.where(exit_.passed, exit_.weight, 0.0)
            where = self._pixel_of(exit_.film_xy)
            keep = (weight != 0) & (where >= 0)
            landed.append(rows[keep])
            landed_pixel.append(where[keep])
            landed_weight.append(weight[keep] / self.path_p[g])
        rows = np.concatenate(landed) if landed else np.zeros(0, np.int64)
        if not len(rows):
            return Splats.empty()
        visible = ~self._occluded(pick[rows], origin[rows], target[rows], normal[rows])
        rows = rows[visible]
        scale = (flux[rows] * np.concatenate(landed_weight)[visible] / self.pixel_area_mm2)[:, None]
        value = self.colours[pick[rows]] * scale
        if spectral:
            value = (spectral_value(value, rgb_basis(wavelength[rows])).astype(np.float64)[:, None]
                     * rgb_response(wavelength[rows]))
        return Splats.of(np.concatenate(landed_pixel)[visible], value)

    def _light_rows(self, light: _Light, u1: np.ndarray, u2: np.ndarray, u3: np.ndarray,
                    u4: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For paths that picked ``light``, from their numbers for the light point (u1, u2) and the
        lens point (u3, u4): the line's start, its point on the lens disk, the flux estimate
        per unit of the light's colour before the picks and the path's throughput (0 where the
        light cannot reach the lens), and the light's emitting normal at the start (0 for a point
        or distant light)."""
        a, z_p, z_far = self.clear_radius, self.z_p, self.z_far
        if isinstance(light.light, DistantLight):
            toward = light.centre  # unit, toward the light
            zeros = np.zeros((len(u3), 3))
            if toward[2] <= 0:  # behind the lens
                return zeros, zeros, np.zeros(len(u3)), zeros
            radius = a + (z_p - z_far) * math.hypot(toward[0], toward[1]) / toward[2]
            x = self._disk_points(np.full(len(u3), radius), u3, u4)
            flux = np.full(len(u3), toward[2] * math.pi * radius ** 2)
            return x + toward / toward[2], x, flux, zeros  # the line starts 1 mm in front of z_p
        y, normal = light.points(u1, u2)
        ahead = y[:, 2] > z_p
        rho = np.hypot(y[:, 0], y[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(ahead, (y[:, 2] - z_p) / (y[:, 2] - z_far), 1.0)
        radius = np.maximum(a, rho * (1.0 - s) + a * s)
        x = self._disk_points(radius, u3, u4)
        offset = x - y
        d2 = np.einsum("ij,ij->i", offset, offset)
        flux = np.where(ahead, np.abs(offset[:, 2]) / (d2 * np.sqrt(d2)) * (math.pi * radius * radius), 0.0)
        if light.has_surface:
            cos_l = np.einsum("ij,ij->i", offset, normal) / np.sqrt(d2)
            flux *= (np.abs(cos_l) if light.two_sided else np.maximum(cos_l, 0.0)) * light.area_mm2
        elif isinstance(light.light, SpotLight):
            world = transform_vectors(self.spot_frames[id(light)], offset)
            flux *= light.light.falloff(world[:, 2] / np.linalg.norm(world, axis=1))
        return y, x, flux, normal

    def _occluded(self, pick: np.ndarray, origin: np.ndarray, target: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Whether the scene hides each line's light from its lens point (shadow rays in world space):
        from just off a surface light (toward the lens, along its ``normal``) or a point light's
        position to the lens point, and from the lens point toward a distant light."""
        start, direction, length = origin.copy(), target - origin, np.full(len(pick), 1.0 - 1e-4)
        for index, light in enumerate(self.lights):
            rows = np.flatnonzero(pick == index)
            if isinstance(light.light, DistantLight):
                start[rows], direction[rows], length[rows] = target[rows], light.centre, FAR
            elif light.has_surface and len(rows):
                side = np.where(np.einsum("ij,ij->i", direction[rows], normal[rows]) >= 0, 1.0, -1.0)
                lift = side * SHADOW_OFFSET * np.maximum(np.abs(origin[rows]).max(axis=1), 1.0)
                start[rows] = origin[rows] + normal[rows] * lift[:, None]
                direction[rows] = target[rows] - start[rows]
        return self.intersector.occluded(transform_points(self.world_from_lens, start).astype(np.float32),
                                         transform_vectors(self.world_from_lens, direction).astype(np.float32),
                                         length.astype(np.float32))

    def _disk_points(self, radius: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Points (N, 3) uniform on disks of ``radius`` about the axis in the plane z_p."""
        x, y = concentric_disk(u, v)
        return np.column_stack([x * radius, y * radius, np.full(len(radius), self.z_p)])

    def _pixel_of(self, film_xy: np.ndarray) -> np.ndarray:
        """Raster index of film points (mm, lens frame), -1 off the film (``LensCamera.film_points``
        inverted)."""
        camera = self.camera
        w_mm, h_mm = camera.film_size_mm
        with np.errstate(invalid="ignore"):
            x = np.floor((0.5 - film_xy[:, 0] / w_mm) * camera.width)
            y = np.floor((film_xy[:, 1] / h_mm + 0.5) * camera.height)
            inside = (x >= 0) & (x < camera.width) & (y >= 0) & (y < camera.height)
        return np.where(inside, np.where(inside, y, 0) * camera.width + np.where(inside, x, 0), -1).astype(np.int64)
