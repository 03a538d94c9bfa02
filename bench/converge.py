"""Convergence benchmark: relative RMSE against a high-spp reference, wall times, time to an error.

    .venv/bin/python bench/converge.py [--scene scenes/dof-dragons/dgauss.pbrt] [--res 512x512]
        [--spps 4,8,16,32,64,128,256] [--reference-spp 1024] [--target 0.02] [--noise-points 2]
        [--light-samples N] [--denoise] [--search-path DIR ...]

Loads the scene once (``build_render_inputs``; the dragons by default, with ``../shared/meshes``
and ``../shared/scenes/pbrt`` as search paths), renders a reference at ``--reference-spp`` (seed 1)
and a test image at each of ``--spps`` (seed 2, so its noise is independent of the reference's),
and prints for each its wall seconds (scene load + ``render``, whose own set-up is included;
Python start-up and imports are not) and

    relative RMSE = sqrt(mean((img - ref)^2)) / mean(ref), over all pixels and channels.

The time to ``--target`` (0.02) is interpolated linearly in log(seconds) against log(error) between
the two measured points around the first crossing ("not reached" when no point is at or below it).
Against a 1024-spp reference such a target mostly measures the reference's own noise. So the
highest ``--noise-points`` counts (two by default) are rendered once more with a third seed, and
the two renders' difference gives each one's error against the converged image with no reference
at all (``convergence.two_seed_noise``). A power law noise = c spp^-q through those points (the
renderer's quasi-random samples converge faster than 1/N, q > 0.5) gives the spp and wall time to
the target; so does the 1/N law from the highest point alone, an upper bound on the time while q
> 0.5 holds. pbrt-v3's time to the target follows the 1/N law from its one point (an optimistic
bound for it: its convergence past 64 spp seemed slower). Beside it, pbrt-v3's figures measured on
the issue's machine for the dragons through dgauss at 512x512 (64 spp: 29.5 s wall, relative RMSE
0.073 against its own converged image), our time to 0.073 and the ratio ours / pbrt-v3. Those
figures are constants: on another processor the ratio compares the machines as well as the
renderers, so the table and the JSON name the processor this run had (``machine.describe``).

``--denoise`` renders each count once more with the albedo and normal AOVs and denoises it with
Open Image Denoise (``renderer.denoise``, the ``denoise`` extra): its wall seconds (the AOVs' extra
first-hit trace and the denoiser included), its relative RMSE against the same (undenoised)
reference, and the time to ``--target`` with and without the denoiser, interpolated the same way.
A denoiser trades variance for bias: its error stops falling with spp once its bias dominates, so
its time to a low target may be "not reached".

``--light-samples N`` renders the tests with N light samples per hit instead of the scene's (the
reference keeps the scene's; both estimators converge to the same image): where the lens's depth of
field, not the light, makes most of the noise, fewer light samples and more camera samples in the
same time may reach the target sooner. pbrt-v3 was measured with the scene's four.

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
sys.path.insert(0, str(ROOT / "bench"))  # first already when run as a script; not when a test loads this file

import machine  # noqa: E402
from realistic.cli.values import checked, parse_resolution, parse_spp_list, positive  # noqa: E402
from realistic.core import validation  # noqa: E402
from realistic.renderer.convergence import relative_rmse, two_seed_noise  # noqa: E402
from realistic.renderer.denoise import GUIDE_AOVS, check_available, denoised  # noqa: E402
from realistic.renderer.inputs import RenderInputs, RenderOptions, build_render_inputs  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402

SHARED = ROOT.parent / "shared"
DEFAULT_SCENE = ROOT / "scenes" / "dof-dragons" / "dgauss.pbrt"
DEFAULT_SEARCH_PATHS = (SHARED / "meshes", SHARED / "scenes" / "pbrt")
REFERENCE_SEED, TEST_SEED, NOISE_SEED = 1, 2, 3
#: pbrt-v3 on the issue's machine: dragons through dgauss, 512x512, 64 spp (issue 11).
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


def noise_power_law(spps: list[int], noises: list[float]) -> tuple[float, float]:
    """(c, q) of noise = c spp^-q, least squares in log-log over the points (q = 0.5, the 1/N law, when
    there is one point)."""
    logs, log_noise = np.log(np.asarray(spps, np.float64)), np.log(np.asarray(noises, np.float64))
    if len(spps) == 1:
        return float(noises[0] * math.sqrt(spps[0])), 0.5
    slope, intercept = np.polyfit(logs, log_noise, 1)
    return float(math.exp(intercept)), float(-slope)


def spp_to_noise(c: float, q: float, target: float) -> float:
    """Samples per pixel at which c spp^-q reaches ``target``."""
    return (c / target) ** (1.0 / q)


def extrapolated_seconds(spps: list[int], render_s: list[float], setup_s: float, spp: float) -> float:
    """Wall seconds of a render at ``spp``: a least-squares line in spp through the measured render
    times, plus ``setup_s``."""
    slope, intercept = np.polyfit(np.asarray(spps, np.float64), np.asarray(render_s, np.float64), 1)
    return setup_s + float(intercept + slope * spp)


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


def render_seconds(inputs: RenderInputs, spp: int, seed: int, light_samples: int | None = None
                   ) -> tuple[np.ndarray, float]:
    """The image at ``spp`` (with ``light_samples`` per hit, default the scene's) and the seconds of
    ``render`` (its set-up included)."""
    camera = dataclasses.replace(inputs.camera, spp=spp)
    start = time.perf_counter()
    job = RenderJob(inputs.scene, (camera,), seed=seed, light_samples=light_samples or inputs.light_samples)
    image = render(job, ThreadPasses(pin_threads=True))[0].image
    return image, time.perf_counter() - start


def denoised_seconds(inputs: RenderInputs, spp: int, seed: int, light_samples: int | None = None
                     ) -> tuple[np.ndarray, float]:
    """The image at ``spp`` rendered with the denoiser's AOVs and denoised, and the seconds of
    ``render`` and the denoiser together."""
    camera = dataclasses.replace(inputs.camera, spp=spp)
    start = time.perf_counter()
    job = RenderJob(inputs.scene, (camera,), seed=seed, light_samples=light_samples or inputs.light_samples,
                    aovs=GUIDE_AOVS)
    image = denoised(render(job, ThreadPasses(pin_threads=True))[0]).image
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
    parser.add_argument("--noise-points", type=checked(int, validation.samples_per_pixel), default=2, metavar="N",
                        help="the N highest counts are rendered with a second seed to measure their noise "
                             "without the reference (default 2)")
    parser.add_argument("--light-samples", type=checked(int, validation.light_samples), metavar="N",
                        help="light samples per hit of the test renders (default: the scene's, 4 for the "
                             "dragons, as pbrt-v3 was measured); the reference keeps the scene's: both converge to "
                             "the same image")
    parser.add_argument("--denoise", action="store_true",
                        help="also time each count with its albedo and normal AOVs and Open Image Denoise, and the "
                             "time to --target with the denoiser (needs the denoise extra)")
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
    if args.denoise:
        check_available()
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)

    start = time.perf_counter()
    inputs = build_render_inputs(RenderOptions(scene=str(args.scene), resolution=args.res,
                                               search_paths=list(search_paths)))
    load_s = time.perf_counter() - start
    version = source_hash(ROOT, args.scene)
    ref = reference(inputs, reference_path(out, args.scene, args.res, args.reference_spp, version),
                    args.reference_spp)
    light_samples = args.light_samples or inputs.light_samples
    print(f"{args.scene.name}, {args.res[0]}x{args.res[1]}, light samples {light_samples} (reference: "
          f"{inputs.light_samples}), reference "
          f"{args.reference_spp} spp (seed {REFERENCE_SEED}), tests seed {TEST_SEED}, scene load {load_s:.2f} s; "
          f"the machine's load is not controlled; processor: {machine.describe()}")
    print("relative RMSE = sqrt(mean((img - ref)^2)) / mean(ref)")
    denoiser = f"{'denoised s':>12}{'wall s':>9}{'rel RMSE':>10}" if args.denoise else ""
    print(f"{'spp':>5}{'render s':>10}{'wall s':>9}{'rel RMSE':>10}{'noise':>8}{denoiser}")
    rows = []
    for spp in args.spps:
        image, seconds = render_seconds(inputs, spp, TEST_SEED, light_samples)
        rows.append({"spp": spp, "render_s": seconds, "wall_s": load_s + seconds,
                     "rel_rmse": relative_rmse(image, ref)})
        if spp in args.spps[-args.noise_points:]:
            rows[-1]["noise"] = two_seed_noise(image, render_seconds(inputs, spp, NOISE_SEED, light_samples)[0])
        noise = f"{rows[-1]['noise']:>8.4f}" if "noise" in rows[-1] else f"{'':>8}"
        if args.denoise:
            clean, clean_s = denoised_seconds(inputs, spp, TEST_SEED, light_samples)
            rows[-1].update({"denoised_s": clean_s, "denoised_wall_s": load_s + clean_s,
                             "denoised_rel_rmse": relative_rmse(clean, ref)})
            noise += f"{clean_s:>12.2f}{load_s + clean_s:>9.2f}{rows[-1]['denoised_rel_rmse']:>10.4f}"
        print(f"{spp:>5}{seconds:>10.2f}{load_s + seconds:>9.2f}{rows[-1]['rel_rmse']:>10.4f}{noise}", flush=True)
    walls, errors = [r["wall_s"] for r in rows], [r["rel_rmse"] for r in rows]
    to_target = time_to_error(walls, errors, args.target)
    to_pbrt = time_to_error(walls, errors, PBRT_V3["rel_rmse"])
    ratio = None if to_pbrt is None else to_pbrt / PBRT_V3["wall_s"]
    print("(noise: each render's own relative RMSE, from two seeds, no reference)")
    print(f"\ntime to relative RMSE {args.target:g}: {_format_time(to_target)} (measured against the reference)")
    to_target_denoised = None
    if args.denoise:
        to_target_denoised = time_to_error([r["denoised_wall_s"] for r in rows],
                                           [r["denoised_rel_rmse"] for r in rows], args.target)
        speedup = "" if to_target is None or to_target_denoised is None else \
            f", {to_target / to_target_denoised:.2f}x sooner"
        print(f"time to relative RMSE {args.target:g} with Open Image Denoise: {_format_time(to_target_denoised)}"
              f"{speedup}")
    measured = [r for r in rows if "noise" in r]
    c, q = noise_power_law([r["spp"] for r in measured], [r["noise"] for r in measured])
    spps, render_s = [r["spp"] for r in rows], [r["render_s"] for r in rows]
    law_spp = spp_to_noise(c, q, args.target)
    law_s = extrapolated_seconds(spps, render_s, load_s, law_spp)
    last = measured[-1]
    bound_spp = spp_to_noise(last["noise"] * math.sqrt(last["spp"]), 0.5, args.target)
    bound_s = extrapolated_seconds(spps, render_s, load_s, bound_spp)
    pbrt_s = pbrt_v3_seconds(args.target)
    comparable = args.scene.resolve() == DEFAULT_SCENE and args.res == (512, 512)
    if light_samples != inputs.light_samples:
        print(f"(light samples {light_samples}, not the scene's {inputs.light_samples} that pbrt-v3 used: "
              "a choice of ours against pbrt-v3's setting, not the same estimator)")
    print(f"noise = {c:.3g} spp^-{q:.3f} through {', '.join(str(r['spp']) for r in measured)} spp: relative RMSE "
          f"{args.target:g} at {law_spp:.0f} spp, {law_s:.1f} s wall (1/N from {last['spp']} spp: {bound_spp:.0f} spp, "
          f"{bound_s:.1f} s)")
    print(f"pbrt-v3 to {args.target:g} by the 1/N law from its measured point: {pbrt_s:.0f} s; pbrt-v3 / ours = "
          f"{pbrt_s / law_s:.2f}x ({pbrt_s / bound_s:.2f}x with our 1/N bound)"
          + ("" if comparable else " (pbrt-v3's figure is for the dragons at 512x512: not comparable)"))
    print(f"pbrt-v3 (dragons, dgauss, 512x512, measured on the issue's machine, not by this run): "
          f"{PBRT_V3['spp']} spp, "
          f"{PBRT_V3['wall_s']} s wall, relative RMSE {PBRT_V3['rel_rmse']}"
          + ("" if comparable else " (another scene or resolution than ours: not comparable)"))
    print(f"ours to relative RMSE {PBRT_V3['rel_rmse']}: {_format_time(to_pbrt)}"
          + ("" if ratio is None else f", ours / pbrt-v3 = {ratio:.2f}"))
    report = {"machine": machine.describe(), "scene": str(args.scene), "resolution": list(args.res),
              "search_paths": [str(p) for p in search_paths],
              "light_samples": light_samples, "reference_light_samples": inputs.light_samples,
              "reference_spp": args.reference_spp,
              "reference_seed": REFERENCE_SEED, "test_seed": TEST_SEED, "noise_seed": NOISE_SEED,
              "source_hash": version, "load_s": load_s, "rows": rows, "target": args.target,
              "time_to_target_s": to_target, "denoise": args.denoise,
              "time_to_target_denoised_s": to_target_denoised, "pbrt_v3": PBRT_V3,
              "noise_law": {"c": c, "q": q, "spp_to_target": law_spp, "seconds_to_target": law_s,
                            "inverse_n_spp_to_target": bound_spp, "inverse_n_seconds_to_target": bound_s,
                            "pbrt_v3_seconds_to_target": pbrt_s, "pbrt_v3_over_ours": pbrt_s / law_s},
              "time_to_pbrt_error_s": to_pbrt, "ratio_to_pbrt": ratio,
              "comparable_to_pbrt": comparable}
    path = out / "converge.json"
    path.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
