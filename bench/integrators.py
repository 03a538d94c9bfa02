"""Integrator benchmark: what MIS and path tracing cost against the direct-lighting fast path.

    .venv/bin/python bench/integrators.py [--res 300x300] [--spp 16] [--backend opencl|numpy]

Renders the dragon (as bench/render.py: ../shared/meshes/dragon.ply, else a procedural mesh) on the
grid floor under a disk light, all Lambertian, with: the Lambertian area-light fast path
(``DirectLighting``, what "directlighting" picks for such scenes), the general MIS direct lighting
(``PathIntegrator`` "direct"), and path tracing to depth 5. Prints wall seconds, shading and embree
thread-seconds, and shading microseconds per camera sample. Writes bench/results/integrators.json.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import realistic.renderer.runner as runner  # noqa: E402
from realistic.renderer.direct_lighting import DirectLighting  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.renderer.path import PathIntegrator  # noqa: E402
from realistic.renderer.thread_count import default_threads  # noqa: E402
from render import staged_subject  # noqa: E402

VARIANTS = {
    "fast path (DirectLighting)": lambda scene, *a, **backend: DirectLighting(scene, *a, **backend),
    "MIS direct (PathIntegrator)": lambda scene, *a, **_: PathIntegrator(scene, *a, max_depth=5, mode="direct"),
    "path, maxdepth 5": lambda scene, *a, **_: PathIntegrator(scene, *a, max_depth=5, mode="path"),
}


def run(setup, camera, backend: str, make) -> dict:
    runner.make_integrator = make  # the bench chooses the integrator the pass runner builds
    result = render(RenderJob(setup.scene, (camera,), backend), ThreadPasses(pin_threads=True))[0]
    return {"seconds": result.seconds, "samples": result.samples_done, "camera_rays": result.primary_rays,
            "shadow_rays": result.shadow_rays, "shading_s": result.stage_seconds.get("shading", 0.0),
            "embree_s": result.stage_seconds.get("embree", 0.0)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", default="300x300")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--backend", default="opencl", choices=("opencl", "numpy"))
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    setup, camera, source, warm = staged_subject("dgauss", width, height, args.spp)
    render(RenderJob(setup.scene, (warm,), args.backend))  # kernel build and caches
    print(f"scene: {source}; {width}x{height}, {args.spp} spp, backend {args.backend}, "
          f"{default_threads()} threads")
    print(f"\n{'integrator':<30}{'wall s':>8}{'shading s':>11}{'embree s':>10}{'shading us/sample':>19}"
          f"{'shadow rays':>13}")
    results = {}
    for name, make in VARIANTS.items():
        r = run(setup, camera, args.backend, make)
        results[name] = r
        print(f"{name:<30}{r['seconds']:>8.2f}{r['shading_s']:>11.2f}{r['embree_s']:>10.2f}"
              f"{1e6 * r['shading_s'] / r['samples']:>19.2f}{r['shadow_rays']:>13}")
    out = ROOT / "bench" / "results" / "integrators.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    report = {"scene": source, "resolution": [width, height], "spp": args.spp, "backend": args.backend,
              "runs": results}
    out.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
