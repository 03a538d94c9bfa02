"""A scene's area lights (disks and quads) as per-light row tables, and points drawn on them by area.

Both integrators sample area lights through this one table: ``DirectLighting`` (the fast path, and
its OpenCL kernel's light rows) and ``LightSampler`` (MIS and path tracing). A light's points are
c + a x + b y (``AreaLight.frame``), with (x, y) uniform on the unit disk (Shirley-Chiu's concentric
map) or on [-1, 1]^2, so uniform by area: the density of a point is 1 / ``area``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from realistic.core.warp import concentric_disk
from realistic.scene.model import AreaLight


def light_outward_flipped(light: AreaLight) -> bool:
    """Whether the outside of an area light's surface, which its material sees (glass: the side it
    enters from), is opposite its tessellation's world winding (``scene.shapes.light_mesh``, wound
    to face +z in object space): under a mirroring transform, xor ReverseOrientation. That makes it
    the side the light emits from (``AreaLight.frame``) and the side the same shape has without the
    light, whose mesh the pbrt importer winds the other way under ReverseOrientation: pbrt hands a
    shape the same ``reverseOrientation`` whether or not it emits (pbrt-v3 ``pbrtShape`` in
    ``src/core/api.cpp``; pbrt-v4 ``BasicScene::CreateLights`` and ``CreateAggregate`` in
    ``src/pbrt/scene.cpp``), and a disk's normal flips by it (pbrt-v3 ``src/shapes/disk.cpp`` through
    ``SurfaceInteraction``'s constructor, ``src/core/interaction.cpp``; pbrt-v4 ``Disk`` in
    ``src/pbrt/shapes.h``, ``flipNormal``)."""
    return bool(np.linalg.det(np.asarray(light.transform, np.float64)[:3, :3]) < 0) != light.reverse_orientation


@dataclass(frozen=True, eq=False)
class AreaLightTable:
    """Row j describes area light j: world frame (centre, axes a and b, unit emitting normal; float32
    (L, 3)), whether it is a disk and two-sided, its area (float64) and RGB radiance (float32 (L, 3))."""

    centre: np.ndarray
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    disk: np.ndarray
    two_sided: np.ndarray
    area: np.ndarray
    radiance: np.ndarray

    @classmethod
    def of(cls, lights: list[AreaLight]) -> AreaLightTable:
        """The table of ``lights`` (a scene's ``area_lights``), in their order."""
        frames = [light.frame() for light in lights]
        return cls(centre=np.array([f[0] for f in frames], np.float32).reshape(-1, 3),
                   a=np.array([f[1] for f in frames], np.float32).reshape(-1, 3),
                   b=np.array([f[2] for f in frames], np.float32).reshape(-1, 3),
                   normal=np.array([f[3] for f in frames], np.float32).reshape(-1, 3),
                   disk=np.array([light.shape == "disk" for light in lights], bool),
                   two_sided=np.array([light.two_sided for light in lights], bool),
                   area=np.array([light.area() for light in lights], np.float64),
                   radiance=np.array([light.radiance for light in lights], np.float32).reshape(-1, 3))

    def __len__(self) -> int:
        return len(self.area)

    def points(self, slot: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
        """Points (N, 3) float32 on lights ``slot`` (N,), uniform by area for (u1, u2) uniform on [0, 1)^2."""
        dx, dy = concentric_disk(u1, u2)
        disk = self.disk[slot]
        x = np.where(disk, dx, 2.0 * u1 - 1.0).astype(np.float32)[:, None]
        y = np.where(disk, dy, 2.0 * u2 - 1.0).astype(np.float32)[:, None]
        return (np.take(self.centre, slot, axis=0) + np.take(self.a, slot, axis=0) * x
                + np.take(self.b, slot, axis=0) * y)
