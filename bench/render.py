"""Render benchmark: where the time goes, against embree's own ceiling on the same scene.

    .venv/bin/python bench/render.py [--res 512x512] [--spp 64] [--backend opencl|numpy] [--threads N]
        [--pass-samples 32768,131072] [--repeats 3]

Renders the dragon (../shared/meshes/dragon.ply, else a procedural mesh of similar size) on the
grid floor under a disk light: samples in raster order at each ``--pass-samples`` size (default: the
renderer's), then at the renderer's size sorted along a Morton curve per pass, then in raster order
with its threads left free to move between CPUs ("free": ``pin_threads=False``). Prints per-stage
thread-seconds of the fastest of ``--repeats`` runs (``--threads`` workers, by default the
renderer's ``default_threads()``: one per core, so they can add up to the wall time times the
cores), shading's thread-seconds per sample against embree's (backend "opencl" shades with
``kernels/shade.cl`` on PoCL, whose own threads are not counted: a worker waiting for its launch
counts the launch's wall time), rays per second, and the ceiling: every primary and shadow ray of
the raster render, made again and traced by embree alone on as many threads, through the
renderer's binding (``scene/intersect``) and through embreex's own (``EmbreeScene.run`` on a
world-space copy of the scene), the issue's original measure; and embree's thread-seconds inside
the render against alone, which says what sharing the cores costs it, in wall time (a render thread
waiting for a core or the GIL counts) and in CPU time (``StageClock.cpu_seconds``: traversal alone,
which the wall figure must not be mistaken for).

The ceiling is traced once per repeat, right after that repeat's renders, so that a render and the
ceiling it is divided by see the same load: the fraction of the ceiling and embree's speed inside
the render against alone are taken within each repeat and printed as their median and spread (min
to max) over the repeats; the ceiling's samples/s likewise. On a shared machine the figures are
noisy: the load average is printed before and after.
Writes bench/results/render.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import machine  # noqa: E402
from realistic import load_lens  # noqa: E402
from realistic.camera.base import SampleBlock  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM, film_size_mm  # noqa: E402
from realistic.core.transforms import transform_points  # noqa: E402
from realistic.renderer.job import PassSettings, RenderJob  # noqa: E402
from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES, plan_passes  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.renderer.runner import PassRunner  # noqa: E402
from realistic.renderer.thread_count import default_threads  # noqa: E402
from realistic.renderer.timing import STAGES, StageClock  # noqa: E402
from realistic.scene.intersect import Intersector  # noqa: E402
from realistic.scene.meshes import MeshObject, load_mesh_file  # noqa: E402
from realistic.scene.model import Mesh  # noqa: E402
from realistic.scene.packet_loop import lane_rows  # noqa: E402
from realistic.scene.shapes import light_mesh, sphere  # noqa: E402
from realistic.scene.staging import auto_eye, mesh_setup  # noqa: E402

DRAGON = ROOT.parent / "shared" / "meshes" / "dragon.ply"


def subject() -> tuple[list[MeshObject], str]:
    if DRAGON.is_file():
        return load_mesh_file(DRAGON), str(DRAGON)
    ball = sphere(1.0, 448)  # about 200k triangles, bumped so it is not trivially convex
    bumps = 1 + 0.08 * np.sin(9 * ball.vertices[:, 0]) * np.sin(7 * ball.vertices[:, 1] + 3 * ball.vertices[:, 2])
    mesh = Mesh(ball.vertices * bumps[:, None], ball.faces, None, None, "procedural")
    return [MeshObject(mesh, np.eye(4), None)], f"procedural ({len(mesh.faces)} triangles)"


def staged_subject(lens_name: str, width: int, height: int, spp: int) -> tuple:
    """The subject on its grid floor and a camera through ``lens_name`` framing it: (setup, camera,
    description of the subject, a 16x16 1-spp camera of the same view for warming up). Shared by
    the benches that render this scene."""
    objects, source = subject()
    setup = mesh_setup(objects)
    lens = load_lens(lens_name)
    eye = auto_eye(setup, lens, min(film_size_mm(FULL_FRAME_DIAGONAL_MM, width, height)))

    def camera(w: int, h: int, samples: int) -> LensCamera:
        return LensCamera.looking_at(lens, eye, setup.target, None, FULL_FRAME_DIAGONAL_MM, w, h, samples)

    return setup, camera(width, height, spp), source, camera(16, 16, 1)


def middle_block(camera, samples: int) -> SampleBlock:
    """Up to ``samples`` samples from the middle of the render (all of a render smaller than that)."""
    samples = min(samples, camera.sample_count)
    return SampleBlock(max(0, camera.sample_count // 2 - samples // 2), samples, camera.spp)


class RecordingIntersector(Intersector):
    """Keeps the rays it is asked to trace (for the ceiling measurement)."""

    def __init__(self, scene):
        super().__init__(scene)
        self.primary, self.shadow = [], []

    def closest(self, origin, direction, coherent=False):
        self.primary.append((origin.copy(), direction.copy()))
        return super().closest(origin, direction, coherent=coherent)

    def occluded(self, origin, direction, distance):
        self.shadow.append((origin.copy(), direction.copy(), np.array(distance)))
        return super().occluded(origin, direction, distance)

    def occluded_lanes(self, origin, vector, length):
        """The shading kernel's rays in lanes kept as point-major rows (copies): the same rays, in the
        order embree traces them."""
        rows = (lane_rows(origin).reshape(-1, 3), lane_rows(vector).reshape(-1, 3), lane_rows(length).reshape(-1))
        self.shadow.append(rows)
        return super().occluded_lanes(origin, vector, length)


class Traced(NamedTuple):
    """A batch of jobs run on threads: its wall seconds and the threads' CPU seconds, summed."""
    wall: float
    cpu: float


def traced_on_threads(jobs: list, threads: int) -> Traced:
    """The jobs (callables) run on ``threads`` threads, dealt out in turn: the wall seconds, and the
    CPU seconds each thread ran (``time.thread_time``), summed. Each job's result is dropped as soon
    as it is made, as a render drops a pass's hits: holding every result until the end (as this once
    did) made each job fault in fresh pages, and understated the ceiling by 3 to 13 %."""
    shares = [jobs[i::threads] for i in range(threads)]
    cpu = [0.0] * threads

    def work(k: int) -> None:
        start = time.thread_time()
        for job in shares[k]:
            job()
        cpu[k] = time.thread_time() - start

    workers = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
    start = time.perf_counter()
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    return Traced(time.perf_counter() - start, sum(cpu))


def recorded_rays(setup, camera, backend: str, pass_samples: int = DEFAULT_PASS_SAMPLES) -> RecordingIntersector:
    """Every primary and shadow ray of the render ``run`` makes (its pass plan, raster order, one
    light sample, seed 0), made again by the renderer's own ``PassRunner`` and kept."""
    recorder = RecordingIntersector(setup.scene)
    runner = PassRunner(setup.scene, camera, PassSettings(backend), StageClock(), recorder)
    for index, block in enumerate(plan_passes(camera.width * camera.height, camera.spp, pass_samples)):
        runner(index, block)
    return recorder


def ceiling_jobs(setup, camera, backend: str) -> tuple[dict, dict, tuple]:
    """The ceiling's work: the render's primary and shadow rays (``recorded_rays``) as 64k-ray jobs,
    per binding (prefix "" the renderer's ``Intersector``, "embreex_" embreex's own), the counts of
    samples and rays, and the scenes the jobs trace (to be held as long as they are used). All of
    the rays, not one pass's: the passes differ in cost (the middle one, where the dragon fills the
    frame, traced 1.5 to 2 times slower per sample than the image's mean), so one pass misstates
    the ceiling."""
    recorder = recorded_rays(setup, camera, backend)
    chunk = 1 << 16
    primary = [(o[s:s + chunk], d[s:s + chunk]) for o, d in recorder.primary for s in range(0, len(o), chunk)]
    shadow = [(o[s:s + chunk], d[s:s + chunk], t[s:s + chunk]) for o, d, t in recorder.shadow
              for s in range(0, len(o), chunk)]
    # shadow rows of dead light samples (length -1; embree skips them) are traced but not counted, as in the render
    counts = {"samples": camera.sample_count, "primary_rays": sum(len(o) for o, _ in primary),
              "shadow_rays": sum(int(np.count_nonzero(t > 0)) for _, _, t in shadow)}
    ours = Intersector(setup.scene)
    theirs, buffers = embreex_scene(setup.scene)
    tracers = {"": (ours.closest, ours.occluded),
               "embreex_": (lambda o, d: theirs.run(o, d, output=1),
                            lambda o, d, t: theirs.run(o, d, query="OCCLUDED", dists=t.copy()))}
    jobs = {prefix: ([lambda rays=rays, f=closest: f(*rays) for rays in primary],
                     [lambda rays=rays, f=occluded: f(*rays) for rays in shadow])
            for prefix, (closest, occluded) in tracers.items()}
    return jobs, counts, (ours, theirs, buffers)


def trace_ceiling(jobs: dict, counts: dict, threads: int) -> dict:
    """One try of the ceiling: each binding's primary jobs, then its shadow jobs, on ``threads``
    threads; rays and samples per second."""
    result = {}
    for prefix, (primary_jobs, shadow_jobs) in jobs.items():
        primary, shadow = traced_on_threads(primary_jobs, threads), traced_on_threads(shadow_jobs, threads)
        result |= {f"{prefix}primary_rays_per_s": counts["primary_rays"] / primary.wall,
                   f"{prefix}shadow_rays_per_s": counts["shadow_rays"] / shadow.wall,
                   f"{prefix}samples_per_s": counts["samples"] / (primary.wall + shadow.wall),
                   f"{prefix}seconds": primary.wall + shadow.wall,
                   f"{prefix}cpu_seconds": primary.cpu + shadow.cpu}
    return result


def spread(values: list[float]) -> dict:
    """The median, least and greatest of ``values``."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def cell(figure: dict, factor: float = 1.0) -> str:
    """A figure's median [min-max] times ``factor``, to one decimal."""
    return f"{figure['median'] * factor:.1f} [{figure['min'] * factor:.1f}-{figure['max'] * factor:.1f}]"


def embreex_scene(scene) -> tuple:
    """The scene's instances and lights copied to world space into one embreex scene (its BVH built),
    and the arrays it reads (to be held as long as it is used)."""
    flat = rtcore_scene.EmbreeScene()
    meshes = [(inst.transform, scene.meshes[inst.mesh]) for inst in scene.instances]
    meshes += [(light.transform, light_mesh(light)) for light in scene.area_lights]
    buffers = []
    for transform, mesh in meshes:
        vertices = np.ascontiguousarray(transform_points(transform, mesh.vertices), np.float32)
        faces = np.ascontiguousarray(mesh.faces, np.int32)
        buffers.append((vertices, faces, TriangleMesh(flat, vertices, faces)))
    one = np.zeros((1, 3), np.float32)
    flat.run(one, one + np.float32(1))
    return flat, buffers


def run(setup, camera, backend: str, morton: bool, threads: int | None = None,
        pass_samples: int = DEFAULT_PASS_SAMPLES, pinned: bool = True) -> dict:
    job = RenderJob(setup.scene, (camera,), backend, seed=0, pass_samples=pass_samples, morton=morton)
    result = render(job, ThreadPasses(threads, pinned))[0]
    rays = result.primary_rays + result.shadow_rays
    label = f"{'morton' if morton else 'raster'} {pass_samples // 1024}k{'' if pinned else ' free'}"
    return {"label": label, "morton": morton, "pass_samples": pass_samples, "pinned": pinned, "seconds": result.seconds,
            "samples": result.samples_done,
            "primary_rays": result.primary_rays, "shadow_rays": result.shadow_rays,
            "samples_per_s": result.samples_done / result.seconds, "rays_per_s": rays / result.seconds,
            "stage_thread_seconds": {s: result.stage_seconds.get(s, 0.0) for s in STAGES},
            "embree_cpu_seconds": result.stage_cpu_seconds.get("embree", 0.0)}


def pass_sizes(text: str) -> list[int]:
    """``--pass-samples``: comma-separated positive sample counts."""
    sizes = [int(v) for v in text.split(",")]
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"pass sizes must be positive integers, got {text!r}")
    return sizes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", default="512x512")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--backend", default="opencl", choices=("opencl", "numpy"))
    parser.add_argument("--lens", default="dgauss")
    parser.add_argument("--threads", type=int, default=default_threads(),
                        help=f"render worker threads (default {default_threads()}: the renderer's, one per core)")
    parser.add_argument("--pass-samples", type=pass_sizes, default=[DEFAULT_PASS_SAMPLES], metavar="N,N,...",
                        help=f"pass sizes to compare in raster order (default {DEFAULT_PASS_SAMPLES}, the renderer's)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="runs of each configuration, interleaved, each followed by a try of the ceiling; "
                             "the fastest run's stages are shown (default 3)")
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    setup, camera, source, warm = staged_subject(args.lens, width, height, args.spp)
    triangles = sum(len(setup.scene.meshes[i.mesh].faces) for i in setup.scene.instances)
    print(f"scene: {source}, {triangles} triangles; {width}x{height}, {args.spp} spp, lens {args.lens}, "
          f"backend {args.backend}, default passes of {DEFAULT_PASS_SAMPLES} samples on {args.threads} thread(s)")
    render(RenderJob(setup.scene, (warm,), args.backend))  # warm-up: kernel build and caches
    jobs, counts, _scenes = ceiling_jobs(setup, camera, args.backend)
    configs = [(False, size, True) for size in args.pass_samples] + [(True, DEFAULT_PASS_SAMPLES, True),
                                                                      (False, DEFAULT_PASS_SAMPLES, False)]
    load_before = os.getloadavg()
    tries: list[list[dict]] = [[] for _ in configs]
    ceilings: list[dict] = []
    for _ in range(args.repeats):  # interleaved, so a load change on a shared machine hits every config alike
        for i, (morton, size, pinned) in enumerate(configs):
            tries[i].append(run(setup, camera, args.backend, morton, args.threads, size, pinned))
        ceilings.append(trace_ceiling(jobs, counts, args.threads))
    load_after = os.getloadavg()
    runs = [min(config_tries, key=lambda r: r["seconds"]) for config_tries in tries]
    top = {"samples": counts["samples"], "threads": args.threads, "primary_rays": counts["primary_rays"],
           "shadow_rays": counts["shadow_rays"], "tries": ceilings}
    for key in ceilings[0]:
        top[key] = statistics.median(c[key] for c in ceilings)
        top[f"{key}_spread"] = spread([c[key] for c in ceilings])
    print(f"load average {load_before[0]:.2f} before, {load_after[0]:.2f} after (shared machine: noisy)")
    column = max(14, *(len(r["label"]) + 4 for r in runs))
    print(f"\n{'stage':<16}" + "".join(f"{r['label'] + ' s':>{column}}{'share':>8}" for r in runs))
    for stage in STAGES:
        cells = []
        for r in runs:
            seconds = r["stage_thread_seconds"][stage]
            cells.append(f"{seconds:>{column}.2f}{100 * seconds / sum(r['stage_thread_seconds'].values()):>7.1f}%")
        print(f"{stage:<16}{''.join(cells)}")
    print(f"{'wall':<16}" + "".join(f"{r['seconds']:>{column}.2f}{'':>8}" for r in runs))
    for r in runs:
        stages = r["stage_thread_seconds"]
        r["shading_over_embree"] = stages["shading"] / max(stages["embree"], 1e-12)
        r["shading_us_per_sample"] = 1e6 * stages["shading"] / r["samples"]
        r["embree_us_per_sample"] = 1e6 * stages["embree"] / r["samples"]
        print(f"{r['label']}: shading {r['shading_us_per_sample']:.3f} us/sample, "
              f"embree {r['embree_us_per_sample']:.3f} us/sample (thread-seconds): "
              f"shading / embree = {r['shading_over_embree']:.2f}")
    for r in runs:
        print(f"{r['label']}: {r['samples_per_s'] / 1e6:.2f} M samples/s, {r['rays_per_s'] / 1e6:.2f} M rays/s "
              f"({r['primary_rays']} primary + {r['shadow_rays']} shadow rays)")
    for prefix, name in (("", "embree ceiling (the renderer's binding)"), ("embreex_", "embreex's own binding")):
        print(f"{name}, all of the render's rays, {args.threads} threads, nothing else, median [min-max] of "
              f"{args.repeats}: primary {cell(top[prefix + 'primary_rays_per_s_spread'], 1e-6)} M/s, "
              f"shadow {cell(top[prefix + 'shadow_rays_per_s_spread'], 1e-6)} M/s, "
              f"{cell(top[prefix + 'samples_per_s_spread'], 1e-6)} M samples/s")
    for r, config_tries in zip(runs, tries):
        # within each repeat: its render against the ceiling traced right after it
        fraction = [t["samples_per_s"] / c["samples_per_s"] for t, c in zip(config_tries, ceilings)]
        embreex = [t["samples_per_s"] / c["embreex_samples_per_s"] for t, c in zip(config_tries, ceilings)]
        # alone, every thread traces until the last chunk: thread-seconds = threads x wall
        alone = [args.threads * c["seconds"] / max(t["stage_thread_seconds"]["embree"], 1e-12)
                 for t, c in zip(config_tries, ceilings)]
        # the same rays' CPU seconds: what traversal costs, whatever the threads waited for
        alone_cpu = [c["cpu_seconds"] / max(t["embree_cpu_seconds"], 1e-12) for t, c in zip(config_tries, ceilings)]
        r["fraction_of_ceiling"], r["fraction_of_ceiling_spread"] = statistics.median(fraction), spread(fraction)
        r["fraction_of_embreex_ceiling"] = statistics.median(embreex)
        r["fraction_of_embreex_ceiling_spread"] = spread(embreex)
        r["embree_alone_over_inside"], r["embree_alone_over_inside_spread"] = statistics.median(alone), spread(alone)
        r["embree_cpu_alone_over_inside"] = statistics.median(alone_cpu)
        r["embree_cpu_alone_over_inside_spread"] = spread(alone_cpu)
        print(f"{r['label']}: end to end / ceiling {cell(r['fraction_of_ceiling_spread'], 100)} % "
              f"(/ embreex's {cell(r['fraction_of_embreex_ceiling_spread'], 100)} %); embree inside the render runs "
              f"at {cell(r['embree_alone_over_inside_spread'], 100)} % of its speed alone in thread wall time, "
              f"{cell(r['embree_cpu_alone_over_inside_spread'], 100)} % in CPU time (median [min-max] of "
              f"{args.repeats} repeats, each against its own ceiling)")
    report = {"machine": machine.describe(), "load_average": [load_before, load_after],
              "scene": source, "triangles": triangles, "resolution": [width, height], "spp": args.spp,
              "backend": args.backend, "lens": args.lens, "default_pass_samples": DEFAULT_PASS_SAMPLES,
              "threads": args.threads, "runs": runs, "ceiling": top}
    out = ROOT / "bench" / "results" / "render.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
