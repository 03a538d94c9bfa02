"""Throughput of camera ray generation: the OpenCL kernel against numpy in float64 and float32.

For each bundled lens and both lens samplers it prints kernel rays/s at 1M and 16M rays per launch
(copy back to host included, the one-time build reported separately, with the rays each work item
traces: ``LensKernel`` times its choices at a configuration's first build), the float64 numpy reference
(``LensCamera.generate_rays``) and a float32 numpy version of the same mathematics (below, written for
this benchmark), and the fraction of rays that pass the lens. numpy runs on one core in chunks
of at most 1M rays and is measured on fewer rays than the kernel (``--numpy-rays``) and
extrapolated as a rate: its cost per ray does not depend on the launch size.

    python bench/lens_kernel.py [--lenses dgauss wide] [--out bench/results/lens_kernel.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic import load_lens  # noqa: E402
from realistic.camera.base import SampleBlock  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402
from realistic.camera.opencl_host import LensKernel  # noqa: E402
from realistic.core import rng  # noqa: E402
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM  # noqa: E402
from realistic.optics.dispersion import D_LINE_NM, refractive_index  # noqa: E402
from realistic.optics.formats import BUNDLED_LENSES  # noqa: E402
from realistic.optics.paraxial import film_distance_for_focus  # noqa: E402
from realistic.optics.sampling import rear_element_sampler  # noqa: E402

F32 = np.float32
CHUNK = 1 << 20


def _surface_f32(o, d, vertex_z: float, radius: float, eta: float, refracts: bool):
    """One surface in float32, the reference's rules: (hit, new direction, blocked-before-aperture)."""
    ox, oy, oz = o
    dx, dy, dz = d
    if radius == 0 or not np.isfinite(radius):
        t = (F32(vertex_z) - oz) / dz
        dead = ~(t > 0)
        hit = (ox + t * dx, oy + t * dy, oz + t * dz)
        nx = ny = np.zeros_like(dz)
        nz = -np.sign(dz)
    else:
        centre = F32(vertex_z - radius)
        ocz = oz - centre
        b = ox * dx + oy * dy + ocz * dz
        c = ox * ox + oy * oy + ocz * ocz - F32(radius * radius)
        disc = b * b - c
        root = np.sqrt(np.maximum(disc, F32(0)))
        t = np.where((dz > 0) == (radius < 0), -b - root, -b + root)
        hit = (ox + t * dx, oy + t * dy, oz + t * dz)
        cz = hit[2] - centre
        dead = (disc < 0) | ~(t > 0) | (cz * F32(radius) <= 0)
        scale = np.where(hit[0] * dx + hit[1] * dy + cz * dz > 0, F32(-1), F32(1)) * F32(1 / abs(radius))
        nx, ny, nz = hit[0] * scale, hit[1] * scale, cz * scale
    if refracts:
        e = F32(eta)
        c1 = -(dx * nx + dy * ny + dz * nz)
        c2sq = F32(1) - e * e * (F32(1) - c1 * c1)
        dead |= c2sq < 0
        k = e * c1 - np.sqrt(np.maximum(c2sq, F32(0)))
        tx, ty, tz = e * dx + k * nx, e * dy + k * ny, e * dz + k * nz
        inv = F32(1) / np.sqrt(tx * tx + ty * ty + tz * tz)
        d = (tx * inv, ty * inv, tz * inv)
    return hit, d, dead


def generate_rays_f32(camera: LensCamera, first: int, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """generate_rays in float32 numpy (world transform left out); returns (direction (3, N), weight)."""
    lens = camera.lens
    pixel, sample = SampleBlock(first, count, camera.spp).ids()
    u_x, u_y, u_lens, v_lens = rng.stratified4(pixel, sample, seed)
    w_mm, h_mm = camera.film_size_mm
    fx = -(((pixel % camera.width).astype(F32) + u_x) / F32(camera.width) - F32(0.5)) * F32(w_mm)
    fy = (((pixel // camera.width).astype(F32) + u_y) / F32(camera.height) - F32(0.5)) * F32(h_mm)
    rho = np.sqrt(fx * fx + fy * fy)
    if camera.lens_sampling == "pupil":
        table = camera.pupil
        k = np.minimum((rho * F32(len(table.bounds) / table.film_radius_mm)).astype(np.int32), len(table.bounds) - 1)
        box = table.bounds.astype(F32)[k]
        x = box[:, 0] + u_lens * (box[:, 1] - box[:, 0])
        y = box[:, 2] + v_lens * (box[:, 3] - box[:, 2])
        safe = np.where(rho > 0, rho, F32(1))
        cos_phi, sin_phi = np.where(rho > 0, fx / safe, F32(1)), np.where(rho > 0, fy / safe, F32(0))
        px, py = x * cos_phi - y * sin_phi, x * sin_phi + y * cos_phi
        area, plane_z = table.area_mm2().astype(F32)[k], table.plane_z_mm
    else:
        rear = rear_element_sampler(lens, camera.film_distance_mm)
        t_far = F32(rear.plane_z_mm / rear.far_z_mm)
        radius = np.maximum(F32(rear.clear_radius_mm), rho * (1 - t_far) + F32(rear.clear_radius_mm) * t_far)
        disk_x, disk_y = _concentric_disk_f32(u_lens, v_lens)
        px, py = disk_x * radius, disk_y * radius
        area, plane_z = F32(np.pi) * radius * radius, rear.plane_z_mm
    dx, dy, dz = px - fx, py - fy, np.full_like(fx, F32(plane_z))
    len2 = dx * dx + dy * dy + dz * dz
    weight = area * F32(plane_z * plane_z) / (len2 * len2)
    inv = F32(1) / np.sqrt(len2)
    o, d = (fx, fy, np.zeros_like(fx)), (dx * inv, dy * inv, dz * inv)
    dead = np.zeros(count, dtype=bool)
    vertex_z = lens.vertex_z_mm(camera.film_distance_mm)
    index = refractive_index(lens.index_d, lens.abbe_v, D_LINE_NM)
    for i in range(lens.surface_count - 1, -1, -1):
        eta = index[i] / (index[i - 1] if i > 0 else 1.0)
        o, d, blocked = _surface_f32(o, d, vertex_z[i], lens.radius_mm[i], eta, i != lens.stop)
        dead |= blocked | ~(o[0] * o[0] + o[1] * o[1] <= F32((lens.aperture_mm[i] / 2) ** 2))
    return np.where(dead, F32(0), np.stack(d)), np.where(dead, F32(0), weight)


def _concentric_disk_f32(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """realistic.sampling.concentric_disk in float32."""
    a, b = F32(2) * u1 - F32(1), F32(2) * u2 - F32(1)
    first = np.abs(a) > np.abs(b)
    r = np.where(first, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(first, F32(np.pi / 4) * (b / a), F32(np.pi / 2) - F32(np.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), F32(0), phi)
    return r * np.cos(phi), r * np.sin(phi)


def _rate(run, rays: int, repeats: int) -> float:
    """Best rays/s over ``repeats`` calls of run()."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return rays / best


def _reference(camera: LensCamera, first: int, count: int, seed: int):
    """The float64 reference on sample ids first .. first + count - 1."""
    return camera.generate_rays(SampleBlock(first, count, camera.spp), seed)


def _chunked(fn, camera: LensCamera, count: int):
    return lambda: [fn(camera, s, min(CHUNK, count - s), 0) for s in range(0, count, CHUNK)]


def bench_one(name: str, sampling: str, sizes: list[int], numpy_rays: int, repeats: int) -> dict:
    lens = load_lens(name)
    film = film_distance_for_focus(lens, 5000.0)
    camera = LensCamera(lens, film, FULL_FRAME_DIAGONAL_MM, 1920, 1080,
                        spp=max(1, -(-2 * max(sizes) // (1920 * 1080))), lens_sampling=sampling)
    start = time.perf_counter()
    kernel = LensKernel(camera)
    kernel.generate(SampleBlock(0, 256, camera.spp), 0)  # PoCL compiles the work-group function at the first launch
    build_s = time.perf_counter() - start
    row = {"lens": name, "sampling": sampling, "build_s": build_s, "rays_per_item": kernel.rays_per_item,
           "kernel_rays_per_s": {}, "pass_fraction": None}
    for size in sizes:
        kernel.generate(SampleBlock(size, size, camera.spp), 0)  # warm: buffers of this size
        block = SampleBlock(0, size, camera.spp)
        row["kernel_rays_per_s"][str(size)] = _rate(lambda block=block: kernel.generate(block, 0), size, repeats)
    batch = kernel.generate(SampleBlock(0, max(sizes), camera.spp), 0)
    row["pass_fraction"] = float(np.mean(np.any(batch.direction != 0, axis=1)))
    row["numpy_f64_rays_per_s"] = _rate(_chunked(_reference, camera, numpy_rays), numpy_rays, 1)
    # the float32 numpy version below knows spheres only: no figure for an aspheric lens
    row["numpy_f32_rays_per_s"] = (None if lens.aspheric.any() else
                                   _rate(_chunked(generate_rays_f32, camera, numpy_rays), numpy_rays, 2))
    row["numpy_rays_measured"] = numpy_rays
    return row


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lenses", nargs="+", default=list(BUNDLED_LENSES), choices=list(BUNDLED_LENSES))
    parser.add_argument("--samplings", nargs="+", default=["pupil", "rear"], choices=["pupil", "rear"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[1 << 20, 1 << 24], help="rays per launch")
    parser.add_argument("--numpy-rays", type=int, default=1 << 20, help="rays numpy is timed on")
    parser.add_argument("--repeats", type=int, default=3, help="kernel timings per size (best is kept)")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "lens_kernel.json")
    args = parser.parse_args(argv)

    rows = []
    sizes_m = [f"{s / 2**20:g}M" for s in args.sizes]
    header = (f"{'lens':<10} {'sampler':<6} {'build s':>7} {'/item':>5} "
              + " ".join(f"{'cl ' + m + ' M/s':>12}" for m in sizes_m)
              + f" {'np64 M/s':>9} {'np32 M/s':>9} {'cl/np32':>8} {'pass':>6}")
    print(header)
    print("-" * len(header))
    for name in args.lenses:
        for sampling in args.samplings:
            row = bench_one(name, sampling, args.sizes, args.numpy_rays, args.repeats)
            rows.append(row)
            kernel = [row["kernel_rays_per_s"][str(s)] / 1e6 for s in args.sizes]
            f32 = row["numpy_f32_rays_per_s"]
            print(f"{name:<10} {sampling:<6} {row['build_s']:>7.2f} {row['rays_per_item']:>5} "
                  + " ".join(f"{k:>12.1f}" for k in kernel)
                  + f" {row['numpy_f64_rays_per_s'] / 1e6:>9.2f}"
                  + (f" {f32 / 1e6:>9.2f} {min(kernel) / (f32 / 1e6):>7.1f}x" if f32 else f" {'-':>9} {'-':>8}")
                  + f" {row['pass_fraction']:>6.3f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": platform.processor() or platform.machine(),
                                    "numpy_note": f"numpy timed on {args.numpy_rays} rays, one core, chunks of "
                                                  f"{CHUNK}; rates extrapolate to any launch size",
                                    "results": rows}, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
