"""Render the gallery of docs/gallery.md: the four homework scenes, their dragon versions, the
seed scene (measured-BRDF dragons) through the four lenses, and lens flare (``scenes/flare.pbrt``
without flare, and with it through bare and MgF2-coated glass).

Each scene is rendered at 4 and at 512 samples per pixel (the seed scenes at ``--seed-spp``: their
measured BRDFs are slow) through the real CLI (OpenCL backend, PNG previews at a fixed exposure of
0 EV, as the scenes' light levels are set per lens); the table of render times is read back from
the EXR headers. Needs ../shared (the homework scenes, the dragon mesh, the floor texture, the
BRDF files), except for the flare scenes (``--only flare,flare-none,flare-mgf2`` renders them alone),
which are rendered at ``--flare-spp``.

    python docs/make_gallery.py [--spp 4,512] [--seed-spp 4,512] [--flare-spp 64] [--only NAME,...]
                                [--out docs/gallery] [--shared ../shared]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LENSES = ("dgauss", "fisheye", "telephoto", "wide")
#: The flare scene's renders: name and options (the lens file's coating is ideal: nothing reflects).
FLARE = (("flare", []), ("flare-none", ["--flare", "on", "--coating", "none"]),
         ("flare-mgf2", ["--flare", "on", "--coating", "mgf2"]))
#: The flare scene's exposure (EV): a dim dusk scene around a very bright lamp.
FLARE_EXPOSURE = "3"


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
    parser.add_argument("--flare-spp", default="64", help="sample counts of the flare scenes (default: %(default)s)")
    parser.add_argument("--only", default="", help="comma-separated scene names to render (default: all)")
    parser.add_argument("--out", default=str(ROOT / "docs" / "gallery"), help="folder for the images")
    parser.add_argument("--shared", default=str(ROOT.parent / "shared"), help="the shared data folder")
    args = parser.parse_args()
    shared = Path(args.shared)
    only = {name for name in args.only.split(",") if name}
    flare_only = bool(only) and only <= {name for name, _ in FLARE}
    if not shared.is_dir() and not flare_only:
        sys.exit(f"{shared}: the shared data (homework scenes, dragon) is needed for the gallery")
    sys.path.insert(0, str(ROOT))
    from realistic.core.image_files import read_exr

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    flare = [(name, ROOT / "scenes" / "flare.pbrt", [*extra, "--exposure", FLARE_EXPOSURE], args.flare_spp)
             for name, extra in FLARE]
    every = [] if flare_only else [(name, scene, extra, args.seed_spp if seed else args.spp)
                                   for name, scene, extra, seed in scenes(shared)]
    for name, scene, extra, spp_list in every + flare:
        if only and name not in only:
            continue
        times = {}
        for spp in [int(s) for s in spp_list.split(",")]:
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
