"""FFT PSF and OTF of sampled pupils against closed forms: the Airy pattern's first zero, the
incoherent diffraction-limited MTF, and Hopkins' (1955) defocus OTF."""

from __future__ import annotations

import numpy as np
import pytest

from realistic.errors import UserError
from realistic.optics.diffraction import (
    box_integrate,
    diffraction_limited_mtf,
    fft_otf,
    fft_psf,
    otf_along,
    pupil_function,
    strehl_ratio,
)

#: First zero of J1(x) over pi: the Airy pattern's first dark ring, in lambda N.
AIRY_ZERO = 3.8317059702075125 / np.pi


def disk_pupil(n: int, w20_waves: float = 0.0) -> np.ndarray:
    """OPD (waves) W20 rho^2 over a disk n cells across, NaN outside (the wavefront's convention)."""
    c = (np.arange(n) - (n - 1) / 2) / (n / 2)
    x, y = np.meshgrid(c, c, indexing="xy")
    rho2 = x * x + y * y
    return np.where(rho2 <= 1.0, w20_waves * rho2, np.nan)


def hopkins_defocus_otf(v: float, w20_waves: float) -> float:
    """Defocus OTF of a circular pupil at v = nu / f_c: (4/pi) int_0^{1-v} sqrt(1 - (x+v)^2)
    cos(8 pi W20 v x) dx (the overlap of the pupil and its copy shifted by 2v radii, where the
    phase difference is 2 pi W20 (|r + v|^2 - |r - v|^2) = 8 pi W20 v x), with x + v = cos(phi)."""
    top = np.arccos(v)
    nodes, weights = np.polynomial.legendre.leggauss(200)
    phi = 0.5 * top * (nodes + 1)
    integrand = np.sin(phi) ** 2 * np.cos(8 * np.pi * w20_waves * v * (np.cos(phi) - v))
    return float(4 / np.pi * 0.5 * top * np.sum(weights * integrand))


def first_zero(row: np.ndarray, start: int) -> float:
    """Fractional index of the first zero of the amplitude whose intensity ``row`` holds, past ``start``:
    the signed amplitude (sqrt, negative past the minimum) fitted by a cubic."""
    k = start + int(np.argmin(row[start:start + start // 2 + 1]))
    j = k - 1 if row[k - 1] < row[k + 1] else k
    index = np.arange(j - 2, j + 4)
    amplitude = np.sqrt(row[index]) * np.where(index <= j, 1.0, -1.0)
    roots = np.roots(np.polyfit(index - j, amplitude, 3))
    real = roots[np.isreal(roots)].real
    return float(j + real[(real >= -0.5) & (real <= 1.5)][0])


@pytest.mark.parametrize(("n", "size"), [(128, 1024), (64, 1024), (256, 2048)])
def test_airy_first_zero_at_1_22_lambda_n(n: int, size: int) -> None:
    # Sample spacing is lambda N n / size, so the first dark ring lies 1.22 size / n samples out.
    psf = fft_psf(pupil_function(disk_pupil(n)), size)
    centre = size // 2
    assert np.unravel_index(np.argmax(psf), psf.shape) == (centre, centre)
    expected = AIRY_ZERO * size / n
    for row in (psf[centre, centre:], psf[centre:, centre]):
        assert first_zero(row, int(0.8 * expected)) == pytest.approx(expected, abs=0.1)
    assert psf.sum() == pytest.approx(1.0)


def test_unaberrated_mtf_is_the_diffraction_limit() -> None:
    n = 256
    otf = fft_otf(pupil_function(disk_pupil(n)))
    v = np.linspace(0.0, 1.2, 61)
    for axis in (0, 1):
        values = otf_along(otf, axis, v * n)  # a shift of n cells (one diameter) is the cut-off
        assert np.abs(values.imag).max() < 1e-9
        assert np.abs(values.real - diffraction_limited_mtf(v)).max() < 1e-3


def test_diffraction_limited_mtf_closed_form() -> None:
    assert diffraction_limited_mtf(np.array([0.0, 0.5, 1.0, 2.0])) == pytest.approx(
        [1.0, 2 / np.pi * (np.pi / 3 - 0.5 * np.sqrt(0.75)), 0.0, 0.0])


@pytest.mark.parametrize("w20", [0.25, 0.5, 1.0])
def test_defocus_otf_matches_hopkins(w20: float) -> None:
    n = 256
    otf = fft_otf(pupil_function(disk_pupil(n, w20)))
    for v in (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9):
        expected = hopkins_defocus_otf(v, w20)
        for axis in (0, 1):
            value = otf_along(otf, axis, np.array([v * n]))[0]
            assert value.real == pytest.approx(expected, abs=2e-3), (v, axis)
            assert abs(value.imag) < 1e-9


def test_hopkins_reference_is_the_diffraction_limit_without_defocus() -> None:
    for v in (0.1, 0.4, 0.8):
        assert hopkins_defocus_otf(v, 0.0) == pytest.approx(float(diffraction_limited_mtf(np.array(v))), abs=1e-12)


def test_strehl_of_defocus_closed_form() -> None:
    # |mean exp(2 pi i W20 rho^2)|^2 over the disk = sinc^2(pi W20) (uniform in rho^2).
    w20 = 0.3
    assert strehl_ratio(pupil_function(disk_pupil(512, w20))) == pytest.approx(np.sinc(w20) ** 2, abs=1e-3)


def test_box_integration_keeps_the_energy_and_moves_with_the_edges() -> None:
    psf = np.zeros((8, 8))
    psf[4, 4] = 1.0  # one cell of side 1 centred on the reference point
    edges = np.array([-1.0, -0.25, 0.25, 1.0])
    pixels = box_integrate(psf, (1.0, 1.0), 4, edges)
    assert pixels.sum() == pytest.approx(1.0)
    assert pixels[1, 1] == pytest.approx(0.25)  # the middle half of the cell in each axis
    assert pixels[0, 1] == pytest.approx(0.125)


def test_empty_pupil_is_refused() -> None:
    with pytest.raises(UserError):
        fft_psf(np.zeros((4, 4), dtype=np.complex128), 8)


def test_strehl_is_the_peak_wherever_a_tilt_moves_it() -> None:
    # A pure tilt only moves the Airy pattern: its peak (the Strehl ratio) stays 1, though the PSF at
    # the reference point falls to (2 J1(x) / x)^2.
    n = 128
    c = (np.arange(n) - (n - 1) / 2) / (n / 2)
    x, _ = np.meshgrid(c, c, indexing="xy")
    tilted = np.where(np.isfinite(disk_pupil(n)), 0.37 * x, np.nan)  # 0.37 waves at the rim
    assert strehl_ratio(pupil_function(tilted)) == pytest.approx(1.0, abs=1e-3)
