"""Integrator benchmark: what MIS and path tracing cost against the direct-lighting fast path, and
the path tracer's bounces in numpy against the OpenCL backend's (``kernels/bounce.cl``).

    .venv/bin/python bench/integrators.py [--res 300x300] [--spp 16] [--backend opencl|numpy] [--repeats 3]

Renders the dragon (as bench/render.py: ../shared/meshes/dragon.ply, else a procedural mesh) on the
grid floor under a disk light with: the Lambertian area-light fast path (``DirectLighting``, what
"directlighting" picks for such scenes), the general MIS direct lighting (``PathIntegrator``
"direct", on each backend), and path tracing to depth 5 with the dragon Lambertian, a rough conductor (copper, alpha
0.1) and plastic, each on the numpy backend (``PathIntegrator._shade``, the numpy BSDFs) and
(backend opencl) on the render's backend (one ``kernels/bounce.cl`` launch per bounce). The
variants run in turn, ``--repeats`` rounds, so old and new alternate under the same load; the table
gives each one's medians: wall seconds, shading and embree thread-seconds, bounces per camera sample
(closest-hit rays traced per camera ray), samples/s per bounce (samples x bounces per sample / wall
s) and that against the fast path's samples/s. Writes bench/results/integrators.json with every
round and the load average before and after.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import statistics
import sys
import threading
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import realistic.renderer.runner as runner  # noqa: E402
from realistic.renderer.direct_lighting import DirectLighting  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.renderer.path import PathIntegrator  # noqa: E402
from realistic.renderer.thread_count import default_threads  # noqa: E402
from realistic.scene.intersect import Intersector  # noqa: E402
from realistic.scene.materials import Conductor, Plastic  # noqa: E402
from realistic.scene.model import Scene  # noqa: E402
from render import staged_subject  # noqa: E402

#: The dragon's glossy materials (the floor stays the grid-textured Lambertian).
GLOSSY = {"conductor": Conductor(roughness_u=0.1, roughness_v=0.1),
          "plastic": Plastic((0.4, 0.2, 0.1), (0.5, 0.5, 0.5), 0.1)}


def path(bsdfs: str):
    """A path tracer to depth 5 on the ``bsdfs`` backend ("numpy", or "device": the render's)."""
    def make(scene, *a, backend, **_):
        return PathIntegrator(scene, *a, max_depth=5, mode="path", backend="numpy" if bsdfs == "numpy" else backend)
    return make


VARIANTS = {
    "fast path (DirectLighting)": (None, lambda scene, *a, **options: DirectLighting(scene, *a, **options)),
    "MIS direct, numpy": (None, lambda scene, *a, **_: PathIntegrator(scene, *a, max_depth=5, mode="direct")),
    "MIS direct, opencl": (None, lambda scene, *a, backend, **_: PathIntegrator(scene, *a, max_depth=5, mode="direct",
                                                                               backend=backend)),
    "path, lambertian, numpy": (None, path("numpy")),
    "path, lambertian, opencl": (None, path("device")),
    "path, conductor, numpy": ("conductor", path("numpy")),
    "path, conductor, opencl": ("conductor", path("device")),
    "path, plastic, numpy": ("plastic", path("numpy")),
    "path, plastic, opencl": ("plastic", path("device")),
}


class RayCount:
    """Counts the closest-hit rays every ``Intersector`` traces (camera rays and path bounces)."""

    def __init__(self) -> None:
        self.rays, self._lock, self._closest = 0, threading.Lock(), Intersector.closest

        def closest(intersector, origin, direction, coherent=False):
            with self._lock:
                self.rays += len(origin)
            return self._closest(intersector, origin, direction, coherent)

        Intersector.closest = closest


def glossy(scene: Scene, material) -> Scene:
    """``scene`` with the subject (every instance but the floor, the last) made of ``material``."""
    out = copy.copy(scene)
    out.instances = [replace(inst, material=material) for inst in scene.instances[:-1]] + scene.instances[-1:]
    return out


def run(scene: Scene, camera, backend: str, make, count: RayCount) -> dict:
    runner.make_integrator = make  # the bench chooses the integrator the pass runner builds
    before = count.rays
    result = render(RenderJob(scene, (camera,), backend), ThreadPasses(pin_threads=True))[0]
    bounces = (count.rays - before) / max(result.primary_rays, 1)
    return {"seconds": result.seconds, "samples": result.samples_done, "camera_rays": result.primary_rays,
            "shadow_rays": result.shadow_rays, "shading_s": result.stage_seconds.get("shading", 0.0),
            "embree_s": result.stage_seconds.get("embree", 0.0), "bounces_per_sample": bounces,
            "sample_bounces_per_s": result.samples_done * bounces / result.seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", default="300x300")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--backend", default="opencl", choices=("opencl", "numpy"))
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    setup, camera, source, warm = staged_subject("dgauss", width, height, args.spp)
    scenes = {None: setup.scene, **{name: glossy(setup.scene, m) for name, m in GLOSSY.items()}}
    variants = {name: v for name, v in VARIANTS.items() if args.backend == "opencl" or "opencl" not in name}
    count = RayCount()
    for scene_name, make in variants.values():  # kernel builds and caches
        runner.make_integrator = make
        render(RenderJob(scenes[scene_name], (warm,), args.backend))
    load_before = os.getloadavg()
    rounds: dict[str, list[dict]] = {name: [] for name in variants}
    for _ in range(args.repeats):
        for name, (scene_name, make) in variants.items():
            rounds[name].append(run(scenes[scene_name], camera, args.backend, make, count))
    load_after = os.getloadavg()
    print(f"scene: {source}; {width}x{height}, {args.spp} spp, backend {args.backend}, "
          f"{default_threads()} threads; medians of {args.repeats} alternating rounds; load average "
          f"{load_before[0]:.2f} before, {load_after[0]:.2f} after")
    print(f"\n{'integrator':<32}{'wall s':>8}{'shading s':>11}{'embree s':>10}{'bounces':>9}"
          f"{'Msample-bounces/s':>19}{'/ fast path':>13}")
    medians = {name: {key: statistics.median(r[key] for r in runs) for key in runs[0]} for name, runs in rounds.items()}
    fast = medians["fast path (DirectLighting)"]["samples"] / medians["fast path (DirectLighting)"]["seconds"]
    for name, r in medians.items():
        r["per_bounce_vs_fast_path"] = r["sample_bounces_per_s"] / fast
        print(f"{name:<32}{r['seconds']:>8.2f}{r['shading_s']:>11.2f}{r['embree_s']:>10.2f}"
              f"{r['bounces_per_sample']:>9.2f}{r['sample_bounces_per_s'] / 1e6:>19.3f}"
              f"{r['per_bounce_vs_fast_path']:>13.2f}")
    out = ROOT / "bench" / "results" / "integrators.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    report = {"scene": source, "resolution": [width, height], "spp": args.spp, "backend": args.backend,
              "threads": default_threads(), "load_average_before": load_before, "load_average_after": load_after,
              "medians": medians, "rounds": rounds}
    out.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
