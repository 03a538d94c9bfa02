"""Farm benchmark: in-process threads against a 2-worker Dask LocalCluster, scheduler overhead, and
the expected wall time of a 4K frame on bigger farms, from what was measured.

    .venv/bin/python bench/farm.py [--res 512x512] [--spp 64] [--workers 2] [--backend opencl|numpy]

1. The dragon (../shared/meshes/dragon.ply; the default scene when it is absent) rendered as
   ``python -m realistic render dragon.ply --res --spp`` does, on threads in this process and on a
   LocalCluster of ``--workers`` single-threaded processes; each after an untimed 1 spp render
   (kernel build, exit-pupil table, BVH), so the figures are steady-state samples/s.
2. Scheduler overhead: empty tasks per second through the scheduler, and tiny passes (1024
   samples, one per task) per second against the same passes on one thread in this process;
   the per-task overhead, and the task size above which it is under 2 % of a task.
3. Scaling on paper: a 3840x2160, 1,024 spp frame on 1, 8, 64 and 512 workers, each worker as
   fast as one measured here, with the scheduler's task rate, result transfer (the film sums: 24
   bytes a pixel) and scene shipping (the pickled scene to every worker) at an assumed 1 Gbit/s.

The machine is shared and has 2 cores: figures are noisy; compare within one run. Writes
bench/results/farm.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pickle
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from distributed import Client, LocalCluster, wait  # noqa: E402

from realistic.renderer.farm import DEFAULT_TASK_SAMPLES, DaskPasses  # noqa: E402
from realistic.renderer.inputs import RenderOptions, build_render_inputs  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.pass_plan import DEFAULT_PASS_SAMPLES  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.renderer.thread_count import default_threads  # noqa: E402

DRAGON = ROOT.parent / "shared" / "meshes" / "dragon.ply"
NETWORK_BYTES_PER_S = 125e6  # 1 Gbit/s: an assumption, not measured
TINY_PASS = 1024
FRAME_4K = (3840, 2160, 1024)
FARMS = (1, 8, 64, 512)


def _noop(i: int) -> int:
    return i


def steady_rate(scene, camera, backend: str, client=None) -> tuple[float, float]:
    """(samples/s, seconds) of a render after an untimed 1 spp one, less this process's set-up (an
    in-process render builds its BVH per call; workers keep theirs)."""
    executor = DaskPasses(client) if client is not None else ThreadPasses(pin_threads=True)
    render(RenderJob(scene, (dataclasses.replace(camera, spp=1),), backend), executor)
    result = render(RenderJob(scene, (camera,), backend), executor)[0]
    seconds = result.seconds - result.stage_seconds.get("setup", 0.0) - result.stage_seconds.get("exit pupil", 0.0)
    return result.samples_done / seconds, seconds


def empty_task_rate(client: Client, count: int = 2000) -> float:
    start = time.perf_counter()
    wait(client.map(_noop, range(count), pure=False))
    return count / (time.perf_counter() - start)


def tiny_pass_overhead(scene, camera, backend: str, client: Client, workers: int) -> dict:
    """Seconds of overhead per task: farm task time x workers / tasks, less one pass's compute."""
    tiny = dataclasses.replace(camera, width=128, height=128, spp=4)
    render(RenderJob(scene, (tiny,), backend, pass_samples=TINY_PASS), ThreadPasses(1, pin_threads=True))  # warm
    local = render(RenderJob(scene, (tiny,), backend, pass_samples=TINY_PASS), ThreadPasses(1, pin_threads=True))[0]
    render(RenderJob(scene, (tiny,), backend, pass_samples=TINY_PASS), DaskPasses(client, TINY_PASS))  # warm
    farm = render(RenderJob(scene, (tiny,), backend, pass_samples=TINY_PASS), DaskPasses(client, TINY_PASS))[0]
    tasks = farm.passes_total
    compute = local.seconds / tasks
    per_task = farm.seconds * workers / tasks
    return {"tasks": tasks, "compute_s_per_pass": compute, "farm_s_per_task_per_worker": per_task,
            "overhead_s_per_task": max(per_task - compute, 0.0), "tiny_passes_per_s": tasks / farm.seconds,
            "sample_seconds": local.seconds / local.samples_done}


def scaling(rate_per_worker: float, overhead_s: float, task_rate: float, scene_bytes: int, setup_s: float,
            task_samples: int) -> list[dict]:
    width, height, spp = FRAME_4K
    samples = width * height * spp
    tasks = math.ceil(samples / task_samples)
    transfer = width * height * 24 / NETWORK_BYTES_PER_S  # float64 RGB sums, each pixel in one pass at 1024 spp
    rows = []
    for workers in FARMS:
        terms = {"compute": samples / (workers * rate_per_worker), "task overhead": tasks * overhead_s / workers,
                 "scheduler": tasks / task_rate,
                 "scene shipping": scene_bytes * math.ceil(math.log2(workers + 1)) / NETWORK_BYTES_PER_S + setup_s,
                 "result transfer": transfer}
        # workers compute while the scheduler hands out tasks and results stream back; shipping comes first
        bounds = {"compute": terms["compute"] + terms["task overhead"], "scheduler": terms["scheduler"],
                  "result transfer": terms["result transfer"]}
        limit = max(bounds, key=bounds.get)
        wall = bounds[limit] + terms["scene shipping"]
        rows.append({"workers": workers, "tasks": tasks, **{k: round(v, 3) for k, v in terms.items()},
                     "wall_s": round(wall, 1), "limited_by": limit})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--res", default="512x512")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--backend", default="opencl", choices=("opencl", "numpy"))
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    scene_file = str(DRAGON) if DRAGON.is_file() else None
    inputs = build_render_inputs(RenderOptions(scene=scene_file, resolution=(width, height), spp=args.spp))
    scene, camera = inputs.scene, inputs.camera
    print(f"scene: {scene_file or 'default scene (dragon not found)'}, {width}x{height}, {args.spp} spp, "
          f"backend {args.backend}; machine shared, 2 cores: compare within this run")

    threads_rate, threads_s = steady_rate(scene, camera, args.backend)
    started = time.perf_counter()
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    cluster_start_s = time.perf_counter() - started
    try:
        farm_rate, farm_s = steady_rate(scene, camera, args.backend, client)
        task_rate = empty_task_rate(client)
        tiny = tiny_pass_overhead(scene, camera, args.backend, client, args.workers)
    finally:
        client.close()
        cluster.close()
    overhead = tiny["overhead_s_per_task"]
    sample_s = 1.0 / (farm_rate / args.workers)
    two_percent = math.ceil(49 * overhead / sample_s) if overhead > 0 else 0
    described = dataclasses.replace(scene, camera=None)
    scene_bytes = len(pickle.dumps(described))
    setup = render(RenderJob(scene, (dataclasses.replace(camera, spp=1),), args.backend),
                   ThreadPasses(pin_threads=True))[0].stage_seconds
    setup_s = setup.get("setup", 0.0) + setup.get("exit pupil", 0.0)
    task_samples = max(DEFAULT_TASK_SAMPLES, two_percent)
    rows = scaling(farm_rate / args.workers, overhead, task_rate, scene_bytes, setup_s, task_samples)

    print(f"\n{'':24}{'seconds':>9}{'M samples/s':>13}")
    print(f"{f'threads ({default_threads()}, in-process)':24}{threads_s:9.2f}{threads_rate / 1e6:13.3f}")
    print(f"{f'LocalCluster ({args.workers} procs)':24}{farm_s:9.2f}{farm_rate / 1e6:13.3f}")
    print(f"ratio cluster / threads: {farm_rate / threads_rate:.2f}   (cluster start {cluster_start_s:.1f} s)")
    print(f"\nscheduler: {task_rate:.0f} empty tasks/s; {tiny['tiny_passes_per_s']:.0f} tiny passes/s "
          f"({TINY_PASS} samples, {tiny['compute_s_per_pass'] * 1e3:.1f} ms each in-process); overhead "
          f"{overhead * 1e3:.1f} ms/task; under 2 % from {two_percent} samples a task "
          f"({two_percent / DEFAULT_PASS_SAMPLES:.2f} passes of {DEFAULT_PASS_SAMPLES})")
    print(f"\nscaling on paper: 3840x2160, 1024 spp ({FRAME_4K[0] * FRAME_4K[1] * FRAME_4K[2] / 1e9:.2f} G samples), "
          f"{farm_rate / args.workers / 1e6:.2f} M samples/s a worker, tasks of {task_samples} samples, "
          f"scene {scene_bytes / 1e6:.1f} MB, worker set-up {setup_s:.2f} s, network 1 Gbit/s (assumed)")
    head = ["workers", "compute", "task overhead", "scheduler", "scene shipping", "result transfer", "wall_s"]
    print("".join(f"{h:>16}" for h in head) + "  limited by")
    for row in rows:
        print("".join(f"{row[h]:>16}" for h in head) + f"  {row['limited_by']}")
    report = {"scene": scene_file or "default", "res": [width, height], "spp": args.spp, "backend": args.backend,
              "workers": args.workers, "threads_samples_per_s": threads_rate, "farm_samples_per_s": farm_rate,
              "ratio": farm_rate / threads_rate, "cluster_start_s": cluster_start_s, "empty_tasks_per_s": task_rate,
              **tiny, "two_percent_task_samples": two_percent, "scene_bytes": scene_bytes, "setup_s": setup_s,
              "scaling": rows}
    out = ROOT / "bench" / "results" / "farm.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(report, indent=1) + "\n")
    print(f"\nwrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
