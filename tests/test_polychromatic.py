"""Polychromatic FFT MTF and PSF (issue 36): several wavelengths' OTFs and PSFs, each sampled at its own
lambda N scale, added by power on one frequency axis and one pixel grid; checked on an ideal (paraxial)
lens against the closed forms of the diffraction limit and the Airy pattern."""

from __future__ import annotations

import json

import numpy as np
import pytest

from realistic.camera.psf import polychromatic_point_spread
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.errors import UserError
from realistic.optics.diffraction import diffraction_limited_mtf
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.mtf import lens_mtf
from test_huygens import airy_pixels
from test_paraxial_surface import single

F_MM, SEMI_MM = 50.0, 10.0  # f/2.5
WAVELENGTHS = [486.1327, 587.5618, 656.2725]
WEIGHTS = [1.0, 2.0, 0.5]
IDEAL = single(F_MM, SEMI_MM)  # an ideal lens at f/2.5


def test_polychromatic_mtf_of_an_ideal_lens_is_the_weighted_sum_of_the_monochromatic_ones() -> None:
    lens = parse_zmx(IDEAL)
    f_number = F_MM / (2 * SEMI_MM)
    top = 0.9 / (WAVELENGTHS[0] * 1e-6 * f_number)  # below the bluest cut-off
    poly = lens_mtf(lens, [0.0, 12.0], WAVELENGTHS, top, samples_across=96, frequency_count=13, weights=WEIGHTS)
    mono = [lens_mtf(lens, [0.0, 12.0], [w], top, samples_across=96, frequency_count=13) for w in WAVELENGTHS]
    share = np.array(WEIGHTS) / sum(WEIGHTS)
    nu = poly.frequencies_lp_mm
    analytic = sum(s * diffraction_limited_mtf(nu * w * 1e-6 * f_number) for s, w in zip(share, WAVELENGTHS))
    np.testing.assert_allclose(poly.diffraction_limit, analytic, atol=1e-12)
    for k in range(2):
        for curve in ("sagittal", "tangential"):
            summed = sum(s * getattr(m, curve)[k] for s, m in zip(share, mono))
            np.testing.assert_allclose(getattr(poly, curve)[k], summed, atol=1e-9)
    # on the axis, the diffraction limit itself (off it the oblique beam's pupil is foreshortened); the
    # ideal lens maps pupil height to the direction's tangent, not its sine, so at f/2.5 it falls 1 % short
    for curve in (poly.sagittal[0], poly.tangential[0]):
        np.testing.assert_allclose(curve, analytic, atol=0.015)


def test_polychromatic_psf_of_an_ideal_lens_is_the_weighted_airy_patterns() -> None:
    # at f/8, where the Airy pattern's paraxial form holds (at f/2.5 the ideal lens's peak is 2 % lower)
    n = 8.0
    lens = parse_zmx(single(F_MM, F_MM / (2 * n)))
    pixel, size = 0.0006, 48  # 0.6 um: the first dark rings, 1.22 lambda N = 4.7 .. 6.4 um, span pixels
    spread = polychromatic_point_spread(lens, 1e7, 0.0, None, pixel, size, WAVELENGTHS, WEIGHTS, 64)
    share = np.array(WEIGHTS) / sum(WEIGHTS)

    def airy(wavelength_nm: float) -> np.ndarray:
        return airy_pixels(wavelength_nm, n, pixel, size)

    expected = sum(s * airy(w) for s, w in zip(share, WAVELENGTHS))
    assert np.max(np.abs(spread.image - expected)) < 0.002 * expected.max()
    wrong_scale = sum(s * airy(587.5618) for s in share)  # every part at the d line's scale
    assert np.max(np.abs(wrong_scale - expected)) > 0.05 * expected.max()
    assert spread.weights == pytest.approx(tuple(share))


def test_weights_are_one_per_wavelength_and_go_with_the_fft_model(tmp_path, capsys) -> None:
    lens = parse_zmx(IDEAL)
    with pytest.raises(UserError, match="2 weights given for 3 wavelengths"):
        lens_mtf(lens, [0.0], WAVELENGTHS, 50.0, weights=[1.0, 2.0])
    with pytest.raises(UserError, match="must be finite, not negative"):
        lens_mtf(lens, [0.0], WAVELENGTHS, 50.0, weights=[1.0, -2.0, 1.0])
    with pytest.raises(UserError, match="weights apply to the FFT model"):
        lens_mtf(lens, [0.0], WAVELENGTHS, 50.0, model="geometric", weights=[1.0, 2.0, 1.0])
    path = tmp_path / "ideal.zmx"
    path.write_text(IDEAL)
    assert main(["lens", "psf", str(path), "--depth", "1000", "--wavelengths", "F,d", "--weights", "1,x",
                 "--out", str(tmp_path / "a.exr")]) == 2
    assert "weight 'x' is not a number" in capsys.readouterr().err


def test_cli_psf_and_mtf_take_wavelengths_and_weights(tmp_path, capsys) -> None:
    path = tmp_path / "ideal.zmx"
    path.write_text(IDEAL)
    out = tmp_path / "poly.exr"
    assert main(["lens", "psf", str(path), "--depth", "10000", "--wavelengths", "F,d,C", "--weights", "1,2,0.5",
                 "--pixel-um", "0.5", "--size", "16", "--out", str(out)]) == 0
    image, header = read_exr(out)
    assert header["weights"] == "0.285714,0.571429,0.142857"
    assert image.sum() * 0.0005 ** 2 / 3 == pytest.approx(float(header["enclosed"]), rel=1e-5)
    record = tmp_path / "mtf.json"
    assert main(["lens", "mtf", str(path), "--field", "0", "--wavelengths", "F,d,C", "--weights", "1,2,0.5",
                 "--samples", "64", "--json", str(record), "--out", str(tmp_path / "mtf.png")]) == 0
    report = json.loads(record.read_text())
    assert report["fields"][0]["sagittal"][0] == pytest.approx(1.0)
    capsys.readouterr()
