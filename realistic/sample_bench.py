"""Benchmark of sample counts: render one scene at several spp, time it, measure convergence.

RMSE is against a reference image when one is given, else against the render with the most
samples (whose own row then reads 0). Printing and plotting live here too, but apart from the
measuring: ``measure_sample_counts`` returns rows, ``format_table`` and ``plot_convergence`` show
them.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.render import render_passes
from realistic.scene import Scene


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root-mean-square difference over all pixels and channels."""
    if image.shape != reference.shape:
        raise UserError(f"the reference image is {reference.shape[1]}x{reference.shape[0]}, "
                        f"the render {image.shape[1]}x{image.shape[0]}: they must match")
    return float(np.sqrt(np.mean((image.astype(np.float64) - reference.astype(np.float64)) ** 2)))


def measure_sample_counts(scene: Scene, camera, spp_list: list[int], backend: str = "opencl", seed: int = 0,
                          light_samples: int = 1, reference: np.ndarray | None = None,
                          cl_device: str | None = None, progress: bool = True) -> tuple[list[dict], np.ndarray]:
    """Rows of seconds, camera rays/s, vignetted fraction and RMSE per spp, and the last image.

    An untimed 1 spp render first pays the one-time costs (kernel build, exit-pupil table), so each
    row times rendering alone.
    """
    render_passes(scene, dataclasses.replace(camera, spp=1), backend, seed, cl_device, light_samples)
    rows, images = [], []
    for spp in spp_list:
        result = render_passes(scene, dataclasses.replace(camera, spp=spp), backend, seed, cl_device,
                               light_samples, progress=progress)
        if result.interrupted:
            raise UserError(f"interrupted during the {spp} spp render")
        seconds = max(result.seconds, 1e-9)
        rows.append({"spp": spp, "seconds": result.seconds, "camera_rays_per_second": result.samples_done / seconds,
                     "vignetted_fraction": 1.0 - result.primary_rays / max(result.samples_done, 1),
                     "shadow_rays": result.shadow_rays})
        images.append(result.image)
    target = reference if reference is not None else images[int(np.argmax(spp_list))]
    for row, image in zip(rows, images):
        row["rmse"] = rmse(image, target)
    return rows, images[-1]


def format_table(rows: list[dict], against: str) -> str:
    lines = [f"{'spp':>6} {'seconds':>9} {'camera rays/s':>14} {'vignetted':>10} {'RMSE vs ' + against:>24}"]
    for r in rows:
        lines.append(f"{r['spp']:6d} {r['seconds']:9.2f} {r['camera_rays_per_second'] / 1e6:12.2f} M "
                     f"{r['vignetted_fraction']:10.3f} {r['rmse']:24.5g}")
    return "\n".join(lines)


def plot_convergence(rows: list[dict], out: Path, title: str) -> None:
    """Log-log RMSE against spp and against seconds, with a 1/sqrt(spp) guide."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [r for r in rows if r["rmse"] > 0]
    if not shown:
        raise UserError("nothing to plot: every render equals the reference")
    fig, (by_spp, by_time) = plt.subplots(1, 2, figsize=(10, 4))
    spp = np.array([r["spp"] for r in shown], dtype=float)
    error = np.array([r["rmse"] for r in shown])
    by_spp.loglog(spp, error, "o-", label="RMSE")
    by_spp.loglog(spp, error[0] * np.sqrt(spp[0] / spp), "--", color="grey", label="1/sqrt(spp)")
    by_spp.set_xlabel("samples per pixel")
    by_spp.set_ylabel("RMSE")
    by_spp.legend()
    by_time.loglog([r["seconds"] for r in shown], error, "o-")
    by_time.set_xlabel("seconds")
    for ax in (by_spp, by_time):
        ax.grid(True, which="both", alpha=0.3)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())  # decade labels only
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def parse_spp_list(text: str) -> list[int]:
    """``"1,4,16"`` -> [1, 4, 16]; each a positive integer."""
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or any(v < 1 for v in values):
        raise UserError(f"--spp {text!r} is not a comma-separated list of positive integers")
    return values


def convergence_slope(rows: list[dict]) -> float:
    """Least-squares slope of log RMSE against log spp (about -0.5 for Monte Carlo)."""
    shown = [r for r in rows if r["rmse"] > 0]
    if len(shown) < 2:
        return math.nan
    x = np.log([r["spp"] for r in shown])
    y = np.log([r["rmse"] for r in shown])
    return float(np.polyfit(x, y, 1)[0])
