"""Per-pass shading cost, numpy reference against the OpenCL kernel, on bench/render.py's scene.

    .venv/bin/python bench/shading.py [--res 512x512] [--spp 64] [--light-samples 1] [--repeats 7]

One pass of ``DEFAULT_PASS_SAMPLES`` samples from the middle of the render (the lens kernel's rays),
shaded on this thread by ``DirectLighting`` with backend numpy and with backend opencl, alternately;
prints the median milliseconds of the "shading" and "embree" stages per pass, and shading's share of
embree's.
The kernel's launch uses PoCL's threads (every core unless POCL_MAX_PTHREAD_COUNT says otherwise:
set it to 1 to compare single-threaded costs). Checks that the two backends' radiance agree to
1e-5 of the pass's largest value. Writes bench/results/shading.json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from realistic.renderer.backends import backend_for  # noqa: E402
from realistic.renderer.direct_lighting import DirectLighting  # noqa: E402
from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES  # noqa: E402
from realistic.renderer.timing import StageClock  # noqa: E402
from realistic.scene.intersect import Intersector  # noqa: E402
from render import middle_block, staged_subject  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", default="512x512")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--light-samples", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    setup, camera, source, _ = staged_subject("dgauss", width, height, args.spp)
    block = middle_block(camera, DEFAULT_PASS_SAMPLES)
    rays = backend_for("opencl").ray_generator(camera, 0)(block)
    alive = np.flatnonzero(rays.weight != 0)
    args_in = (rays.origin[alive].astype(np.float32), rays.direction[alive].astype(np.float32), rays.pixel[alive],
               block.ids()[1][alive])
    intersector = Intersector(setup.scene)
    threads = os.environ.get("POCL_MAX_PTHREAD_COUNT", "all cores")
    print(f"scene: {source}; {width}x{height}, {args.spp} spp; one pass of {DEFAULT_PASS_SAMPLES} samples "
          f"({len(alive)} camera rays), {args.light_samples} light sample(s); PoCL threads: {threads}")
    backends = ("numpy", "opencl")
    integrators = {backend: DirectLighting(setup.scene, intersector, args.light_samples, 0,
                                           camera.pixel_spread_radians(), backend=backend) for backend in backends}
    images, rays_traced = {}, {}
    stages = {backend: {"shading": [], "embree": []} for backend in backends}
    for backend in backends:
        integrators[backend].radiance(*args_in)  # warm-up: kernel build, buffers, caches
    for _ in range(args.repeats):  # the backends alternate, so a busy moment slows both alike
        for backend in backends:
            clock = StageClock()
            images[backend], rays_traced[backend] = integrators[backend].radiance(*args_in, clock=clock)
            for stage, seconds in stages[backend].items():
                seconds.append(clock.seconds[stage])
    results = {backend: {stage: 1e3 * float(np.median(v)) for stage, v in stages[backend].items()}
               for backend in backends}
    for backend in backends:
        results[backend]["shadow_rays"] = rays_traced[backend]
    scale = float(np.abs(images["numpy"]).max())
    error = float(np.abs(images["numpy"] - images["opencl"]).max() / scale)
    print(f"\n{'backend':<10}{'shading ms':>12}{'embree ms':>11}{'shading/embree':>16}{'us/sample':>11}")
    for backend, r in results.items():
        print(f"{backend:<10}{r['shading']:>12.1f}{r['embree']:>11.1f}{r['shading'] / r['embree']:>16.2f}"
              f"{1e3 * r['shading'] / DEFAULT_PASS_SAMPLES:>11.3f}")
    print(f"kernel speed-up on shading: {results['numpy']['shading'] / results['opencl']['shading']:.1f}x; "
          f"largest difference {error:.1e} of the pass's largest radiance")
    report = {"scene": source, "resolution": [width, height], "spp": args.spp, "pass_samples": DEFAULT_PASS_SAMPLES,
              "camera_rays": len(alive), "light_samples": args.light_samples, "pocl_threads": threads,
              "milliseconds_per_pass": results, "max_relative_difference": error}
    out = ROOT / "bench" / "results" / "shading.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2) + "\n")
    if error > 1e-5:
        raise SystemExit(f"the kernel's radiance differs from numpy's by {error:.1e}")


if __name__ == "__main__":
    main()
