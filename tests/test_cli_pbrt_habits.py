"""pbrt-v4's command-line habits on ``render`` and ``bench`` (issue 33): the names pbrt-v4's
``src/pbrt/cmd/pbrt.cpp`` gives its options (``--outfile``, ``--nthreads``, ``--quiet``, ``--seed``,
``--spp``), ``--version``, and ``--resume`` starting afresh when there is nothing to resume."""

import numpy as np
import pytest
import trimesh

from realistic import __version__
from realistic.cli import build_parser, main
from realistic.core.image_files import read_exr

FAST = ["--backend", "numpy", "--res", "12x8", "--spp", "1"]


@pytest.fixture
def box_file(tmp_path):
    path = tmp_path / "box.ply"
    trimesh.creation.box((1.0, 0.5, 0.3)).export(path)
    return path


def test_version_prints_the_package_version(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["--version"])
    assert exited.value.code == 0
    assert capsys.readouterr().out.strip() == f"realistic {__version__}"


@pytest.mark.parametrize("flag", ["-o", "--outfile", "--out"])
def test_outfile_and_o_name_the_output(tmp_path, box_file, flag, capsys):
    out = tmp_path / "named.exr"
    assert main(["render", str(box_file), *FAST, flag, str(out)]) == 0
    assert read_exr(out)[0].shape == (8, 12, 3) and (tmp_path / "named.png").is_file()


@pytest.mark.parametrize("command", ["render", "bench"])
def test_nthreads_is_threads(command):
    parser = build_parser()
    assert parser.parse_args([command, "--nthreads", "3"]).threads == 3
    assert parser.parse_args([command, "--threads", "3"]).threads == 3


def test_seed_and_spp_as_pbrt_names_them():
    args = build_parser().parse_args(["render", "--seed", "7", "--spp", "5"])
    assert (args.seed, args.spp) == (7, 5)


def test_quiet_prints_no_progress_and_no_information(tmp_path, box_file, capsys):
    out = tmp_path / "q.exr"
    assert main(["render", str(box_file), *FAST, "-o", str(out), "--quiet", "--resume"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert read_exr(out)[0].shape == (8, 12, 3)


def test_quiet_still_prints_errors(tmp_path, box_file, capsys):
    assert main(["render", str(box_file), *FAST, "--quiet", "--spp", "0"]) == 2
    assert "samples per pixel" in capsys.readouterr().err


def test_resume_without_a_checkpoint_starts_from_scratch_with_a_note(tmp_path, box_file, capsys):
    """README's ``render scene.pbrt --checkpoint-every 60 --resume`` works on a first run."""
    out = tmp_path / "r.exr"
    assert main(["render", str(box_file), *FAST, "-o", str(out), "--checkpoint-every", "60", "--resume"]) == 0
    captured = capsys.readouterr()
    notes = [line for line in captured.err.splitlines() if "no checkpoint to resume" in line]
    assert len(notes) == 1 and "rendering from the start" in notes[0]
    again = tmp_path / "again.exr"
    assert main(["render", str(box_file), *FAST, "-o", str(again)]) == 0
    assert np.array_equal(read_exr(out)[0], read_exr(again)[0])  # the same render as one without --resume
    assert not (tmp_path / "r.exr.partial").exists()


def test_resume_still_refuses_a_checkpoint_it_cannot_continue(tmp_path, box_file, capsys):
    out = tmp_path / "r.exr"
    (tmp_path / "r.exr.partial").write_bytes(b"not a checkpoint")
    assert main(["render", str(box_file), *FAST, "-o", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "cannot resume" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_quiet_leaves_out_the_farms_information_line(tmp_path, box_file, capsys):
    pytest.importorskip("distributed", reason="dask[distributed] is the farm extra")
    out = tmp_path / "f.exr"
    assert main(["render", str(box_file), *FAST, "-o", str(out), "--workers", "1", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["render", str(box_file), *FAST, "-o", str(tmp_path / "g.exr"), "--workers", "1"]) == 0
    assert "LocalCluster" in capsys.readouterr().err
