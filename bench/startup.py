"""Start-up benchmark: the exit-pupil table per lens, uncached and cached, and a user's first renders.

    .venv/bin/python bench/startup.py [--repeats 3] [--skip-tables] [--skip-renders] [--baseline DIR]
        [--no-bytecode]

For every bundled lens focused at infinity on a full-frame film: the seconds to build its
exit-pupil table (d line, and the three wavelengths of a spectral camera) with an empty disk cache,
and to read it back from the disk cache in a fresh process state (memory cache cleared). Then the
table's cost against the number of surfaces (flat glass plates in front of the double Gauss: the
search traces the same rays, each through more surfaces).

Then a user's first renders: the wall seconds of README's first command (``python -m realistic
render``) and of the dragons homework scene (``scenes/dof-dragons/dgauss.pbrt`` at 4 spp; skipped
when ``../shared`` lacks its meshes), each run three times in a row on empty caches (ours, PoCL's,
``POCL_CACHE_DIR``, and numba's, ``NUMBA_CACHE_DIR``, which a fresh machine has none of either):
the first is a cold start (every kernel and packet loop compiled), the later ones find what the
earlier left. The Python bytecode of every module a render imports is written before the first
sequence by an untimed render of each case, into a folder of the bench's own
(``PYTHONPYCACHEPREFIX``), as installing a package compiles it; with ``--no-bytecode`` every run
compiles the checkout's sources it imports (PYTHONDONTWRITEBYTECODE).
``--baseline DIR``: another checkout (an older commit, say) whose runs alternate with this tree's,
so both see the same load. Medians of ``--repeats`` sequences; the load average is printed and
stored. Writes bench/results/startup.json.
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


SHARED = ROOT.parent / "shared"
DRAGONS = ["scenes/dof-dragons/dgauss.pbrt", "--spp", "4", "--search-path", str(SHARED / "meshes"),
           "--search-path", str(SHARED / "scenes" / "pbrt"), "--search-path", str(SHARED / "lenses")]
#: Renders in a row on the same caches: the first a cold start, the others after it.
RUNS = ("first", "second", "third")


#: The environment variables of a render's caches, each given an empty folder per sequence.
CACHES = ("REALISTIC_CACHE_DIR", "POCL_CACHE_DIR", "NUMBA_CACHE_DIR")


def render_seconds(tree: Path, arguments: list[str], caches: dict[str, str]) -> float:
    """Wall seconds of ``python -m realistic render ARGUMENTS`` run from checkout ``tree`` with
    ``caches`` (environment variables: ``CACHES`` and the bytecode's)."""
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "PYTHONPATH": str(tree), **caches}
        if "PYTHONPYCACHEPREFIX" in caches:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
        else:  # nothing written into the trees
            env["PYTHONDONTWRITEBYTECODE"] = "1"
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "realistic", "render", *arguments, "--out", str(Path(folder) / "r.exr")],
                       check=True, cwd=tree, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - start


def compiled_bytecode(trees: dict[str, Path], cases: dict[str, list[str]], prefix: Path) -> str:
    """``prefix`` holding the bytecode of every module a render of ``cases`` imports from each tree
    and from the installed libraries, written by one untimed render of each (caches thrown away)."""
    for path in trees.values():
        for arguments in cases.values():
            with tempfile.TemporaryDirectory(prefix="realistic-bench-caches-") as folder:
                caches = {name: str(Path(folder) / name) for name in CACHES}
                render_seconds(path, arguments, {**caches, "PYTHONPYCACHEPREFIX": str(prefix)})
    return str(prefix)


def first_renders(trees: dict[str, Path], cases: dict[str, list[str]], repeats: int,
                  bytecode: str | None) -> dict[str, object]:
    """Per case and tree, the median wall seconds of each of ``RUNS`` renders in a row on empty
    caches, the trees' sequences taken in turn; ``bytecode``: the PYTHONPYCACHEPREFIX holding the
    modules' bytecode (None: every run compiles its sources)."""
    seconds: dict[str, dict[str, dict[str, list[float]]]] = {
        case: {tree: {run: [] for run in RUNS} for tree in trees} for case in cases}
    for _ in range(repeats):
        for case, arguments in cases.items():
            for tree, path in trees.items():
                with tempfile.TemporaryDirectory(prefix="realistic-bench-caches-") as folder:
                    caches = {name: str(Path(folder) / name) for name in CACHES}
                    if bytecode is not None:
                        caches["PYTHONPYCACHEPREFIX"] = bytecode
                    for run in RUNS:
                        seconds[case][tree][run].append(render_seconds(path, arguments, caches))
    print(f"\n{'render':<10}{'tree':<12}" + "".join(f"{run + ' s':>10}" for run in RUNS))
    results: dict[str, object] = {}
    for case, by_tree in seconds.items():
        results[case] = {tree: {run: statistics.median(values) for run, values in runs.items()}
                         for tree, runs in by_tree.items()}
        for tree, runs in by_tree.items():
            print(f"{case:<10}{tree:<12}" + "".join(f"{statistics.median(runs[run]):>10.2f}" for run in RUNS))
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the median is shown")
    parser.add_argument("--skip-tables", action="store_true", help="skip timing the exit-pupil tables")
    parser.add_argument("--skip-renders", action="store_true", help="skip timing the first renders")
    parser.add_argument("--baseline", type=Path, help="another checkout whose renders alternate with this tree's")
    parser.add_argument("--no-bytecode", action="store_true",
                        help="every render compiles the Python sources it imports (no .pyc)")
    args = parser.parse_args()
    results: dict[str, object] = {"load_average_before": os.getloadavg(), "cpu_count": os.cpu_count(),
                                  "bytecode": not args.no_bytecode, "numba_cache": "empty"}
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")

    if not args.skip_tables:
        lenses: dict[str, object] = {}
        surfaces: dict[int, float] = {}
        print(f"{'lens':<12}{'d line s':>10}{'cached s':>10}{'spectral s':>12}{'cached s':>10}")
        for name in BUNDLED_LENSES:
            lens = load_lens(name)
            mono = table_seconds(lens, (D_LINE_NM,), args.repeats)
            spectral = table_seconds(lens, SPECTRAL, args.repeats)
            lenses[name] = {"d_line": mono, "spectral": spectral}
            print(f"{name:<12}{mono[0]:>10.3f}{mono[1]:>10.4f}{spectral[0]:>12.3f}{spectral[1]:>10.4f}")

        print(f"\n{'surfaces':<12}{'table s':>10}{'s per surface':>15}")
        for plates in (0, 45, 495):
            lens = plated_lens(plates)
            seconds = table_seconds(lens, (D_LINE_NM,), 1)[0]
            surfaces[lens.surface_count] = seconds
            print(f"{lens.surface_count:<12}{seconds:>10.3f}{seconds / lens.surface_count:>15.5f}")
        results.update(lenses=lenses, surfaces=surfaces)

    if not args.skip_renders:
        trees = {"this": ROOT} if args.baseline is None else {"baseline": args.baseline.resolve(), "this": ROOT}
        cases: dict[str, list[str]] = {"readme": []}
        if (SHARED / "meshes" / "dragon.ply").is_file():
            cases["dragons"] = DRAGONS
        else:
            print(f"\nthe dragons render is skipped: {SHARED / 'meshes' / 'dragon.ply'} is absent")
        with tempfile.TemporaryDirectory(prefix="realistic-bench-bytecode-") as folder:
            bytecode = None if args.no_bytecode else compiled_bytecode(trees, cases, Path(folder))
            results["renders"] = first_renders(trees, cases, args.repeats, bytecode)
        results["load_average_after"] = os.getloadavg()
        print(f"load average {os.getloadavg()[0]:.2f}")

    out = ROOT / "bench" / "results" / "startup.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
