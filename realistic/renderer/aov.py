"""Arbitrary output variables: what each pixel's camera rays first hit (depth, normal, albedo, position).

The channels and their conventions are pbrt-v4's ``GBufferFilm`` (``src/pbrt/film.cpp``,
``GBufferFilm::AddSample`` and ``GetImage``), so a pbrt user's tools read them unchanged:

- ``position``: "P.X", "P.Y", "P.Z", the hit point in camera space, in the scene's units (the
  camera's axes, +z toward the scene, origin where the scene's camera puts it: ``LensCamera.origin``),
  averaged over the samples that hit something (pbrt-v4 divides by ``gBufferWeightSum``);
- ``depth``: "P.Z" alone, pbrt-v4's depth (it has no other depth channel);
- ``normal``: "N.X", "N.Y", "N.Z", the geometric normal turned toward the camera ray, in camera
  space: the normalised weighted sum (pbrt-v4 ``Normalize(nSum)``);
- ``albedo``: "Albedo.R", "Albedo.G", "Albedo.B", the surface's reflectance at the hit (a matte
  material's Kd, textures included; other BSDFs' directional albedo, ``PathIntegrator.first_albedo``),
  averaged over every sample (pbrt-v4 divides by ``weightSum``).

Rays that miss contribute nothing, as in pbrt-v4 (no ``VisibleSurface``): a pixel that sees only
background has depth, position and normal 0, and a pixel partly on background keeps the depth of
what it does see while its albedo is diluted by the misses. Each sample counts with its pixel-filter
weight's sign (the camera's weight is sign(f) |integral f| / integral f times positive radiometric
factors, and pbrt-v4's GBuffer sums use the filter weight alone): the magnitude cancels in every
ratio above. Vignetted samples (weight 0) carry no hit and count in neither sum.

Per pass the runner adds, per pixel, float64 sums of these per-sample values (``AovLayout.values``)
as extra columns after the radiance's three, so they go through ``film.PassFilm`` (plan order,
bit-identical whatever the executor), the farm and checkpoints with the radiance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Film columns before the AOVs': the radiance's R, G, B sums.
RADIANCE_COLUMNS = 3


@dataclass(frozen=True)
class FirstHits:
    """What N camera rays hit first, in world space: ``hit`` (N,) bool, and where it is True the hit
    ``point`` (N, 3), the unit geometric ``normal`` (N, 3) facing the ray and the ``albedo`` (N, 3)."""

    hit: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray


@dataclass(frozen=True)
class CameraFrame:
    """Camera space in the scene's units: p_camera = rotation @ (p_world - origin) (``of``)."""

    rotation: np.ndarray  # (3, 3) orthogonal: world directions to camera axes
    origin: np.ndarray  # (3,) camera space's origin in world units

    @classmethod
    def of(cls, world_from_camera: np.ndarray) -> CameraFrame:
        """The frame of a camera's ``world_from_camera`` (4, 4), with its scale (a lens camera's mm
        per scene unit) taken out, so that positions and depths are in scene units."""
        matrix = np.asarray(world_from_camera, np.float64)
        linear = matrix[:3, :3] / np.linalg.norm(matrix[:3, 0])
        return cls(np.linalg.inv(linear), matrix[:3, 3].copy())

    def points(self, world: np.ndarray) -> np.ndarray:
        return (np.asarray(world, np.float64) - self.origin) @ self.rotation.T

    def directions(self, world: np.ndarray) -> np.ndarray:
        return np.asarray(world, np.float64) @ self.rotation.T


@dataclass(frozen=True)
class AovLayout:
    """The film columns of a set of AOVs (after the radiance's 3) and the EXR channels they make."""

    aovs: tuple[str, ...]

    @property
    def groups(self) -> tuple[tuple[str, tuple[str, ...]], ...]:
        """(quantity, its channel names) in column order: quantities "albedo", "position", "normal"."""
        groups: list[tuple[str, tuple[str, ...]]] = []
        if "albedo" in self.aovs:
            groups.append(("albedo", ("Albedo.R", "Albedo.G", "Albedo.B")))
        if "position" in self.aovs:
            groups.append(("position", ("P.X", "P.Y", "P.Z")))
        elif "depth" in self.aovs:
            groups.append(("position", ("P.Z",)))
        if "normal" in self.aovs:
            groups.append(("normal", ("N.X", "N.Y", "N.Z")))
        return tuple(groups)

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(name for _, names in self.groups for name in names)

    @property
    def columns(self) -> int:
        """Film columns in all: radiance, the AOVs' channels, and the two weight sums (every sample's
        and the hitting samples') when there are AOVs."""
        return RADIANCE_COLUMNS + (len(self.channel_names) + 2 if self.aovs else 0)

    def values(self, hits: FirstHits, sign: np.ndarray, frame: CameraFrame) -> np.ndarray:
        """Per-sample values (N, columns - 3) float64 whose per-pixel sums are the AOV columns:
        each channel times the sample's filter sign (0 where nothing was hit), then the sign and
        the sign where something was hit."""
        sign = np.asarray(sign, np.float64)
        hit_sign = np.where(hits.hit, sign, 0.0)
        parts = []
        for quantity, names in self.groups:
            if quantity == "albedo":
                value = np.asarray(hits.albedo, np.float64)
            elif quantity == "position":
                value = frame.points(hits.point)[:, 3 - len(names):]
            else:
                value = frame.directions(hits.normal)
            parts.append(np.where(hits.hit[:, None], value, 0.0) * hit_sign[:, None])
        return np.column_stack([*parts, sign, hit_sign])

    def images(self, sums: np.ndarray, width: int, height: int) -> dict[str, np.ndarray]:
        """EXR channel name -> (height, width) float32 image, from the film's sums (pixels, columns)."""
        if not self.aovs:
            return {}
        every, hitting = sums[:, -2], sums[:, -1]
        out: dict[str, np.ndarray] = {}
        column = RADIANCE_COLUMNS
        for quantity, names in self.groups:
            block = sums[:, column:column + len(names)]
            column += len(names)
            if quantity == "normal":
                length = np.linalg.norm(block, axis=1, keepdims=True)
                value = np.divide(block, length, out=np.zeros_like(block), where=length > 0)
            else:
                weight = (every if quantity == "albedo" else hitting)[:, None]
                value = np.divide(block, weight, out=np.zeros_like(block), where=weight != 0)
            for index, name in enumerate(names):
                out[name] = value[:, index].reshape(height, width).astype(np.float32)
        return out
