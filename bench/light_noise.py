"""Noise of direct lighting against light samples per camera sample, split into camera and light parts.

    .venv/bin/python bench/light_noise.py [--res 256x256] [--spp 16] [--light-samples 1,4,16]
        [--seeds 1,2] [--backend opencl|numpy] [--root DIR] [--label NAME] [--out DIR]

Renders ``scenes/dof-dragons/dgauss.pbrt`` (search paths ``../shared/meshes`` and
``../shared/scenes/pbrt``; skipped with the reason when they are absent) at each light-sample count
L with two seeds a and b, and prints the relative noise of one render,

    noise(L) = sqrt(mean((a - b)^2) / 2) / mean((a + b) / 2)   over all pixels and channels,

then fits noise^2 = camera + light / L by least squares over the L given: the camera part (film,
lens, everything L does not average) and the light part (what one light sample per camera sample
adds). ``--root DIR`` imports ``realistic`` from another checkout (e.g. an export of the main branch)
to measure its sampling with the same script: the noise figures are deterministic for given seeds,
so runs of different versions compare exactly; the seconds are wall times on whatever else the
machine runs (upper bounds on a busy machine). Writes ``OUT/light_noise[-LABEL].json`` (default OUT:
bench/results).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
SCENE = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"


def counts(text: str) -> list[int]:
    """A comma-separated list of positive integers."""
    values = [int(v) for v in text.split(",")]
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected positive integers, got {text!r}")
    return values


def resolution(text: str) -> tuple[int, int]:
    width, _, height = text.partition("x")
    if not (width.isdigit() and height.isdigit() and int(width) > 0 and int(height) > 0):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}")
    return int(width), int(height)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--res", type=resolution, default=(256, 256), help="image size (default 256x256)")
    parser.add_argument("--spp", type=int, default=16, help="camera samples per pixel (default 16)")
    parser.add_argument("--light-samples", type=counts, default=[1, 4, 16], help="L values (default 1,4,16)")
    parser.add_argument("--seeds", type=counts, default=[1, 2], help="the two seeds (default 1,2)")
    parser.add_argument("--backend", choices=("opencl", "numpy"), default="opencl")
    parser.add_argument("--root", type=Path, default=ROOT, help="checkout whose realistic/ to measure")
    parser.add_argument("--label", default="", help="suffix of the JSON file name (e.g. main)")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    return parser


def relative_noise(a: np.ndarray, b: np.ndarray) -> float:
    """Noise of one render from two renders with different seeds, relative to the image mean."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return float(np.sqrt(np.mean((a - b) ** 2) / 2) / np.mean((a + b) / 2))


def split(light_samples: list[int], noise: list[float]) -> tuple[float, float]:
    """Least-squares (camera, light) of noise^2 = camera + light / L."""
    design = np.column_stack([np.ones(len(light_samples)), 1.0 / np.asarray(light_samples, np.float64)])
    (camera, light), *_ = np.linalg.lstsq(design, np.square(noise), rcond=None)
    return float(camera), float(light)


def main() -> None:
    args = build_parser().parse_args()
    missing = [p for p in (SCENE, SHARED / "meshes", SHARED / "scenes" / "pbrt") if not p.exists()]
    if missing:
        print(f"skipped: {missing[0]} not found (no ../shared data)")
        return
    if len(args.seeds) != 2:
        sys.exit("--seeds takes two seeds")
    sys.path.insert(0, str(args.root.resolve()))
    from realistic.renderer.inputs import RenderOptions, build_render_inputs
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import ThreadPasses, render

    print(f"{SCENE.relative_to(ROOT)} {args.res[0]}x{args.res[1]}, {args.spp} spp, backend {args.backend}, "
          f"seeds {args.seeds}, code from {args.root}; seconds are wall times on a machine whose load is not "
          f"controlled")
    print(f"{'light samples':>14}{'rel. noise':>12}{'variance':>11}{'seconds':>10}")
    rows = []
    for light_samples in args.light_samples:
        options = RenderOptions(scene=SCENE, resolution=args.res, spp=args.spp, light_samples=light_samples,
                                search_paths=[SHARED / "meshes", SHARED / "scenes" / "pbrt"])
        inputs = build_render_inputs(options)
        images, seconds = [], []
        for seed in args.seeds:
            start = time.perf_counter()
            job = RenderJob(inputs.scene, (inputs.camera,), args.backend, seed)
            images.append(render(job, ThreadPasses(pin_threads=True))[0].image)
            seconds.append(time.perf_counter() - start)
        noise = relative_noise(*images)
        rows.append({"light_samples": light_samples, "relative_noise": noise, "seconds": min(seconds)})
        print(f"{light_samples:>14d}{noise:>12.4f}{noise**2:>11.5f}{min(seconds):>10.2f}", flush=True)
    camera, light = split([r["light_samples"] for r in rows], [r["relative_noise"] for r in rows])
    print(f"relative variance = {camera:.4f} (camera) + {light:.4f} / light samples")
    report = {"scene": str(SCENE.relative_to(ROOT)), "resolution": list(args.res), "spp": args.spp,
              "backend": args.backend, "seeds": args.seeds, "root": str(args.root), "rows": rows,
              "camera_variance": camera, "light_variance": light}
    args.out.mkdir(parents=True, exist_ok=True)
    out = args.out / f"light_noise{'-' + args.label if args.label else ''}.json"
    out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
