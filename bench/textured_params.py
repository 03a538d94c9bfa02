"""Textured-parameters benchmark: a pbrt-v4 scene of textured roughness and mix amount, path traced, two trees.

    .venv/bin/python bench/textured_params.py [--against ../old] [--rounds 3] [--res 300x200] [--spp 16]
        [--dispersion]

The fused bounce kernel (``kernels/bounce.cl``) first took a material only when every parameter but its
diffuse-like colour was constant: a textured roughness or a textured mix amount sent every hit on that
material to numpy's ``PathIntegrator._shade``. This renders one small pbrt-v4 scene (``scene_text``): a
floor of pbrt-v4's plastic (``coateddiffuse``) whose roughness is a checkerboard texture, spheres of a
mix of a matte and a rough conductor whose amount is a checkerboard, a conductor sphere of textured
roughness and a rough glass sphere, under a distant light and a constant sky, with ``Integrator
"path"`` (maxdepth 5), by ``python -m realistic render`` in a fresh process (``bench/seed.py``'s
``render``: CPU-seconds of the process, user + system, and wall), the trees alternating for
``--rounds`` rounds after one untimed small render each (kernels and tables built and cached).
``--dispersion`` renders through the dgauss lens with dispersion on (spectral rays). Prints the
median CPU-seconds and wall per tree and the ratio other / this, the CPU and the load average;
writes bench/results/textured_params.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))  # first already when run as a script; not when a test loads this file

import machine  # noqa: E402
from seed import render  # noqa: E402


def scene_text(res: str, spp: int) -> str:
    """The benchmark's pbrt-v4 scene at ``res`` (WxH) and ``spp`` samples per pixel."""
    width, height = res.split("x")
    return "\n".join([
        'LookAt 0 1.2 3.5  0 0.3 0  0 1 0', 'Camera "perspective" "float fov" [40]',
        f'Film "rgb" "integer xresolution" [{width}] "integer yresolution" [{height}] "string filename" "x.exr"',
        f'Sampler "halton" "integer pixelsamples" [{spp}]', 'Integrator "path" "integer maxdepth" [5]',
        'WorldBegin',
        'LightSource "distant" "point3 from" [1 4 2] "point3 to" [0 0 0] "rgb L" [2 2 2]',
        'LightSource "infinite" "rgb L" [0.4 0.45 0.5]',
        'Texture "rough" "float" "checkerboard" "float uscale" [16] "float vscale" [16] "float tex1" [0.02] '
        '"float tex2" [0.3]',
        'Texture "amount" "float" "checkerboard" "float uscale" [8] "float vscale" [8] "float tex1" [0.15] '
        '"float tex2" [0.85]',
        'MakeNamedMaterial "matte" "string type" "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
        'MakeNamedMaterial "metal" "string type" "conductor" "float roughness" [0.1]',
        'MakeNamedMaterial "blend" "string type" "mix" "string materials" ["matte" "metal"] "texture amount" "amount"',
        'AttributeBegin',
        'Material "coateddiffuse" "rgb reflectance" [0.5 0.55 0.6] "texture roughness" "rough"',
        'Shape "trianglemesh" "point3 P" [-4 0 -4  4 0 -4  4 0 4  -4 0 4] "point2 uv" [0 0  1 0  1 1  0 1] '
        '"integer indices" [0 2 1 0 3 2]',
        'AttributeEnd',
        'AttributeBegin', 'Translate -0.8 0.35 0.5', 'NamedMaterial "blend"', 'Shape "sphere" "float radius" [0.35]',
        'AttributeEnd',
        'AttributeBegin', 'Translate 0.9 0.35 0.3', 'NamedMaterial "blend"', 'Shape "sphere" "float radius" [0.35]',
        'AttributeEnd',
        'AttributeBegin', 'Translate 0.05 0.3 -0.4', 'Material "conductor" "texture roughness" "rough"',
        'Shape "sphere" "float radius" [0.3]', 'AttributeEnd',
        'AttributeBegin', 'Translate 0.1 0.25 0.9', 'Material "dielectric" "float roughness" [0.2]',
        'Shape "sphere" "float radius" [0.25]', 'AttributeEnd']) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, help="the other tree (a checkout of this project)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    parser.add_argument("--res", default="300x200", help="resolution WxH (default 300x200)")
    parser.add_argument("--spp", type=int, default=16, help="samples per pixel (default 16)")
    parser.add_argument("--dispersion", action="store_true",
                        help="through the dgauss lens with dispersion on (spectral rays)")
    args = parser.parse_args()
    trees = {"this": ROOT} if args.against is None else {"other": args.against.resolve(), "this": ROOT}
    lens = ["--lens", "dgauss", "--dispersion", "on"] if args.dispersion else []
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        scene = work / "textured.pbrt"
        scene.write_text(scene_text(args.res, args.spp))
        for name, tree in trees.items():  # untimed: kernels built, tables cached
            render(tree, scene, ["--res", "16x12", "--spp", "1", *lens], work / f"cache-{name}", work)
        for _ in range(args.rounds):
            for name, tree in trees.items():
                runs[name].append(render(tree, scene, lens, work / f"cache-{name}", work))
    row: dict[str, Any] = {name: {"cpu_s": [v[0] for v in values], "wall_s": [v[1] for v in values],
                                  "median_cpu_s": statistics.median(v[0] for v in values),
                                  "median_wall_s": statistics.median(v[1] for v in values)}
                           for name, values in runs.items()}
    if "other" in row:
        row["other_over_this_cpu"] = row["other"]["median_cpu_s"] / row["this"]["median_cpu_s"]
    load = os.getloadavg()
    print(f"{args.res}, {args.spp} spp, path (maxdepth 5), median of {args.rounds} rounds"
          + (", dgauss lens, dispersion on" if args.dispersion else ""))
    print(f"{'tree':6} {'CPU-s':>8} {'wall':>8}  runs (CPU-s)")
    for name in trees:
        print(f"{name:6} {row[name]['median_cpu_s']:8.2f} {row[name]['median_wall_s']:8.2f}  "
              + " ".join(f"{v:.2f}" for v in row[name]["cpu_s"]))
    if "other" in row:
        print(f"other/this CPU-s: {row['other_over_this_cpu']:.2f}")
    print(f"cpu: {machine.describe()}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    out = ROOT / "bench" / "results" / "textured_params.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cpu": machine.describe(), "load_average": load, "res": args.res, "spp": args.spp,
                               "rounds": args.rounds, "dispersion": args.dispersion,
                               "trees": {t: str(p) for t, p in trees.items()}, **row}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
