"""Convergence in sample count: render one scene at several spp, time each, measure the error.

RMSE is against a reference image when one is given, else against the render with the most
samples (whose own row then reads 0). ``measure_sample_counts`` returns rows; the ``bench``
command prints them and ``realistic.renderer.convergence_plot`` draws them.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from realistic.camera.base import Camera
from realistic.errors import UserError
from realistic.renderer.passes import render_passes
from realistic.scene.model import Scene


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root-mean-square difference over all pixels and channels."""
    if image.shape != reference.shape:
        raise UserError(f"the reference image is {reference.shape[1]}x{reference.shape[0]}, "
                        f"the render {image.shape[1]}x{image.shape[0]}: they must match")
    return float(np.sqrt(np.mean((image.astype(np.float64) - reference.astype(np.float64)) ** 2)))


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """RMSE over all pixels and channels divided by the reference's mean (one scale for the image,
    not per pixel), as the convergence benches quote it."""
    return rmse(image, reference) / float(np.mean(reference, dtype=np.float64))


def two_seed_noise(first: np.ndarray, second: np.ndarray) -> float:
    """Relative RMSE of one render against its converged image, from two renders that differ only in
    seed: independent, unbiased estimates a and b of the same image give E[(a - b)^2] = 2 var, so
    sqrt(mean((a - b)^2) / 2) over the mean needs no reference and carries none of its noise."""
    mean = float(np.mean(0.5 * (first.astype(np.float64) + second.astype(np.float64))))
    return rmse(first, second) / math.sqrt(2.0) / mean


def measure_sample_counts(scene: Scene, camera: Camera, spp_list: list[int], backend: str = "opencl", seed: int = 0,
                          light_samples: int = 1, reference: np.ndarray | None = None,
                          cl_device: str | None = None, progress: bool = True,
                          max_memory_bytes: int | None = None, client=None,
                          threads: int | None = None, pin_threads: bool = False) -> tuple[list[dict], np.ndarray]:
    """Rows of seconds, camera rays/s, vignetted fraction and RMSE per spp, and the last image.

    An untimed 1 spp render first pays the one-time costs (kernel build, exit-pupil table), so each
    row times rendering alone. ``client`` (a ``dask.distributed.Client``) renders on its workers,
    else ``threads`` (None: ``default_threads()``) in this process, each on one CPU unless not ``pin_threads``.
    """
    render_passes(scene, dataclasses.replace(camera, spp=1), backend, seed, cl_device, light_samples,
                  threads=threads, max_memory_bytes=max_memory_bytes, client=client, pin_threads=pin_threads)
    rows, images = [], []
    for spp in spp_list:
        result = render_passes(scene, dataclasses.replace(camera, spp=spp), backend, seed, cl_device,
                               light_samples, threads=threads, progress=progress,
                               max_memory_bytes=max_memory_bytes, client=client, pin_threads=pin_threads)
        if result.interrupted:
            raise UserError(f"interrupted during the {spp} spp render")
        seconds = max(result.seconds, 1e-9)
        camera_rays = result.samples_done * camera.rays_per_sample  # a spectral sample is K rays
        rows.append({"spp": spp, "seconds": result.seconds, "camera_rays_per_second": camera_rays / seconds,
                     "vignetted_fraction": 1.0 - result.primary_rays / max(camera_rays, 1),
                     "shadow_rays": result.shadow_rays})
        images.append(result.image)
    target = reference if reference is not None else images[int(np.argmax(spp_list))]
    for row, image in zip(rows, images):
        row["rmse"] = rmse(image, target)
    return rows, images[-1]


def convergence_slope(rows: list[dict]) -> float:
    """Least-squares slope of log RMSE against log spp (about -0.5 for Monte Carlo)."""
    shown = [r for r in rows if r["rmse"] > 0]
    if len(shown) < 2:
        return math.nan
    x = np.log([r["spp"] for r in shown])
    y = np.log([r["rmse"] for r in shown])
    return float(np.polyfit(x, y, 1)[0])
