"""Autofocus: the focus distance that makes the scene point seen at a pixel sharp.

1. The pixel centre's chief ray (aimed at the middle of its exit-pupil box, or the mean of the rays
   that pass when that one is vignetted) is traced through the lens into the scene; its first hit,
   found by the caller's ``hit_distance`` (the scene's intersector), gives the depth (mm from the
   film along the axis).
2. Thick-lens focusing gives a first film distance for that depth.
3. A real-ray search refines it: for each candidate film distance, a fixed bundle of rays from the
   pixel's film point through the rear element is traced, and the spread (RMS radius) of the
   bundle where it reaches the depth plane is minimised by golden-section search. That includes
   the lens's spherical aberration and field curvature, which the thick-lens model ignores.

The result is a focus distance (mm from the film) that thick-lens focusing maps back to the
refined film distance exactly, so callers build their camera as for any ``--focus``.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from realistic.camera.base import HitDistance
from realistic.core.transforms import transform_points, transform_vectors
from realistic.errors import UserError
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, focus_distance_for_film
from realistic.optics.sampling import ExitPupilTable, rear_element_sampler
from realistic.optics.tracer import trace_from_film

BUNDLE = 4096
GOLDEN = (math.sqrt(5) - 1) / 2


class FocusableCamera(Protocol):
    """What autofocus reads of a camera (``camera.lens_camera.LensCamera`` has it all; that module
    calls this one, so this one names only the attributes it needs)."""

    # Read-only (properties), as the frozen dataclass that implements them holds them.
    @property
    def lens(self) -> LensSystem: ...

    @property
    def film_distance_mm(self) -> float: ...

    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...

    @property
    def pupil(self) -> ExitPupilTable:
        """The exit-pupil table at this focus."""

    @property
    def world_from_lens(self) -> np.ndarray:
        """(4, 4) from the lens frame to world units."""

    def film_points(self, pixel: np.ndarray, u_x: np.ndarray, u_y: np.ndarray) -> np.ndarray:
        """Film points (N, 2) in mm for pixels and raster offsets from their corner."""


def _pixel_film_point(camera: FocusableCamera, x: float, y: float) -> np.ndarray:
    if not (0 <= x < camera.width and 0 <= y < camera.height):
        raise UserError(f"focus pixel ({x:g}, {y:g}) is outside the {camera.width}x{camera.height} image")
    pixel = np.array([int(y) * camera.width + int(x)])
    return camera.film_points(pixel, np.array([x % 1 or 0.5]), np.array([y % 1 or 0.5]))[0]


def _chief_ray(camera: FocusableCamera, film_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origin and direction (lens frame) of the ray through the middle of the pixel's pupil."""
    rng = np.random.default_rng(0)
    u = np.concatenate([[0.5], rng.random(BUNDLE)])
    v = np.concatenate([[0.5], rng.random(BUNDLE)])
    film = np.tile(film_xy, (len(u), 1))
    targets, _ = camera.pupil.sample(film, u, v)
    start = np.column_stack([film, np.zeros(len(u))])
    traced = trace_from_film(camera.lens, camera.film_distance_mm, start, targets - start)
    if traced.passed[0]:
        return traced.origin[0], traced.direction[0]
    if not traced.passed.any():
        raise UserError("the focus pixel lies outside the lens's image circle: no ray passes there")
    direction = traced.direction[traced.passed].mean(axis=0)
    return traced.origin[traced.passed].mean(axis=0), direction / np.linalg.norm(direction)


def _depth_mm(camera: FocusableCamera, origin: np.ndarray, direction: np.ndarray, hit_distance: HitDistance) -> float:
    to_world = camera.world_from_lens
    world_origin = transform_points(to_world, origin)
    world_direction = transform_vectors(to_world, direction)
    world_direction /= np.linalg.norm(world_direction)
    distance = hit_distance(world_origin, world_direction)
    if distance is None:
        raise UserError("nothing at the focus pixel to focus on (its ray leaves the scene)")
    hit = world_origin + distance * world_direction
    return float(transform_points(np.linalg.inv(to_world), hit)[2])


def bundle_spread_mm(lens: LensSystem, film_distance_mm: float, film_xy: np.ndarray, depth_mm: float,
                     u: np.ndarray, v: np.ndarray) -> float:
    """RMS radius of the rays from a film point where they reach the plane z = depth (lens frame)."""
    sampler = rear_element_sampler(lens, film_distance_mm)
    film = np.tile(film_xy, (len(u), 1))
    targets, _ = sampler.sample(film, u, v)
    start = np.column_stack([film, np.zeros(len(u))])
    traced = trace_from_film(lens, film_distance_mm, start, targets - start)
    if traced.passed.sum() < 8:
        return math.inf
    o, d = traced.origin[traced.passed], traced.direction[traced.passed]
    at = o[:, :2] + d[:, :2] * ((depth_mm - o[:, 2:3]) / d[:, 2:3])
    return float(np.sqrt(np.mean(np.sum((at - at.mean(axis=0)) ** 2, axis=1))))


def autofocus_distance_mm(camera: FocusableCamera, x: float, y: float, hit_distance: HitDistance) -> float:
    """Focus distance (mm from the film) at which the point seen at raster (x, y) is sharpest."""
    film_xy = _pixel_film_point(camera, x, y)
    depth = _depth_mm(camera, *_chief_ray(camera, film_xy), hit_distance)
    lens = camera.lens
    start = film_distance_for_focus(lens, depth)
    rng = np.random.default_rng(1)
    u, v = rng.random(BUNDLE), rng.random(BUNDLE)
    lo, hi = start * 0.97, start * 1.03
    a, b = hi - GOLDEN * (hi - lo), lo + GOLDEN * (hi - lo)
    fa, fb = (bundle_spread_mm(lens, d, film_xy, depth, u, v) for d in (a, b))
    while hi - lo > 1e-5 * start:
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - GOLDEN * (hi - lo)
            fa = bundle_spread_mm(lens, a, film_xy, depth, u, v)
        else:
            lo, a, fa = a, b, fb
            b = lo + GOLDEN * (hi - lo)
            fb = bundle_spread_mm(lens, b, film_xy, depth, u, v)
    return focus_distance_for_film(lens, (lo + hi) / 2)
