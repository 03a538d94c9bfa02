"""Time of judging a lens: spot diagrams, geometric MTF and the camera-ray PSF, per library lens.

For each lens it prints the seconds of ``lens spot`` (fields 0, 4, 8 deg x F, d, C, 64 pupil samples across,
best focus), ``lens mtf`` (the same at 128 samples across, 101 frequencies) and ``lens psf`` (a
64 x 64 window at 256 camera samples per pixel, numpy reference), each the median of ``--repeat``
runs after one untimed warm-up (the exit-pupil table is then cached), and the rays traced per second.

    python bench/lens_judge.py [--lenses dgauss tessar.100mm] [--out bench/results/lens_judge.json]
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

from realistic.camera.psf import point_spread  # noqa: E402
from realistic.optics.formats import load_lens  # noqa: E402
from realistic.optics.forward_trace import pupil_grid  # noqa: E402
from realistic.optics.mtf import lens_mtf  # noqa: E402
from realistic.optics.spot import NAMED_WAVELENGTHS_NM, spot_diagram  # noqa: E402

FIELDS = [0.0, 4.0, 8.0]
WAVES = list(NAMED_WAVELENGTHS_NM.values())


def timed(work, repeat: int) -> float:
    """Median seconds of ``work()`` over ``repeat`` runs, after one untimed run."""
    work()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lenses", nargs="+", default=["dgauss", "tessar.100mm", "zoom.70-200mm-135"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "lens_judge.json"))
    args = parser.parse_args()
    rows = []
    for name in args.lenses:
        lens = load_lens(name)
        spot = timed(lambda lens=lens: spot_diagram(lens, FIELDS, WAVES, "best", 64), args.repeat)
        mtf = timed(lambda lens=lens: lens_mtf(lens, FIELDS, WAVES, 100.0, "best", 128), args.repeat)
        psf = timed(lambda lens=lens: point_spread(lens, 3000.0, 0.0, pixel_mm=0.002, size=64, spp=256),
                    args.repeat)
        rays = {"spot": len(FIELDS) * len(WAVES) * len(pupil_grid(64)),
                "mtf": len(FIELDS) * len(WAVES) * len(pupil_grid(128)), "psf": 64 * 64 * 256}
        rows.append({"lens": name, "spot_s": spot, "mtf_s": mtf, "psf_s": psf,
                     "spot_rays_per_s": rays["spot"] / spot, "mtf_rays_per_s": rays["mtf"] / mtf,
                     "psf_rays_per_s": rays["psf"] / psf})
    print(f"{'lens':<20} {'spot s':>8} {'mtf s':>8} {'psf s':>8} {'spot Mray/s':>12} {'mtf Mray/s':>11} "
          f"{'psf Mray/s':>11}")
    for r in rows:
        print(f"{r['lens']:<20} {r['spot_s']:8.3f} {r['mtf_s']:8.3f} {r['psf_s']:8.3f} "
              f"{r['spot_rays_per_s'] / 1e6:12.2f} {r['mtf_rays_per_s'] / 1e6:11.2f} {r['psf_rays_per_s'] / 1e6:11.2f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": platform.platform(), "rows": rows}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
