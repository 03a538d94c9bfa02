"""Every light of a scene behind one batched interface: pick by power, sample, and give densities.

``sample`` picks light j with probability P_j proportional to its power (pbrt's
``PowerLightSampler``; powers as pbrt-v3's ``Light::Power``) and one point or direction on it;
densities are per unit solid angle at the shading point and include P_j. Area lights (their table
and points: ``renderer.area_lights``) and emitting instances are sampled uniformly by area
(solid-angle pdf d^2 / (cos_q A)), except an emitting sphere (``EmissiveInstance.sphere``) seen from
outside it, sampled uniformly within the cone it subtends (pdf 1 / (2 pi (1 - cos theta_max)), as
pbrt-v3 ``src/shapes/sphere.cpp`` Sphere::Sample(const Interaction &, ...) and pbrt-v4
``src/pbrt/shapes.h`` Sphere::Sample(ShapeSampleContext) do; from inside, by area as they do). Its
mesh is inscribed in the sphere: a direction of the cone meets the mesh (found by a ray against that
mesh alone, in its object space) or misses it and brings nothing, so the estimate stays unbiased for
the mesh that is rendered; point, spot and distant lights are deltas (``delta`` True,
pdf = P_j); an infinite light with a map is importance sampled by a ``Distribution2D`` over its
texels' luminance (times sin(theta) for a lat-long map, whose texels shrink toward the poles),
without one uniformly over the sphere. ``pdf_area``, ``pdf_instance``
and ``pdf_environment`` give the same densities for directions that BSDF sampling found, for MIS;
``escaping`` gives a ray that leaves the scene its radiance and that density from one lookup of its
direction in each map.

Colours come back as (N, C): C = 3 for RGB rays, C = 1 spectral values at each ray's wavelength
(``basis``: the rows of ``realistic.core.spectrum.rgb_basis`` of those rays).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from realistic.core.distribution import Distribution2D
from realistic.core.jit import compiled
from realistic.core.spectrum import spectral_value
from realistic.core.transforms import transform_points, transform_vectors
from realistic.core.vectors import dot
from realistic.renderer.area_lights import AreaLightTable
from realistic.renderer.bsdf.base import ShadingFrame
from realistic.scene.intersect import Intersector
from realistic.scene.lights import (
    DistantLight,
    EmissiveInstance,
    InfiniteLight,
    PointLight,
    SpotLight,
)
from realistic.scene.model import AreaLight, Instance, Scene

AREA, POINT, SPOT, DISTANT, INFINITE, INSTANCE = range(6)
#: Luminance weights of linear sRGB (Rec. 709), for the environment maps' sampling densities.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: Shadow-ray length toward distant and infinite lights (beyond any scene embree holds in float32).
FAR = np.float32(1e30)
#: Shadow-ray length toward a point, in units of the vector from the ray's offset start to the point:
#: short of the point, so that the light's own surface does not block it.
SHADOW_LENGTH = np.float32(1 - 1e-4)
#: ``FAR`` and ``SHADOW_LENGTH`` as the kernels that write shadow rays read them (``shade.cl``, ``bounce.cl``).
SHADOW_DEFINES = f"#define FAR {float(FAR)!r}f\n#define SHADOW_LENGTH {float(SHADOW_LENGTH)!r}f\n"


def colour(rgb: np.ndarray, basis: np.ndarray | None) -> np.ndarray:
    """RGB rows (N, 3) as they are, or their spectral values (N, 1) at the rays' basis rows."""
    rgb = np.asarray(rgb, np.float32)
    return rgb if basis is None else spectral_value(rgb, basis)[:, None]


@dataclass
class LightSample:
    """Per shading point: unit direction to the light, the light's point (for shadow rays; unused for
    distant and infinite lights), the distance to it (``FAR`` for those), incident radiance (N, C),
    density (solid angle, times the pick probability; the pick probability for deltas)."""

    wi: np.ndarray
    target: np.ndarray
    distance: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray
    delta: np.ndarray
    valid: np.ndarray


def _area_loop(p: np.ndarray, slot: np.ndarray, u1: np.ndarray, u2: np.ndarray, centre: np.ndarray, a: np.ndarray,
               b: np.ndarray, normal: np.ndarray, disk: np.ndarray, two_sided: np.ndarray, area: np.ndarray,
               radiance: np.ndarray, probability: np.ndarray, target: np.ndarray, wi: np.ndarray,
               distance: np.ndarray, rgb: np.ndarray, pdf: np.ndarray, valid: np.ndarray) -> None:
    """``LightSampler.sample``'s numpy path for rows that all pick area lights (``slot``, each picked
    with ``probability``): ``AreaLightTable.points``, ``LightSampler._towards_surface``, the pick's
    probability and ``valid``, in one loop with the same arithmetic in the same precisions (the map's
    angle in float64, the point and its direction in float32, the density in float64)."""
    tiny = np.float32(1e-30)
    for r in range(p.shape[0]):
        s = slot[r]
        x1, x2 = 2.0 * u1[r] - 1.0, 2.0 * u2[r] - 1.0
        if disk[s]:  # Shirley-Chiu's concentric map (``realistic.core.warp.concentric_disk``)
            if x1 == 0.0 and x2 == 0.0:
                radius, phi = 0.0, 0.0
            elif abs(x1) > abs(x2):
                radius, phi = x1, (np.pi / 4) * (x2 / x1)
            else:
                radius, phi = x2, (np.pi / 2) - (np.pi / 4) * (x1 / x2)
            x, y = np.float32(radius * math.cos(phi)), np.float32(radius * math.sin(phi))
        else:
            x, y = np.float32(x1), np.float32(x2)
        for c in range(3):
            target[r, c] = centre[s, c] + a[s, c] * x + b[s, c] * y
        t0, t1, t2 = target[r, 0] - p[r, 0], target[r, 1] - p[r, 1], target[r, 2] - p[r, 2]
        d2 = t0 * t0 + t1 * t1 + t2 * t2
        d = np.sqrt(max(d2, tiny))
        wi[r, 0], wi[r, 1], wi[r, 2] = t0 / d, t1 / d, t2 / d
        cos_q = -(wi[r, 0] * normal[s, 0] + wi[r, 1] * normal[s, 1] + wi[r, 2] * normal[s, 2])
        if two_sided[s]:
            cos_q = abs(cos_q)
        distance[r] = d
        ok = cos_q > 0 and d2 > 0
        pdf[r] = np.float64(d2) / (np.float64(cos_q) * area[s]) * probability[s] if ok else 0.0
        lit = False
        for c in range(3):
            rgb[r, c] = radiance[s, c] if ok else np.float32(0.0)
            lit = lit or rgb[r, c] != 0
        valid[r] = pdf[r] > 0 and lit


class _Environment:
    """One infinite light's sampling tables, and its map scaled by its radiance."""

    def __init__(self, light: InfiniteLight):
        self.light = light
        self.rgb = np.asarray(light.radiance, np.float64)
        if light.image is None:
            self.distribution = None
            self._scaled = self.rgb.astype(np.float32)[None, :]  # one texel: pbrt's map of one
            return
        image = np.asarray(light.image, np.float64)
        lum = np.maximum(image @ LUMINANCE, 0.0)
        if light.mapping == "latlong":
            rows = lum.shape[0]
            lum = lum * np.sin((np.arange(rows) + 0.5) / rows * math.pi)[:, None]
        self.distribution = Distribution2D(lum)
        # texel times radiance in float64, rounded to float32 once, as every lookup rounded it
        self._scaled = (image * self.rgb).astype(np.float32).reshape(-1, 3)
        self._density = self.distribution.density.ravel()

    def look_up(self, direction: np.ndarray, density: bool) -> tuple[np.ndarray, np.ndarray]:
        """RGB radiance (N, 3) float32 arriving from world directions (N, 3) and, with ``density``,
        the solid-angle densities (N,) with which ``sample`` draws them (else zeros). Each
        direction's map coordinates and texel (``InfiniteLight.to_uv`` and ``texels``: the
        nearest texel, which is also the ``Distribution2D`` cell its density reads) are found once
        for both."""
        n = len(direction)
        if self.distribution is None:
            rgb = np.broadcast_to(self._scaled[0], (n, 3))
            return rgb, np.full(n, 1.0 / (4 * math.pi)) if density else np.zeros(n)
        uv = self.light.to_uv(direction)
        texel = self.light.texel_index(uv)
        rgb = np.take(self._scaled, texel, axis=0)
        return rgb, np.take(self._density, texel) * self.jacobian(uv) if density else np.zeros(n)

    def jacobian(self, uv: np.ndarray) -> np.ndarray:
        """d(uv) / d(solid angle) of the mapping at uv."""
        if self.light.mapping == "equal-area":
            return np.full(len(uv), 1.0 / (4 * math.pi))
        sin_theta = np.sin(uv[:, 1] * math.pi)
        with np.errstate(divide="ignore"):
            return np.where(sin_theta > 0, 1.0 / (2 * math.pi * math.pi * sin_theta), 0.0)

    def sample(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World directions (N, 3) and their solid-angle densities (N,)."""
        if self.distribution is None:
            z = 1.0 - 2.0 * u1.astype(np.float64)
            r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
            phi = 2 * math.pi * u2
            return np.column_stack([r * np.cos(phi), r * np.sin(phi), z]), np.full(len(u1), 1.0 / (4 * math.pi))
        uv, density = self.distribution.sample(u1, u2)
        return self.light.to_world(uv), density * self.jacobian(uv)


class Emitter:
    """An emitting instance's world triangles and their area CDF (``points`` draws on them by area:
    the light sampler's area strategy and the flare's light points)."""

    def __init__(self, light: EmissiveInstance, scene: Scene):
        inst = scene.instances[light.instance]
        mesh = scene.meshes[inst.mesh]
        corners = transform_points(inst.transform, mesh.vertices)[mesh.faces]
        self.origin, self.e1, self.e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
        cross = np.cross(self.e1, self.e2)
        area = np.linalg.norm(cross, axis=1)
        self.normal = cross / np.maximum(area, 1e-300)[:, None]
        self.area = float(area.sum() / 2)
        self.cdf = np.cumsum(area) / area.sum()
        self.light = light
        self.mesh = mesh
        self.to_object = np.linalg.inv(np.asarray(inst.transform, np.float64)) if light.sphere else np.eye(4)
        # the world winding's side of an object-space direction: flipped by a mirroring transform
        self.winding = -1.0 if np.linalg.det(np.asarray(inst.transform, np.float64)[:3, :3]) < 0 else 1.0

    def points(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (N, 3) uniform by area over the triangles, and their triangles' unit normals, for
        (u1, u2) uniform on [0, 1)^2: u1 picks the triangle and, rescaled within its CDF step, with
        u2 places the point in it (Turk's square-root map)."""
        tri = np.minimum(np.searchsorted(self.cdf, u1, side="right"), len(self.cdf) - 1)
        lo = np.where(tri > 0, self.cdf[tri - 1], 0.0)
        s = np.clip((u1 - lo) / np.maximum(self.cdf[tri] - lo, 1e-300), 0.0, 1.0)
        r = np.sqrt(s)
        b1, b2 = 1.0 - r, u2 * r
        return self.origin[tri] + self.e1[tri] * b1[:, None] + self.e2[tri] * b2[:, None], self.normal[tri]

    def cone(self, point: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For points (N, 3) and this emitter's sphere: whether each lies outside it, the unit axis
        to its centre, and 1 - cos(theta_max) of the cone it subtends (float64; as sin^2 / (1 + cos),
        which keeps its digits for a small or distant sphere)."""
        assert self.light.sphere is not None
        centre, radius = self.light.sphere
        to_centre = np.asarray(centre, np.float64) - np.asarray(point, np.float64)
        d2 = np.einsum("ij,ij->i", to_centre, to_centre)
        outside = d2 > radius * radius
        sin2 = np.where(outside, radius * radius / np.where(outside, d2, 1.0), 1.0)
        cos_max = np.sqrt(np.maximum(0.0, 1.0 - sin2))
        axis = to_centre / np.sqrt(np.maximum(d2, 1e-300))[:, None]
        return outside, axis, sin2 / (1.0 + cos_max)


class LightSampler:
    """All of a scene's lights, picked by power."""

    def __init__(self, scene: Scene, extent: float):
        self.lights = list(scene.lights)
        self.background = np.asarray(scene.background, np.float32)
        radius = max(extent, 1e-6) * math.sqrt(3) / 2  # the scene box's bounding sphere
        area_index = {id(light): j for j, light in enumerate(scene.area_lights)}
        self.kind = np.zeros(len(self.lights), np.int64)
        power = np.zeros(len(self.lights))
        self.area_slot = np.full(len(self.lights), -1)  # light index -> index among the area lights
        self.environments: dict[int, _Environment] = {}
        self.emitters: dict[int, Emitter] = {}
        self.instance_light: dict[int, int] = {}  # emitting instance -> light index
        self._mesh_alone: dict[int, Intersector] = {}  # an emitting sphere's mesh -> rays against it alone
        for i, light in enumerate(self.lights):
            if isinstance(light, AreaLight):
                self.kind[i], self.area_slot[i] = AREA, area_index[id(light)]
                power[i] = math.pi * light.area() * (2 if light.two_sided else 1) * float(np.mean(light.radiance))
            elif isinstance(light, EmissiveInstance):
                self.kind[i] = INSTANCE
                self.emitters[i] = Emitter(light, scene)
                self.instance_light[light.instance] = i
                power[i] = light.power(self.emitters[i].area)
            else:
                self.kind[i] = {PointLight: POINT, SpotLight: SPOT, DistantLight: DISTANT,
                                InfiniteLight: INFINITE}[type(light)]
                power[i] = light.power(radius)
                if isinstance(light, InfiniteLight):
                    self.environments[i] = _Environment(light)
        power = np.where(np.isfinite(power) & (power > 0), power, 0.0)
        self.probability = power / power.sum() if power.sum() > 0 else power
        self.cdf = np.cumsum(self.probability)
        self.has_lights = bool(len(self.lights)) and power.sum() > 0
        # whether a ray can reach emission (an area light, an emitting instance, the sky)
        self.hittable = bool(np.any((power > 0) & np.isin(self.kind, (AREA, INSTANCE, INFINITE))))
        # per light arrays (zeros where not that kind)
        n = len(self.lights)
        self.position = np.zeros((n, 3))
        self.intensity = np.zeros((n, 3))
        self.to_light_frame = np.tile(np.eye(3), (n, 1, 1))
        for i, light in enumerate(self.lights):
            if isinstance(light, PointLight | SpotLight):
                self.position[i] = light.position
                self.intensity[i] = light.intensity
            if isinstance(light, SpotLight):
                self.to_light_frame[i] = np.linalg.inv(np.asarray(light.light_to_world, np.float64)[:3, :3])
            if isinstance(light, DistantLight):
                d = np.asarray(light.direction, np.float64)
                self.position[i] = d / np.linalg.norm(d)
                self.intensity[i] = light.radiance
        self.area_lights = AreaLightTable.of(scene.area_lights)
        slot_light = np.full(len(self.area_lights), -1)
        for i, slot in enumerate(self.area_slot):
            if slot >= 0:
                slot_light[slot] = i
        self.area_probability = self.probability[slot_light] if len(self.area_lights) else np.zeros(0)
        self.area_only = bool(len(self.lights)) and bool(np.all(self.kind == AREA))

    # ---- sampling ------------------------------------------------------------------------------
    def sample(self, point: np.ndarray, u_pick: np.ndarray, u1: np.ndarray, u2: np.ndarray,
               basis: np.ndarray | None) -> LightSample:
        """One light sample per point (N, 3)."""
        n = len(point)
        p = np.asarray(point, np.float32)
        j = np.minimum(np.searchsorted(self.cdf, u_pick, side="right"), len(self.cdf) - 1)
        u1, u2 = np.asarray(u1, np.float64), np.asarray(u2, np.float64)
        if self.area_only:  # area lights alone (the seed scene): one compiled loop, no gathers
            return self._sample_areas(p, j, u1, u2, basis)
        wi = np.zeros((n, 3), np.float32)
        target = np.zeros((n, 3), np.float32)
        distance = np.zeros(n, np.float32)
        rgb = np.zeros((n, 3), np.float32)
        pdf = np.zeros(n)
        kind = self.kind[j]
        area_rows = np.flatnonzero(kind == AREA)
        if len(area_rows):
            rows = slice(None) if len(area_rows) == n else area_rows  # area lights alone: no gathers
            slot = self.area_slot[j[rows]]
            q = self.area_lights.points(slot, u1[rows], u2[rows])
            target[rows] = q
            table = self.area_lights
            self._towards_surface(rows, p, q, np.take(table.normal, slot, axis=0), table.two_sided[slot],
                                  table.area[slot], np.take(table.radiance, slot, axis=0), wi, distance, rgb, pdf)
        for i, emitter in self.emitters.items():
            rows = np.flatnonzero(j == i)
            if len(rows) and emitter.light.sphere is not None:
                outside, axis, one_minus_cos = emitter.cone(p[rows])
                cone = rows[outside]
                if len(cone):
                    self._towards_sphere(emitter, cone, p, axis[outside], one_minus_cos[outside], u1[cone],
                                         u2[cone], wi, target, distance, rgb, pdf)
                rows = rows[~outside]  # inside its sphere: by area (pbrt: "sample shape by area")
            if len(rows):
                q, normal = emitter.points(u1[rows], u2[rows])
                target[rows] = q
                self._towards_surface(rows, p, q, normal, np.full(len(rows), emitter.light.two_sided),
                                      np.full(len(rows), emitter.area),
                                      np.broadcast_to(np.asarray(emitter.light.radiance, np.float64), (len(rows), 3)),
                                      wi, distance, rgb, pdf)
        rows = np.flatnonzero((kind == POINT) | (kind == SPOT))
        if len(rows):
            jr = j[rows]
            target[rows] = self.position[jr]
            to_light = self.position[jr] - p[rows]
            d2 = np.einsum("ij,ij->i", to_light, to_light)
            wi[rows] = to_light / np.sqrt(np.maximum(d2, 1e-300))[:, None]
            distance[rows] = np.sqrt(d2)
            scale = 1.0 / np.maximum(d2, 1e-300)
            spot = kind[rows] == SPOT
            if np.any(spot):
                local = np.einsum("nij,nj->ni", self.to_light_frame[jr[spot]], -wi[rows[spot]])
                cos = local[:, 2] / np.maximum(np.linalg.norm(local, axis=1), 1e-300)
                falloff = np.zeros(len(cos))
                for i in np.unique(jr[spot]):
                    mine = jr[spot] == i
                    falloff[mine] = self.lights[i].falloff(cos[mine])
                scale[spot] *= falloff
            rgb[rows] = self.intensity[jr] * scale[:, None]
            pdf[rows] = 1.0
        rows = np.flatnonzero(kind == DISTANT)
        if len(rows):
            wi[rows] = self.position[j[rows]]
            distance[rows] = FAR
            rgb[rows] = self.intensity[j[rows]]
            pdf[rows] = 1.0
        for i, env in self.environments.items():
            rows = np.flatnonzero(j == i)
            if len(rows):
                w, density = env.sample(u1[rows], u2[rows])
                wi[rows], distance[rows], pdf[rows] = w, FAR, density
                with np.errstate(divide="ignore", invalid="ignore"):
                    rgb[rows] = np.where(density[:, None] > 0, env.look_up(w, density=False)[0], 0.0)
        pdf *= self.probability[j]
        delta = (kind == POINT) | (kind == SPOT) | (kind == DISTANT)
        valid = (pdf > 0) & np.any(rgb != 0, axis=1)
        return LightSample(wi, target, distance, colour(rgb, basis), pdf, delta, valid)

    def _towards_sphere(self, emitter: Emitter, rows: np.ndarray, p: np.ndarray, axis: np.ndarray,
                        one_minus_cos: np.ndarray, u1: np.ndarray, u2: np.ndarray, wi: np.ndarray,
                        target: np.ndarray, distance: np.ndarray, rgb: np.ndarray, pdf: np.ndarray) -> None:
        """Fill ``wi``, ``distance``, ``rgb``, ``pdf`` and ``target`` at ``rows`` (points ``p[rows]``
        outside ``emitter``'s sphere) with directions uniform in the cone the sphere subtends, about
        ``axis``; where one misses the emitter's mesh or meets its back, it brings nothing."""
        lower = u1 * one_minus_cos  # 1 - cos(theta), uniform on [0, 1 - cos(theta_max)]
        cos = 1.0 - lower
        sin = np.sqrt(np.maximum(0.0, lower * (2.0 - lower)))
        phi = 2.0 * math.pi * u2
        frame = ShadingFrame(axis.astype(np.float32))
        w = frame.to_world(np.column_stack([sin * np.cos(phi), sin * np.sin(phi), cos]).astype(np.float32))
        ok, t = self.meets_sphere_mesh(emitter, p[rows], w)
        wi[rows], distance[rows] = w, t
        target[rows] = p[rows] + t[:, None] * w
        rgb[rows] = np.where(ok[:, None], np.asarray(emitter.light.radiance, np.float32), 0.0)
        pdf[rows] = np.where(ok, 1.0 / (2.0 * math.pi * one_minus_cos), 0.0)

    def meets_sphere_mesh(self, emitter: Emitter, point: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whether rays from float32 ``point`` (N, 3) along unit ``w`` (N, 3) meet emitting sphere
        ``emitter``'s mesh on an emitting side, and where (t along w; 0 where not): a ray against that
        mesh alone, in its object space (``_towards_sphere``'s, and the bounce kernel's cone samples')."""
        to_object = emitter.to_object
        origin = transform_points(to_object, point.astype(np.float64)).astype(np.float32)
        direction = transform_vectors(to_object, w.astype(np.float64)).astype(np.float32)
        hits = self._alone(emitter).closest(origin, direction)  # t: world units along w, as the map is affine
        front = emitter.winding * dot(direction, hits.normal) < 0
        ok = (hits.geom >= 0) & (front | emitter.light.two_sided)
        return ok, np.where(ok, hits.t, 0.0).astype(np.float32)

    def _alone(self, emitter: Emitter) -> Intersector:
        """Rays against ``emitter``'s mesh alone in its object space: one per mesh, built on first use
        (equal spheres share their tessellation, and so this)."""
        key = id(emitter.mesh)
        if key not in self._mesh_alone:
            self._mesh_alone[key] = Intersector(Scene(meshes=[emitter.mesh], instances=[Instance(0)]), share=False)
        return self._mesh_alone[key]

    def _sample_areas(self, p: np.ndarray, j: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                      basis: np.ndarray | None) -> LightSample:
        """``sample`` where every light is an area light: ``_area_loop`` on lights ``j``."""
        n, table = len(p), self.area_lights
        target, wi, rgb = (np.empty((n, 3), np.float32) for _ in range(3))
        distance, pdf, valid = np.empty(n, np.float32), np.empty(n), np.empty(n, bool)
        compiled(_area_loop)(p, self.area_slot[j], u1, u2, table.centre, table.a, table.b, table.normal, table.disk,
                             table.two_sided, table.area, table.radiance, self.area_probability, target, wi,
                             distance, rgb, pdf, valid)
        return LightSample(wi, target, distance, colour(rgb, basis), pdf, np.zeros(n, bool), valid)

    @staticmethod
    def _towards_surface(rows: slice | np.ndarray, p: np.ndarray, q: np.ndarray, normal: np.ndarray,
                         two_sided: np.ndarray, area: np.ndarray, radiance: np.ndarray, wi: np.ndarray,
                         distance: np.ndarray, rgb: np.ndarray, pdf: np.ndarray) -> None:
        """Fill ``wi``, ``distance``, ``rgb`` and ``pdf`` at ``rows`` for points ``q`` sampled on
        surfaces (by area, ``area`` each) seen from ``p``."""
        to_light = np.asarray(q - p[rows], np.float32)
        d2 = dot(to_light, to_light)
        d = np.sqrt(np.maximum(d2, np.float32(1e-30)))
        w = to_light / d[:, None]
        cos_q = -dot(w, np.asarray(normal, np.float32))
        cos_q = np.where(two_sided, np.abs(cos_q), cos_q)
        ok = (cos_q > 0) & (d2 > 0)
        wi[rows], distance[rows] = w, d
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf[rows] = np.where(ok, d2 / (cos_q * area), 0.0)
        rgb[rows] = np.where(ok[:, None], radiance, 0.0)

    # ---- densities and emission for directions found by BSDF sampling ----------------------
    def pdf_area(self, slot: np.ndarray, origin: np.ndarray, hit: np.ndarray) -> np.ndarray:
        """Density with which ``sample`` would pick points ``hit`` on area lights ``slot`` from ``origin``."""
        to = np.asarray(hit, np.float64) - origin
        d2 = np.einsum("ij,ij->i", to, to)
        cos_q = np.abs(np.einsum("ij,ij->i", to, self.area_lights.normal[slot])) / np.sqrt(np.maximum(d2, 1e-300))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(cos_q > 0, self.area_probability[slot] * d2 / (cos_q * self.area_lights.area[slot]), 0.0)

    def area_emission(self, slot: np.ndarray, direction: np.ndarray, basis: np.ndarray | None) -> np.ndarray:
        """Radiance (N, C) seen along ``direction`` on area lights ``slot`` (zero on a one-sided back)."""
        table = self.area_lights
        front = (dot(direction, table.normal[slot].astype(np.float32)) < 0) | table.two_sided[slot]
        return colour(table.radiance[slot] * front[:, None], basis)

    def instance_emission(self, light: int, direction: np.ndarray, normal: np.ndarray,
                          basis: np.ndarray | None) -> np.ndarray:
        """Radiance (N, C) of emitting instance light ``light`` seen along ``direction`` at faces of
        geometric normal ``normal`` (as embree gives it, the winding's side)."""
        emitter = self.emitters[light]
        front = (dot(direction, normal) < 0) | emitter.light.two_sided
        rgb = np.asarray(emitter.light.radiance, np.float32)[None, :] * front[:, None]
        return colour(rgb, basis)

    def pdf_instance(self, light: int, origin: np.ndarray, hit: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Density with which ``sample`` would find the points ``hit`` (faces of geometric normal
        ``normal``) on emitting instance ``light`` from ``origin``: the cone's for an emitting sphere
        seen from outside it, by area otherwise."""
        emitter = self.emitters[light]
        to = np.asarray(hit, np.float64) - origin
        d2 = np.einsum("ij,ij->i", to, to)
        n = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        cos_q = np.abs(np.einsum("ij,ij->i", to, n)) / np.sqrt(np.maximum(d2, 1e-300))
        with np.errstate(divide="ignore", invalid="ignore"):
            density = np.where(cos_q > 0, d2 / (cos_q * emitter.area), 0.0)
        if emitter.light.sphere is not None:
            outside, _, one_minus_cos = emitter.cone(origin)
            density = np.where(outside, 1.0 / (2.0 * math.pi * one_minus_cos), density)
        return self.probability[light] * density

    def escaping(self, direction: np.ndarray, basis: np.ndarray | None, camera: bool, density: bool
                 ) -> tuple[np.ndarray, np.ndarray]:
        """For rays leaving the scene along ``direction``: the radiance (N, C) from the infinite lights
        (with none, the background for camera rays and black for others) and, with ``density``, the
        density (N,) with which ``sample`` finds those directions, for MIS (else zeros), from one
        lookup of each direction in each map."""
        n = len(direction)
        if not self.environments:
            rgb = np.broadcast_to(self.background if camera else np.zeros(3, np.float32), (n, 3))
            return colour(rgb, basis), np.zeros(n)
        total, pdf = np.zeros((n, 3), np.float32), np.zeros(n)
        for i, env in self.environments.items():
            rgb, env_pdf = env.look_up(direction, density)
            total += rgb
            pdf += self.probability[i] * env_pdf
        return colour(total, basis), pdf

    def pdf_environment(self, direction: np.ndarray) -> np.ndarray:
        """Density with which ``sample`` finds the infinite lights' directions ``direction``."""
        return self.escaping(direction, None, camera=False, density=True)[1]
