"""Inputs that hang or bomb (issue 32): a FIFO or directory where a file is expected says what it is
(it blocked, or was "not found"); an image header claiming 100000 x 100000 pixels and a gzip scene
that inflates without end are refused in one line; lens-side messages say what is wrong."""

import gzip
import os
import struct
import warnings
import zlib
from pathlib import Path

import pytest

from realistic.cli import main
from realistic.core.image_files import MAX_INPUT_PIXELS, read_image
from realistic.core.input_files import input_file
from realistic.errors import UserError
from realistic.scene.pbrt import lexer


def _png_header_only(path: Path, width: int, height: int) -> None:
    """A PNG whose header claims ``width`` x ``height`` pixels and whose data holds almost nothing."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(b"\0" * 100))
                     + chunk(b"IEND", b""))


@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_an_image_claiming_100000_squared_pixels_is_one_line(tmp_path, suffix):
    """Pillow's DecompressionBombError was a traceback."""
    path = tmp_path / f"bomb{suffix}"
    _png_header_only(path, 100_000, 100_000)
    with pytest.raises(UserError, match=f"claims more pixels than {MAX_INPUT_PIXELS:,}") as err:
        read_image(path)
    assert "\n" not in str(err.value)


def test_a_gzip_scene_that_inflates_past_the_cap_is_refused(tmp_path, monkeypatch):
    """An included 4.3 MB .pbrt.gz inflated to 2 GiB in memory; reading now stops at the cap."""
    monkeypatch.setattr(lexer, "MAX_GZIP_TEXT_BYTES", 1 << 20)
    bomb = tmp_path / "bomb.pbrt.gz"
    bomb.write_bytes(gzip.compress(b"#" * (3 << 20)))
    with pytest.raises(UserError, match="decompresses to more than"):
        lexer.read_scene_text(bomb)
    fine = tmp_path / "fine.pbrt.gz"
    fine.write_bytes(gzip.compress(b"WorldBegin\n"))
    assert lexer.read_scene_text(fine) == "WorldBegin\n"


@pytest.mark.parametrize("kind,words", [("fifo", "is a named pipe (FIFO)"), ("directory", "is a directory"),
                                        ("missing", "no such")])
def test_every_kind_of_path_is_named(tmp_path, kind, words):
    path = tmp_path / "x.pbrt"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    with pytest.raises(UserError) as err:
        input_file(path, "scene file")
    assert str(err.value).startswith(f"{path}: {words}")


@pytest.mark.parametrize("option", [None, "--aperture-mask"])
def test_render_names_a_fifo_scene_or_mask(tmp_path, capsys, option):
    """A FIFO scene named .pbrt was "no such scene file"; a FIFO mask would block."""
    fifo = tmp_path / "scene.pbrt"
    os.mkfifo(fifo)
    args = ["render", str(fifo)] if option is None else ["render", "--aperture-mask", str(fifo)]
    assert main(args + ["--res", "8x8", "--spp", "1", "--out", str(tmp_path / "o.exr")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a named pipe (FIFO)" in err


def test_codev_and_rays_say_what_is_missing(tmp_path, capsys):
    """"CIR None is not a finite number" and "got None" named Python's None, not the file's text."""
    seq = tmp_path / "c.seq"
    seq.write_text("RDM\nSO 0 1e20\nS 10 2 1.5\nCIR\n")
    assert main(["lens", "info", str(seq)]) == 2
    assert f"{seq}:4: CIR has no value" in capsys.readouterr().err
    rays = tmp_path / "r.json"
    rays.write_text('{"rays": [{"origin": [0, 0, 0], "direction": null}]}')
    assert main(["lens", "trace", "dgauss", "--film-distance", "36", "--input", str(rays)]) == 2
    assert "rays[0].direction must be a list of 3 finite numbers, got null" in capsys.readouterr().err


def test_lens_film_distance_is_bounded(capsys):
    """``--film-distance 1e300`` traced with overflow warnings and printed a 300-digit distance."""
    assert main(["lens", "info", "dgauss", "--film-distance", "1e300"]) == 2
    assert "film distance (mm) must be at most 1e+06" in capsys.readouterr().err


@pytest.mark.parametrize("args,words", [
    (["lens", "info", "dgauss", "--wavelength", "1e-300"], "wavelength (nm) must be at least 200"),
    (["lens", "info", "dgauss", "--wavelength", "1e300"], "wavelength (nm) must be at most 2000"),
    (["lens", "curves", "dgauss", "--aperture", "1e-9"], "aperture diameter must be at least 0.001 mm"),
])
def test_lens_commands_refuse_before_numpy_warns_or_divides(tmp_path, capsys, args, words):
    """``--wavelength 1e-300`` printed numpy RuntimeWarnings (division by zero) before its result; a
    stop too small for any traced ray to pass made ``lens curves`` a ZeroDivisionError traceback."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(args + (["--out", str(tmp_path / "c.png")] if args[1] == "curves" else [])) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err
