"""Seed-scene benchmark: the measured-BRDF dragons rendered by this tree and another, alternating.

    .venv/bin/python bench/seed.py [--against ../old] [--rounds 3] [--scene dof-dragons|seed]
                                   [--res WxH] [--spp N]

Scenes: ``dof-dragons`` is pbrt-v2's ``../shared/scenes/pbrt/dof-dragons.pbrt`` (thin-lens
perspective camera, 128 light samples, measured ``.brdf`` dragons) with its missing
``geometry/dragon.pbrt`` supplied as ``../shared/meshes/dragon.ply`` (a one-line file in a temporary
search path), by default at 500 x 212 and 16 spp as pbrt-v2 was timed; ``seed`` is
``scenes/dof-dragons/seed.pbrt`` (the dgauss lens, 4 light samples), by default at 300 x 300 and 512 spp, the
issue's target of ``SEED_WALL_S`` seconds wall. Each render is ``python -m realistic render`` in a
fresh process, the two trees alternating for ``--rounds`` rounds so that the machine's drift falls
on both alike, each with its own kernel and table cache, warmed by one small untimed render first
(so that a table built once per file is not timed). Per tree: the median CPU-seconds of the process
(user + system) and its wall seconds, the ratio of the medians, and the CPU-seconds against
pbrt-v2's on the issue's machine (``PBRT_V2_CPU_S``, dof-dragons at 500 x 212, 16 spp; not measured
by this run), and whether the wall time meets its target. Prints a table and the load average, and
writes bench/results/seed.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))  # first already when run as a script; not when a test loads this file

import machine  # noqa: E402

SHARED = ROOT.parent / "shared"
#: pbrt-v2 on dof-dragons.pbrt at 500 x 212, 16 spp, 128 light samples: CPU-seconds (issue 35).
PBRT_V2_CPU_S = 157.0
SCENES = {"dof-dragons": SHARED / "scenes" / "pbrt" / "dof-dragons.pbrt",
          "seed": ROOT / "scenes" / "dof-dragons" / "seed.pbrt"}
#: Each scene's default resolution and samples per pixel.
DEFAULTS = {"dof-dragons": ("500x212", 16), "seed": ("300x300", 512)}
#: The seed scene at 300 x 300 and 512 spp: the issue's target in wall seconds.
SEED_WALL_S = 60.0


def render(tree: Path, scene: Path, arguments: list[str], cache: Path, work: Path) -> tuple[float, float]:
    """CPU-seconds (user + system) and wall seconds of one render by ``tree`` in a fresh process."""
    environment = dict(os.environ, PYTHONPATH=str(tree), REALISTIC_CACHE_DIR=str(cache))
    command = [sys.executable, "-m", "realistic", "render", str(scene), "--search-path", str(work),
               "-o", str(work / "out.exr"), "--quiet", *arguments]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, cwd=tree, env=environment, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, help="the other tree (a checkout of this project)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    parser.add_argument("--scene", choices=sorted(SCENES), default="dof-dragons")
    parser.add_argument("--res", help="resolution WxH (default: 500x212 for dof-dragons, 300x300 for seed)")
    parser.add_argument("--spp", type=int, help="samples per pixel (default: 16 for dof-dragons, 512 for seed)")
    args = parser.parse_args()
    args.res = args.res or DEFAULTS[args.scene][0]
    args.spp = args.spp or DEFAULTS[args.scene][1]
    scene = SCENES[args.scene]
    if not scene.is_file() or not (SHARED / "meshes" / "dragon.ply").is_file():
        raise SystemExit(f"bench/seed.py needs ../shared (the scene and meshes/dragon.ply): {SHARED}")
    trees = {"this": ROOT}
    if args.against is not None:
        trees = {"other": args.against.resolve(), "this": ROOT}
    arguments = ["--res", args.res, "--spp", str(args.spp)]
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        (work / "geometry").mkdir()
        (work / "geometry" / "dragon.pbrt").write_text(
            f'Shape "plymesh" "string filename" "{SHARED / "meshes" / "dragon.ply"}"\n')
        for name, tree in trees.items():  # warm-up: kernels compiled, tables built and cached
            render(tree, scene, ["--res", "16x8", "--spp", "1"], work / f"cache-{name}", work)
        for round_number in range(args.rounds):
            for name, tree in trees.items():
                cpu, wall = render(tree, scene, arguments, work / f"cache-{name}", work)
                runs[name].append((cpu, wall))
                print(f"round {round_number + 1}, {name}: {cpu:.1f} CPU-s, {wall:.1f} s wall", file=sys.stderr)
    load = os.getloadavg()
    print(f"{args.scene} {args.res} {args.spp} spp, median of {args.rounds}")
    target = SEED_WALL_S if (args.scene, args.res, args.spp) == ("seed", "300x300", 512) else None
    print(f"{'tree':8} {'CPU-s':>8} {'wall s':>8} {'pbrt-v2 CPU-s / CPU-s':>22}"
          + (f" {'wall < ' + format(target, 'g') + ' s':>12}" if target else ""))
    rows: list[dict[str, Any]] = []
    for name, values in runs.items():
        cpu, wall = statistics.median(v[0] for v in values), statistics.median(v[1] for v in values)
        versus = PBRT_V2_CPU_S / cpu if (args.scene, args.res, args.spp) == ("dof-dragons", "500x212", 16) else None
        meets = None if target is None else wall < target
        rows.append({"tree": name, "path": str(trees[name]), "cpu_s": [v[0] for v in values],
                     "wall_s": [v[1] for v in values], "median_cpu_s": cpu, "median_wall_s": wall,
                     "pbrt_v2_ratio": versus, "meets_wall_target": meets})
        shown = f"{versus:22.2f}" if versus is not None else f"{'-':>22}"
        print(f"{name:8} {cpu:8.1f} {wall:8.1f} {shown}" + ("" if meets is None else f" {str(meets):>12}"))
    ratio = None
    if len(rows) == 2:
        ratio = rows[0]["median_cpu_s"] / rows[1]["median_cpu_s"]
        print(f"other / this CPU-s: {ratio:.2f}")
    print(f"cpu: {machine.describe()}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    out = ROOT / "bench" / "results" / "seed.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cpu": machine.describe(), "load_average": load,
                               "scene": args.scene, "res": args.res, "spp": args.spp, "rounds": args.rounds,
                               "pbrt_v2_cpu_s": PBRT_V2_CPU_S, "rows": rows, "other_over_this_cpu": ratio},
                              indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
