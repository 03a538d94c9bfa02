"""Robustness of the command line: every bad value is one line and exit 2 with nothing written;
resource guards refuse before work; signals keep what was rendered; files are never lost or
stranded. Each case is a reproducible report from trying the CLI as a new user would."""

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import sigint_by_default
from realistic.cli import main
from realistic.core.atomic_files import remove_stale_temporaries
from realistic.core.image_files import read_exr, write_exr

REPO = Path(__file__).resolve().parents[1]
#: A render whose set-up is quick: numpy rays aimed at the rear element (no exit-pupil table).
QUICK = ["--backend", "numpy", "--lens-sampling", "rear", "--dispersion", "off"]


def refused(args: list[str], tmp_path: Path, capsys) -> str:
    """Run ``realistic ARGS``; assert exit 2, one error line and no file written; return the line."""
    before = set(tmp_path.iterdir())
    status = main(args)
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.startswith("realistic: error:") and err.count("\n") == 1 and "Traceback" not in err, err
    assert set(tmp_path.iterdir()) == before
    return err


@pytest.mark.parametrize("args,message", [
    (["--seed", "-1"], "seed must be between 0 and 4294967295"),
    (["--seed", "9223372036854775808"], "seed must be between"),
    (["--seed", "4294967296"], "seed must be between"),
    (["--seed", "1.5"], "not a whole number"),
    (["--blades", "0"], "blade count must be between 3 and 64"),
    (["--blades", "100000"], "blade count must be between 3 and 64"),
    (["--blades", "10000"], "blade count"),
    (["--exposure", "nan"], "exposure must be a finite number"),
    (["--exposure", "inf"], "exposure must be a finite number"),
    (["--res", "-64x48"], "is not WIDTHxHEIGHT"),
    (["--res", "100000x100000"], "resolution width must be between 1 and 65536"),
    (["--spp", "10000000000"], "samples per pixel must be between 1 and"),
    (["--film-diagonal", "-70"], "film diagonal"),
    (["--film-diagonal", "1e9"], "film diagonal (mm) must be at most 1000"),
    (["--light-samples", "0"], "light samples"),
    (["--threads", "0"], "threads must be between 1 and 1024, got 0"),
    (["--threads", "2", "--workers", "2"], "not allowed with argument"),
    (["--aperture", "nan"], "aperture diameter must be a positive number of mm"),
    (["--aperture", "1000"], "aperture diameter 1000 mm is wider than dgauss's widest element (25.2 mm)"),
    (["--aperture", "1e-300"], "aperture diameter must be at least 0.001 mm"),  # was an all-black image, exit 0
    (["--fstop", "1e308"], "f-number must be at most 10000"),  # the same
    (["--sweep", "fstop=2:1e308:3"], "f-number must be at most 10000"),
    (["--iso", "-100"], "ISO speed"),
    (["--max-memory", "lots"], "is not a positive size"),
    (["--target", "-1,0"], "is not three finite numbers"),
    (["--nonsense"], "unrecognized arguments"),
])
def test_bad_values_are_one_line_before_any_work(tmp_path, capsys, args, message):
    err = refused(["render", *QUICK, "--res", "8x8", *args, "--out", str(tmp_path / "x.exr")], tmp_path, capsys)
    assert message in err


def test_memory_guard_refuses_before_work(tmp_path, capsys):
    start = time.perf_counter()
    err = refused(["render", *QUICK, "--res", "20000x20000", "--spp", "1", "--out", str(tmp_path / "x.exr")],
                  tmp_path, capsys)
    assert "needs about" in err and "GiB" in err and "available" in err
    assert time.perf_counter() - start < 30  # refused up front, not after filling memory
    err = refused(["render", *QUICK, "--res", "8x8", "--max-memory", "1M", "--out", str(tmp_path / "x.exr")],
                  tmp_path, capsys)
    assert "allowed by --max-memory" in err


@pytest.mark.parametrize("diagonal", ["0", "-70", "1e9"])
def test_pbrt_film_diagonal_is_checked_like_the_option(tmp_path, capsys, diagonal):
    scene = tmp_path / "s.pbrt"
    scene.write_text(f'Film "image" "float diagonal" {diagonal}\n'
                     'Camera "realistic" "string lensfile" "dgauss.50mm.dat" "float aperturediameter" 10\n'
                     '    "float focusdistance" 2\nWorldBegin\nShape "sphere"\n')
    err = refused(["render", str(scene), *QUICK, "--res", "8x8", "--out", str(tmp_path / "x.exr")], tmp_path, capsys)
    assert "film diagonal (mm)" in err


def test_unwritable_place_is_refused_before_rendering(tmp_path, capsys):
    err = refused(["render", *QUICK, "--res", "8x8", "--out", "/proc/r.exr"], tmp_path, capsys)
    assert "/proc/r.exr: cannot be written" in err


def test_a_finished_render_is_kept_when_its_folder_vanishes(tmp_path, capsys, monkeypatch):
    import realistic.renderer.passes as passes

    folder = tmp_path / "out"
    folder.mkdir()
    render = passes.render

    def render_then_remove_the_folder(*args, **kwargs):
        results = render(*args, **kwargs)
        shutil.rmtree(folder)  # with the render's final checkpoint in it
        return results

    monkeypatch.setattr(passes, "render", render_then_remove_the_folder)
    status = main(["render", *QUICK, "--res", "8x6", "--spp", "1", "--out", str(folder / "x.exr")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert status == 2 and "the render was saved as" in err, err
    rescued = Path(err.split("the render was saved as ")[1].split(" (and")[0])
    image, header = read_exr(rescued)
    assert image.shape == (6, 8, 3) and header["samplesDone"] == 48
    assert rescued.with_suffix(".png").is_file()
    rescued.unlink()
    rescued.with_suffix(".png").unlink()


def test_stale_temporaries_of_dead_writers_are_removed(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".x.exr.{dead.pid}.k3j2.tmp.exr"
    alive = tmp_path / f".x.exr.{os.getpid()}.a9b8.tmp.exr"
    other = tmp_path / f".y.exr.{dead.pid}.k3j2.tmp.exr"
    for path in (stale, alive, other):
        path.write_bytes(b"partial")
    write_exr(tmp_path / "x.exr", _tiny_image())
    assert not stale.exists() and alive.exists() and other.exists()
    assert remove_stale_temporaries(tmp_path / "y.exr") == [other]


def _tiny_image():
    import numpy as np

    return np.ones((2, 3, 3), np.float32)


def _render_process(out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "realistic", "render", *QUICK, "--res", "160x160",
                             "--spp", "512", "--out", str(out), *extra],
                            cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.PIPE, preexec_fn=sigint_by_default)


def _wait_for(process: subprocess.Popen, text: bytes, seen: bytes = b"") -> bytes:
    """Read the process's stderr until ``text`` shows (or 90 s pass); return all read so far."""
    deadline = time.monotonic() + 90
    while text not in seen and time.monotonic() < deadline:
        chunk = os.read(process.stderr.fileno(), 256)
        if not chunk:
            break
        seen += chunk
    return seen


def _wait_for_a_pass(process: subprocess.Popen) -> bytes:
    return _wait_for(process, b"1/")  # the progress bar shows a pass done


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
@pytest.mark.parametrize("stop", ["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_act_like_ctrl_c(tmp_path, stop):
    out = tmp_path / "r.exr"
    process = _render_process(out)
    seen = _wait_for_a_pass(process)
    process.send_signal(getattr(signal, stop))
    _, rest = process.communicate(timeout=90)
    err = (seen + rest).decode()
    assert process.returncode == 130, err
    assert "Traceback" not in err and f"samples taken to {out}" in err
    image, header = read_exr(out)
    assert header["interrupted"] == 1 and 0 < header["samplesDone"] < header["samplesTotal"]
    assert image.max() > 0


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_a_second_interrupt_stops_at_once_and_writes_nothing(tmp_path):
    out = tmp_path / "r.exr"
    # passes of seconds each: the second signal lands while the first interrupt waits for them to finish
    process = _render_process(out, "--light-samples", "1024")
    seen = _wait_for_a_pass(process)
    process.send_signal(signal.SIGINT)
    seen = _wait_for(process, b"interrupt again", seen)
    process.send_signal(signal.SIGINT)
    _, rest = process.communicate(timeout=90)
    err = (seen + rest).decode()
    assert process.returncode == 130, err
    assert "stopped at once: nothing written" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def _plated_lens(path: Path, plates: int) -> Path:
    """The double Gauss behind ``plates`` thin flat glass plates: a lens whose exit-pupil table takes
    seconds to build (it grows linearly with the surfaces)."""
    plate = "inf 0.05 1.5 0 40\ninf 0.05 1 0 40\n" * plates  # 5 columns, as the file has
    path.write_text(plate + (REPO / "realistic/optics/formats/lenses/dgauss.50mm.dat").read_text())
    return path


def test_interrupt_during_set_up_says_nothing_was_written(tmp_path):
    lens = _plated_lens(tmp_path / "plates.dat", 495)  # 1001 surfaces: a table of seconds
    out = tmp_path / "out"
    out.mkdir()
    process = subprocess.Popen([sys.executable, "-m", "realistic", "render", *QUICK[:2], "--lens", str(lens),
                                "--res", "64x64", "--out", str(out / "r.exr")], cwd=REPO, stderr=subprocess.PIPE,
                               env={**os.environ, "REALISTIC_CACHE_DIR": "off"}, preexec_fn=sigint_by_default)
    time.sleep(2.5)  # Python has started and is building the table
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130
    assert b"nothing written" in err and b"Traceback" not in err
    assert list(out.iterdir()) == []


def test_api_scene_beyond_single_precision_is_a_user_error():
    import numpy as np

    from realistic.camera.lens_camera import LensCamera
    from realistic.errors import UserError
    from realistic.optics.formats import load_lens
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import render
    from realistic.scene.model import Scene
    from realistic.scene.shapes import sphere

    scene = Scene()
    scene.add(sphere(1e200, 16))
    camera = LensCamera.looking_at(load_lens("dgauss"), np.zeros(3), np.array([0, 0, 5.0]), width=4, height=4, spp=1)
    with pytest.raises(UserError, match="not finite in single precision"):
        render(RenderJob(scene, (camera,), "numpy"))


@pytest.mark.parametrize("aspect", [1e-300, 1e-8, 1.0, 1e8, 1e300])
def test_cone_normals_are_unit_and_outward_at_any_aspect(aspect):
    import numpy as np

    from realistic.scene.shapes import cone

    mesh = cone(1.0, aspect, segments=16)
    assert np.all(np.isfinite(mesh.normals)) and np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
    # the side normal leans out from the axis by atan(height / radius) from the z axis
    expected_z = 1.0 / np.hypot(1.0, aspect)
    assert np.allclose(mesh.normals[:, 2], expected_z)


@pytest.mark.parametrize("make", ["disk", "sphere", "cone", "quad"])
@pytest.mark.parametrize("size", [0.0, -1.0, float("nan"), float("inf")])
def test_shapes_refuse_sizes_that_are_not_positive_lengths(make, size):
    from realistic.errors import UserError
    from realistic.scene import shapes

    args = {"disk": (size,), "sphere": (size,), "cone": (size, 1.0), "quad": (1.0, size)}[make]
    with pytest.raises(UserError, match="must be a positive finite number"):
        getattr(shapes, make)(*args)


@pytest.mark.parametrize("args,message", [
    (["lens", "plot", "dgauss", "--film-diagonal", "1e9"], "film diagonal (mm) must be at most 1000"),
    (["lens", "info", "dgauss", "--aperture", "0"], "aperture diameter must be a positive number of mm"),
    (["lens", "info", "dgauss", "--aperture", "1000"], "wider than dgauss's widest element"),
    (["lens", "info", "dgauss", "--wavelength", "-5"], "wavelength (nm) must be a positive finite number"),
])
def test_lens_commands_check_quantities_as_render_does(tmp_path, capsys, args, message):
    assert message in refused(args, tmp_path, capsys)


def test_bench_warm_up_honours_max_memory(monkeypatch):
    import numpy as np

    import realistic.renderer.memory as memory
    from realistic.camera.lens_camera import LensCamera
    from realistic.optics.formats import load_lens
    from realistic.renderer.convergence import measure_sample_counts
    from realistic.renderer.job import RenderJob
    from realistic.scene.staging import default_setup

    monkeypatch.setattr(memory, "available_bytes", lambda: 1)  # the system says nothing fits
    setup = default_setup()
    camera = LensCamera.looking_at(load_lens("dgauss"), setup.eye, setup.target, width=4, height=4, spp=1,
                                   lens_sampling="rear")
    job = RenderJob(setup.scene, (camera,), "numpy", max_memory_bytes=1 << 40)  # ... but the user allows it
    rows, image = measure_sample_counts(job, [1, 2], progress=False)
    assert [row["spp"] for row in rows] == [1, 2] and np.all(np.isfinite(image))
