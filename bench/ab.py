"""A/B render benchmark: ``bench/render.py`` of this tree against another tree's, in one run.

    .venv/bin/python bench/ab.py --against ../old [--rounds 3] [-- --res 512x512 --spp 16 ...]

Runs each tree's own ``bench/render.py`` (with the arguments after ``--``) in a fresh process, the
two trees alternating for ``--rounds`` rounds so that a machine's drift falls on both alike, each
tree importing its own package and keeping its own kernel cache. Prints, per row of render.py's
table (the render rows by label, and the embree ceiling through the renderer's binding), the median
samples/s of each tree and their ratio; writes bench/results/ab.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))  # first already when run as a script; not when a test loads this file

import machine  # noqa: E402

CEILING = "ceiling (renderer's binding)"


def run_tree(tree: Path, arguments: list[str], cache: Path) -> dict[str, float]:
    """Samples/s per row of ``tree``'s bench/render.py run once with ``arguments``."""
    environment = dict(os.environ, PYTHONPATH=str(tree), REALISTIC_CACHE_DIR=str(cache))
    subprocess.run([sys.executable, "bench/render.py", *arguments], cwd=tree, env=environment, check=True,
                   stdout=subprocess.DEVNULL)
    result = json.loads((tree / "bench" / "results" / "render.json").read_text())
    rows = {run["label"]: float(run["samples_per_s"]) for run in result["runs"]}
    rows[CEILING] = float(result["ceiling"]["samples_per_s"])
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, required=True, help="the other tree (a checkout of this project)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    parser.add_argument("render_arguments", nargs="*", help="arguments for bench/render.py (after --)")
    args = parser.parse_args()
    trees = {"other": args.against.resolve(), "this": ROOT}
    samples: dict[str, dict[str, list[float]]] = {name: {} for name in trees}
    with tempfile.TemporaryDirectory() as caches:
        for round_number in range(args.rounds):
            for name, tree in trees.items():
                rows = run_tree(tree, args.render_arguments, Path(caches) / name)
                for label, value in rows.items():
                    samples[name].setdefault(label, []).append(value)
                print(f"round {round_number + 1}, {name}: "
                      + ", ".join(f"{label} {value / 1e6:.2f}" for label, value in rows.items()), file=sys.stderr)
    labels = [label for label in samples["this"] if label in samples["other"]]
    table = []
    print(f"{'row':32} {'other M samples/s':>18} {'this M samples/s':>17} {'this / other':>13}")
    for label in labels:
        other, this = (statistics.median(samples[name][label]) for name in ("other", "this"))
        table.append({"row": label, "other": samples["other"][label], "this": samples["this"][label],
                      "median_other": other, "median_this": this, "ratio": this / other})
        print(f"{label:32} {other / 1e6:18.2f} {this / 1e6:17.2f} {this / other:13.3f}")
    out = ROOT / "bench" / "results" / "ab.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cpu": machine.describe(), "against": str(trees["other"]),
                               "rounds": args.rounds, "render_arguments": args.render_arguments, "rows": table},
                              indent=1) + "\n")
    print(f"cpu: {machine.describe()}; wrote {out}")


if __name__ == "__main__":
    main()
