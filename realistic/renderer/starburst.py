"""The diffraction starburst of the aperture blades: the stop's Fraunhofer PSF convolved with the
image's brightest sources (``--starburst on``, issue 37).

The renderer's rays obey geometric optics; the spikes a photograph shows around a bright light are
diffraction at the edges of the stop. Each straight blade edge diffracts light perpendicular to
itself, so an even number N of blades (edges in parallel pairs) gives N spikes and an odd N gives 2N.

**The PSF.** The opening (the lens's ``StopShape``, or a circle) is sampled on a pupil grid in units
of the stop's diameter, as the paraxial exit pupil images it (its shape scaled, its orientation
kept), and ``optics.diffraction.fft_psf`` gives |FFT(P)|^2. A pupil frequency nu (cycles per pupil
diameter) lands at x = lambda N_w nu on the film, with N_w the working f-number: the exit pupil's
distance to the film over its diameter (``optics.paraxial``), so the FFT's film spacing is
lambda N_w / (M du) for an M-point FFT of cell du. That spacing is set to the pixel pitch over an
odd m >= 2 p / (lambda N_w) (the intensity, band-limited to 1 / (lambda N_w), sampled at Nyquist or
finer), and the m x m fine samples are summed into each pixel: the PSF integrated over pixels, for
an odd K x K kernel (M = m K up to ``FFT_BUDGET``), normalised to sum 1 per channel. Wavelengths:
``WAVELENGTHS_NM`` for R, G, B (near the peaks of the sRGB primaries' spectra). The image's rows run
down the film's +y and its columns along -x (``LensCamera.film_points``): with the PSF's point
symmetry (a real pupil), a pupil grid whose first row is at +y gives the kernel in image order.

**The sources.** Diffraction spreads every pixel's light, but at the pitches of a render the PSF's
core lies within a pixel and its wings carry a small fraction of the light; they show only around
pixels far brighter than what the exposure maps to white. A source is a pixel whose luminance is
above the white of the metered exposure (``camera.exposure``: middle grey 0.18 at the meter's
reading, white at 1 / 0.18 of it), the pixels that clip in the metered PNG. Those pixels are split
off, convolved with the PSF (an FFT convolution) and added back in place of themselves; the rest of
the image is unchanged. A source near the border would send part of its PSF off the image: it is
divided by the fraction of the PSF that lands on the image, so each channel's sum is preserved
(the film's irradiance is moved, not lost). Applied to the finished image (``passes``); the film
and checkpoints keep the raw sums.
"""

from __future__ import annotations

import math

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.exposure import LUMINANCE_WEIGHTS, MIDDLE_GREY, metered_log2
from realistic.camera.lens_camera import LensCamera
from realistic.core.film_geometry import pixel_pitch_mm
from realistic.errors import UserError
from realistic.optics.diffraction import fft_psf
from realistic.optics.paraxial import paraxial_data
from realistic.optics.stop_shape import StopShape

#: R, G, B wavelengths of the PSF (nm).
WAVELENGTHS_NM = (610.0, 550.0, 465.0)
#: Most FFT points along each axis of the PSF's grid (bounds memory and time: M^2 complex values).
FFT_BUDGET = 2048
#: Largest kernel side in pixels.
MAX_KERNEL_PX = 255
#: The one-line error for a starburst without a real lens, from the options and from ``RenderJob``.
STARBURST_NEEDS_LENS = "--starburst on needs a real lens (--lens): a thin-lens or perspective camera has no blades"


def working_f_number(camera: LensCamera, wavelength_nm: float) -> float:
    """The exit pupil's paraxial distance to the film over its diameter."""
    data = paraxial_data(camera.lens, wavelength_nm)
    return (camera.film_distance_mm - data.exit_pupil_mm) / data.exit_pupil_diameter_mm


def _opening(shape: StopShape | None, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Whether points (units of the stop's diameter) are open: ``shape``, or the stop's circle."""
    if shape is None:
        return x * x + y * y <= 0.25
    return shape.inside(x, y, 1.0)


def pupil_grid(shape: StopShape | None, cell: float) -> np.ndarray:
    """The opening (n, n), 1 open and 0 shut at the centres of cells of side ``cell`` (stop
    diameters), centred on the axis, first row at +y. Binary: cells weighted by their open fraction
    made an edge along the grid diffract unlike an oblique one, by a different amount at each
    wavelength (coloured spikes); sampled at cell centres a regular stop's spikes agree within a
    fifth (the FFT's periodic copies of each spike fold back by its direction;
    ``tests/test_starburst.py``)."""
    reach = 0.5 if shape is None else shape.reach_mm(1.0)
    half = math.ceil(reach / cell)
    centres = np.arange(-half, half + 1) * cell
    x, y = np.meshgrid(centres, -centres)
    return _opening(shape, x, y).astype(np.float64)


def kernel_layout(pitch_mm: float, lambda_n_mm: float) -> tuple[int, int]:
    """(m, K): fine samples per pixel side (odd, at least 2 p / (lambda N_w)) and the kernel's side
    in pixels (odd, m K <= ``FFT_BUDGET``; 1 when the PSF is finer than that allows)."""
    m = math.ceil(2 * pitch_mm / lambda_n_mm)
    m += 1 - m % 2
    side = min(MAX_KERNEL_PX, FFT_BUDGET // m)
    return m, max(1, side - 1 + side % 2)


def pixel_psf(shape: StopShape | None, pitch_mm: float, lambda_n_mm: float) -> np.ndarray:
    """The PSF (K, K) of an opening integrated over pixels of side ``pitch_mm`` on a film whose
    lambda N_w is ``lambda_n_mm``, centred on the middle pixel, summing to 1."""
    m, side = kernel_layout(pitch_mm, lambda_n_mm)
    if side == 1:
        return np.ones((1, 1))
    size = m * side
    # film spacing lambda N_w / (size * cell) = pitch / m
    pupil = pupil_grid(shape, lambda_n_mm * m / (pitch_mm * size))
    if pupil.shape[0] > size:
        raise UserError(f"starburst: the pupil grid ({pupil.shape[0]}) exceeds the FFT ({size})")
    fine = fft_psf(pupil, size)  # the reference point at size // 2, the middle of the middle pixel
    binned = fine.reshape(side, m, side, m).sum(axis=(1, 3))
    return binned / binned.sum()


def camera_psfs(camera: LensCamera) -> list[np.ndarray]:
    """The R, G, B pixel PSFs (``WAVELENGTHS_NM``) of ``camera``'s stop on its film."""
    pitch = pixel_pitch_mm(camera.film_diagonal_mm, camera.width, camera.height)
    return [pixel_psf(camera.lens.stop_shape, pitch, wavelength * 1e-6 * working_f_number(camera, wavelength))
            for wavelength in WAVELENGTHS_NM]


def sources(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels above the metered exposure's white (none in a black image)."""
    reading = metered_log2(image)
    if reading is None:
        return np.zeros(image.shape[:2], dtype=bool)
    luminance = np.asarray(image, dtype=np.float64) @ np.asarray(LUMINANCE_WEIGHTS)
    white = 2.0**reading / MIDDLE_GREY
    return np.isfinite(luminance) & (luminance > white)


def convolve_sources(image: np.ndarray, bright: np.ndarray, psfs: list[np.ndarray]) -> np.ndarray:
    """``image`` (H, W, 3) with its ``bright`` pixels replaced by their light spread by each
    channel's PSF, each source divided by the share of its PSF that lands on the image so that
    every channel's sum is kept."""
    from scipy.signal import fftconvolve  # a dependency, imported by renders that ask for a starburst

    height, width = bright.shape
    out = np.where(bright[..., None], 0.0, np.asarray(image, dtype=np.float64))
    window = np.ones((height, width))
    for channel, psf in enumerate(psfs):
        light = np.where(bright, image[..., channel], 0.0).astype(np.float64)
        landed = fftconvolve(window, psf[::-1, ::-1], mode="same")  # share of a pixel's PSF on the image
        light[bright] /= landed[bright]
        out[..., channel] += np.maximum(fftconvolve(light, psf, mode="same"), 0.0)
    return out.astype(image.dtype)


def starburst(image: np.ndarray, camera: Camera) -> np.ndarray:
    """The finished ``image`` of ``camera`` (a ``LensCamera``) with the starburst of its brightest sources."""
    if not isinstance(camera, LensCamera):
        raise UserError(STARBURST_NEEDS_LENS)
    bright = sources(image)
    if not bright.any():
        return image  # the same array: nothing to spread
    return convolve_sources(image, bright, camera_psfs(camera))
