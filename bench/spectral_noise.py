"""Colour noise of spectral rendering: spectral (dispersion on) against RGB (dispersion off).

    .venv/bin/python bench/spectral_noise.py [--res default=150x150,dof-dragons.dgauss.pbrt=160x160]
        [--spps 16,64] [--reference-spp 1024] [--scenes default,dof-dragons.dgauss.pbrt]
        [--wavelengths-per-sample 1,DEFAULT] [--repeats 3] [--out DIR]

For each scene and each mode (RGB: dispersion off; spectral: dispersion on, once per number K of
wavelengths traced per camera sample in ``--wavelengths-per-sample``), renders a reference at
``--reference-spp`` and a test image at each of ``--spps`` (a different seed from the reference),
and prints the relative RMSE of each test image against its own mode's (and K's) reference:

    relative RMSE = sqrt(mean((img - ref)^2)) / mean(ref), over all pixels and channels,

and the ratio spectral / RGB at equal spp (the issue's target: at most 1.3). Each test image is
rendered once untimed (building the kernel and the BVH) and then ``--repeats`` times with the same
settings; the shortest wall time (and CPU time) is reported, the least disturbed by other work on
the machine, so the equal-time picture can be stated too: a spectral sample costs K camera rays.
The column ``ratio@time`` is the ratio at equal wall time, estimated as ratio x sqrt(spectral
seconds / RGB seconds) (error falling as 1 / sqrt(samples)); ``ratio@cpu`` the same from the
process's CPU seconds, which other work on a shared machine disturbs less.
Where the time goes: for each scene, spp and mode, the same render's passes run once more by one
pass runner on this thread, each stage's CPU seconds (``time.process_time``: every thread of the
process, PoCL's included, so a stage's kernel launches count in it; other work on a shared machine
disturbs CPU time far less than wall time) per camera sample in microseconds ("ray generation" is
the lens kernel; "embree" the closest hits and the shadow rays; "shading" the shading kernel, the
host's sums and the pass's ray gathers), with the camera rays and shadow rays per sample, and each
spectral mode's stage costs over the RGB mode's, per sample ("x") and per camera ray traced ("x per
ray": that ratio over the ratio of camera rays).
First it prints, for the wavelength densities considered and for K stratified wavelengths of the
density used, the per-sample variance of each channel's estimator for a flat white spectrum
(``realistic.core.spectrum.estimator_variance``, ``stratified_response_variance``; it multiplies
every other noise of a spectral sample) and the colour noise of a white pixel at each spp (what
stratification leaves of it). References dominate the cost, so
they are cached in the output folder as .npy, keyed by scene, resolution, mode, K, spp, seed and a
hash of the sampling code (``kernels/lens.cl``, ``realistic/core/rng.py``,
``realistic/core/spectrum.py``, ``realistic/renderer/passes.py``), so a change to how samples are
drawn makes a new reference. Writes ``OUT/spectral_noise.json`` (default OUT: bench/results), with
the machine's load averages before and after the timed renders (times on a shared machine are only
as good as its load).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import realistic  # noqa: E402
from realistic.core.rng import spectral_rays, stratified5  # noqa: E402
from realistic.core.spectrum import (  # noqa: E402
    DEFAULT_WAVELENGTHS_PER_SAMPLE,
    LAMBDA_MAX_NM,
    LAMBDA_MIN_NM,
    cie_rgb,
    estimator_variance,
    rgb_response,
    stratified_response_variance,
    wavelength_pdf,
    wavelengths_nm,
)
from realistic.renderer.convergence import relative_rmse  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.pass_plan import plan_passes  # noqa: E402
from realistic.renderer.passes import ThreadPasses  # noqa: E402
from realistic.renderer.passes import render as render_job  # noqa: E402
from realistic.renderer.runner import PassRunner  # noqa: E402
from realistic.renderer.timing import StageClock  # noqa: E402
from realistic.scene.intersect import Intersector  # noqa: E402
from realistic.scene.model import Scene  # noqa: E402

SHARED_SCENES = ROOT.parent / "shared" / "scenes" / "pbrt"
SAMPLING_CODE = ("kernels/lens.cl", "realistic/core/rng.py", "realistic/core/spectrum.py",
                 "realistic/renderer/passes.py")
DEFAULT_RES = {"default": (150, 150), "dof-dragons.dgauss.pbrt": (160, 160)}
REFERENCE_SEED, TEST_SEED = 1, 2


def code_hash() -> str:
    digest = hashlib.sha256()
    for name in SAMPLING_CODE:
        digest.update((ROOT / name).read_bytes())
    return digest.hexdigest()[:12]


def load(scene_name: str, res: tuple[int, int], wavelengths: int | None) -> Scene:
    """The scene at ``res``: RGB (``wavelengths`` None) or spectral with K = ``wavelengths``."""
    path = None if scene_name == "default" else SHARED_SCENES / scene_name
    if path is not None and not path.is_file():
        raise SystemExit(f"spectral_noise: {path} not found")
    return realistic.load_scene(None if path is None else str(path), resolution=res,
                                dispersion=wavelengths is not None, wavelengths_per_sample=wavelengths)


def render(scene: Scene, spp: int, seed: int) -> tuple[np.ndarray, float, float]:
    """The image, its wall seconds and this process's CPU seconds (all threads, PoCL's included)."""
    if scene.camera is None:
        raise SystemExit("spectral_noise: the scene has no camera")
    start, cpu = time.perf_counter(), time.process_time()
    job = RenderJob(scene, (dataclasses.replace(scene.camera, spp=spp),), seed=seed)
    image = render_job(job, ThreadPasses(pin_threads=True))[0].image
    return image, time.perf_counter() - start, time.process_time() - cpu


#: The stages of a render's passes (``realistic.renderer.timing``) that ``stage_costs`` reports.
PASS_STAGES = ("ray generation", "embree", "shading", "accumulation")


class CpuStageClock(StageClock):
    """A ``StageClock`` summing this process's CPU seconds per stage instead of wall seconds: with
    one pass runner working alone, each stage's own cost, kernel threads included."""

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        start = time.process_time()
        try:
            yield
        finally:
            self.seconds[stage] += time.process_time() - start


def stage_costs(scene: Scene, spp: int, seed: int) -> dict[str, float]:
    """The render's passes run in order by one ``PassRunner`` on this thread (after one untimed
    pass, which builds the kernels): each of ``PASS_STAGES`` in CPU microseconds per camera sample,
    their total, and the camera and shadow rays per sample."""
    if scene.camera is None:
        raise SystemExit("spectral_noise: the scene has no camera")
    camera = dataclasses.replace(scene.camera, spp=spp)
    camera.prepare()
    job = RenderJob(scene, (camera,), seed=seed)
    clock = CpuStageClock()
    runner = PassRunner(scene, camera, job.settings, clock, Intersector(scene))
    blocks = plan_passes(camera.width * camera.height, spp, job.pass_size)
    runner.run([(0, blocks[0])])
    clock.seconds.clear()
    results = runner.run(list(enumerate(blocks)))
    samples = sum(block.count for block in blocks)
    costs = {stage: 1e6 * clock.seconds[stage] / samples for stage in PASS_STAGES}
    costs["total"] = sum(costs.values())
    costs["camera_rays"] = sum(r.primary_rays for r in results) / samples
    costs["shadow_rays"] = sum(r.shadow_rays for r in results) / samples
    return costs


def reference(scene: Scene, key: str, spp: int, out: Path) -> np.ndarray:
    path = out / f"reference-{key}.npy"
    if path.is_file():
        return np.load(path)
    image, seconds, _ = render(scene, spp, REFERENCE_SEED)
    np.save(path, image)
    print(f"  reference {key}: {seconds:.1f} s", file=sys.stderr)
    return image


def parse_res(text: str | None) -> dict[str, tuple[int, int]]:
    res = dict(DEFAULT_RES)
    for item in (text or "").split(","):
        if item:
            name, _, size = item.rpartition("=")
            w, h = (int(v) for v in size.lower().split("x"))
            res[name or "*"] = (w, h)
    return res


def density_table(spps: list[int], wavelength_counts: list[int], pixels: int = 4000) -> dict[str, dict]:
    """Per wavelength density, and per K stratified wavelengths of the density used: each channel's
    per-sample variance for a flat white spectrum, and the relative RMSE of a white pixel's colour
    from its spp samples' wavelengths (R5's fifth dimension, rotated K ways for K wavelengths,
    through the density's inverse CDF), the colour noise alone."""
    lam = np.linspace(LAMBDA_MIN_NM, LAMBDA_MAX_NM, 400_001)
    densities = {"uniform": np.ones_like(lam),
                 "pbrt-v4 visible (sech^2)": 1 / np.cosh(0.0072 * (lam - 538.0)) ** 2,
                 "|rgb| piecewise linear (used)": wavelength_pdf(lam)}
    table = {}
    for name, density in densities.items():
        p = density / np.trapezoid(density, lam)
        cdf = np.concatenate([[0.0], np.cumsum((p[1:] + p[:-1]) / 2 * np.diff(lam))])
        white = []
        for spp in spps:
            pixel, sample = np.repeat(np.arange(pixels), spp), np.tile(np.arange(spp), pixels)
            sampled = np.interp(stratified5(pixel, sample, 7)[4].astype(np.float64), cdf / cdf[-1], lam)
            colour = (cie_rgb(sampled) / np.interp(sampled, lam, p)[:, None]).reshape(pixels, spp, 3).mean(axis=1)
            white.append(float(np.sqrt(np.mean((colour - 1.0) ** 2))))
        table[name] = {"variance_rgb": estimator_variance(density, lam).tolist(), "white_rel_rmse": white}
    for k in wavelength_counts:
        if k == 1:
            continue  # the row "used" above
        white = []
        for spp in spps:
            pixel, sample = np.repeat(np.arange(pixels), spp), np.tile(np.arange(spp), pixels)
            sampled = wavelengths_nm(spectral_rays(pixel, sample, 7, k)[4])
            colour = rgb_response(sampled).astype(np.float64).reshape(pixels, spp * k, 3).mean(axis=1)
            white.append(float(np.sqrt(np.mean((colour - 1.0) ** 2))))
        table[f"used, K = {k} per sample"] = {"variance_rgb": stratified_response_variance(k).tolist(),
                                              "white_rel_rmse": white}
    return table


def print_stages(stages: list[dict]) -> None:
    """The stage table: microseconds per camera sample, and each spectral mode's over RGB's, per
    sample and per camera ray traced."""
    names = (*PASS_STAGES, "total")
    print(f"{'scene':28s} {'spp':>4s} {'mode':>13s} " + " ".join(f"{n[:10]:>10s}" for n in names)
          + f" {'cam rays':>8s} {'shadow':>7s}   (CPU us per sample; x: over RGB)")
    rgb = {(s["scene"], s["spp"]): s for s in stages if s["mode"] == "rgb"}
    for s in stages:
        print(f"{s['scene']:28s} {s['spp']:4d} {s['mode']:>13s} " + " ".join(f"{s[n]:10.3f}" for n in names)
              + f" {s['camera_rays']:8.2f} {s['shadow_rays']:7.2f}")
        base = rgb.get((s["scene"], s["spp"]))
        if s["mode"] != "rgb" and base is not None:
            rays = s["camera_rays"] / base["camera_rays"]
            print(f"{'':28s} {'':4s} {'x':>13s} "
                  + " ".join(f"{s[n] / base[n]:10.2f}" if base[n] > 0 else f"{'-':>10s}" for n in names)
                  + f" {rays:8.2f} "
                  + (f"{s['shadow_rays'] / base['shadow_rays']:7.2f}" if base["shadow_rays"] else f"{'-':>7s}"))
            print(f"{'':28s} {'':4s} {'x per ray':>13s} "
                  + " ".join(f"{s[n] / base[n] / rays:10.2f}" if base[n] > 0 else f"{'-':>10s}" for n in names))


def parse_counts(text: str) -> list[int]:
    counts = [int(v) for v in text.split(",") if v]
    if not counts or min(counts) < 1:
        raise SystemExit("spectral_noise: --wavelengths-per-sample takes positive whole numbers, e.g. 1,3")
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--res", help=f"WxH for every scene, or SCENE=WxH,... (default: {DEFAULT_RES})")
    parser.add_argument("--spps", default="16,64", help="test samples per pixel (default 16,64)")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--scenes", default="default,dof-dragons.dgauss.pbrt",
                        help="'default' and/or pbrt files in ../shared/scenes/pbrt")
    parser.add_argument("--wavelengths-per-sample", default=f"1,{DEFAULT_WAVELENGTHS_PER_SAMPLE}",
                        help="wavelengths (rays) per spectral camera sample, one spectral run each "
                             f"(default: 1,{DEFAULT_WAVELENGTHS_PER_SAMPLE}: one wavelength, and the default)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="timed renders of each test image; the shortest time is reported (default 3)")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    res = parse_res(args.res)
    spps = [int(v) for v in args.spps.split(",")]
    counts = parse_counts(args.wavelengths_per_sample)
    version = code_hash()
    densities = density_table(spps, counts)
    print(f"{'wavelength density':30s} {'var R':>6s} {'var G':>6s} {'var B':>6s}  "
          + " ".join(f"white@{spp:<4d}" for spp in spps))
    for name, d in densities.items():
        v = d["variance_rgb"]
        print(f"{name:30s} {v[0]:6.2f} {v[1]:6.2f} {v[2]:6.2f}  " + " ".join(f"{e:10.4f}" for e in d["white_rel_rmse"]))
    rows: list[dict] = []
    stages: list[dict] = []
    load_before = os.getloadavg()
    for scene_name in args.scenes.split(","):
        size = res.get("*", res.get(scene_name, (150, 150)))
        errors = {}
        for mode, wavelengths in [("rgb", None)] + [(f"spectral-k{k}", k) for k in counts]:
            scene = load(scene_name, size, wavelengths)
            key = f"{scene_name}-{size[0]}x{size[1]}-{mode}-{args.reference_spp}spp-seed{REFERENCE_SEED}-{version}"
            ref = reference(scene, key, args.reference_spp, args.out)
            for spp in spps:
                render(scene, spp, TEST_SEED)  # warm: the kernel for this spp, the BVH's first build
                timed = [render(scene, spp, TEST_SEED) for _ in range(args.repeats)]
                image = timed[0][0]
                seconds, cpu = min(t[1] for t in timed), min(t[2] for t in timed)
                errors[mode, spp] = (relative_rmse(image, ref), seconds, cpu)
                stages.append({"scene": scene_name, "spp": spp, "mode": mode,
                               **stage_costs(scene, spp, TEST_SEED)})
        for spp in spps:
            rgb, rgb_s, rgb_cpu = errors["rgb", spp]
            for k in counts:
                spec, spec_s, spec_cpu = errors[f"spectral-k{k}", spp]
                rows.append({"scene": scene_name, "resolution": list(size), "spp": spp, "wavelengths_per_sample": k,
                             "rel_rmse_rgb": rgb, "rel_rmse_spectral": spec, "ratio": spec / rgb,
                             "seconds_rgb": rgb_s, "seconds_spectral": spec_s,
                             "cpu_seconds_rgb": rgb_cpu, "cpu_seconds_spectral": spec_cpu,
                             "ratio_equal_time": spec / rgb * float(np.sqrt(spec_s / rgb_s)),
                             "ratio_equal_cpu_time": spec / rgb * float(np.sqrt(spec_cpu / rgb_cpu))})
    print(f"{'scene':28s} {'res':>8s} {'spp':>4s} {'K':>3s} {'relRMSE rgb':>12s} {'relRMSE spec':>13s} "
          f"{'ratio':>6s} {'s rgb':>6s} {'s spec':>7s} {'cpu rgb':>7s} {'cpu spec':>8s} {'ratio@time':>10s} "
          f"{'ratio@cpu':>9s}")
    for r in rows:
        res_text = "x".join(map(str, r["resolution"]))
        print(f"{r['scene']:28s} {res_text:>8s} {r['spp']:4d} {r['wavelengths_per_sample']:3d} "
              f"{r['rel_rmse_rgb']:12.5f} {r['rel_rmse_spectral']:13.5f} {r['ratio']:6.3f} "
              f"{r['seconds_rgb']:6.2f} {r['seconds_spectral']:7.2f} {r['cpu_seconds_rgb']:7.2f} "
              f"{r['cpu_seconds_spectral']:8.2f} {r['ratio_equal_time']:10.3f} {r['ratio_equal_cpu_time']:9.3f}")
    print_stages(stages)
    load_after = os.getloadavg()
    print(f"load average (1, 5, 15 min): {' '.join(f'{v:.2f}' for v in load_before)} before, "
          f"{' '.join(f'{v:.2f}' for v in load_after)} after, on {os.cpu_count()} CPUs")
    result = {"reference_spp": args.reference_spp, "code_hash": version, "densities": densities,
              "wavelengths_per_sample": counts, "repeats": args.repeats, "rows": rows, "stages": stages,
              "load_average": {"before": list(load_before), "after": list(load_after), "cpus": os.cpu_count()}}
    (args.out / "spectral_noise.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
