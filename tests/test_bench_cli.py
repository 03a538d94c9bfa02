"""`realistic bench`: sample-count table, RMSE convergence, plot and JSON."""

import json
import subprocess
import sys

import pytest
from PIL import Image

from realistic.cli import main

TINY = ["--backend", "numpy", "--res", "24x16"]


def test_bench_converges_like_monte_carlo(tmp_path, capsys):
    out, plot = tmp_path / "bench.json", tmp_path / "conv.png"
    status = main(["bench", *TINY, "--spp", "1,4,16,64", "--json", str(out), "--plot", str(plot)])
    printed = capsys.readouterr().out
    assert status == 0
    report = json.loads(out.read_text())
    rows = report["rows"]
    assert [r["spp"] for r in rows] == [1, 4, 16, 64] and report["against"] == "64 spp"
    assert rows[-1]["rmse"] == 0  # the highest count is the reference
    errors = [r["rmse"] for r in rows[:-1]]
    assert errors[0] > errors[1] > errors[2] > 0
    assert -0.9 < report["slope"] < -0.25  # about -1/2 (the last point, measured against itself, is left out)
    assert all(0 <= r["vignetted_fraction"] < 1 and r["camera_rays_per_second"] > 0 for r in rows)
    assert "RMSE vs 64 spp" in printed
    assert Image.open(plot).size[0] > 400


def test_bench_against_a_reference_image(tmp_path, capsys):
    reference = tmp_path / "ref.exr"
    assert main(["render", *TINY, "--spp", "32", "--out", str(reference)]) == 0
    capsys.readouterr()
    out = tmp_path / "b.json"
    assert main(["bench", *TINY, "--spp", "2,8", "--reference", str(reference), "--json", str(out),
                 "--plot", str(tmp_path / "p.png")]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert rows[0]["rmse"] > rows[1]["rmse"] > 0


@pytest.mark.parametrize(("flags", "pinned"), [([], False), (["--pin-threads"], True)])
def test_bench_renders_pin_their_threads_when_told_to(tmp_path, capsys, thread_pools, flags, pinned):
    assert main(["bench", *TINY, "--spp", "1,2", *flags, "--json", str(tmp_path / "b.json"),
                 "--plot", str(tmp_path / "p.png")]) == 0
    assert [pin for _, pin in thread_pools] == [pinned] * 3  # the untimed 1 spp render, then 1 and 2 spp


@pytest.mark.parametrize("args,message", [(["--spp", "1,x"], "not a comma-separated list"),
                                          (["--spp", "0,4"], "not a comma-separated list"),
                                          (["--reference", "missing.exr"], "no such reference image")])
def test_bench_bad_input_is_one_line(tmp_path, args, message):
    run = subprocess.run([sys.executable, "-m", "realistic", "bench", *TINY, *args,
                          "--plot", str(tmp_path / "p.png")], capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
