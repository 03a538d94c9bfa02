"""--denoise (issue 33): Open Image Denoise through the optional pyoidn binding, guided by the AOVs."""

import importlib.util

import numpy as np
import pytest

from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.errors import UserError
from realistic.renderer import denoise

FAST = ["--backend", "numpy", "--res", "32x24", "--spp", "2"]
needs_oidn = pytest.mark.skipif(importlib.util.find_spec("pyoidn") is None,
                                reason="pyoidn (the denoise extra) is not installed")


@needs_oidn
def test_a_noisy_flat_image_comes_back_close_to_its_true_value():
    """A constant 0.5 grey with Gaussian noise (sigma 0.1), a flat albedo and one normal: the denoised
    image's error against 0.5 is a fraction of the noise's."""
    rng = np.random.default_rng(3)
    noisy = (0.5 + 0.1 * rng.standard_normal((64, 64, 3))).astype(np.float32)
    albedo = np.full((64, 64, 3), 0.5, np.float32)
    normal = np.broadcast_to(np.array([0, 0, -1], np.float32), (64, 64, 3))
    clean = denoise.denoise_image(noisy, albedo, normal)
    assert clean.shape == noisy.shape and clean.dtype == np.float32
    assert np.sqrt(np.mean((clean - 0.5) ** 2)) < 0.3 * np.sqrt(np.mean((noisy - 0.5) ** 2))


@needs_oidn
def test_cli_denoise_writes_the_denoised_image_and_keeps_the_films_as_a_layer(tmp_path, capsys):
    import OpenEXR

    out = tmp_path / "d.exr"
    assert main(["render", *FAST, "--out", str(out), "--denoise", "--aov", "depth"]) == 0
    capsys.readouterr()
    with OpenEXR.File(str(out), separate_channels=True) as exr:
        channels = {name: channel.pixels for name, channel in exr.channels().items()}
    assert {"Noisy.R", "Noisy.G", "Noisy.B", "Albedo.R", "N.X", "P.Z"} <= set(channels)
    assert "P.X" not in channels
    image = read_exr(out)[0]
    noisy = np.stack([channels[f"Noisy.{c}"] for c in "RGB"], axis=-1)
    assert np.all(np.isfinite(image)) and image.max() > 0 and not np.array_equal(image, noisy)
    # the same render without --denoise writes the film's image: the Noisy layer is it
    plain = tmp_path / "p.exr"
    assert main(["render", *FAST, "--out", str(plain)]) == 0
    np.testing.assert_array_equal(read_exr(plain)[0], noisy)


def test_without_the_binding_denoising_is_refused_in_one_line_naming_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None)
    with pytest.raises(UserError, match=r"pip install 'realistic\[denoise\]'"):
        denoise.check_available()
    status = main(["render", *FAST, "--out", str(tmp_path / "x.exr"), "--denoise"])
    err = capsys.readouterr().err
    assert status != 0 and "realistic[denoise]" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.exr").exists()


def test_cli_aov_names_are_checked_before_rendering(tmp_path, capsys):
    assert main(["render", *FAST, "--out", str(tmp_path / "x.exr"), "--aov", "depth,zdepth"]) != 0
    assert "unknown AOV 'zdepth'" in capsys.readouterr().err and not (tmp_path / "x.exr").exists()
