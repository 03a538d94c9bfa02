"""What a pixel filter costs: camera ray generation and a whole render, per filter.

Filter importance sampling adds work only to ray generation (a closed-form offset for box and
triangle, a 256-bin table search for the others); accumulation is unchanged. For each filter
(at pbrt-v4's default parameters, and the 0.5-pixel box) it prints the OpenCL kernel's rays/s
(median of ``--repeats`` launches of ``--rays`` rays, dgauss, exit-pupil sampling, build excluded)
and the seconds of one render of the default scene (its program built beforehand), and writes them
as JSON.

    python bench/pixel_filter.py [--rays 4000000] [--res 160x120] [--spp 16] [--out bench/results/pixel_filter.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import realistic as rl  # noqa: E402
from realistic.camera.base import SampleBlock  # noqa: E402
from realistic.camera.opencl_host import LensKernel  # noqa: E402
from realistic.core.pixel_filter import PIXEL_BOX  # noqa: E402
from realistic.renderer.inputs import MESH_FILTER_DIALECT  # noqa: E402

FILTERS = ("box", "triangle", "gaussian", "mitchell", "sinc")


def kernel_rate(camera: rl.LensCamera, rays: int, repeats: int) -> float:
    """Median M rays/s of ``repeats`` launches of ``rays`` rays (the program is built first)."""
    kernel = LensKernel(camera)
    kernel.generate(SampleBlock(0, 1024, camera.spp))
    times = []
    for seed in range(repeats):
        start = time.perf_counter()
        kernel.generate(SampleBlock(0, rays, camera.spp), seed)
        times.append(time.perf_counter() - start)
    return rays / statistics.median(times) / 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=4_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--res", default="160x120")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "pixel_filter.json")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.res.split("x"))
    scene = rl.load_scene(None, resolution=(width, height), spp=args.spp)
    base = scene.camera
    # the kernel launch needs as many sample ids as rays: a camera with enough samples per pixel
    launch_camera = dataclasses.replace(base, spp=max(args.spp, -(-args.rays // (width * height))))
    rl.render(scene, base)  # warm-up: exit-pupil table, thread start
    rows = []
    header = f"{'filter':<52} {'kernel M rays/s':>16} {'render s':>9}"
    print(header)
    print("-" * len(header))
    for name in ("box 0.5 (default)", *FILTERS):
        pixel_filter = PIXEL_BOX if name.startswith("box 0.5") else MESH_FILTER_DIALECT.pixel_filter(name)
        rate = kernel_rate(dataclasses.replace(launch_camera, pixel_filter=pixel_filter), args.rays, args.repeats)
        camera = dataclasses.replace(base, pixel_filter=pixel_filter)
        rl.render(scene, camera)  # builds this filter's kernel program (cold, ~0.5 s) outside the timing
        start = time.perf_counter()
        rl.render(scene, camera)
        seconds = time.perf_counter() - start
        rows.append({"filter": pixel_filter.describe(), "kernel_mrays_per_s": rate, "render_s": seconds})
        print(f"{pixel_filter.describe():<52} {rate:>16.1f} {seconds:>9.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": platform.processor() or platform.machine(), "rays": args.rays,
                                    "resolution": [width, height], "spp": args.spp, "rows": rows}, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
