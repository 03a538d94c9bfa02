"""``python -m realistic render``: end to end, bad input, and Ctrl-C."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from conftest import shared_file, sigint_by_default
from realistic import load_lens
from realistic.camera.lens_camera import LensCamera
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.renderer.job import RenderJob, RenderObserver
from realistic.renderer.passes import ThreadPasses, render
from realistic.scene.staging import default_setup

REPO = Path(__file__).resolve().parents[1]
FAST = ["--backend", "numpy", "--res", "24x16", "--spp", "2"]


def run_cli(args, capsys):
    status = main(["render", *args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.fixture
def box_file(tmp_path):
    path = tmp_path / "box.ply"
    trimesh.creation.box((1.0, 0.5, 0.3)).export(path)
    return path


def test_renders_a_mesh_with_metadata_and_preview(tmp_path, box_file, capsys):
    out = tmp_path / "box.exr"
    status, stdout, _ = run_cli([str(box_file), *FAST, "--out", str(out), "--seed", "5", "--aperture", "8"], capsys)
    assert status == 0 and str(out) in stdout
    image, header = read_exr(out)
    assert image.shape == (16, 24, 3) and np.all(np.isfinite(image)) and image.max() > 0
    assert header["lens"] == "dgauss" and header["spp"] == 2 and header["seed"] == 5
    assert header["apertureDiameterMm"] == pytest.approx(8.0)
    assert header["fNumber"] > 2.5 and header["focusDistanceMm"] > 0 and header["renderSeconds"] > 0
    assert header["interrupted"] == 0
    assert (tmp_path / "box.png").stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["box.exr", "box.ply", "box.png"]


def test_the_subject_fills_the_frame_and_is_lit(tmp_path, box_file, capsys):
    out = tmp_path / "box.exr"
    assert run_cli([str(box_file), "--backend", "numpy", "--res", "40x40", "--spp", "4", "--out", str(out)],
                   capsys)[0] == 0
    image = read_exr(out)[0][..., 0]
    centre, corner = image[15:25, 15:25].mean(), image[:4, :4].mean()
    assert centre > 0 and abs(centre - corner) > 0.1 * max(centre, corner)  # something differs from the floor


def test_default_scene_renders(tmp_path, capsys):
    out = tmp_path / "default.exr"
    status, _, _ = run_cli([*FAST, "--out", str(out)], capsys)
    assert status == 0
    image, header = read_exr(out)
    assert header["scene"] == "default" and image.max() > 0


def test_threads_renders_on_that_many_threads_in_process_whatever_the_environment(tmp_path, capsys, monkeypatch,
                                                                                  thread_pools):
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://192.0.2.1:8786")  # no cluster there: not to be used
    images = {}
    for threads in ("1", "4"):
        out = tmp_path / f"t{threads}.exr"
        status, _, _ = run_cli([*FAST, "--threads", threads, "--out", str(out)], capsys)
        assert status == 0
        images[threads] = read_exr(out)[0]
    assert [threads for threads, _ in thread_pools] == [1, 4]
    np.testing.assert_array_equal(images["1"], images["4"])


@pytest.mark.parametrize(("flags", "pinned"), [([], False), (["--pin-threads"], True)])
def test_render_threads_keep_to_one_cpu_when_told_to(tmp_path, capsys, thread_pools, flags, pinned):
    assert run_cli([*FAST, *flags, "--out", str(tmp_path / "p.exr")], capsys)[0] == 0
    assert [pin for _, pin in thread_pools] == [pinned]


def test_bunny_from_shared_data(tmp_path, capsys):
    bunny = shared_file("meshes/stanford-bunny.obj")
    out = tmp_path / "bunny.exr"
    assert run_cli([str(bunny), *FAST, "--out", str(out)], capsys)[0] == 0


def bad_inputs(tmp_path):
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    text = tmp_path / "notes.ply"
    text.write_text("hello\n")
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n")
    return {
        "missing mesh": ([str(tmp_path / "nope.obj")], "no such mesh file"),
        "empty mesh": ([str(empty)], "empty"),
        "non-mesh": ([str(text)], "not a readable PLY"),
        "non-finite": ([str(nan)], "non-finite"),
        "unknown lens": (["--lens", "nosuchlens"], "no such lens file"),
        "unreachable focus": (["--focus", "0.05"], "closer than"),
        "zero resolution": (["--res", "0x10"], "resolution"),
        "bad resolution": (["--res", "big"], "WIDTHxHEIGHT"),
        "zero spp": (["--spp", "0"], "samples per pixel"),
        "unwritable output": (["--out", str(tmp_path / "no" / "dir" / "x.exr")], "does not exist"),
        "not exr": (["--out", str(tmp_path / "x.tif")], ".exr file (the PNG preview goes beside it), a .png or a .pfm"),
    }


@pytest.mark.parametrize("case", ["missing mesh", "empty mesh", "non-mesh", "non-finite", "unknown lens",
                                  "unreachable focus", "zero resolution", "bad resolution", "zero spp",
                                  "unwritable output", "not exr"])
def test_bad_input_is_one_line_and_status_2(tmp_path, capsys, case):
    args, message = bad_inputs(tmp_path)[case]
    out_args = [] if "--out" in args else ["--out", str(tmp_path / "out.exr")]
    before = set(tmp_path.iterdir())
    status, _, err = run_cli([*FAST, *args, *out_args], capsys)
    assert status == 2
    assert err.startswith("realistic: error:") and err.count("\n") == 1 and message in err
    assert set(tmp_path.iterdir()) == before  # no output, no temporary file


def test_subprocess_error_has_no_traceback(tmp_path):
    result = subprocess.run([sys.executable, "-m", "realistic", "render", str(tmp_path / "none.stl"),
                             "--backend", "numpy", "--out", str(tmp_path / "x.exr")],
                            capture_output=True, text=True, cwd=REPO, timeout=60)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and result.stderr.count("\n") == 1


def test_interrupt_keeps_the_passes_done():
    setup = default_setup()
    camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, None, 43.27, 32, 32, 4)
    calls = []

    def interrupt(result):
        calls.append(result.samples_done)
        if len(calls) == 2:
            raise KeyboardInterrupt

    result = render(RenderJob(setup.scene, (camera,), "numpy", pass_samples=512), ThreadPasses(threads=2),
                    RenderObserver(on_pass=interrupt))[0]
    assert result.interrupted
    assert 2 * 512 <= result.samples_done < result.samples_total
    assert result.samples_done % 512 == 0  # only whole passes
    assert result.image.max() > 0  # which pixels they cover: tests/test_progressive.py


@pytest.mark.skipif(os.name != "posix", reason="SIGINT delivery")
def test_ctrl_c_writes_what_has_accumulated(tmp_path):
    out = tmp_path / "big.exr"
    process = subprocess.Popen([sys.executable, "-m", "realistic", "render", "--backend", "numpy",
                                "--res", "200x200", "--spp", "256", "--out", str(out)],
                               cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.PIPE, preexec_fn=sigint_by_default)
    seen = b""
    deadline = time.monotonic() + 60
    while b"1/" not in seen and time.monotonic() < deadline:  # the progress bar shows a pass done
        seen += os.read(process.stderr.fileno(), 256)
    process.send_signal(signal.SIGINT)
    _, rest = process.communicate(timeout=90)
    err = (seen + rest).decode()
    assert process.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    image, header = read_exr(out)
    assert header["interrupted"] == 1 and 0 < header["samplesDone"] < header["samplesTotal"]
    assert image.max() > 0


def test_renders_a_pbrt_homework_scene_with_overrides(tmp_path, capsys, monkeypatch):
    scene = shared_file("scenes/pbrt/dof-dragons.telephoto.pbrt")
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli([str(scene), *FAST, "--aperture", "20", "--focus", "1.2"], capsys)
    assert status == 0, err
    image, header = read_exr(tmp_path / "dof-dragons.telephoto.exr")  # the scene's Film filename
    assert image.shape == (16, 24, 3) and image.max() > 0
    assert float(header["apertureDiameterMm"]) == 20
    assert float(header["focusDistanceMm"]) == pytest.approx(1.2 * 5000)  # Scale 5000: 1 unit = 5 m
    assert (tmp_path / "dof-dragons.telephoto.png").exists()


def test_pbrt_scene_rejects_mesh_only_options(tmp_path, capsys):
    scene = shared_file("scenes/pbrt/dof-dragons.dgauss.pbrt")
    status, _, err = run_cli([str(scene), *FAST, "--target", "0,0,0", "--out", str(tmp_path / "x.exr")], capsys)
    assert status == 2 and "--target apply to mesh scenes" in err
    assert list(tmp_path.iterdir()) == []


def test_unsupported_pbrt_features_are_reported_and_rendered(tmp_path, capsys):
    scene = tmp_path / "s.pbrt"
    scene.write_text('Film "image" "integer xresolution" 8 "integer yresolution" 8\nCamera "perspective"\n'
                     'WorldBegin\nMaterial "velvet"\nShape "sphere"\n')
    status, _, err = run_cli([str(scene), "--spp", "1", "--out", str(tmp_path / "x.exr")], capsys)
    assert status == 0
    assert f'{scene}:4: unsupported: Material "velvet", rendered as matte grey' in err
