"""Render the gallery of docs/gallery.md: the four homework scenes, their dragon versions, and the
seed scene (measured-BRDF dragons) through the four lenses.

Each scene is rendered at 4 and at 512 samples per pixel (the seed scenes at ``--seed-spp``: their
measured BRDFs are slow) through the real CLI (OpenCL backend, PNG previews at a fixed exposure of
0 EV, as the scenes' light levels are set per lens); the table of render times is read back from
the EXR headers. Needs ../shared (the homework scenes, the dragon mesh, the floor texture, the
BRDF files).

    python docs/make_gallery.py [--spp 4,512] [--seed-spp 4,512] [--only NAME,...] [--out docs/gallery]
                                [--shared ../shared]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LENSES = ("dgauss", "fisheye", "telephoto", "wide")


def scenes(shared: Path) -> list[tuple[str, Path, list[str], bool]]:
    """(name, scene file, extra arguments, whether it is a seed scene) for the twelve gallery scenes."""
    homework = [(f"{lens}", shared / "scenes" / "pbrt" / f"dof-dragons.{lens}.pbrt", [], False) for lens in LENSES]
    search = ["--search-path", str(shared / "meshes"), "--search-path", str(shared / "scenes" / "pbrt")]
    dragons = [(f"{lens}-dragons", ROOT / "scenes" / "dof-dragons" / f"{lens}.pbrt", search, False)
               for lens in LENSES]
    seeds = [(f"{lens}-seed", ROOT / "scenes" / "dof-dragons" / ("seed.pbrt" if lens == "dgauss" else
                                                                 f"seed.{lens}.pbrt"), [], True) for lens in LENSES]
    return homework + dragons + seeds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spp", default="4,512", help="sample counts (default: %(default)s)")
    parser.add_argument("--seed-spp", default="4,512",
                        help="sample counts of the measured-BRDF seed scenes (default: %(default)s)")
    parser.add_argument("--only", default="", help="comma-separated scene names to render (default: all)")
    parser.add_argument("--out", default=str(ROOT / "docs" / "gallery"), help="folder for the images")
    parser.add_argument("--shared", default=str(ROOT.parent / "shared"), help="the shared data folder")
    args = parser.parse_args()
    shared = Path(args.shared)
    if not shared.is_dir():
        sys.exit(f"{shared}: the shared data (homework scenes, dragon) is needed for the gallery")
    sys.path.insert(0, str(ROOT))
    from realistic.core.image_files import read_exr

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    only = {name for name in args.only.split(",") if name}
    for name, scene, extra, seed in scenes(shared):
        if only and name not in only:
            continue
        times = {}
        for spp in [int(s) for s in (args.seed_spp if seed else args.spp).split(",")]:
            exr = out / f"{name}-{spp}spp.exr"
            command = [sys.executable, "-m", "realistic", "render", str(scene), "--spp", str(spp),
                       "--exposure", "0", "--out", str(exr), *extra]
            subprocess.run(command, check=True, cwd=ROOT)
            times[spp] = float(read_exr(exr)[1]["renderSeconds"])
            exr.unlink()  # the PNG preview is what the page shows
            print(f"{name} {spp} spp: {times[spp]:.1f} s", flush=True)
        rows.append((name, scene, times))
    lines = ["| scene | spp: seconds |", "|---|---|"]
    for name, scene, times in rows:
        lines.append(f"| {name} (`{scene.name}`) | " + ", ".join(f"{s}: {t:.1f}" for s, t in sorted(times.items()))
                     + " |")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
