"""Convergence benchmark: relative RMSE against a high-spp reference, wall times, time to an error.

    .venv/bin/python bench/converge.py [--scene scenes/dof-dragons/dgauss.pbrt] [--res 512x512]
        [--spps 4,8,16,32,64,128,256] [--reference-spp 1024] [--target 0.02] [--search-path DIR ...]

Loads the scene once (``build_render_inputs``; the dragons by default, with ``../shared/meshes``
and ``../shared/scenes/pbrt`` as search paths), renders a reference at ``--reference-spp`` (seed 1)
and a test image at each of ``--spps`` (seed 2, so its noise is independent of the reference's),
and prints for each its wall seconds (scene load + ``render_passes``, whose own set-up is included;
Python start-up and imports are not) and

    relative RMSE = sqrt(mean((img - ref)^2)) / mean(ref), over all pixels and channels.

The time to ``--target`` (0.02) is interpolated linearly in log(seconds) against log(error) between
the two measured points around the first crossing ("not reached" when no point is at or below it).
The reference's own noise, estimated from the highest test count, is printed too: a target near it
measures the reference, not the test. So the script also fits error^2 = a/spp + b (test variance
plus the reference's own squared error) and extrapolates the spp and wall time to the target
against the converged image by the 1/N law, and pbrt-v3's time by the same law from its one point.
Beside it, pbrt-v3's figures measured on this machine for the dragons through dgauss at 512x512
(64 spp: 29.5 s wall, relative RMSE 0.073), our time to 0.073 and the ratio ours / pbrt-v3.

The reference is cached in bench/results as .npy, keyed by scene, resolution, spp, seed and a hash
of the package's source (``realistic/**/*.py``, ``kernels/*``) and the scene file, so a changed
renderer never reuses a stale reference. The machine's load is not controlled: on a shared machine
the times are upper bounds. Writes bench/results/converge.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic.cli.values import checked, parse_resolution, parse_spp_list, positive  # noqa: E402
from realistic.core import validation  # noqa: E402
from realistic.renderer.convergence import relative_rmse  # noqa: E402
from realistic.renderer.inputs import RenderInputs, RenderOptions, build_render_inputs  # noqa: E402
from realistic.renderer.passes import render_passes  # noqa: E402

SHARED = ROOT.parent / "shared"
DEFAULT_SCENE = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"
DEFAULT_SEARCH_PATHS = (SHARED / "meshes", SHARED / "scenes" / "pbrt")
REFERENCE_SEED, TEST_SEED = 1, 2
#: pbrt-v3 on this machine: dragons through dgauss, 512x512, 64 spp (issue 11).
PBRT_V3 = {"spp": 64, "wall_s": 29.5, "setup_s": 5.6, "render_s": 24.0, "rel_rmse": 0.073}


def time_to_error(seconds: list[float], errors: list[float], target: float) -> float | None:
    """Seconds at which the error first reaches ``target``, interpolating log(seconds) linearly in
    log(error) between the measured points around the crossing; the first point's seconds when it
    is already at or below ``target`` (an upper bound); None when no point reaches it."""
    for i, error in enumerate(errors):
        if error > target:
            continue
        if i == 0 or error <= 0 or error == errors[i - 1]:
            return seconds[i]
        step = (math.log(target) - math.log(errors[i - 1])) / (math.log(error) - math.log(errors[i - 1]))
        return math.exp(math.log(seconds[i - 1]) + step * (math.log(seconds[i]) - math.log(seconds[i - 1])))
    return None


def reference_noise(error: float, spp: int, reference_spp: int) -> float:
    """The reference's own relative RMSE, estimated from one test's ``error`` at ``spp``.

    Test and reference are independent with variances v/spp and v/reference_spp (the 1/N regime,
    fair at the highest test count), so error^2 = v/spp + v/reference_spp and the reference's part
    is error * sqrt(spp / (spp + reference_spp)). No target near or below it can be timed here.
    """
    return error * math.sqrt(spp / (spp + reference_spp))


def inverse_n_fit(spps: list[int], errors: list[float]) -> tuple[float, float]:
    """(a, b) of error^2 = a / spp + b, least squares over the measured points.

    Test and reference noise are independent, so the squared error against the reference is the
    test's variance a / spp plus the reference's own squared error b (clamped at 0). sqrt(a / spp) is
    then the test's error against the converged image, which a target near the reference's noise
    needs: a 1024-spp reference cannot time 0.02 directly when its own error is about that.
    """
    design = np.column_stack([1.0 / np.asarray(spps, np.float64), np.ones(len(spps))])
    (a, b), *_ = np.linalg.lstsq(design, np.square(np.asarray(errors, np.float64)), rcond=None)
    return float(a), max(float(b), 0.0)


def extrapolated_seconds(spps: list[int], render_s: list[float], setup_s: float, variance: float,
                         target: float) -> tuple[float, float]:
    """(spp, wall seconds) to reach ``target`` under the 1/N law with variance ``variance`` (``a``
    of ``inverse_n_fit``): spp = a / target^2; render seconds from a least-squares line in spp
    through the measured renders, plus ``setup_s``."""
    spp = variance / target**2
    slope, intercept = np.polyfit(np.asarray(spps, np.float64), np.asarray(render_s, np.float64), 1)
    return spp, setup_s + float(intercept + slope * spp)


def pbrt_v3_seconds(target: float) -> float:
    """pbrt-v3's wall seconds to ``target`` by the same 1/N law from its one measured point: set-up
    plus render time scaled by (error / target)^2. Convergence slower than 1/N past 64 spp (as
    pbrt-v3's seemed) only makes it slower, so a ratio against this is a lower bound."""
    return PBRT_V3["setup_s"] + PBRT_V3["render_s"] * (PBRT_V3["rel_rmse"] / target) ** 2


def source_hash(root: Path, scene: Path) -> str:
    """Short hash of the package's source, its kernels and the scene file."""
    digest = hashlib.sha256()
    files = sorted((root / "realistic").rglob("*.py")) + sorted((root / "kernels").glob("*"))
    for path in [*files, scene]:
        digest.update(str(path.relative_to(root) if path.is_relative_to(root) else path).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def reference_path(folder: Path, scene: Path, res: tuple[int, int], spp: int, version: str) -> Path:
    """Where the reference of ``scene`` at ``res`` and ``spp`` made by source ``version`` is cached."""
    slug = re.sub(r"[^A-Za-z0-9]+", "-", str(scene.resolve().relative_to(ROOT) if scene.resolve().is_relative_to(ROOT)
                                             else scene.resolve())).strip("-")
    return folder / f"converge-reference-{slug}-{res[0]}x{res[1]}-{spp}spp-seed{REFERENCE_SEED}-{version}.npy"


def render_seconds(inputs: RenderInputs, spp: int, seed: int) -> tuple[np.ndarray, float]:
    """The image at ``spp`` and the seconds of ``render_passes`` (its set-up included)."""
    camera = dataclasses.replace(inputs.camera, spp=spp)
    start = time.perf_counter()
    image = render_passes(inputs.scene, camera, seed=seed, light_samples=inputs.light_samples).image
    return image, time.perf_counter() - start


def reference(inputs: RenderInputs, path: Path, spp: int) -> np.ndarray:
    """The cached reference image, rendered and saved when absent."""
    if path.is_file():
        print(f"reference: {path.name} (cached)", file=sys.stderr)
        return np.load(path)
    print(f"reference: rendering {spp} spp ...", file=sys.stderr, flush=True)
    image, seconds = render_seconds(inputs, spp, REFERENCE_SEED)
    np.save(path, image)
    print(f"reference: {seconds:.1f} s, saved {path.name}", file=sys.stderr)
    return image


def _format_time(seconds: float | None) -> str:
    return "not reached" if seconds is None else f"{seconds:.1f} s"


def build_parser() -> argparse.ArgumentParser:
    """The command line: scene, resolution, sample counts and the error to time."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE, help="pbrt scene (default: the dgauss dragons)")
    parser.add_argument("--res", type=checked(str, parse_resolution), default=(512, 512), metavar="WxH",
                        help="resolution (default 512x512)")
    parser.add_argument("--spps", type=checked(str, parse_spp_list), default=[4, 8, 16, 32, 64, 128, 256],
                        metavar="N,N,...", help="test samples per pixel (default 4,8,16,32,64,128,256)")
    parser.add_argument("--reference-spp", type=checked(int, validation.samples_per_pixel), default=1024,
                        metavar="N", help="samples per pixel of the reference (default 1024)")
    parser.add_argument("--target", type=positive("target relative RMSE"), default=0.02,
                        help="relative RMSE to time (default 0.02)")
    parser.add_argument("--search-path", type=Path, action="append", metavar="DIR",
                        help="pbrt search path (default for the dragons: ../shared/meshes, ../shared/scenes/pbrt)")
    return parser


def main() -> None:
    args = build_parser().parse_args()
    search_paths = args.search_path
    if search_paths is None:
        search_paths = list(DEFAULT_SEARCH_PATHS) if args.scene.resolve() == DEFAULT_SCENE else []
    missing = [p for p in (args.scene, *search_paths) if not p.exists()]
    if missing:
        raise SystemExit(f"converge: {missing[0]} not found (the dragons need ../shared data)")
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)

    start = time.perf_counter()
    inputs = build_render_inputs(RenderOptions(scene=str(args.scene), resolution=args.res,
                                               search_paths=list(search_paths)))
    load_s = time.perf_counter() - start
    version = source_hash(ROOT, args.scene)
    ref = reference(inputs, reference_path(out, args.scene, args.res, args.reference_spp, version),
                    args.reference_spp)
    print(f"{args.scene.name}, {args.res[0]}x{args.res[1]}, light samples {inputs.light_samples}, reference "
          f"{args.reference_spp} spp (seed {REFERENCE_SEED}), tests seed {TEST_SEED}, scene load {load_s:.2f} s; "
          "the machine's load is not controlled")
    print("relative RMSE = sqrt(mean((img - ref)^2)) / mean(ref)")
    print(f"{'spp':>5}{'render s':>10}{'wall s':>9}{'rel RMSE':>10}")
    rows = []
    for spp in args.spps:
        image, seconds = render_seconds(inputs, spp, TEST_SEED)
        rows.append({"spp": spp, "render_s": seconds, "wall_s": load_s + seconds,
                     "rel_rmse": relative_rmse(image, ref)})
        print(f"{spp:>5}{seconds:>10.2f}{load_s + seconds:>9.2f}{rows[-1]['rel_rmse']:>10.4f}", flush=True)
    walls, errors = [r["wall_s"] for r in rows], [r["rel_rmse"] for r in rows]
    to_target = time_to_error(walls, errors, args.target)
    to_pbrt = time_to_error(walls, errors, PBRT_V3["rel_rmse"])
    ratio = None if to_pbrt is None else to_pbrt / PBRT_V3["wall_s"]
    floor = reference_noise(errors[-1], rows[-1]["spp"], args.reference_spp)
    print(f"\nthe reference's own relative RMSE, estimated from {rows[-1]['spp']} spp: {floor:.4f} "
          "(errors near it measure the reference; raise --reference-spp to time lower targets)")
    print(f"time to relative RMSE {args.target:g}: {_format_time(to_target)} (measured against the reference)")
    variance, reference_squared = inverse_n_fit([r["spp"] for r in rows], errors)
    fit_spp, fit_s = extrapolated_seconds([r["spp"] for r in rows], [r["render_s"] for r in rows], load_s,
                                          variance, args.target)
    pbrt_s = pbrt_v3_seconds(args.target)
    print(f"1/N fit error^2 = {variance:.4g}/spp + {reference_squared:.3g} (the reference's own error "
          f"{math.sqrt(reference_squared):.4f}): relative RMSE {args.target:g} against the converged image "
          f"at {fit_spp:.0f} spp, {fit_s:.1f} s wall; pbrt-v3 by the same law {pbrt_s:.0f} s: "
          f"pbrt-v3 / ours = {pbrt_s / fit_s:.1f}x")
    comparable = args.scene.resolve() == DEFAULT_SCENE and args.res == (512, 512)
    print(f"pbrt-v3 (dragons, dgauss, 512x512, measured on this machine): {PBRT_V3['spp']} spp, "
          f"{PBRT_V3['wall_s']} s wall, relative RMSE {PBRT_V3['rel_rmse']}"
          + ("" if comparable else " (another scene or resolution than ours: not comparable)"))
    print(f"ours to relative RMSE {PBRT_V3['rel_rmse']}: {_format_time(to_pbrt)}"
          + ("" if ratio is None else f", ours / pbrt-v3 = {ratio:.2f}"))
    report = {"scene": str(args.scene), "resolution": list(args.res), "search_paths": [str(p) for p in search_paths],
              "light_samples": inputs.light_samples, "reference_spp": args.reference_spp,
              "reference_seed": REFERENCE_SEED, "test_seed": TEST_SEED, "source_hash": version, "load_s": load_s,
              "rows": rows, "reference_noise_estimate": floor, "target": args.target,
              "time_to_target_s": to_target, "pbrt_v3": PBRT_V3,
              "fit": {"variance_per_spp": variance, "reference_squared_error": reference_squared,
                      "spp_to_target": fit_spp, "seconds_to_target": fit_s, "pbrt_v3_seconds_to_target": pbrt_s,
                      "pbrt_v3_over_ours": pbrt_s / fit_s},
              "time_to_pbrt_error_s": to_pbrt, "ratio_to_pbrt": ratio,
              "comparable_to_pbrt": comparable}
    path = out / "converge.json"
    path.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
