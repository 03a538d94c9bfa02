"""Output targets (issue 32): a device, pipe or socket is never replaced by the atomic rename, and
a bad output name (wrong extension, missing folder, too long) is one line before any work, for
every command that writes."""

import os
import stat
from pathlib import Path

import numpy as np
import pytest

import realistic as rl
from realistic.cli import main
from realistic.core.atomic_files import check_writable, write_text_atomically
from realistic.core.image_files import write_exr

QUICK = ["--backend", "numpy", "--lens-sampling", "rear", "--dispersion", "off", "--threads", "1", "--res", "8x6",
         "--spp", "1"]


def _device_copy_of_dev_full(path: Path) -> Path:
    """A character device like /dev/full at ``path`` (mknod: root only, else the test is skipped)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    except (PermissionError, AttributeError, OSError) as err:
        pytest.skip(f"cannot make a device here ({err})")
    return path


def _refused(args: list[str], capsys) -> str:
    status = main(args)
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("realistic: error:") and err.count("\n") == 1, err
    assert "Traceback" not in err
    return err


def _is_char_device(path: Path) -> bool:
    return stat.S_ISCHR(os.lstat(path).st_mode)


@pytest.mark.parametrize("command", [
    lambda out: ["render", *QUICK, "--out", str(out.with_suffix(".exr"))],
    lambda out: ["lens", "plot", "dgauss", "--out", str(out.with_suffix(".png"))],
    lambda out: ["lens", "curves", "dgauss", "--out", str(out.with_suffix(".png"))],
    lambda out: ["lens", "curves", "dgauss", "--json", str(out.with_suffix(".json"))],
    lambda out: ["lens", "curves", "dgauss", "--vignetting-map", str(out.with_suffix(".exr"))],
    lambda out: ["lens", "spot", "dgauss", "--out", str(out.with_suffix(".png"))],
    lambda out: ["lens", "mtf", "dgauss", "--json", str(out.with_suffix(".json"))],
    lambda out: ["lens", "psf", "dgauss", "--depth", "2", "--out", str(out.with_suffix(".exr"))],
    lambda out: ["lens", "convert", "dgauss", str(out.with_suffix(".dat"))],
    lambda out: ["bench", *QUICK[:-2], "--spp", "1", "--plot", str(out.with_suffix(".png"))],
])
def test_a_device_is_refused_and_left_as_it_is(tmp_path, capsys, command):
    args = command(tmp_path / "full")
    device = _device_copy_of_dev_full(Path(args[args.index("--out") + 1] if "--out" in args else
                                           next(a for a in args if a.startswith(str(tmp_path)))))
    err = _refused(args, capsys)
    assert f"{device}: cannot write" in err and "not a regular file" in err
    assert _is_char_device(device)


def test_the_library_does_not_replace_a_device_either(tmp_path):
    device = _device_copy_of_dev_full(tmp_path / "full.exr")
    with pytest.raises(rl.UserError, match="not a regular file"):
        write_exr(device, np.zeros((2, 2, 3), np.float32))
    with pytest.raises(rl.UserError, match="not a regular file"):
        write_text_atomically(tmp_path / "full.exr", "text")
    assert _is_char_device(device) and sorted(p.name for p in tmp_path.iterdir()) == ["full.exr"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_a_fifo_output_is_refused_without_blocking(tmp_path, capsys):
    fifo = tmp_path / "out.json"
    os.mkfifo(fifo)
    rays = tmp_path / "rays.json"
    rays.write_text('{"rays": [{"origin": [0, 0, 0], "direction": [0, 0, 1]}]}')
    err = _refused(["lens", "trace", "dgauss", "--film-distance", "40", "--input", str(rays), "--output", str(fifo)],
                   capsys)
    assert "not a regular file" in err and stat.S_ISFIFO(os.lstat(fifo).st_mode)


@pytest.mark.parametrize("args, message", [
    (["lens", "plot", "dgauss", "--out", "{tmp}/x.txt"], "x.txt: cannot be written: the name must end in"),
    (["lens", "curves", "dgauss", "--out", "{tmp}/x.exr"], "the name must end in"),
    (["lens", "spot", "dgauss", "--out", "{tmp}/x"], "the name must end in"),
    (["lens", "mtf", "dgauss", "--out", "{tmp}/x.json"], "the name must end in"),
    (["lens", "psf", "dgauss", "--depth", "2", "--out", "{tmp}/x.png"], "the name must end in .exr"),
    (["lens", "curves", "dgauss", "--vignetting-map", "{tmp}/x.png"], "the name must end in .exr"),
    (["lens", "curves", "dgauss", "--vignetting-map", "{tmp}/x.exr", "--map-res", "0x0"], "resolution"),
    (["bench", *QUICK[:-2], "--spp", "1", "--plot", "{tmp}/x.txt"], "the name must end in"),
    (["lens", "plot", "dgauss", "--out", "{tmp}/missing/x.png"], "does not exist"),
    (["lens", "curves", "dgauss", "--json", "{tmp}/missing/x.json"], "does not exist"),
    (["render", *QUICK, "--out", "{tmp}/" + "a" * 300 + ".exr"], "File name too long"),
    (["lens", "plot", "dgauss", "--out", "{tmp}/" + "a" * 300 + ".png"], "File name too long"),
    (["lens", "convert", "dgauss", "{tmp}/" + "a" * 300 + ".dat"], "File name too long"),
])
def test_bad_output_names_are_one_line_before_any_work(tmp_path, capsys, args, message):
    err = _refused([a.replace("{tmp}", str(tmp_path)) for a in args], capsys)
    assert message in err
    assert list(tmp_path.iterdir()) == []


def test_check_writable_accepts_new_and_regular_files(tmp_path):
    check_writable(tmp_path / "new.png", {".png"})
    (tmp_path / "old.png").write_bytes(b"x")
    check_writable(tmp_path / "old.png", {".png"})
    check_writable(tmp_path / "OLD.PNG", {".png"})


def test_a_plot_that_fails_halfway_leaves_the_old_file_whole(tmp_path):
    """Plots go through ``save_figure`` (matplotlib wrote the target itself before): a figure whose
    writer fails after writing part of the file leaves the file that was there as it was, and no
    temporary beside it."""
    from realistic.core.atomic_files import save_figure

    class Failing:
        def savefig(self, fname: str, *, dpi: int, format: str) -> object:  # noqa: A002 (matplotlib's name)
            Path(fname).write_bytes(b"\x89PNG half")
            raise RuntimeError("the renderer stopped")

    target = tmp_path / "plot.png"
    target.write_bytes(b"the old plot")
    with pytest.raises(RuntimeError):
        save_figure(Failing(), target, 120)
    assert target.read_bytes() == b"the old plot"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]


def test_a_plot_is_written_in_the_format_its_suffix_names(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from realistic.core.atomic_files import save_figure

    fig = plt.figure()
    for suffix, magic in ((".png", b"\x89PNG"), (".pdf", b"%PDF"), (".svg", b"<?xml")):
        save_figure(fig, tmp_path / f"plot{suffix}", 60)
        assert (tmp_path / f"plot{suffix}").read_bytes().startswith(magic)
    plt.close(fig)
