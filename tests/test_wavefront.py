"""The wavefront from real rays (OPD, Zernike fit) and the FFT PSF and MTF of real lenses, against
closed forms: the Airy ring and diffraction-limited MTF of a nearly perfect slow singlet, the
defocus term of a film shift, and the Marechal estimate of the Strehl ratio."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from realistic.camera.psf import fft_point_spread
from realistic.cli import main
from realistic.core.image_files import read_exr
from realistic.errors import UserError
from realistic.optics.diffraction import fft_psf, pupil_function, strehl_ratio
from realistic.optics.formats import load_lens
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.lens import LensSystem
from realistic.optics.mtf import lens_mtf
from realistic.optics.paraxial import focus_distance_for_film, paraxial_data, stop_diameter_for_f_number
from realistic.optics.spot import best_focus_mm, trace_fields
from realistic.optics.wavefront import Wavefront, noll_indices, wavefront, zernike, zernike_fit

D_NM = 587.5618
#: Plano-convex singlet (f = 100 mm), stopped to f/50: its spherical aberration is ~1e-4 waves.
SINGLET = "0 1 0 4\n51.68 4 1.5168 30\ninf 0 1 30\n"


def slow_singlet() -> LensSystem:
    return parse_prescription(SINGLET).with_stop_diameter(2.0)


def dgauss_f8() -> LensSystem:
    lens = load_lens("dgauss")
    return lens.with_stop_diameter(stop_diameter_for_f_number(lens, 8.0))


def test_noll_numbering() -> None:
    assert [noll_indices(j) for j in range(1, 12)] == [
        (0, 0), (1, 1), (1, -1), (2, 0), (2, -2), (2, 2), (3, -1), (3, 1), (3, -3), (3, 3), (4, 0)]


def test_zernike_terms_are_orthonormal_over_the_disk() -> None:
    n = 1024
    c = (np.arange(n) - (n - 1) / 2) / (n / 2)
    x, y = np.meshgrid(c, c)
    inside = x * x + y * y <= 1
    rho, theta = np.hypot(x[inside], y[inside]), np.arctan2(y[inside], x[inside])
    basis = np.array([zernike(j, rho, theta) for j in range(1, 23)])
    gram = basis @ basis.T / inside.sum()
    np.testing.assert_allclose(gram, np.eye(22), atol=5e-3)


def test_fit_recovers_a_wavefront_built_from_zernike_terms() -> None:
    n = 96
    c = (np.arange(n) - (n - 1) / 2) * 0.1
    x, y = np.meshgrid(c, c)
    radius = 4.8
    inside = x * x + y * y <= radius * radius
    rho, theta = np.hypot(x, y) / radius, np.arctan2(y, x)
    truth = np.zeros(22)
    truth[[3, 5, 6, 10, 21]] = [0.3, -0.2, 0.15, 0.05, -0.02]
    opd = sum(truth[j - 1] * zernike(j, rho, theta) for j in range(1, 23))
    front = Wavefront(np.where(inside, opd, np.nan), 0.1, D_NM, 0.0, 1.0, (0.0, 0.0), (100.0, 100.0),
                      np.stack([x, y], axis=-1))
    assert zernike_fit(front) == pytest.approx(truth, abs=2e-3)  # the grid's rim is not exactly the circle


def test_a_nearly_perfect_lens_has_the_airy_ring_at_1_22_lambda_n() -> None:
    lens = slow_singlet()
    para = paraxial_data(lens)
    front = wavefront(lens, 0.0, D_NM, para.bfl_mm, 128)
    assert front.rms_waves < 1e-3
    assert front.scale_mm == pytest.approx((para.efl_mm, para.efl_mm), rel=1e-3)  # the sine condition
    size = 2048
    psf = fft_psf(pupil_function(front.opd_waves), size)
    spacing = D_NM * 1e-6 * front.scale_mm[0] / (size * front.spacing_mm)
    ring = 3.8317059702075125 / np.pi * D_NM * 1e-6 * para.f_number  # mm
    row = psf[size // 2, size // 2:]
    start, stop = int(0.8 * ring / spacing), int(1.2 * ring / spacing)
    found = (start + int(np.argmin(row[start:stop]))) * spacing
    assert found == pytest.approx(ring, abs=spacing)


def test_fft_mtf_of_a_nearly_perfect_lens_is_the_diffraction_limit() -> None:
    lens = slow_singlet()
    cutoff = 1 / (D_NM * 1e-6 * paraxial_data(lens).f_number)
    report = lens_mtf(lens, [0.0], [D_NM], 0.99 * cutoff, samples_across=256, frequency_count=21)
    assert report.model == "fft" and report.diffraction_limit is not None
    for curve in (report.sagittal[0], report.tangential[0]):
        assert np.abs(curve - report.diffraction_limit).max() < 1e-3


def test_a_film_shift_adds_the_defocus_of_its_sag() -> None:
    # Moving the film by s adds W20 = -s / (8 N^2) (waves: / lambda) to the OPD; Noll's Z4 is
    # sqrt(3) (2 rho^2 - 1), so its coefficient changes by W20 / (2 sqrt(3)).
    lens, shift = dgauss_f8(), 0.05
    para = paraxial_data(lens)
    near = wavefront(lens, 0.0, D_NM, para.bfl_mm, 64)
    far = wavefront(lens, 0.0, D_NM, para.bfl_mm + shift, 64)
    n_working = near.scale_mm[0] / para.entrance_pupil_diameter_mm
    expected = -shift / (8 * n_working**2) / (D_NM * 1e-6) / (2 * math.sqrt(3))
    assert zernike_fit(far)[3] - zernike_fit(near)[3] == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("best", [False, True])
def test_dgauss_at_f8_is_near_perfect_and_obeys_marechal(best: bool) -> None:
    lens = dgauss_f8()
    film = best_focus_mm(trace_fields(lens, [0.0], [D_NM], 64)) if best else paraxial_data(lens).bfl_mm
    front = wavefront(lens, 0.0, D_NM, film, 64)
    coefficients = zernike_fit(front)
    assert front.rms_waves < 0.02
    assert math.sqrt(np.sum(coefficients[1:] ** 2)) == pytest.approx(front.rms_waves, rel=0.05)
    marechal = math.exp(-(2 * math.pi * front.rms_waves) ** 2)
    assert strehl_ratio(pupil_function(front.opd_waves)) == pytest.approx(marechal, abs=1e-3)


def test_the_fft_psf_window_holds_the_light_and_lies_on_the_spot() -> None:
    lens = dgauss_f8()
    psf = fft_point_spread(lens, 3000.0, 10.0, pixel_mm=0.001, size=64)
    assert psf.enclosed == pytest.approx(1.0, abs=0.05)
    assert max(psf.fft_spacing_mm) <= 0.001 / 4
    yy = np.arange(64) - 31.5
    image = psf.image / psf.image.sum()
    assert abs(float(np.sum(image.sum(axis=1) * yy))) < 0.5  # centroid within half a pixel of the centre
    assert abs(float(np.sum(image.sum(axis=0) * yy))) < 0.5


def test_a_tilted_reference_moves_the_psf_the_other_way() -> None:
    lens = dgauss_f8()
    para = paraxial_data(lens)
    shift = 0.01
    front = wavefront(lens, 0.0, D_NM, para.bfl_mm, 64, reference_mm=(0.0, shift))
    size = 1024
    psf = fft_psf(pupil_function(front.opd_waves), size)
    spacing = D_NM * 1e-6 * front.scale_mm[1] / (size * front.spacing_mm)
    row, column = np.unravel_index(np.argmax(psf), psf.shape)
    assert (row - size // 2) * spacing == pytest.approx(-shift, abs=spacing)  # rows along +y
    assert column == size // 2


def test_lens_mtf_cli_draws_the_fft_mtf_with_its_diffraction_limit(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    report = tmp_path / "mtf.json"
    assert main(["lens", "mtf", "dgauss", "--field", "0,15", "--samples", "64", "--json", str(report),
                 "--out", str(tmp_path / "mtf.png")]) == 0
    data = json.loads(report.read_text())
    assert data["model"] == "fft" and len(data["fields"]) == 2
    f_number = paraxial_data(load_lens("dgauss")).f_number
    nu = np.array(data["frequencies_lp_mm"])
    limit = np.mean([2 / np.pi * (np.arccos(v) - v * np.sqrt(1 - v * v))
                     for v in (nu * w * 1e-6 * f_number for w in (486.1327, 587.5618, 656.2725))], axis=0)
    np.testing.assert_allclose(data["diffraction_limit"], limit, atol=1e-9)
    for field in data["fields"]:
        assert np.all(np.array(field["tangential"]) <= np.array(data["diffraction_limit"]) + 1e-3)
    assert "diff. lim" in capsys.readouterr().out
    assert (tmp_path / "mtf.png").stat().st_size > 0


def test_lens_wavefront_and_fft_psf_commands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    report = tmp_path / "w.json"
    assert main(["lens", "wavefront", "dgauss", "--field", "10", "--wavelength", "550", "--samples", "32",
                 "--json", str(report)]) == 0
    data = json.loads(report.read_text())
    assert data["wavelength_nm"] == 550 and len(data["zernike_waves"]) == 22
    assert "spherical" in capsys.readouterr().out
    out = tmp_path / "psf.exr"
    assert main(["lens", "psf", "dgauss", "--depth", "3", "--size", "16", "--out", str(out)]) == 0
    image, header = read_exr(out)
    assert image.shape[:2] == (16, 16) and float(header["strehl"]) <= 1.0


@pytest.mark.parametrize("argv", [["lens", "wavefront", "dgauss", "--terms", "0"],
                                  ["lens", "psf", "dgauss", "--depth", "3", "--model", "wave"],
                                  ["lens", "mtf", "dgauss", "--model", "wave"]])
def test_bad_wave_options_are_one_line_errors(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "error" in err


def test_a_psf_needing_a_huge_fft_is_refused() -> None:
    with pytest.raises(UserError, match="FFT"):
        fft_point_spread(dgauss_f8(), 3000.0, pixel_mm=0.00001, size=4)


@pytest.mark.parametrize(("name", "field"), [("dgauss", 15.0), ("fisheye", 60.0)])
def test_fft_mtf_tends_to_the_geometric_mtf_when_the_aberration_is_many_waves(name: str, field: float) -> None:
    # 0.5 mm of defocus is tens of waves: the geometric limit, where diffraction changes little at low
    # frequency. Off the axis the pupil maps to the film with different scales along x and y.
    lens = load_lens(name)
    focus = focus_distance_for_film(lens, paraxial_data(lens).bfl_mm + 0.5)
    fft = lens_mtf(lens, [field], [D_NM], 40.0, focus, samples_across=256, frequency_count=9)
    geometric = lens_mtf(lens, [field], [D_NM], 40.0, focus, samples_across=256, frequency_count=9,
                         model="geometric")
    assert fft.sagittal[0][1] == pytest.approx(geometric.sagittal[0][1], abs=0.03)  # 5 lp/mm
    assert fft.tangential[0][1] == pytest.approx(geometric.tangential[0][1], abs=0.03)


def test_a_wavefront_steeper_than_half_a_wave_per_sample_is_flagged(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    c = np.arange(8, dtype=np.float64)
    x, y = np.meshgrid(c, c)
    grid = np.stack([x, y], axis=-1)

    def front(opd: np.ndarray) -> Wavefront:
        return Wavefront(opd, 1.0, D_NM, 0.0, 1.0, (0.0, 0.0), (100.0, 100.0), grid)

    assert front(0.4 * x).undersampled_fraction == 0.0
    assert front(0.6 * x).undersampled_fraction == pytest.approx(0.5)  # the x steps, not the y ones
    assert main(["lens", "mtf", "dgauss", "--field", "15", "--samples", "16", "--out", str(tmp_path / "m.png")]) == 0
    err = capsys.readouterr().err
    assert "raise --samples" in err and err.count("\n") == 1
