"""Finished work is never lost (issue 32): an interrupt while the image is written waits for the
write, an interrupted render keeps a better image that is there, a render without --resume keeps
an earlier checkpoint, a full disk is rescued or reported, the EXR header after a resume is true."""

import errno
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import realistic as rl
from realistic.cli import main
from realistic.core import image_files
from realistic.core.image_files import read_exr
from realistic.renderer import checkpoint as checkpoint_module
from realistic.renderer import output, passes
from realistic.renderer.checkpoint import RenderIdentity, save_checkpoint
from realistic.renderer.film import Film, PassFilm
from realistic.renderer.job import Checkpointing, RenderJob, RenderObserver
from realistic.renderer.pass_plan import plan_passes
from realistic.renderer.passes import ThreadPasses, render

REPO = Path(__file__).resolve().parents[1]
SMALL = {"resolution": (8, 6), "spp": 4, "lens_sampling": "rear", "dispersion": False}
QUICK = ["--backend", "numpy", "--lens-sampling", "rear", "--dispersion", "off", "--threads", "1"]


@pytest.fixture(scope="module")
def scene():
    return rl.load_scene(**SMALL)


def _job(scene, checkpoint: Path | None = None, resume: bool = False) -> RenderJob:
    return RenderJob(scene, (scene.camera,), "numpy", pass_samples=16,
                     checkpoint=None if checkpoint is None else Checkpointing(checkpoint, None, resume))


def _interrupted(scene, checkpoint: Path | None = None, passes_before_stop: int = 1):
    calls = []

    def stop(result):
        calls.append(1)
        if len(calls) == passes_before_stop:
            raise KeyboardInterrupt

    return render(_job(scene, checkpoint), ThreadPasses(1), RenderObserver(on_pass=stop))[0]


@pytest.fixture
def sigint_raises():
    """SIGINT as Python's KeyboardInterrupt for the test, whatever the test run set (a background
    run ignores it)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_an_interrupt_while_the_image_is_written_waits_for_both_files(scene, tmp_path, monkeypatch, sigint_raises):
    result = render(_job(scene), ThreadPasses(1))[0]
    write_png = output.write_png

    def interrupted_between_the_files(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # the EXR is written; Ctrl-C lands before the PNG
        write_png(*args, **kwargs)

    monkeypatch.setattr(output, "write_png", interrupted_between_the_files)
    with pytest.raises(KeyboardInterrupt):
        output.save(result, tmp_path / "r.exr")
    image, header = read_exr(tmp_path / "r.exr")
    np.testing.assert_array_equal(image, result.image)
    assert (tmp_path / "r.png").is_file() and header["samplesDone"] == result.samples_total


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_the_cli_keeps_the_image_written_when_interrupted_while_writing(tmp_path, monkeypatch, capsys,
                                                                          sigint_raises):
    write_png = output.write_png

    def interrupted(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        write_png(*args, **kwargs)

    monkeypatch.setattr(output, "write_png", interrupted)
    out = tmp_path / "r.exr"
    assert main(["render", *QUICK, "--res", "8x6", "--spp", "2", "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert f"wrote the 96 of 96 samples taken to {out}" in err and "Traceback" not in err
    assert read_exr(out)[1]["samplesDone"] == 96 and out.with_suffix(".png").is_file()


def test_an_interrupted_render_keeps_a_better_image(scene, tmp_path):
    out = tmp_path / "r.exr"
    whole = render(_job(scene), ThreadPasses(1))[0]
    rl.save(whole, out)
    before = out.read_bytes(), out.with_suffix(".png").read_bytes()
    partial = _interrupted(scene)
    assert partial.interrupted and partial.samples_done < whole.samples_done
    with pytest.raises(rl.UserError, match=f"{whole.samples_done} samples, this interrupted render") as err:
        rl.save(partial, out)
    assert "\n" not in str(err.value)
    assert (out.read_bytes(), out.with_suffix(".png").read_bytes()) == before


def test_an_interrupted_render_replaces_a_worse_one(scene, tmp_path):
    out = tmp_path / "r.exr"
    rl.save(_interrupted(scene, passes_before_stop=1), out)
    better = _interrupted(scene, passes_before_stop=3)
    rl.save(better, out)
    assert read_exr(out)[1]["samplesDone"] == better.samples_done


def test_a_render_without_resume_keeps_an_earlier_checkpoint(scene, tmp_path):
    checkpoint = tmp_path / "r.exr.partial"
    _interrupted(scene, checkpoint, passes_before_stop=2)
    saved = checkpoint.read_bytes()
    with pytest.raises(rl.UserError, match="--resume") as err:
        render(_job(scene, checkpoint), ThreadPasses(1))
    assert str(checkpoint) in str(err.value) and "\n" not in str(err.value)
    assert checkpoint.read_bytes() == saved


def test_the_cli_refuses_to_replace_a_checkpoint_before_any_work(tmp_path, capsys):
    out = tmp_path / "r.exr"
    checkpoint = tmp_path / "r.exr.partial"
    checkpoint.write_bytes(b"161 passes of work")
    assert main(["render", *QUICK, "--res", "8x6", "--spp", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--resume" in err and "remove" in err
    assert checkpoint.read_bytes() == b"161 passes of work" and not out.exists()


def _full_disk_in(folder: Path, monkeypatch) -> None:
    """Every image written into ``folder`` fails as on a full disk (ENOSPC from the writer)."""
    write_atomically = image_files.write_atomically

    def full(path, write):
        if Path(path).parent == folder:
            def no_space(temporary: str) -> None:
                Path(temporary).write_bytes(b"\0" * 10)
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return write_atomically(path, no_space)
        return write_atomically(path, write)

    monkeypatch.setattr(image_files, "write_atomically", full)


def test_a_full_disk_at_the_end_rescues_the_image_and_keeps_the_checkpoint(scene, tmp_path, monkeypatch):
    checkpoint = tmp_path / "r.exr.partial"
    result = render(_job(scene, checkpoint), ThreadPasses(1))[0]
    _full_disk_in(tmp_path, monkeypatch)
    with pytest.raises(rl.UserError, match="No space left on device.*saved as") as err:
        rl.save(result, tmp_path / "r.exr")
    rescued = Path(str(err.value).split("saved as ")[1].split(" (and")[0])
    try:
        np.testing.assert_array_equal(read_exr(rescued)[0], result.image)
        assert "\n" not in str(err.value) and checkpoint.is_file() and not (tmp_path / "r.exr").exists()
        assert [p.name for p in tmp_path.iterdir()] == ["r.exr.partial"]  # no temporaries left
    finally:
        rescued.unlink()
        rescued.with_suffix(".png").unlink()


def test_a_checkpoint_on_a_full_disk_is_reported_and_the_render_goes_on(scene, tmp_path, monkeypatch, capsys):
    write_atomically = checkpoint_module.write_atomically

    def full(path, write):
        def no_space(temporary: str) -> None:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        write_atomically(path, no_space)

    monkeypatch.setattr(checkpoint_module, "write_atomically", full)
    job = RenderJob(scene, (scene.camera,), "numpy", pass_samples=16,
                    checkpoint=Checkpointing(tmp_path / "r.exr.partial", 0.0))
    result = render(job, ThreadPasses(1))[0]
    assert not result.interrupted and result.samples_done == result.samples_total
    err = capsys.readouterr().err
    assert err.count("checkpoint not saved") == 1 and "No space left on device" in err
    assert list(tmp_path.iterdir()) == []  # no temporaries left behind


def test_the_header_after_a_resume_counts_the_passes_that_waited(scene, tmp_path):
    """A checkpoint taken while later passes had finished before earlier ones (as a kill leaves
    it): the resumed render's samplesDone must still reach the total when it says it is complete."""
    camera = scene.camera
    plan = plan_passes(camera.width * camera.height, camera.spp, 16)
    film = PassFilm(Film(camera.width, camera.height, camera.spp), plan)
    for index in (0, 1, 3, 4):  # pass 2 is missing: 3 and 4 wait for it
        film.add(index, plan[index].first_pixel, np.zeros((plan[index].pixel_count, 3)))
    assert sorted(film.waiting) == [3, 4]
    checkpoint = tmp_path / "r.exr.partial"
    save_checkpoint(checkpoint, RenderIdentity.of(scene, camera, 0, 16, "numpy", 1), film)
    result = render(_job(scene, checkpoint, resume=True), ThreadPasses(1))[0]
    assert not result.interrupted and result.samples_done == result.samples_total
    rl.save(result, tmp_path / "r.exr")
    header = read_exr(tmp_path / "r.exr")[1]
    assert header["interrupted"] == 0 and header["samplesDone"] == header["samplesTotal"]


@pytest.mark.parametrize("args, message", [
    (["--shutter", "0"], "shutter time '0' is not a positive number"),
    (["--shutter", "1/0"], "shutter time '1/0'"),
    (["--shutter", "abc"], "shutter time 'abc'"),
    (["--shutter", "nan"], "shutter time 'nan'"),
    (["--shutter", "inf"], "shutter time 'inf'"),
    (["--shutter", "1e308"], "shutter time (seconds) must be between"),
    (["--shutter", "1e-300"], "shutter time (seconds) must be between"),
    (["--iso", "1e308"], "ISO speed must be between"),
    (["--iso", "nan"], "ISO speed must be a finite number"),
    (["--iso", "0"], "ISO speed must be between"),
    (["--exposure", "1e308"], "exposure must be between -64 and 64"),
    (["--exposure", "-1e308"], "exposure must be between"),
])
def test_photographic_options_are_refused_before_any_work(tmp_path, capsys, monkeypatch, args, message):
    def no_work(*args, **kwargs):
        raise AssertionError("rendered before the options were checked")

    monkeypatch.setattr(passes, "render", no_work)
    out = tmp_path / "r.exr"
    status = main(["render", *QUICK, "--res", "8x6", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_the_largest_accepted_exposure_gives_a_finite_image(tmp_path):
    out = tmp_path / "r.exr"
    assert main(["render", *QUICK, "--res", "8x6", "--spp", "2", "--out", str(out), "--shutter", "1e6",
                 "--iso", "1e7", "--exposure", "64"]) == 0
    assert np.all(np.isfinite(read_exr(out)[0]))


def _cli(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "realistic", *args], cwd=REPO, capture_output=False,
                          stderr=subprocess.PIPE, text=True, timeout=120, **kwargs)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
@pytest.mark.parametrize("command", [["lens", "list"], ["lens", "info", "dgauss"], ["--help"]])
def test_a_full_standard_output_is_one_line(command):
    with open("/dev/full", "w") as full:
        run = _cli(*command, stdout=full)
    assert run.returncode == 1 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr == "realistic: error: cannot write to standard output: No space left on device\n"


@pytest.mark.skipif(os.name != "posix", reason="POSIX pipes")
def test_a_closed_pipe_on_standard_output_is_quiet():
    read, write = os.pipe()
    os.close(read)  # `| head` that has stopped reading
    try:
        run = _cli("lens", "list", stdout=write)
    finally:
        os.close(write)
    assert run.returncode == 1 and run.stderr == "", run.stderr


@pytest.mark.skipif(os.name != "posix", reason="POSIX file descriptors")
def test_a_closed_standard_output_is_no_traceback():
    run = subprocess.run([sys.executable, "-m", "realistic", "lens", "list"], cwd=REPO, stdout=None,
                         stderr=subprocess.PIPE, text=True, timeout=120, preexec_fn=lambda: os.close(1))
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_an_interrupted_rerender_keeps_the_complete_image_and_its_samples_in_the_checkpoint(tmp_path):
    """The issue's case: a complete image at --out, the same render again interrupted at once."""
    from conftest import sigint_by_default

    out = tmp_path / "r.exr"
    command = [sys.executable, "-m", "realistic", "render", *QUICK, "--res", "48x48", "--spp", "256", "--out", str(out)]
    assert subprocess.run(command, cwd=REPO, capture_output=True, timeout=120).returncode == 0
    complete = out.read_bytes()
    samples = read_exr(out)[1]["samplesDone"]
    command[command.index("--spp") + 1] = "4096"
    command += ["--light-samples", "64"]  # samples 65 times as slow: it stops far short of the first's
    process = subprocess.Popen(command, cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                               preexec_fn=sigint_by_default)
    seen = b""
    while b"1/" not in seen:  # a pass done
        chunk = os.read(process.stderr.fileno(), 256)
        assert chunk, seen
        seen += chunk
    process.send_signal(signal.SIGINT)
    _, rest = process.communicate(timeout=120)
    err = (seen + rest).decode()
    assert process.returncode == 130 and "Traceback" not in err, err
    assert f"{out} holds {samples} samples" in err and "kept it" in err
    assert out.read_bytes() == complete and (tmp_path / "r.exr.partial").is_file()
