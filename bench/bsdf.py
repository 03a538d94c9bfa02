"""BSDF benchmark: hits per second for building, evaluating and sampling each material's BSDF.

    .venv/bin/python bench/bsdf.py [--hits 200000]

For each material (constant parameters, RGB rays): ``bsdf_for`` on ``--hits`` hits, then one
``evaluate`` + ``pdf`` (the light-sampling side of MIS) and one ``sample`` (the BSDF side) with
random local directions, each timed once after a warm-up run. The measured BRDFs use the seed
scene's ../shared/scenes/pbrt/brdfs/acryl_blue.brdf (skipped when absent) and a synthetic MERL
table. Lambertian is the baseline a matte, direct-lit scene pays; the ratio column is each
material's evaluate + pdf + sample time over Lambertian's. The machine's load is not controlled:
compare ratios within one run. Prints a table and writes bench/results/bsdf.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from realistic.renderer.bsdf import bsdf_for  # noqa: E402
from realistic.renderer.bsdf.measured import MeasuredBRDF  # noqa: E402
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
from realistic.scene.measured import HalfangleTable  # noqa: E402
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


def materials() -> dict[str, object]:
    found = {"lambertian": Material((0.5,) * 3), "oren-nayar": Material((0.5,) * 3, sigma=20.0),
             "plastic": Plastic(), "coated diffuse": CoatedDiffuse(roughness=0.1),
             "conductor": Conductor(roughness_u=0.1, roughness_v=0.1), "mirror": Mirror(),
             "glass": Dielectric(1.5), "substrate": Substrate(), "mix": Mix(Material(), Plastic(), 0.5)}
    if BRDF.is_file():
        found["measured .brdf"] = Measured(str(BRDF))
    return found


def _timed(run) -> float:
    run()
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def measure(hits: int) -> list[dict]:
    rng = np.random.default_rng(0)
    wo = rng.normal(size=(hits, 3)).astype(np.float32)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wo[:, 2] = np.abs(wo[:, 2])
    wi = rng.normal(size=(hits, 3)).astype(np.float32)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    u, u_lobe = rng.random((hits, 2)).astype(np.float32), rng.random(hits).astype(np.float32)
    table = HalfangleTable(rng.random((90, 90, 180, 3)).astype(np.float32))
    rows = []
    found = materials()
    for name, material in found.items():
        bsdf = bsdf_for(material, Hits(hits))
        rows.append({"material": name, "hits": hits,
                     "build_s": _timed(lambda m=material: bsdf_for(m, Hits(hits))),
                     "evaluate_pdf_s": _timed(lambda b=bsdf: (b.evaluate(wo, wi), b.pdf(wo, wi))),
                     "sample_s": _timed(lambda b=bsdf: b.sample(wo, u, u_lobe))})
    merl = MeasuredBRDF(table, np.tile(np.eye(3, dtype=np.float32), (hits, 1, 1)))
    rows.append({"material": "measured MERL", "hits": hits, "build_s": 0.0,
                 "evaluate_pdf_s": _timed(lambda: (merl.evaluate(wo, wi), merl.pdf(wo, wi))),
                 "sample_s": _timed(lambda: merl.sample(wo, u, u_lobe))})
    base = rows[0]["evaluate_pdf_s"] + rows[0]["sample_s"]
    for row in rows:
        row["m_hits_per_s"] = hits / (row["evaluate_pdf_s"] + row["sample_s"]) / 1e6
        row["ratio_to_lambertian"] = (row["evaluate_pdf_s"] + row["sample_s"]) / base
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hits", type=int, default=200_000, help="hits per batch (default 200000)")
    args = parser.parse_args()
    rows = measure(args.hits)
    print(f"{'material':<16} {'build s':>8} {'eval+pdf s':>10} {'sample s':>9} {'M hits/s':>9} {'x lambert':>9}")
    for r in rows:
        print(f"{r['material']:<16} {r['build_s']:8.4f} {r['evaluate_pdf_s']:10.4f} {r['sample_s']:9.4f} "
              f"{r['m_hits_per_s']:9.2f} {r['ratio_to_lambertian']:9.1f}")
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "bsdf.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
