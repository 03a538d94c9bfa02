"""Cost of the coatings in the camera-ray kernel: rays/s with ``ideal``, ``none`` and ``mgf2``.

For each lens, non-spectral and spectral, it builds ``kernels/lens.cl`` for the three coatings
(``LensKernel``: each choosing its rays per work item as in a render) and times launches of
``--rays`` rays, the coatings taken in turn ``--repeat`` times (a busy machine's noise falls on
each alike), reporting the median rays/s per coating and its ratio to ``ideal``, then the table
as JSON.

    python bench/coating.py [--lenses dgauss wide] [--rays 1048576] [--out bench/results/coating.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic import load_lens  # noqa: E402
from realistic.camera.base import SampleBlock  # noqa: E402
from realistic.camera.lens_camera import LensCamera  # noqa: E402
from realistic.camera.opencl_host import LensKernel  # noqa: E402
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM  # noqa: E402
from realistic.optics.coating import COATINGS  # noqa: E402
from realistic.optics.paraxial import film_distance_for_focus  # noqa: E402

SPP = 64


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lenses", nargs="+", default=["dgauss", "wide", "canon-rf50-f1.2"])
    parser.add_argument("--rays", type=int, default=1 << 20)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "coating.json"))
    args = parser.parse_args()
    rows = []
    print(f"{'lens':<18} {'spectral':>8} " + " ".join(f"{c + ' Mrays/s':>15}" for c in COATINGS)
          + "   none/ideal  mgf2/ideal")
    for name in args.lenses:
        lens = load_lens(name)
        film = film_distance_for_focus(lens, 5000.0)
        for spectral in (False, True):
            kernels = {}
            for coating in COATINGS:
                camera = LensCamera(lens.with_coating(coating), film, FULL_FRAME_DIAGONAL_MM, 512, 512, spp=SPP,
                                    spectral=spectral)
                kernels[coating] = LensKernel(camera)
            block = SampleBlock(0, args.rays // (kernels["ideal"].camera.rays_per_sample), SPP)
            for kernel in kernels.values():
                kernel.generate(block)  # PoCL compiles at the first launch
            times: dict[str, list[float]] = {c: [] for c in COATINGS}
            for _ in range(args.repeat):
                for coating, kernel in kernels.items():
                    start = time.perf_counter()
                    kernel.generate(block)
                    times[coating].append(time.perf_counter() - start)
            rays = block.count * kernels["ideal"].camera.rays_per_sample
            rate = {c: rays / statistics.median(t) for c, t in times.items()}
            row = {"lens": name, "spectral": spectral, "rays": rays,
                   "rays_per_item": {c: k.rays_per_item for c, k in kernels.items()},
                   "mrays_per_s": {c: r / 1e6 for c, r in rate.items()},
                   "ratio_to_ideal": {c: rate[c] / rate["ideal"] for c in COATINGS}}
            rows.append(row)
            print(f"{name:<18} {str(spectral):>8} " + " ".join(f"{rate[c] / 1e6:15.2f}" for c in COATINGS)
                  + f"   {row['ratio_to_ideal']['none']:10.3f}  {row['ratio_to_ideal']['mgf2']:10.3f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": platform.processor() or platform.machine(), "repeat": args.repeat,
                               "rows": rows}, indent=2))
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
