"""Start-up benchmark: the exit-pupil table per lens, uncached and cached, and the README command.

    .venv/bin/python bench/startup.py [--repeats 3] [--skip-readme]

For every bundled lens focused at infinity on a full-frame film: the seconds to build its
exit-pupil table (d line, and the three wavelengths of a spectral camera) with an empty disk cache,
and to read it back from the disk cache in a fresh process state (memory cache cleared). Then the
table's cost against the number of surfaces (flat glass plates in front of the double Gauss: the
search traces the same rays, each through more surfaces), and the wall time of README's first
command (``python -m realistic render``) with an empty and with a filled cache. Medians of
``--repeats`` runs. Writes bench/results/startup.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM  # noqa: E402
from realistic.core.spectrum import LAMBDA_MAX_NM, LAMBDA_MIN_NM  # noqa: E402
from realistic.optics import sampling  # noqa: E402
from realistic.optics.dispersion import D_LINE_NM  # noqa: E402
from realistic.optics.formats import BUNDLED_LENSES, load_lens  # noqa: E402
from realistic.optics.lens import LensSystem, build_lens  # noqa: E402
from realistic.optics.paraxial import film_distance_for_focus  # noqa: E402

SPECTRAL = (LAMBDA_MIN_NM, D_LINE_NM, LAMBDA_MAX_NM)


def _median_seconds(run: Callable[[], object], repeats: int, before: Callable[[], None]) -> float:
    times = []
    for _ in range(repeats):
        before()
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _fresh_cache() -> None:
    """An empty disk cache and an empty memory cache."""
    os.environ["REALISTIC_CACHE_DIR"] = tempfile.mkdtemp(prefix="realistic-bench-cache-")
    sampling._cached_table.cache_clear()


def table_seconds(lens: LensSystem, wavelengths: tuple[float, ...], repeats: int) -> tuple[float, float]:
    """(uncached, cached from disk) seconds of one exit-pupil table."""
    film = film_distance_for_focus(lens, np.inf)

    def build() -> object:
        return sampling.exit_pupil_table(lens, film, FULL_FRAME_DIAGONAL_MM, wavelengths_nm=wavelengths)

    uncached = _median_seconds(build, repeats, _fresh_cache)
    cached = _median_seconds(build, repeats, sampling._cached_table.cache_clear)  # the disk entry stays
    return uncached, cached


def plated_lens(plates: int) -> LensSystem:
    """The double Gauss behind ``plates`` thin flat glass plates (2 surfaces each)."""
    base = load_lens("dgauss")
    rows = [(np.inf, 0.05, 1.5, 0.0, 40.0), (np.inf, 0.05, 1.0, 0.0, 40.0)] * plates
    rows += list(zip(base.radius_mm, base.thickness_mm, base.index_d, base.abbe_v, base.aperture_mm))
    columns = [list(map(float, column)) for column in zip(*rows)]
    return build_lens("plates", list(range(1, len(rows) + 1)), *columns, name=f"dgauss+{plates} plates")


def readme_seconds(cache: str) -> float:
    """Wall seconds of ``python -m realistic render`` (README's first command) with ``cache``."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "realistic", "render", "--out", str(Path(folder) / "r.exr")],
                       check=True, cwd=ROOT, env={**os.environ, "REALISTIC_CACHE_DIR": cache},
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the median is shown")
    parser.add_argument("--skip-readme", action="store_true", help="skip timing README's render command")
    args = parser.parse_args()
    results: dict[str, object] = {"lenses": {}, "surfaces": {}, "readme": {}}

    print(f"{'lens':<12}{'d line s':>10}{'cached s':>10}{'spectral s':>12}{'cached s':>10}")
    for name in BUNDLED_LENSES:
        lens = load_lens(name)
        mono = table_seconds(lens, (D_LINE_NM,), args.repeats)
        spectral = table_seconds(lens, SPECTRAL, args.repeats)
        results["lenses"][name] = {"d_line": mono, "spectral": spectral}
        print(f"{name:<12}{mono[0]:>10.3f}{mono[1]:>10.4f}{spectral[0]:>12.3f}{spectral[1]:>10.4f}")

    print(f"\n{'surfaces':<12}{'table s':>10}{'s per surface':>15}")
    for plates in (0, 45, 495):
        lens = plated_lens(plates)
        seconds = table_seconds(lens, (D_LINE_NM,), 1)[0]
        results["surfaces"][lens.surface_count] = seconds
        print(f"{lens.surface_count:<12}{seconds:>10.3f}{seconds / lens.surface_count:>15.5f}")

    if not args.skip_readme:
        empty = [readme_seconds(tempfile.mkdtemp(prefix="realistic-bench-cache-")) for _ in range(args.repeats)]
        filled_cache = tempfile.mkdtemp(prefix="realistic-bench-cache-")
        readme_seconds(filled_cache)
        filled = [readme_seconds(filled_cache) for _ in range(args.repeats)]
        results["readme"] = {"empty_cache": statistics.median(empty), "filled_cache": statistics.median(filled)}
        print(f"\nREADME command wall s: empty cache {statistics.median(empty):.2f}, "
              f"filled cache {statistics.median(filled):.2f}")

    out = ROOT / "bench" / "results" / "startup.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
