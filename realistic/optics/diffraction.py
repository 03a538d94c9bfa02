"""Diffraction of the pupil function: FFT PSF, OTF and MTF, and the diffraction-limited MTF.

The pupil function P = A exp(2 pi i W) is sampled on an n x n grid of cell size dh (mm on the
entrance-pupil plane) and zero-padded to M x M. In the Fraunhofer approximation the amplitude
at a film point u (mm from the reference point) is the Fourier transform of P at u / (lambda L),
where L is the length that turns pupil heights into image-space direction sines (sin theta' =
h / L: the focal length for an object at infinity, by the sine condition; ``Wavefront.scale_mm``
measures it from the real rays, along x and y apart, since off the axis they differ). So the FFT
samples the PSF at spacing

    du = lambda L / (M dh)   ( = lambda N_w n / M with N_w = L / D the working f-number and D = n dh ),

and the OTF (the autocorrelation of P, computed as the inverse FFT of |FFT(P)|^2 with M >= 2n so
nothing wraps) at shifts of k cells, i.e. at spatial frequency nu_k = k dh / (lambda L) cycles per
mm. A full pupil diameter of shift is the incoherent cut-off f_c = D / (lambda L) = 1 / (lambda N_w),
where a circular pupil's diffraction-limited MTF, 2/pi (acos v - v sqrt(1 - v^2)) with v = nu / f_c,
reaches 0.
"""

from __future__ import annotations

import numpy as np

from realistic.errors import UserError


def pupil_function(opd_waves: np.ndarray) -> np.ndarray:
    """exp(2 pi i W) where the OPD is finite (a ray passed), 0 elsewhere."""
    passed = np.isfinite(opd_waves)
    return np.where(passed, np.exp(2j * np.pi * np.where(passed, opd_waves, 0.0)), 0.0)


def _padded(pupil: np.ndarray, size: int) -> np.ndarray:
    n = pupil.shape[0]
    if pupil.ndim != 2 or pupil.shape[1] != n:
        raise UserError(f"a pupil function must be a square array, got shape {pupil.shape}")
    if size < n:
        raise UserError(f"FFT size {size} is smaller than the pupil grid ({n})")
    out = np.zeros((size, size), dtype=np.complex128)
    out[:n, :n] = pupil
    return out


def fft_psf(pupil: np.ndarray, size: int) -> np.ndarray:
    """(size, size) PSF |FFT(P)|^2 summing to 1, the reference point at index (size // 2, size // 2);
    rows run along the pupil's first axis."""
    field = np.fft.fft2(_padded(pupil, size))
    psf = np.fft.fftshift(np.abs(field) ** 2)
    total = psf.sum()
    if total <= 0:
        raise UserError("the pupil function is zero everywhere: no light passes")
    return psf / total


def fft_otf(pupil: np.ndarray) -> np.ndarray:
    """(2n, 2n) OTF normalised to 1 at zero frequency, unshifted: entry [i, j] is the shift of i cells
    along the first axis and j along the second (negative shifts wrap to the end)."""
    n = pupil.shape[0]
    field = np.fft.fft2(_padded(pupil, 2 * n))
    otf = np.fft.ifft2(np.abs(field) ** 2)
    if otf[0, 0].real <= 0:
        raise UserError("the pupil function is zero everywhere: no light passes")
    return otf / otf[0, 0].real


#: Sub-sample offsets (in samples of a 2x padded FFT) where ``strehl_ratio`` refines the PSF's peak.
_PEAK_OFFSETS = np.linspace(-1.0, 1.0, 17)


def strehl_ratio(pupil: np.ndarray) -> float:
    """Peak of the PSF relative to the peak of the same pupil without aberration, (sum |P|)^2.

    The peak is found on a 2x padded FFT and refined by the pupil's exact Fourier transform on a
    17 x 17 grid within one sample of it (a padded FFT can miss the peak by half a sample). For a
    small aberration about the reference point it is |sum P|^2 / (sum |P|)^2, the PSF there.
    """
    amplitude = np.abs(pupil).sum()
    if amplitude <= 0:
        raise UserError("the pupil function is zero everywhere: no light passes")
    n = pupil.shape[0]
    coarse = np.abs(np.fft.fft2(_padded(pupil, 2 * n))) ** 2
    row, column = np.unravel_index(int(np.argmax(coarse)), coarse.shape)
    cells = np.arange(n)

    def kernel(index: int) -> np.ndarray:
        """exp(-2 pi i f k) at frequencies (cycles per cell) around the FFT's ``index``."""
        return np.exp(-2j * np.pi * np.outer((index + _PEAK_OFFSETS) / (2 * n), cells))

    fine = np.abs(kernel(int(row)) @ pupil @ kernel(int(column)).T) ** 2
    peak = max(float(fine.max()), float(coarse.max()), abs(pupil.sum()) ** 2)
    return peak / float(amplitude) ** 2


def diffraction_limited_mtf(v: np.ndarray) -> np.ndarray:
    """Incoherent MTF of an aberration-free circular pupil at v = nu / f_c (0 beyond the cut-off)."""
    v = np.clip(np.abs(np.asarray(v, dtype=np.float64)), 0.0, 1.0)
    return 2 / np.pi * (np.arccos(v) - v * np.sqrt(1 - v * v))


def otf_along(otf: np.ndarray, axis: int, shifts: np.ndarray) -> np.ndarray:
    """The OTF at fractional cell shifts along ``axis`` (0: the first), linearly interpolated in its
    real and imaginary parts; 0 beyond the largest shift the grid holds."""
    size = otf.shape[0]
    line = otf[: size // 2 + 1, 0] if axis == 0 else otf[0, : size // 2 + 1]
    k = np.arange(len(line))
    shifts = np.abs(shifts)
    inside = shifts <= k[-1]
    value = np.interp(shifts, k, line.real) + 1j * np.interp(shifts, k, line.imag)
    return np.where(inside, value, 0.0)


def box_integrate(psf: np.ndarray, spacing: tuple[float, float], centre_index: float, edges: np.ndarray
                  ) -> np.ndarray:
    """Integrals of a sampled PSF (each sample the value over its cell, ``spacing`` (rows, columns)
    apart) over the pixels bounded by ``edges`` (same units as ``spacing``, measured from the sample
    at ``centre_index``) along both axes: a summed-area table read at fractional positions."""
    size = psf.shape[0]
    table = np.zeros((size + 1, size + 1))
    table[1:, 1:] = psf.cumsum(axis=0).cumsum(axis=1)
    rows_at = np.clip(edges / spacing[0] + centre_index + 0.5, 0.0, size)  # in table coordinates
    columns_at = np.clip(edges / spacing[1] + centre_index + 0.5, 0.0, size)
    cells = np.arange(size + 1, dtype=np.float64)
    # Bilinear reading of the piecewise-linear integral along rows, then along columns.
    rows = np.array([np.interp(rows_at, cells, table[:, j]) for j in range(size + 1)]).T
    full = np.array([np.interp(columns_at, cells, rows[i]) for i in range(len(rows_at))])
    return full[1:, 1:] - full[:-1, 1:] - full[1:, :-1] + full[:-1, :-1]


#: Film points summed at once by ``huygens_psf`` (bounds its (points x pupil cells) phase array).
_HUYGENS_CHUNK = 2048


def _cell_areas(sphere_mm: np.ndarray) -> np.ndarray:
    """(n, n) area on the reference sphere of each grid cell (|dq/di x dq/dj| by central differences;
    a cell without passing neighbours on both sides of an axis takes the median of the others)."""
    di, dj = np.gradient(sphere_mm, axis=(0, 1))
    area = np.linalg.norm(np.cross(di, dj), axis=-1)
    known = np.isfinite(area)
    fill = float(np.median(area[known])) if known.any() else 0.0
    return np.where(known, area, fill)


def huygens_psf(opd_waves: np.ndarray, sphere_mm: np.ndarray, wavelength_nm: float,
                points_mm: np.ndarray) -> np.ndarray:
    """Irradiance per unit power (1/mm^2) at film points ``points_mm`` ((m, 2), from the reference point)
    by the Huygens-Fresnel sum over the reference sphere (``Wavefront.sphere_mm``, points from the
    reference point; the film is its z = 0 plane).

    Each passing cell of the entrance-pupil grid carries the same power 1/N; on the sphere it covers
    the area dA_j (``_cell_areas``), so its amplitude is a_j = (N dA_j)^(-1/2) and its phase the OPD's.
    The film field is U(x) = 1/(i lambda) sum_j a_j e^(2 pi i W_j) e^(i k (r_j - R_j)) cos_j dA_j / r_j,
    r_j = |x - q_j|, R_j = |q_j|, cos_j the obliquity between the sphere's inward normal and x - q_j
    (Rayleigh-Sommerfeld), and the irradiance |U|^2. No Fraunhofer approximation and no FFT grid: the
    PSF is exact for the sampled sphere at any film point, so a beam meeting the film obliquely keeps
    its shape, at a cost of one exponential per point and cell.
    """
    passed = np.isfinite(opd_waves)
    if not passed.any():
        raise UserError("the pupil function is zero everywhere: no light passes")
    q = sphere_mm[passed]
    area = _cell_areas(sphere_mm)[passed]
    weight = np.sqrt(area / passed.sum()) * np.exp(2j * np.pi * opd_waves[passed])  # a_j dA_j e^(2 pi i W_j)
    lam = wavelength_nm * 1e-6
    k = 2 * np.pi / lam
    radius = np.linalg.norm(q, axis=1)
    inward = -q / radius[:, None]
    points = np.column_stack([points_mm, np.zeros(len(points_mm))])
    irradiance = np.empty(len(points))
    for start in range(0, len(points), _HUYGENS_CHUNK):
        v = points[start:start + _HUYGENS_CHUNK, None, :] - q[None, :, :]  # (m, k, 3) sphere to film
        r = np.linalg.norm(v, axis=-1)
        cosine = np.sum(v * inward[None], axis=-1) / r
        field = (np.exp(1j * k * (r - radius[None])) * cosine / r) @ weight / (1j * lam)
        irradiance[start:start + _HUYGENS_CHUNK] = np.abs(field) ** 2
    return irradiance
