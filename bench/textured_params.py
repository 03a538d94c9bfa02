"""Textured-parameters benchmark: a pbrt-v4 scene of textured roughness and mix amount, path traced, two trees.

    .venv/bin/python bench/textured_params.py [--against ../old] [--rounds 3] [--res 300x200] [--spp 16]
        [--dispersion] [--scene params|mixes|nested|nested-constant] [--images]

The fused bounce kernel (``kernels/bounce.cl``) first took a material only when every parameter but its
diffuse-like colour was constant: a textured roughness or a textured mix amount sent every hit on that
material to numpy's ``PathIntegrator._shade``. This renders one small pbrt-v4 scene (``scene_text``): a
floor of pbrt-v4's plastic (``coateddiffuse``) whose roughness is a checkerboard texture, spheres of a
mix of a matte and a rough conductor whose amount is a checkerboard, a conductor sphere of textured
roughness and a rough glass sphere, under a distant light and a constant sky, with ``Integrator "path"``
(maxdepth 5). ``--scene mixes`` swaps the floor and spheres for mixes whose second material is textured
(``MIXES``), which the fused bounce first sent to numpy: a floor mixing two image-textured materials,
spheres of a matte and a conductor of checkerboard roughness under a checkerboard amount, and one of a
conductor and an image-textured coateddiffuse (no glass). ``--scene nested`` makes them pbrt-v4 mixes
holding mixes (``NESTED``), which the fused bounce first sent to numpy: a floor mixing (a mix of a matte
and a rough conductor under a checkerboard amount) and an image-textured coateddiffuse under a constant
amount, spheres three levels deep, and one of (a mix of a matte and a conductor) and glass;
``--scene nested-constant`` the same trees with nothing textured (``NESTED_CONSTANT``), whose rows the
fused bounce makes once per material for RGB rays rather than per hit. ``--images``
also renders the scene once more per tree and once with ``--backend numpy`` (this tree, the reference
shading), all at the same seed, and prints each image's mean and max absolute difference from the
numpy one. Each is rendered by ``python -m realistic
render`` in a fresh process (``bench/seed.py``'s ``render``: CPU-seconds of the process, user + system,
and wall), the trees alternating for ``--rounds`` rounds after one untimed small render each (kernels
and tables built and cached). ``--dispersion`` renders through the dgauss lens with dispersion on
(spectral rays). Prints the median CPU-seconds and wall per tree and the ratio other / this, the CPU and
the load average; writes bench/results/textured_params.json (textured_params_<scene>.json for the
other scenes).
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

import numpy as np  # noqa: E402

import machine  # noqa: E402
from realistic.core.image_files import read_exr, write_exr  # noqa: E402
from seed import render  # noqa: E402

#: The image textures of the ``mixes`` scene (``write_textures``): name -> (H, W, 3) linear RGB, a
#: tinted product of sines each, so that neither is constant over a sphere.
TEXTURES = {name: np.clip(np.stack([0.45 + 0.35 * np.sin(np.linspace(0, 6 * np.pi, 128))[None, :]
                                     * np.cos(np.linspace(0, k * np.pi, 64))[:, None] * c
                                     for c in colour], axis=-1), 0.02, 0.95).astype(np.float32)
            for name, k, colour in (("wood.exr", 3, (1.0, 0.7, 0.4)), ("tiles.exr", 5, (0.3, 0.8, 1.0)))}
#: The ``mixes`` scene's textures and materials (its shapes: ``objects``): mixes whose second material is textured.
MIXES = [
    'Texture "wood" "spectrum" "imagemap" "string filename" "wood.exr" "float uscale" [4] "float vscale" [4]',
    'Texture "tiles" "spectrum" "imagemap" "string filename" "tiles.exr" "float uscale" [6] "float vscale" [6]',
    'MakeNamedMaterial "grain" "string type" "diffuse" "texture reflectance" "wood"',
    'MakeNamedMaterial "glaze" "string type" "coateddiffuse" "texture reflectance" "tiles" '
    '"texture roughness" "rough"',
    'MakeNamedMaterial "matte" "string type" "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
    'MakeNamedMaterial "metal" "string type" "conductor" "texture roughness" "rough"',
    'MakeNamedMaterial "floor" "string type" "mix" "string materials" ["grain" "glaze"] "float amount" [0.4]',
    'MakeNamedMaterial "blend" "string type" "mix" "string materials" ["matte" "metal"] "texture amount" "amount"',
    'MakeNamedMaterial "glazed metal" "string type" "mix" "string materials" ["metal" "glaze"] "float amount" [0.5]']

def nested_mixes(worn_amount: str, blend_amount: str) -> list[str]:
    """The mixes holding mixes of both nested scenes, over the leaves ``matte``, ``metal``, ``glaze``,
    ``grain`` and ``glass`` they define: ``worn`` and ``blend`` under the pbrt amount parameters given
    (textured or constant), the rest under constant amounts, each defined before the mixes that hold it."""
    trees = [("worn", "matte", "metal", worn_amount), ("floor", "worn", "glaze", '"float amount" [0.4]'),
             ("grained", "worn", "grain", '"float amount" [0.3]'), ("glazed", "glaze", "metal", '"float amount" [0.5]'),
             ("blend", "grained", "glazed", blend_amount), ("scuffed", "matte", "metal", '"float amount" [0.5]'),
             ("glassy", "scuffed", "glass", '"float amount" [0.5]')]
    return [f'MakeNamedMaterial "{name}" "string type" "mix" "string materials" ["{first}" "{second}"] {amount}'
            for name, first, second, amount in trees]


#: The ``nested`` scene's materials (its textures: ``MIXES``' two images and the head's checkerboards):
#: pbrt-v4 mixes holding mixes, textured amounts and lobes at both levels.
NESTED = [
    *MIXES[:2],
    'MakeNamedMaterial "matte" "string type" "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
    'MakeNamedMaterial "metal" "string type" "conductor" "texture roughness" "rough"',
    'MakeNamedMaterial "glaze" "string type" "coateddiffuse" "texture reflectance" "tiles" "float roughness" [0.1]',
    'MakeNamedMaterial "grain" "string type" "diffuse" "texture reflectance" "wood"',
    'MakeNamedMaterial "glass" "string type" "dielectric"',
    *nested_mixes('"texture amount" "amount"', '"texture amount" "amount"')]

#: The ``nested-constant`` scene's materials: ``NESTED``'s trees with constant amounts and lobes.
NESTED_CONSTANT = [
    'MakeNamedMaterial "matte" "string type" "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
    'MakeNamedMaterial "metal" "string type" "conductor" "float roughness" [0.1]',
    'MakeNamedMaterial "glaze" "string type" "coateddiffuse" "rgb reflectance" [0.3 0.5 0.6] "float roughness" [0.1]',
    'MakeNamedMaterial "grain" "string type" "diffuse" "rgb reflectance" [0.6 0.45 0.3]',
    'MakeNamedMaterial "glass" "string type" "dielectric"',
    *nested_mixes('"float amount" [0.35]', '"float amount" [0.6]')]

def objects(floor: str, small: str) -> list[str]:
    """Both scenes' shapes: a floor under the material statement ``floor``, two spheres of the
    ``blend`` mix, and a small sphere under ``small``."""
    return [
        'AttributeBegin', floor,
        'Shape "trianglemesh" "point3 P" [-4 0 -4  4 0 -4  4 0 4  -4 0 4] "point2 uv" [0 0  1 0  1 1  0 1] '
        '"integer indices" [0 2 1 0 3 2]',
        'AttributeEnd',
        'AttributeBegin', 'Translate -0.8 0.35 0.5', 'NamedMaterial "blend"', 'Shape "sphere" "float radius" [0.35]',
        'AttributeEnd',
        'AttributeBegin', 'Translate 0.9 0.35 0.3', 'NamedMaterial "blend"', 'Shape "sphere" "float radius" [0.35]',
        'AttributeEnd',
        'AttributeBegin', 'Translate 0.05 0.3 -0.4', small, 'Shape "sphere" "float radius" [0.3]', 'AttributeEnd']


def write_textures(folder: Path) -> None:
    """The ``mixes`` scene's image textures (``TEXTURES``) as EXR files in ``folder``."""
    for name, pixels in TEXTURES.items():
        write_exr(folder / name, pixels)


def scene_text(res: str, spp: int, scene: str = "params") -> str:
    """The benchmark's pbrt-v4 scene (``params``, or ``mixes``: ``MIXES``, whose textures
    ``write_textures`` writes, ``nested``: ``NESTED``, or ``nested-constant``: ``NESTED_CONSTANT``) at
    ``res`` (WxH) and ``spp`` samples per pixel."""
    width, height = res.split("x")
    head = [
        'LookAt 0 1.2 3.5  0 0.3 0  0 1 0', 'Camera "perspective" "float fov" [40]',
        f'Film "rgb" "integer xresolution" [{width}] "integer yresolution" [{height}] "string filename" "x.exr"',
        f'Sampler "halton" "integer pixelsamples" [{spp}]', 'Integrator "path" "integer maxdepth" [5]',
        'WorldBegin',
        'LightSource "distant" "point3 from" [1 4 2] "point3 to" [0 0 0] "rgb L" [2 2 2]',
        'LightSource "infinite" "rgb L" [0.4 0.45 0.5]',
        'Texture "rough" "float" "checkerboard" "float uscale" [16] "float vscale" [16] "float tex1" [0.02] '
        '"float tex2" [0.3]',
        'Texture "amount" "float" "checkerboard" "float uscale" [8] "float vscale" [8] "float tex1" [0.15] '
        '"float tex2" [0.85]']
    if scene == "mixes":
        return "\n".join(head + MIXES + objects('NamedMaterial "floor"', 'NamedMaterial "glazed metal"')) + "\n"
    if scene in ("nested", "nested-constant"):
        materials = NESTED if scene == "nested" else NESTED_CONSTANT
        return "\n".join(head + materials + objects('NamedMaterial "floor"', 'NamedMaterial "glassy"')) + "\n"
    return "\n".join(head + [
        'MakeNamedMaterial "matte" "string type" "diffuse" "rgb reflectance" [0.7 0.3 0.2]',
        'MakeNamedMaterial "metal" "string type" "conductor" "float roughness" [0.1]',
        'MakeNamedMaterial "blend" "string type" "mix" "string materials" ["matte" "metal"] "texture amount" "amount"',
        *objects('Material "coateddiffuse" "rgb reflectance" [0.5 0.55 0.6] "texture roughness" "rough"',
                 'Material "conductor" "texture roughness" "rough"'),
        'AttributeBegin', 'Translate 0.1 0.25 0.9', 'Material "dielectric" "float roughness" [0.2]',
        'Shape "sphere" "float radius" [0.25]', 'AttributeEnd']) + "\n"


def compare_images(trees: dict[str, Path], scene: Path, lens: list[str], work: Path
                   ) -> dict[str, tuple[float, float, float]]:
    """Per tree: the mean and max absolute difference of its render of ``scene`` from this tree's
    ``--backend numpy`` render (the same seed), and that image's mean."""
    reference = None
    images = {}
    for name, tree in {"numpy": trees["this"], **trees}.items():
        render(tree, scene, [*lens, "--seed", "1"] + (["--backend", "numpy"] if name == "numpy" else []),
               work / f"cache-{'this' if name == 'numpy' else name}", work)
        image = read_exr(work / "out.exr")[0].astype(np.float64)
        if reference is None:
            reference = image
        else:
            difference = np.abs(image - reference)
            images[name] = float(difference.mean()), float(difference.max()), float(reference.mean())
    return images


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, help="the other tree (a checkout of this project)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    parser.add_argument("--res", default="300x200", help="resolution WxH (default 300x200)")
    parser.add_argument("--spp", type=int, default=16, help="samples per pixel (default 16)")
    parser.add_argument("--dispersion", action="store_true",
                        help="through the dgauss lens with dispersion on (spectral rays)")
    parser.add_argument("--scene", choices=("params", "mixes", "nested", "nested-constant"), default="params",
                        help="params: textured roughness and amount (default); mixes: textured second materials; "
                             "nested: mixes holding mixes; nested-constant: the same, nothing textured")
    parser.add_argument("--images", action="store_true",
                        help="also each tree's image against the numpy backend's (mean, max abs difference)")
    args = parser.parse_args()
    trees = {"this": ROOT} if args.against is None else {"other": args.against.resolve(), "this": ROOT}
    lens = ["--lens", "dgauss", "--dispersion", "on"] if args.dispersion else []
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        scene = work / "textured.pbrt"
        scene.write_text(scene_text(args.res, args.spp, args.scene))
        if args.scene != "params":
            write_textures(work)
        for name, tree in trees.items():  # untimed: kernels built, tables cached
            render(tree, scene, ["--res", "16x12", "--spp", "1", *lens], work / f"cache-{name}", work)
        for _ in range(args.rounds):
            for name, tree in trees.items():
                runs[name].append(render(tree, scene, lens, work / f"cache-{name}", work))
        images = compare_images(trees, scene, lens, work) if args.images else {}
    row: dict[str, Any] = {name: {"cpu_s": [v[0] for v in values], "wall_s": [v[1] for v in values],
                                  "median_cpu_s": statistics.median(v[0] for v in values),
                                  "median_wall_s": statistics.median(v[1] for v in values)}
                           for name, values in runs.items()}
    if "other" in row:
        row["other_over_this_cpu"] = row["other"]["median_cpu_s"] / row["this"]["median_cpu_s"]
    load = os.getloadavg()
    print(f"{args.scene} scene, {args.res}, {args.spp} spp, path (maxdepth 5), median of {args.rounds} rounds"
          + (", dgauss lens, dispersion on" if args.dispersion else ""))
    print(f"{'tree':6} {'CPU-s':>8} {'wall':>8}  runs (CPU-s)")
    for name in trees:
        print(f"{name:6} {row[name]['median_cpu_s']:8.2f} {row[name]['median_wall_s']:8.2f}  "
              + " ".join(f"{v:.2f}" for v in row[name]["cpu_s"]))
    if "other" in row:
        print(f"other/this CPU-s: {row['other_over_this_cpu']:.2f}")
    for name, (mean, top, reference) in images.items():
        print(f"{name} against numpy: mean abs difference {mean:.3g}, max {top:.3g} (numpy image mean {reference:.4g})")
    print(f"cpu: {machine.describe()}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    out = ROOT / "bench" / "results" / ("textured_params.json" if args.scene == "params"
                                        else f"textured_params_{args.scene}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cpu": machine.describe(), "load_average": load, "scene": args.scene,
                               "res": args.res, "spp": args.spp,
                               "rounds": args.rounds, "dispersion": args.dispersion,
                               "trees": {t: str(p) for t, p in trees.items()}, **row,
                               "against_numpy": {name: {"mean_abs": mean, "max_abs": top, "numpy_mean": reference}
                                                 for name, (mean, top, reference) in images.items()}},
                              indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
