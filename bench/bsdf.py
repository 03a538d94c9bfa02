"""BSDF benchmark: hits per second for building, evaluating and sampling each material's BSDF, in
numpy and in ``kernels/bsdf.cl``.

    .venv/bin/python bench/bsdf.py [--hits 200000] [--repeats 3]

For each material (constant parameters, RGB rays): ``bsdf_for`` on ``--hits`` hits, then one
``evaluate`` + ``pdf`` (the light-sampling side of MIS) and one ``sample`` (the BSDF side) with
random local directions; and, where the kernel covers the material, the same work on it (the host's
rows, then one launch evaluating the light direction and drawing the sample). A warm-up run, then
``--repeats`` rounds in which numpy and the kernel alternate per material, so both see the same
load; the table gives medians. The measured BRDFs use the seed scene's
../shared/scenes/pbrt/brdfs/acryl_blue.brdf (skipped when absent) and a synthetic MERL table
(random bins, written to a temporary .binary file and read once, as a scene's would be).
Lambertian is the baseline a matte, direct-lit scene pays; the ratio column is each material's
numpy evaluate + pdf + sample time over Lambertian's, and "x numpy" the numpy build + evaluate +
pdf + sample time over the kernel's rows + launch. The machine's load is not controlled: compare
ratios within one run. Prints a table and writes bench/results/bsdf.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic.device.opencl import Device  # noqa: E402
from realistic.renderer.bsdf import bsdf_for  # noqa: E402
from realistic.renderer.bsdf_kernel import BsdfKernel  # noqa: E402
from realistic.scene.materials import (  # noqa: E402
    CoatedDiffuse,
    Conductor,
    Dielectric,
    Measured,
    Mirror,
    Mix,
    Plastic,
    Substrate,
)
from realistic.scene.measured import MERL_SHAPE  # noqa: E402
from realistic.scene.model import Material  # noqa: E402

BRDF = ROOT.parent / "shared" / "scenes" / "pbrt" / "brdfs" / "acryl_blue.brdf"


class Hits:
    """Constant parameters at N hits (RGB rays)."""

    def __init__(self, n: int):
        self.n = n

    def colour(self, value):
        return np.tile(np.asarray(value, np.float32).reshape(1, 3), (self.n, 1))

    def scalar(self, value):
        return np.full(self.n, value, np.float32)


def merl_file(folder: Path, rng: np.random.Generator) -> Path:
    """A MERL .binary file in ``folder`` of random bins (0 to 0.2, 0.23 and 0.33 after the channel scales)."""
    path = folder / "synthetic.binary"
    raw = rng.random(3 * int(np.prod(MERL_SHAPE))) * 300.0
    path.write_bytes(np.array(MERL_SHAPE, "<i4").tobytes() + raw.astype("<f8").tobytes())
    return path


def materials(folder: Path, rng: np.random.Generator) -> dict[str, object]:
    found = {"lambertian": Material((0.5,) * 3), "oren-nayar": Material((0.5,) * 3, sigma=20.0),
             "plastic": Plastic(), "coated diffuse": CoatedDiffuse(roughness=0.1),
             "conductor": Conductor(roughness_u=0.1, roughness_v=0.1), "mirror": Mirror(),
             "glass": Dielectric(1.5), "rough glass": Dielectric(1.5, roughness_u=0.2, roughness_v=0.2),
             "substrate": Substrate(), "mix": Mix(Material(), Plastic(), 0.5)}
    if BRDF.is_file():
        found["measured .brdf"] = Measured(str(BRDF))
    found["measured MERL"] = Measured(str(merl_file(folder, rng)))
    return found


def _timed(run) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def measure(hits: int, repeats: int) -> list[dict]:
    rng = np.random.default_rng(0)
    wo = rng.normal(size=(hits, 3)).astype(np.float32)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wo[:, 2] = np.abs(wo[:, 2])
    wi = rng.normal(size=(hits, 3)).astype(np.float32)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    u, u_lobe = rng.random((hits, 2)).astype(np.float32), rng.random(hits).astype(np.float32)
    kernel = BsdfKernel(Device.for_spec())
    runs: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, material in materials(Path(folder), rng).items():
            runs[name] = {"build": lambda m=material: bsdf_for(m, Hits(hits))}
            if kernel.rows(material, Hits(hits), hits) is not None:
                runs[name]["kernel"] = lambda m=material: kernel(kernel.rows(m, Hits(hits), hits), wo, wi[None], u,
                                                                 u_lobe)
            bsdf = runs[name]["build"]()
            runs[name]["evaluate_pdf"] = lambda b=bsdf: (b.evaluate(wo, wi), b.pdf(wo, wi))
            runs[name]["sample"] = lambda b=bsdf: b.sample(wo, u, u_lobe)
    times: dict[str, dict[str, list[float]]] = {name: {part: [] for part in run} for name, run in runs.items()}
    for round_ in range(repeats + 1):  # round 0 warms up (builds, tables, caches) and is not kept
        for name, run in runs.items():
            for part, call in run.items():
                seconds = _timed(call)
                if round_:
                    times[name][part].append(seconds)
    rows = []
    for name, parts in times.items():
        median = {part: statistics.median(values) for part, values in parts.items()}
        numpy_s = median["build"] + median["evaluate_pdf"] + median["sample"]
        rows.append({"material": name, "hits": hits, "repeats": repeats,
                     "build_s": median["build"],
                     "evaluate_pdf_s": median["evaluate_pdf"], "sample_s": median["sample"],
                     "kernel_s": median.get("kernel"),
                     "kernel_speedup": numpy_s / median["kernel"] if "kernel" in median else None,
                     "rounds": parts})
    base = rows[0]["evaluate_pdf_s"] + rows[0]["sample_s"]
    for row in rows:
        row["m_hits_per_s"] = hits / (row["evaluate_pdf_s"] + row["sample_s"]) / 1e6
        row["ratio_to_lambertian"] = (row["evaluate_pdf_s"] + row["sample_s"]) / base
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hits", type=int, default=200_000, help="hits per batch (default 200000)")
    parser.add_argument("--repeats", type=int, default=3, help="alternating rounds (default 3)")
    args = parser.parse_args()
    load_before = os.getloadavg()
    rows = measure(args.hits, args.repeats)
    load_after = os.getloadavg()
    print(f"{args.hits} hits, medians of {args.repeats} alternating rounds; load average {load_before[0]:.2f} "
          f"before, {load_after[0]:.2f} after")
    print(f"{'material':<16} {'build s':>8} {'eval+pdf s':>10} {'sample s':>9} {'M hits/s':>9} {'x lambert':>9}"
          f" {'kernel s':>9} {'x numpy':>8}")
    for r in rows:
        kernel = "" if r["kernel_s"] is None else f"{r['kernel_s']:9.4f} {r['kernel_speedup']:8.1f}"
        print(f"{r['material']:<16} {r['build_s']:8.4f} {r['evaluate_pdf_s']:10.4f} {r['sample_s']:9.4f} "
              f"{r['m_hits_per_s']:9.2f} {r['ratio_to_lambertian']:9.1f} {kernel}")
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    report = {"load_average_before": load_before, "load_average_after": load_after, "rows": rows}
    (out / "bsdf.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
