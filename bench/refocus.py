"""Refocus benchmark: a first render against re-renders after ``with_focus`` and ``with_stop``.

    .venv/bin/python bench/refocus.py [--scene ../shared/meshes/dragon.ply] [--res 96x64] [--spp 1] [--repeats 3]

In one process (the Python API, as a notebook uses it): the first render of a scene (embree BVH,
kernel programs, exit-pupil table), then, alternating, re-renders of the same Scene object through
``camera.with_focus(d)`` and ``camera.with_stop(f_number=N)`` (new focus distances and f-numbers
each round, so no exit-pupil table comes from memory; the disk cache has those an earlier run of
this bench built, as ``REALISTIC_CACHE_DIR`` says), and the same refocus on a copy of the Scene
(a new object: its BVH is built again), which is what a re-render cost before the intersector was
kept per Scene. Prints the median seconds of each; writes bench/results/refocus.json.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import realistic as rl  # noqa: E402
from realistic.camera.base import Camera  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402

DEFAULT_SCENE = ROOT.parent / "shared" / "meshes" / "dragon.ply"


def seconds(scene: rl.Scene, camera: Camera) -> float:
    """Wall-clock seconds of one render of ``scene`` through ``camera``."""
    start = time.perf_counter()
    rl.render(scene, camera)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(DEFAULT_SCENE) if DEFAULT_SCENE.exists() else None,
                        help="scene or mesh file (default: ../shared/meshes/dragon.ply, else the default scene)")
    parser.add_argument("--res", default="96x64", help="resolution WxH (default: %(default)s)")
    parser.add_argument("--spp", type=int, default=1, help="samples per pixel (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of re-renders (default: %(default)s)")
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.lower().split("x"))
    scene = rl.load_scene(args.scene, resolution=(width, height), spp=args.spp)
    camera = scene.camera
    if not isinstance(camera, LensCamera):
        raise SystemExit("the scene's camera has no lens to refocus")
    first = seconds(scene, camera)
    timings: dict[str, list[float]] = {"re-render, with_focus": [], "re-render, with_stop": [],
                                       "re-render, with_focus, copied Scene (BVH rebuilt)": []}
    for k in range(args.repeats):
        focus = camera.focus_distance * (1.1 + 0.1 * k)
        f_number = 4.0 + k
        timings["re-render, with_focus"].append(seconds(scene, camera.with_focus(focus)))
        timings["re-render, with_stop"].append(seconds(scene, camera.with_stop(f_number=f_number)))
        timings["re-render, with_focus, copied Scene (BVH rebuilt)"].append(
            seconds(copy.copy(scene), camera.with_focus(focus * 1.01)))
    rows = [{"row": "first render", "seconds": [first], "median_s": first}]
    rows += [{"row": label, "seconds": values, "median_s": statistics.median(values)}
             for label, values in timings.items()]
    print(f"scene {args.scene or 'default'}, {width}x{height}, {args.spp} spp, lens {camera.lens.name}")
    print(f"{'':52} {'median s':>9}")
    for row in rows:
        print(f"{row['row']:52} {row['median_s']:9.3f}")
    out = ROOT / "bench" / "results" / "refocus.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"scene": args.scene, "resolution": [width, height], "spp": args.spp,
                               "repeats": args.repeats, "cores": os.cpu_count(), "rows": rows}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
