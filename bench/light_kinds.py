"""Light-kinds benchmark: path tracing and direct lighting under each kind of light, this tree and another.

    .venv/bin/python bench/light_kinds.py [--against ../old] [--rounds 2] [--res 200x150] [--spp 32]
        [--only point,sky,map,mesh,sphere] [--dispersion]

The fused bounce kernel (``kernels/bounce.cl``) first sampled area lights alone: a scene with any other
light shaded every path vertex in numpy. This renders one small pbrt-v4 scene (a floor, a matte and a
rough copper sphere, and ``../shared/meshes/dragon.ply`` when it is there) under each kind of light,
``SCENES``: a point light; a distant light under a constant sky; a spot light under an image sky
(``../shared/scenes/pbrt/textures/lines.exr``, skipped without it); an emitting quad (a triangle mesh
under ``AreaLightSource``, the Cornell box's light); an emitting sphere. Each with ``Integrator
"path"`` (maxdepth 5) and ``"directlighting"``, by ``python -m realistic render`` in a fresh process
(``bench/seed.py``'s ``render``: CPU-seconds of the process, user + system, and wall), the trees
alternating for ``--rounds`` rounds after one untimed small render each (kernels and tables built and
cached). ``--dispersion`` renders through the dgauss lens with dispersion on (``--lens dgauss
--dispersion on``: each sample K rays of one wavelength each, the bounce kernel's spectral build). Prints
the median CPU-seconds and wall per scene and tree and the ratio other / this, the
CPU and the load average; writes bench/results/light_kinds.json.
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
from seed import SHARED, render  # noqa: E402

DRAGON = SHARED / "meshes" / "dragon.ply"
SKY_MAP = SHARED / "scenes" / "pbrt" / "textures" / "lines.exr"

#: The lights of each scene, in pbrt-v4's syntax ({sky} is the image sky's file).
SCENES = {
    "point": 'LightSource "point" "rgb I" [6 6 6] "point3 from" [1 3 2]',
    "sky": 'LightSource "distant" "point3 from" [1 4 2] "point3 to" [0 0 0] "rgb L" [2 2 2]\n'
           'LightSource "infinite" "rgb L" [0.4 0.45 0.5]',
    "map": 'LightSource "spot" "point3 from" [2 4 2] "point3 to" [0 0 0] "float coneangle" [30] "rgb I" [30 30 30]\n'
           'AttributeBegin\nRotate -90 1 0 0\nLightSource "infinite" "string filename" "{sky}"\nAttributeEnd',
    "mesh": 'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [12 11 9]\n'
            'Shape "trianglemesh" "point3 P" [-0.5 3 -0.5  0.5 3 -0.5  0.5 3 0.5  -0.5 3 0.5] '
            '"integer indices" [0 2 1 0 3 2]\nAttributeEnd',
    "sphere": 'AttributeBegin\nTranslate 0.5 2.5 1\nAreaLightSource "diffuse" "rgb L" [10 10 10]\n'
              'Shape "sphere" "float radius" [0.25]\nAttributeEnd',
}
INTEGRATORS = {"path": 'Integrator "path" "integer maxdepth" [5]', "direct": 'Integrator "directlighting"'}


def scene_text(lights: str, integrator: str, dragon: Path | None) -> str:
    """The benchmark's pbrt-v4 scene with ``lights`` and ``integrator`` (``dragon``: a PLY to add, or None)."""
    lines = ['LookAt 0 1.2 3.5  0 0.3 0  0 1 0', 'Camera "perspective" "float fov" [40]',
             'Film "rgb" "integer xresolution" [200] "integer yresolution" [150] "string filename" "x.exr"',
             'Sampler "halton" "integer pixelsamples" [16]', integrator, 'WorldBegin', lights,
             'Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]',
             'Shape "trianglemesh" "point3 P" [-4 0 -4  4 0 -4  4 0 4  -4 0 4] "integer indices" [0 2 1 0 3 2]',
             'AttributeBegin', 'Translate -0.8 0.3 0.5',
             'Material "conductor" "float roughness" [0.05]',
             'Shape "sphere" "float radius" [0.3]', 'AttributeEnd',
             'AttributeBegin', 'Translate 0.9 0.35 0.3', 'Material "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
             'Shape "sphere" "float radius" [0.35]', 'AttributeEnd']
    if dragon is not None:
        lines += ['AttributeBegin', 'Scale 4 4 4', 'Material "diffuse" "rgb reflectance" [0.5 0.6 0.4]',
                  f'Shape "plymesh" "string filename" "{dragon}"', 'AttributeEnd']
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, help="the other tree (a checkout of this project)")
    parser.add_argument("--rounds", type=int, default=2, help="alternating rounds (default 2)")
    parser.add_argument("--res", default="200x150", help="resolution WxH (default 200x150)")
    parser.add_argument("--spp", type=int, default=32, help="samples per pixel (default 32)")
    parser.add_argument("--only", help=f"comma-separated scenes among {', '.join(SCENES)} (default: all)")
    parser.add_argument("--dispersion", action="store_true",
                        help="through the dgauss lens with dispersion on (spectral rays)")
    args = parser.parse_args()
    names = args.only.split(",") if args.only else list(SCENES)
    unknown = [name for name in names if name not in SCENES]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r} (choose among {', '.join(SCENES)})")
    if "map" in names and not SKY_MAP.is_file():
        print(f"map: skipped: {SKY_MAP} is missing (../shared)", file=sys.stderr)
        names.remove("map")
    trees = {"this": ROOT} if args.against is None else {"other": args.against.resolve(), "this": ROOT}
    dragon = DRAGON if DRAGON.is_file() else None
    lens = ["--lens", "dgauss", "--dispersion", "on"] if args.dispersion else []
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        for name in names:
            for integrator, line in INTEGRATORS.items():
                scene = work / f"{name}-{integrator}.pbrt"
                scene.write_text(scene_text(SCENES[name].format(sky=SKY_MAP), line, dragon))
                for tree_name, tree in trees.items():  # untimed: kernels built, tables cached
                    render(tree, scene, ["--res", "16x12", "--spp", "1", *lens], work / f"cache-{tree_name}", work)
                runs: dict[str, list[tuple[float, float]]] = {tree_name: [] for tree_name in trees}
                for _ in range(args.rounds):
                    for tree_name, tree in trees.items():
                        runs[tree_name].append(render(tree, scene, ["--res", args.res, "--spp", str(args.spp), *lens],
                                                      work / f"cache-{tree_name}", work))
                row: dict[str, Any] = {"scene": name, "integrator": integrator}
                for tree_name, values in runs.items():
                    row[tree_name] = {"cpu_s": [v[0] for v in values], "wall_s": [v[1] for v in values],
                                      "median_cpu_s": statistics.median(v[0] for v in values),
                                      "median_wall_s": statistics.median(v[1] for v in values)}
                if "other" in row:
                    row["other_over_this_cpu"] = row["other"]["median_cpu_s"] / row["this"]["median_cpu_s"]
                rows.append(row)
                print(f"{name} {integrator}: " + ", ".join(
                    f"{t} {row[t]['median_cpu_s']:.2f} CPU-s" for t in trees), file=sys.stderr)
    load = os.getloadavg()
    print(f"{args.res}, {args.spp} spp, median of {args.rounds} rounds" + ("" if dragon else " (no dragon)")
          + (", dgauss lens, dispersion on" if args.dispersion else ""))
    header = f"{'scene':8} {'integrator':10}" + "".join(f" {t + ' CPU-s':>12} {t + ' wall':>11}" for t in trees)
    print(header + (f" {'other/this':>10}" if "other" in trees else ""))
    for row in rows:
        line = f"{row['scene']:8} {row['integrator']:10}" + "".join(
            f" {row[t]['median_cpu_s']:12.2f} {row[t]['median_wall_s']:11.2f}" for t in trees)
        print(line + (f" {row['other_over_this_cpu']:10.2f}" if "other" in trees else ""))
    print(f"cpu: {machine.describe()}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    out = ROOT / "bench" / "results" / "light_kinds.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cpu": machine.describe(), "load_average": load, "res": args.res, "spp": args.spp,
                               "rounds": args.rounds, "dispersion": args.dispersion,
                               "dragon": str(dragon) if dragon else None,
                               "trees": {t: str(p) for t, p in trees.items()}, "rows": rows}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
