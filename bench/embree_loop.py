"""Ray-loop benchmark: embree alone through ``scene/embree``'s packet loops, this tree against another.

    .venv/bin/python bench/embree_loop.py [--against ../old] [--rounds 3] [--res 256x256] [--spp 16]
        [--startup-runs 5]

Throughput (``bench/render.py``'s ceiling, for the binding alone): every primary and shadow ray of
the dragon render (``recorded_rays``, made once by this tree with the numpy backend) traced through
``scene/intersect`` on 1 and 2 threads in 64k-ray chunks, the fastest of three tries, by a process
of each tree in turn for ``--rounds`` rounds; medians of samples/s and their ratio.

Start-up: a fresh process's first closest-hit trace (one ray at one triangle; for this tree, numba
imported and the loops compiled or loaded from numba's disk cache) with an empty cache ("cold") and
with the one the cold run filled ("warm"), and the whole process's wall time; medians of
``--startup-runs``, each tree in turn. Writes bench/results/embree_loop.json.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHUNK = 1 << 16

#: A child's first trace: run with the tree to measure as its working directory and first on sys.path.
FIRST_TRACE = """
import json, sys, time
import numpy as np
from realistic.scene.embree import EmbreeScene
scene = EmbreeScene()
scene.add_triangles(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]), 0)
scene.commit()
start = time.perf_counter()
scene.intersect(np.array([[0.25, 0.25, 1]], np.float32), np.array([[0, 0, -1]], np.float32))
print(json.dumps({"first_trace_s": time.perf_counter() - start}))
"""


def record(path: Path, res: str, spp: int) -> dict:
    """The render's primary and shadow rays, made by this tree and saved to ``path``."""
    sys.path.insert(0, str(ROOT))
    from bench.render import recorded_rays, staged_subject

    width, height = (int(v) for v in res.split("x"))
    setup, camera, _, _ = staged_subject("dgauss", width, height, spp)
    recorder = recorded_rays(setup, camera, "numpy")
    arrays: dict[str, Any] = {"primary_origin": np.concatenate([o for o, _, _ in recorder.primary]),
              "primary_direction": np.concatenate([d for _, d, _ in recorder.primary]),
              "shadow_origin": np.concatenate([o for o, _, _ in recorder.shadow]),
              "shadow_direction": np.concatenate([d for _, d, _ in recorder.shadow]),
              "shadow_distance": np.concatenate([np.broadcast_to(np.reshape(t, -1), len(o))
                                                        for o, _, t in recorder.shadow])}
    np.savez(path, samples=camera.sample_count, **arrays)
    return {"samples": int(camera.sample_count), "primary_rays": len(arrays["primary_origin"]),
            "shadow_rays": int(np.count_nonzero(arrays["shadow_distance"] > 0))}


def trace(rays: Path, res: str, spp: int, threads: int) -> dict:
    """(In a child whose tree is first on sys.path.) The saved rays traced through that tree's
    ``Intersector`` on ``threads`` threads: the fastest of three tries, as ``bench/render.py``'s ceiling."""
    from bench.render import staged_subject, traced_on_threads
    from realistic.scene.intersect import Intersector

    width, height = (int(v) for v in res.split("x"))
    setup, _, _, _ = staged_subject("dgauss", width, height, spp)
    saved = np.load(rays)
    ours = Intersector(setup.scene)
    po, pd = saved["primary_origin"], saved["primary_direction"]
    so, sd, st = saved["shadow_origin"], saved["shadow_direction"], saved["shadow_distance"]
    # camera rays, traced as the render traces them (coherent, ``EmbreeScene.intersect``, in a tree that has it)
    camera = {"coherent": True} if "coherent" in inspect.signature(Intersector.closest).parameters else {}
    primary = [lambda s=s: ours.closest(po[s:s + CHUNK], pd[s:s + CHUNK], **camera)
               for s in range(0, len(po), CHUNK)]
    shadow = [lambda s=s: ours.occluded(so[s:s + CHUNK], sd[s:s + CHUNK], st[s:s + CHUNK])
              for s in range(0, len(so), CHUNK)]
    ours.closest(po[:16], pd[:16])  # the loops compiled or loaded before timing
    ours.occluded(so[:16], sd[:16], st[:16])
    seconds = min(traced_on_threads(primary, threads).wall for _ in range(3)) + min(
        traced_on_threads(shadow, threads).wall for _ in range(3))
    return {"seconds": seconds, "samples_per_s": int(saved["samples"]) / seconds}


def child(tree: Path, arguments: list[str], env: dict[str, str] | None = None) -> dict:
    """Python with ``arguments`` in a process of its own, with ``tree`` as its working directory and
    first on sys.path; its last line of output, read as JSON."""
    environment = dict(env or os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, *arguments], cwd=tree, env=environment, capture_output=True, text=True,
                          check=False)
    if done.returncode:
        raise SystemExit(f"{tree}: {done.stderr.strip().splitlines()[-1]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def startup(tree: Path) -> dict:
    """First-trace seconds and process wall time of ``tree`` with an empty numba cache, then warm."""
    folder = tempfile.mkdtemp(prefix="numba-cache-")
    env = dict(os.environ, NUMBA_CACHE_DIR=folder)
    result = {}
    for name in ("cold", "warm"):
        start = time.perf_counter()
        first = child(tree, ["-c", FIRST_TRACE], env)["first_trace_s"]
        result[name] = {"first_trace_s": first, "process_s": time.perf_counter() - start}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, default=ROOT.parent / "old", help="the other tree (default ../old)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--res", default="256x256")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--startup-runs", type=int, default=5)
    parser.add_argument("--child-trace", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--threads", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child_trace:
        print(json.dumps(trace(args.child_trace, args.res, args.spp, args.threads)))
        return
    trees = {"this": ROOT, "against": args.against.resolve()}
    with tempfile.TemporaryDirectory() as folder:
        rays = Path(folder) / "rays.npz"
        counts = record(rays, args.res, args.spp)
        print(f"{counts['samples']} samples, {counts['primary_rays']} primary and {counts['shadow_rays']} shadow rays")
        throughput: dict = {f"{name} {threads}t": [] for threads in (1, 2) for name in trees}
        for _ in range(args.rounds):  # alternating, so a change of load hits both trees alike
            for threads in (1, 2):
                for name, tree in trees.items():
                    throughput[f"{name} {threads}t"].append(child(tree, [
                        str(Path(__file__)), "--child-trace", str(rays), "--res", args.res, "--spp", str(args.spp),
                        "--threads", str(threads)])["samples_per_s"])
    starts: dict = {name: [] for name in trees}
    for _ in range(args.startup_runs):
        for name, tree in trees.items():
            starts[name].append(startup(tree))
    print(f"\nthroughput, samples/s (median of {args.rounds}; this = {ROOT}, against = {trees['against']})")
    report: dict = {"counts": counts, "throughput": throughput, "startup": starts}
    for threads in (1, 2):
        ours, theirs = (statistics.median(throughput[f"{name} {threads}t"]) for name in trees)
        report[f"ratio_{threads}t"] = ours / theirs
        print(f"  {threads} thread(s): this {ours:,.0f}  against {theirs:,.0f}  ratio {ours / theirs:.3f}")
    print(f"\nstart-up, seconds (median of {args.startup_runs}): first trace / whole process")
    for name in trees:
        for cache in ("cold", "warm"):
            first = statistics.median([s[cache]["first_trace_s"] for s in starts[name]])
            process = statistics.median([s[cache]["process_s"] for s in starts[name]])
            print(f"  {name:<8} {cache} numba cache: {first:.3f} / {process:.3f}")
    out = ROOT / "bench" / "results" / "embree_loop.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
