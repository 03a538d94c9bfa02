"""Texture-filtering benchmark: MIP-map lookups per second by filter, and what filtering costs a render.

    .venv/bin/python bench/textures.py [--points 200000] [--res 128x128] [--spp 4]

Lookups: a 1024 x 1024 random image, points uniform over it, footprints whose minor axis spans
0.1 to 30 texels (log-uniform) and whose major axis is 1 to 16 times longer, as a floor receding to
the horizon gives. Render: the homework scene ../shared/scenes/pbrt/dof-dragons.dgauss.pbrt (its
floor is a 1024 x 1024 imagemap) with each filter, and with footprints off (point sampling, the
renderer before filtering), after one warm-up render; ``far_floor_std`` is the spread of the green
channel over rows 0.45 H to 0.5 H, the far floor, where aliasing shows. Prints two tables and
writes bench/results/textures.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic.renderer.inputs import RenderOptions, build_render_inputs  # noqa: E402
from realistic.renderer.job import RenderJob  # noqa: E402
from realistic.renderer.passes import ThreadPasses, render  # noqa: E402
from realistic.scene.mipmap import MipMap  # noqa: E402

SCENE = ROOT.parent / "shared" / "scenes" / "pbrt" / "dof-dragons.dgauss.pbrt"
LENSES = ROOT.parent / "shared" / "lenses"


def lookups(points: int) -> list[dict]:
    rng = np.random.default_rng(0)
    mipmap = MipMap(rng.random((1024, 1024, 3)).astype(np.float32))
    st = rng.random((points, 2))
    minor_texels = np.exp(rng.uniform(np.log(0.1), np.log(30.0), points))
    angle = rng.uniform(0, np.pi, points)
    ratio = rng.uniform(1, 16, points)
    unit = np.column_stack([np.cos(angle), np.sin(angle)]) / 1024
    major = unit * (minor_texels * ratio)[:, None]
    minor = unit[:, ::-1] * [-1, 1] * minor_texels[:, None]
    width = 2 * np.maximum(np.abs(major).max(axis=1), np.abs(minor).max(axis=1))
    runs = {"bilinear (no footprint)": lambda: mipmap.bilinear(st), "point": lambda: mipmap.point(st, width),
            "trilinear": lambda: mipmap.trilinear(st, width), "ewa": lambda: mipmap.ewa(st, major, minor)}
    rows = []
    for name, run in runs.items():
        run()  # warm-up: page in the texel array
        start = time.perf_counter()
        run()
        seconds = time.perf_counter() - start
        rows.append({"filter": name, "points": points, "seconds": seconds, "m_lookups_per_s": points / seconds / 1e6})
    return rows


class _NoFootprint:
    """A camera wrapper whose pixels have no spread: textures are point-sampled."""

    def __init__(self, camera):
        self._camera = camera

    def __getattr__(self, name):
        return getattr(self._camera, name)

    def pixel_spread_radians(self) -> float:
        return 0.0


def renders(width: int, height: int, spp: int) -> list[dict]:
    if not SCENE.is_file():
        print(f"skipping the render table: {SCENE} not found")
        return []
    imported = build_render_inputs(RenderOptions(scene=SCENE, resolution=(width, height), spp=spp,
                                                 search_paths=[LENSES]))
    scene = imported.scene
    floor = scene.instances[0]
    render(RenderJob(scene, (scene.camera,), "numpy"))  # warm-up: imports, BVH, the MIP map
    rows = []
    far_rows = slice(int(0.45 * height), height // 2)  # the floor toward the horizon, between the cones
    for name in ("none (point-sampled)", "bilinear", "trilinear", "ewa"):
        texture = dataclasses.replace(floor.material.texture, filter=name if name in ("bilinear", "trilinear",
                                                                                           "ewa") else "ewa")
        material = dataclasses.replace(floor.material, texture=texture)
        scene.instances[0] = dataclasses.replace(floor, material=material)
        camera = _NoFootprint(scene.camera) if name.startswith("none") else scene.camera
        result = render(RenderJob(scene, (camera,), "numpy"), ThreadPasses(pin_threads=True))[0]
        rows.append({"filter": name, "resolution": f"{width}x{height}", "spp": spp, "seconds": result.seconds,
                     "shading_s": result.stage_seconds.get("shading", 0.0),
                     "far_floor_std": float(result.image[far_rows, :, 1].std())})
    return rows


def table(rows: list[dict]) -> str:
    if not rows:
        return ""
    keys = list(rows[0])
    lines = [" | ".join(keys), " | ".join("---" for _ in keys)]
    lines += [" | ".join(f"{row[k]:.4g}" if isinstance(row[k], float) else str(row[k]) for k in keys) for row in rows]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200_000)
    parser.add_argument("--res", default="128x128")
    parser.add_argument("--spp", type=int, default=4)
    args = parser.parse_args()
    width, height = (int(v) for v in args.res.split("x"))
    lookup_rows = lookups(args.points)
    print(table(lookup_rows), end="\n\n")
    render_rows = renders(width, height, args.spp)
    print(table(render_rows))
    out = ROOT / "bench" / "results" / "textures.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"lookups": lookup_rows, "renders": render_rows}, indent=2))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
