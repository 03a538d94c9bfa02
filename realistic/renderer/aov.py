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
  material's Kd, textures included; other BSDFs' directional albedo, ``PathIntegrator.first_albedo``;
  an area light's material's too, while a pure emitter reads 0: ``DirectLighting.first_hits``),
  averaged over every sample (pbrt-v4 divides by ``weightSum``).

Rays that miss contribute nothing, as in pbrt-v4 (no ``VisibleSurface``): a pixel that sees only
background has depth, position and normal 0, and a pixel partly on background keeps the depth of
what it does see while its albedo is diluted by the misses. Each sample counts with its pixel-filter
weight's sign (the camera's weight is sign(f) |integral f| / integral f times positive radiometric
factors, and pbrt-v4's GBuffer sums use the filter weight alone): the magnitude cancels in every
ratio above. Vignetted samples (weight 0, never traced) count in neither sum.

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
        """World points (N, 3) in camera space, float64."""
        return (np.asarray(world, np.float64) - self.origin) @ self.rotation.T

    def directions(self, world: np.ndarray) -> np.ndarray:
        """World directions (N, 3) in camera space, float64."""
        return np.asarray(world, np.float64) @ self.rotation.T


#: Each quantity's three channels, in film column order.
CHANNELS = {"albedo": ("Albedo.R", "Albedo.G", "Albedo.B"), "position": ("P.X", "P.Y", "P.Z"),
            "normal": ("N.X", "N.Y", "N.Z")}


@dataclass(frozen=True)
class AovLayout:
    """The film columns of a set of AOVs (after the radiance's 3) and the EXR channels they make.

    Each quantity takes three columns of world-space sums (depth alone too: the camera's z is a
    mix of the world's three); camera space is applied to the per-pixel averages (``images``), as
    an affine map commutes with a weighted mean and a rotation with a normalisation."""

    aovs: tuple[str, ...]

    @property
    def quantities(self) -> tuple[str, ...]:
        """"albedo", "position", "normal" as the AOVs need them, in column order."""
        wanted = {"albedo": "albedo", "position": "position", "depth": "position", "normal": "normal"}
        return tuple(q for q in CHANNELS if any(wanted[name] == q for name in self.aovs))

    @property
    def channel_names(self) -> tuple[str, ...]:
        """The EXR channels, in order: depth alone is "P.Z" (pbrt-v4 has no other depth channel)."""
        names: list[str] = []
        for quantity in self.quantities:
            depth_only = quantity == "position" and "position" not in self.aovs
            names += ["P.Z"] if depth_only else CHANNELS[quantity]
        return tuple(names)

    @property
    def columns(self) -> int:
        """Film columns in all: radiance, three per quantity, and the two weight sums (every
        sample's and the hitting samples') when there are AOVs."""
        return RADIANCE_COLUMNS + (3 * len(self.quantities) + 2 if self.aovs else 0)

    def values(self, hits: FirstHits, sign: np.ndarray) -> np.ndarray:
        """Per-sample values (N, columns - 3) float64 whose per-pixel sums are the AOV columns:
        each quantity (world space) times the sample's filter sign where it hit something (misses
        add nothing), then the sign and the sign where something was hit. A transposed view of a
        (columns - 3, N) array: each column is contiguous, as the per-pixel sums read it."""
        out = np.empty((self.columns - RADIANCE_COLUMNS, len(hits.hit)), np.float64)
        out[-2] = sign
        np.multiply(out[-2], hits.hit, out=out[-1])
        sources = {"albedo": hits.albedo, "position": hits.point, "normal": hits.normal}
        for index, quantity in enumerate(self.quantities):
            block = out[3 * index:3 * index + 3]
            block[:] = sources[quantity].T
            block *= out[-1]
        return out.T

    def images(self, sums: np.ndarray, width: int, height: int, frame: CameraFrame) -> dict[str, np.ndarray]:
        """EXR channel name -> (height, width) float32 image from the film's sums (pixels, columns):
        albedo over every sample's weight, position over the hitting samples' (then in ``frame``'s
        camera space), normals normalised (then rotated into camera space); 0 where undefined."""
        if not self.aovs:
            return {}
        every, hitting = sums[:, -2:-1], sums[:, -1:]
        values: dict[str, np.ndarray] = {}
        for index, quantity in enumerate(self.quantities):
            block = sums[:, RADIANCE_COLUMNS + 3 * index:RADIANCE_COLUMNS + 3 * index + 3]
            if quantity == "albedo":
                value = np.divide(block, every, out=np.zeros_like(block), where=every != 0)
            elif quantity == "position":
                seen = hitting != 0
                mean = np.divide(block, hitting, out=np.zeros_like(block), where=seen)
                value = np.where(seen, frame.points(mean), 0.0)
            else:
                length = np.linalg.norm(block, axis=1, keepdims=True)
                value = frame.directions(np.divide(block, length, out=np.zeros_like(block), where=length > 0))
            values.update(zip(CHANNELS[quantity], value.T, strict=True))
        return {name: values[name].reshape(height, width).astype(np.float32) for name in self.channel_names}
