"""Lights other than ``model.AreaLight``: point, spot, distant, infinite, and emitting instances.

Plain data in world space; the renderer samples them (``realistic.renderer.light_sampler``).
Radiometric quantities are RGB: ``intensity`` W/sr-like (radiance times area), ``radiance`` as
``AreaLight``'s. Conventions follow pbrt: a spot light's cone is about +z of its light frame
(pbrt-v3 ``src/lights/spot.cpp``, pbrt-v4 ``src/pbrt/lights.cpp``); a distant light's
``direction`` points from the scene toward the light (pbrt's ``from - to``). An infinite light's
map is indexed by direction in its light frame: "latlong" (pbrt-v1/v2/v3 ``InfiniteAreaLight``:
u = phi / 2 pi, v = theta / pi, theta from +z, row 0 of the image at v = 0) or "equal-area"
(pbrt-v4 ``ImageInfiniteLight``: Clarberg's octahedral equal-area square, ``EqualAreaSquareToSphere``
in pbrt-v4 ``src/pbrt/util/math.cpp``, square images only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from realistic.core import validation
from realistic.core.transforms import transform_vectors
from realistic.errors import UserError
from realistic.scene.model import RGB, AreaLight

SPOT_FALLOFFS = ("quartic", "smoothstep")
MAPPINGS = ("latlong", "equal-area")


@dataclass(frozen=True, eq=False)
class PointLight:
    """Isotropic point emitter: irradiance I cos / r^2 at distance r."""

    intensity: RGB
    position: np.ndarray  # (3,) world

    def __post_init__(self) -> None:
        validation.emission(self.intensity, "point light intensity")

    def power(self, scene_radius: float) -> float:
        """Mean-channel power (pbrt-v3 ``PointLight::Power``: 4 pi I)."""
        return 4.0 * math.pi * float(np.mean(self.intensity))


@dataclass(frozen=True, eq=False)
class SpotLight:
    """A point emitter restricted to a cone about +z of ``light_to_world`` (its origin is the light).

    Intensity at angle theta from the axis is ``intensity`` times the falloff: 1 inside
    ``cos_falloff_start``, 0 outside ``cos_total_width``, between them pbrt-v1/v2/v3's
    ((cos - cos_total) / (cos_start - cos_total))^4 ("quartic") or pbrt-v4's smoothstep.
    """

    intensity: RGB
    light_to_world: np.ndarray  # (4, 4)
    cos_total_width: float
    cos_falloff_start: float
    falloff_kind: str = "quartic"

    def __post_init__(self) -> None:
        validation.emission(self.intensity, "spot light intensity")

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.light_to_world, np.float64)[:3, 3]

    def falloff(self, cos_theta: np.ndarray) -> np.ndarray:
        """The falloff factor at cosines (to the cone axis, in the light frame) ``cos_theta``."""
        c = np.asarray(cos_theta, np.float64)
        span = self.cos_falloff_start - self.cos_total_width
        t = np.clip((c - self.cos_total_width) / span, 0.0, 1.0) if span > 0 else (c >= self.cos_total_width) * 1.0
        return t ** 4 if self.falloff_kind == "quartic" else t * t * (3.0 - 2.0 * t)

    def power(self, scene_radius: float) -> float:
        """Mean-channel power: pbrt-v3's 2 pi I (1 - (cos_start + cos_total) / 2) for both falloffs."""
        return 2.0 * math.pi * float(np.mean(self.intensity)) * (
            1.0 - 0.5 * (self.cos_falloff_start + self.cos_total_width))


@dataclass(frozen=True, eq=False)
class DistantLight:
    """Parallel light of ``radiance`` (irradiance on a plane facing it) arriving from ``direction``."""

    radiance: RGB
    direction: np.ndarray  # (3,) unit, toward the light

    def __post_init__(self) -> None:
        validation.emission(self.radiance, "distant light radiance")

    def power(self, scene_radius: float) -> float:
        """pbrt-v3 ``DistantLight::Power``: L pi r^2 over the scene's bounding disk."""
        return math.pi * scene_radius ** 2 * float(np.mean(self.radiance))


@dataclass(frozen=True, eq=False)
class InfiniteLight:
    """Radiance from every direction: ``radiance`` times the map's texel (white without a map)."""

    radiance: RGB
    image: np.ndarray | None = None  # (H, W, 3) float32 linear, row 0 first in the file
    mapping: str = "latlong"
    light_to_world: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        validation.emission(self.radiance, "infinite light radiance")
        if self.mapping not in MAPPINGS:
            raise ValueError(f"unknown environment mapping {self.mapping!r}")

    def power(self, scene_radius: float) -> float:
        """pbrt-v3 ``InfiniteAreaLight::Power``: pi r^2 times the map's mean (over solid angle) radiance."""
        return math.pi * scene_radius ** 2 * float(np.mean(self.radiance)) * self.mean_map_value()

    def mean_map_value(self) -> float:
        """The map's mean over the sphere of directions (1 without a map)."""
        if self.image is None:
            return 1.0
        grey = np.asarray(self.image, np.float64).mean(axis=2)
        if self.mapping == "equal-area":
            return float(grey.mean())
        rows = grey.shape[0]
        sin_theta = np.sin((np.arange(rows) + 0.5) / rows * math.pi)
        return float((grey.mean(axis=1) * sin_theta).sum() / sin_theta.sum())

    def to_uv(self, direction_world: np.ndarray) -> np.ndarray:
        """Map coordinates (N, 2) in [0, 1)^2 of world directions (N, 3)."""
        linear = np.asarray(self.light_to_world, np.float64)[:3, :3]
        w = transform_vectors(np.linalg.inv(linear), np.asarray(direction_world, np.float64))
        w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)
        return equal_area_sphere_to_square(w) if self.mapping == "equal-area" else latlong_uv(w)

    def to_world(self, uv: np.ndarray) -> np.ndarray:
        """Unit world directions (N, 3) of map coordinates uv (N, 2)."""
        w = equal_area_square_to_sphere(uv) if self.mapping == "equal-area" else latlong_direction(uv)
        w = transform_vectors(np.asarray(self.light_to_world, np.float64), w)
        return w / np.linalg.norm(w, axis=1, keepdims=True)

    def texels(self, uv: np.ndarray) -> np.ndarray:
        """Nearest texel (N, 3) of the map at uv (pbrt-v4 reads its map by nearest texel, as here); white
        without a map (pbrt's map of one texel)."""
        if self.image is None:
            return np.ones((len(uv), 3), np.float32)
        return np.asarray(self.image).reshape(-1, 3)[self.texel_index(uv)]

    def texel_index(self, uv: np.ndarray) -> np.ndarray:
        """The row-major index (N,) int64 of the map's nearest texel at uv (``texels``' texel, and the
        cell of a ``Distribution2D`` over the map); the map must exist."""
        assert self.image is not None
        h, w = self.image.shape[:2]
        x = np.clip((np.asarray(uv[:, 0]) * w).astype(np.int64), 0, w - 1)
        y = np.clip((np.asarray(uv[:, 1]) * h).astype(np.int64), 0, h - 1)
        return y * w + x


@dataclass(frozen=True, eq=False)
class EmissiveInstance:
    """Instance ``Scene.instances[instance]`` emits ``radiance`` from its front faces (both with
    ``two_sided``) and still reflects by its material: pbrt's area light on an arbitrary shape.
    ``sphere``: the world centre and radius of the sphere the instance's mesh is inscribed in when it
    tessellates one (``sphere_in_world``), which the renderer samples by the cone it subtends."""

    instance: int
    radiance: RGB
    two_sided: bool = False
    sphere: tuple[tuple[float, float, float], float] | None = None

    def __post_init__(self) -> None:
        validation.emission(self.radiance, "area light radiance")
        if self.sphere is not None:
            centre, radius = self.sphere
            for value in centre:
                validation.finite(value, "emitting sphere centre")
            if not validation.finite(radius, "emitting sphere radius") > 0:
                raise UserError(f"emitting sphere radius must be positive, got {radius:g}")

    def power(self, area: float) -> float:
        return math.pi * area * (2.0 if self.two_sided else 1.0) * float(np.mean(self.radiance))


def sphere_in_world(transform: np.ndarray, radius: float) -> tuple[tuple[float, float, float], float] | None:
    """World centre and radius of the sphere of ``radius`` about the object-space origin that the
    affine ``transform`` places; None where the transform is no similarity (it makes an ellipsoid)."""
    m = np.asarray(transform, np.float64)
    linear = m[:3, :3]
    with np.errstate(all="ignore"):
        gram = linear.T @ linear
        scale2 = float(np.trace(gram)) / 3.0
        similar = 0 < scale2 < np.inf and np.allclose(gram, scale2 * np.eye(3), rtol=0.0, atol=1e-9 * scale2)
    if not (similar and np.all(np.isfinite(m[:3, 3]))):
        return None
    return (float(m[0, 3]), float(m[1, 3]), float(m[2, 3])), float(radius) * math.sqrt(scale2)


Light = AreaLight | PointLight | SpotLight | DistantLight | InfiniteLight | EmissiveInstance


def latlong_uv(w: np.ndarray) -> np.ndarray:
    """pbrt-v3's (phi / 2 pi, theta / pi) of unit vectors w (N, 3), theta measured from +z."""
    phi = np.arctan2(w[:, 1], w[:, 0])
    phi = np.where(phi < 0, phi + 2 * math.pi, phi)
    theta = np.arccos(np.clip(w[:, 2], -1.0, 1.0))
    return np.column_stack([phi / (2 * math.pi), theta / math.pi])


def latlong_direction(uv: np.ndarray) -> np.ndarray:
    """Inverse of ``latlong_uv``."""
    phi, theta = uv[:, 0] * 2 * math.pi, uv[:, 1] * math.pi
    s = np.sin(theta)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)])


def equal_area_square_to_sphere(uv: np.ndarray) -> np.ndarray:
    """Clarberg's octahedral equal-area map of [0, 1]^2 onto the unit sphere (as pbrt-v4's)."""
    u, v = 2.0 * uv[:, 0] - 1.0, 2.0 * uv[:, 1] - 1.0
    up, vp = np.abs(u), np.abs(v)
    signed = 1.0 - (up + vp)
    r = 1.0 - np.abs(signed)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(r == 0, 1.0, (vp - up) / r + 1.0) * (math.pi / 4)
    z = np.copysign(1.0 - r * r, signed)
    radial = r * np.sqrt(np.maximum(0.0, 2.0 - r * r))
    return np.column_stack([np.copysign(np.cos(phi), u) * radial, np.copysign(np.sin(phi), v) * radial, z])


def equal_area_sphere_to_square(w: np.ndarray) -> np.ndarray:
    """Inverse of ``equal_area_square_to_sphere`` for unit vectors w (N, 3)."""
    x, y, z = np.abs(w[:, 0]), np.abs(w[:, 1]), np.abs(w[:, 2])
    r = np.sqrt(np.maximum(0.0, 1.0 - z))
    a, b = np.maximum(x, y), np.minimum(x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(a == 0, 0.0, b / a)
    phi = np.arctan(ratio) * (2.0 / math.pi)
    phi = np.where(x < y, 1.0 - phi, phi)
    v = phi * r
    u = r - v
    south = w[:, 2] < 0
    u, v = np.where(south, 1.0 - v, u), np.where(south, 1.0 - u, v)
    u, v = np.copysign(u, w[:, 0]), np.copysign(v, w[:, 1])
    return np.column_stack([(u + 1.0) / 2.0, (v + 1.0) / 2.0])
