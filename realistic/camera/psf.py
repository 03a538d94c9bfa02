"""The point-spread function on the film: by diffraction of the pupil function (``fft_point_spread``),
or rendered with the camera's own rays (``point_spread``, the geometric model described below).

The FFT model traces the wavefront of the point (``realistic.optics.wavefront``) at each wavelength
(``polychromatic_point_spread`` adds several by their powers) and transforms its pupil function
(``realistic.optics.diffraction``); the window is centred on the centroid of the rays' landings (the
reference sphere's centre), the FFT samples at a quarter pixel or finer are integrated over each
pixel, and the image is irradiance per unit power reaching the
film (1/mm^2: the window's sum times the pixel area is the fraction of the light inside it).

The geometric model:

A point at ``depth_mm`` from the film and ``field_deg`` off the axis (the chief ray's angle seen
from the entrance pupil, toward +y) is modelled as a small sphere of unit radiance. A
``LensCamera`` with square pixels of the requested pitch, focused at the point (or at ``focus_mm``),
makes its rays exactly as for an image; only the pixels of a window around the point's image
are generated, and a ray adds its radiometric weight to its pixel when it hits the sphere. The
window is centred on where the forward-traced rays from the point land
(``realistic.optics.forward_trace``).

The result is film irradiance per unit source radiance, E = (1/spp) sum weight * hit, so its
integral over the window (sum E * pixel area) is the flux the lens passes from the source: for a
source on the axis L * pi r^2 * (projected solid angle of the entrance pupil).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from realistic.camera.base import RayGenerator, SampleBlock, check_backend
from realistic.camera.lens_camera import LensCamera
from realistic.core import validation
from realistic.errors import UserError
from realistic.optics.diffraction import box_integrate, fft_psf, huygens_psf, pupil_function, strehl_ratio
from realistic.optics.forward_trace import trace_object_point
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data
from realistic.optics.wavefront import wavefront

#: Largest FFT side for the diffraction PSF (a complex128 array of this side squared is held).
MAX_FFT_SIZE = 4096
#: FFT samples per pixel side, at least (each pixel integrates them).
FFT_SAMPLES_PER_PIXEL = 4


@dataclass(frozen=True)
class PointSpread:
    """A PSF window: irradiance per unit radiance, (size, size), raster order (row 0 at the top)."""

    image: np.ndarray
    pixel_mm: float
    centre_film_mm: tuple[float, float]  # film x, y of the window's centre
    source_centre_mm: tuple[float, float, float]  # lens frame (film at z = 0)
    source_radius_mm: float
    film_distance_mm: float
    spp: int

    @property
    def flux(self) -> float:
        """Integral of the irradiance over the window (mm^2 per unit radiance)."""
        return float(self.image.sum() * self.pixel_mm**2)


@dataclass(frozen=True)
class DiffractionSpread:
    """An FFT PSF window: irradiance per unit power (1/mm^2), (size, size), rows along +y, columns along -x
    (the layout of ``PointSpread``), centred on ``centre_film_mm``."""

    image: np.ndarray
    pixel_mm: float
    centre_film_mm: tuple[float, float]
    film_distance_mm: float
    wavelength_nm: float
    fft_size: int  # 0 for the Huygens sum (``huygens_point_spread``)
    fft_spacing_mm: tuple[float, float]  # the FFT's samples along film x and y (the Huygens sum's points)
    strehl: float
    opd_rms_waves: float
    undersampled: float  # ``Wavefront.undersampled_fraction``

    @property
    def enclosed(self) -> float:
        """Fraction of the light that reaches the film landing inside the window."""
        return float(self.image.sum() * self.pixel_mm**2)


def _focused(lens: LensSystem, depth_mm: float, focus_mm: float | None) -> tuple[float, float]:
    """The film distance focused at ``focus_mm`` (None: at the point), and the distance of a point
    ``depth_mm`` from the film to the paraxial entrance pupil."""
    film_distance_mm = film_distance_for_focus(lens, focus_mm if focus_mm is not None else depth_mm)
    pupil_z = film_distance_mm + lens.track_length_mm - paraxial_data(lens).entrance_pupil_mm
    front_z = film_distance_mm + lens.track_length_mm
    if depth_mm <= front_z:
        raise UserError(f"depth {depth_mm:g} mm is not in front of the lens (its front vertex is "
                        f"{front_z:.6g} mm from the film)")
    return film_distance_mm, depth_mm - pupil_z


def fft_point_spread(lens: LensSystem, depth_mm: float, field_deg: float = 0.0, focus_mm: float | None = None,
                     pixel_mm: float = 0.002, size: int = 64, wavelength_nm: float = 587.5618,
                     samples_across: int = 64, reference_mm: tuple[float, float] | None = None) -> DiffractionSpread:
    """Diffraction PSF of a point ``depth_mm`` from the film (see the module docstring).

    The pupil is sampled with ``samples_across`` cells across its paraxial diameter, or finer where
    the window needs it (the FFT's field, lambda L / cell, spans at least twice the window), and
    zero-padded until the PSF samples are a quarter pixel or finer. ``reference_mm``: the window's
    centre on the film (default: the centroid of this wavelength's rays).
    """
    validation.positive_length(depth_mm, "depth (mm)")
    validation.positive_length(pixel_mm, "pixel size (mm)")
    if not (isinstance(size, int) and 1 <= size <= 4096):
        raise UserError(f"PSF window size must be 1..4096 pixels, got {size!r}")
    film_distance, distance = _focused(lens, depth_mm, focus_mm)
    first = wavefront(lens, field_deg, wavelength_nm, film_distance, samples_across, distance, reference_mm)
    wave_l = wavelength_nm * 1e-6 * np.array(first.scale_mm)  # lambda L (x, y): FFT field = lambda L / cell
    spacing = min(first.spacing_mm, float(wave_l.min()) / (2 * size * pixel_mm))
    front = wavefront(lens, field_deg, wavelength_nm, film_distance, samples_across, distance,
                      reference_mm=first.reference_mm, spacing_mm=spacing)
    n = front.opd_waves.shape[0]
    fft_size = max(2 * n, math.ceil(FFT_SAMPLES_PER_PIXEL * float(wave_l.max()) / (spacing * pixel_mm)))
    fft_size += fft_size % 2
    if fft_size > MAX_FFT_SIZE:
        raise UserError(f"the diffraction PSF needs a {fft_size}-point FFT (more than {MAX_FFT_SIZE}) for "
                        f"{size} pixels of {pixel_mm * 1000:g} um: use fewer or larger pixels")
    pupil = pupil_function(front.opd_waves)
    psf = fft_psf(pupil, fft_size)
    du = wave_l / (fft_size * spacing)  # along x, y
    edges = (np.arange(size + 1) - size / 2) * pixel_mm
    image = box_integrate(psf, (float(du[1]), float(du[0])), fft_size // 2, edges)[:, ::-1] / pixel_mm**2
    return DiffractionSpread(image, pixel_mm, front.reference_mm, film_distance, wavelength_nm, fft_size,
                             (float(du[0]), float(du[1])),
                             strehl_ratio(pupil), front.rms_waves, front.undersampled_fraction)


#: Film points per pixel side where ``huygens_point_spread`` samples the PSF (each pixel averages them).
HUYGENS_SAMPLES_PER_PIXEL = 3


def huygens_point_spread(lens: LensSystem, depth_mm: float, field_deg: float = 0.0, focus_mm: float | None = None,
                         pixel_mm: float = 0.002, size: int = 64, wavelength_nm: float = 587.5618,
                         samples_across: int = 64) -> DiffractionSpread:
    """The PSF of a point ``depth_mm`` from the film by the Huygens-Fresnel sum over the reference sphere
    (``realistic.optics.diffraction.huygens_psf``), on the window of ``fft_point_spread``: each pixel the
    mean of ``HUYGENS_SAMPLES_PER_PIXEL`` squared points. The result's ``fft_size`` is 0 and its
    ``fft_spacing_mm`` the spacing of those points."""
    validation.positive_length(depth_mm, "depth (mm)")
    validation.positive_length(pixel_mm, "pixel size (mm)")
    if not (isinstance(size, int) and 1 <= size <= 512):
        raise UserError(f"Huygens PSF window size must be 1..512 pixels, got {size!r}")
    film_distance, distance = _focused(lens, depth_mm, focus_mm)
    front = wavefront(lens, field_deg, wavelength_nm, film_distance, samples_across, distance)
    sub = HUYGENS_SAMPLES_PER_PIXEL
    step = pixel_mm / sub
    offsets = (np.arange(size * sub) - (size * sub - 1) / 2) * step
    y, x = np.meshgrid(offsets, -offsets, indexing="ij")  # rows along +y, columns along -x, as the FFT's window
    values = huygens_psf(front.opd_waves, front.sphere_mm, wavelength_nm, np.column_stack([x.ravel(), y.ravel()]))
    image = values.reshape(size, sub, size, sub).mean(axis=(1, 3))
    return DiffractionSpread(image, pixel_mm, front.reference_mm, film_distance, wavelength_nm, 0, (step, step),
                             strehl_ratio(pupil_function(front.opd_waves)), front.rms_waves,
                             front.undersampled_fraction)


@dataclass(frozen=True)
class PolychromaticSpread:
    """Several wavelengths' FFT PSFs (``parts``, one window about one film point) and their sum
    weighted by relative power (``weights``, summing to 1): irradiance per unit power, as each part."""

    image: np.ndarray
    parts: tuple[DiffractionSpread, ...]
    weights: tuple[float, ...]

    @property
    def enclosed(self) -> float:
        """Fraction of the light that reaches the film landing inside the window."""
        return float(self.image.sum() * self.parts[0].pixel_mm ** 2)


def polychromatic_point_spread(lens: LensSystem, depth_mm: float, field_deg: float = 0.0,
                               focus_mm: float | None = None, pixel_mm: float = 0.002, size: int = 64,
                               wavelengths_nm: Sequence[float] = (587.5618,), weights: Sequence[float] | None = None,
                               samples_across: int = 64) -> PolychromaticSpread:
    """The FFT PSF of several wavelengths of relative powers ``weights`` (None: equal) on one window.

    Each wavelength's PSF comes sampled at its own lambda L / (M dh) and is integrated over the
    window's pixels (``fft_point_spread``), so the parts share the pixel grid and add; the window
    is centred on the weighted mean of the wavelengths' ray centroids, so lateral colour shows.
    """
    power = validation.spectral_weights(weights, len(wavelengths_nm))
    film_distance, distance = _focused(lens, depth_mm, focus_mm)
    centroids = [wavefront(lens, field_deg, w, film_distance, samples_across, distance).reference_mm
                 for w in wavelengths_nm]
    reference = np.average(centroids, axis=0, weights=power)
    parts = tuple(fft_point_spread(lens, depth_mm, field_deg, focus_mm, pixel_mm, size, w, samples_across,
                                   (float(reference[0]), float(reference[1]))) for w in wavelengths_nm)
    image = sum((p * part.image for p, part in zip(power, parts)), np.zeros((size, size)))
    return PolychromaticSpread(image, parts, tuple(power))


def _sphere_hits(origin: np.ndarray, direction: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """True where a ray meets the sphere ahead of its origin, in float64 from the distance of the
    sphere's centre to the ray's line (b^2 - c of the quadratic cancels badly for a sphere metres
    away, and the OpenCL rays are float32)."""
    d = np.asarray(direction, dtype=np.float64)
    length = np.linalg.norm(d, axis=1, keepdims=True)
    d = np.divide(d, length, out=np.zeros_like(d), where=length > 0)
    to_centre = centre - np.asarray(origin, dtype=np.float64)
    along = np.sum(to_centre * d, axis=1)
    across = to_centre - along[:, None] * d
    return (along > 0) & (np.sum(across * across, axis=1) <= radius * radius)


def _ray_generator(camera: LensCamera, backend: str, seed: int) -> RayGenerator:
    """``backend``'s rays of ``camera``: ``lens.cl``'s on the default device, or the numpy reference's."""
    check_backend(backend)
    if backend == "numpy":
        return lambda block: camera.generate_rays(block, seed)
    from realistic.camera.opencl_host import LensKernel  # imports pyopencl: only when chosen
    from realistic.device.opencl import Device

    kernel = LensKernel(camera, Device.for_spec())
    return lambda block: kernel.generate(block, seed)


def point_spread(lens: LensSystem, depth_mm: float, field_deg: float = 0.0, focus_mm: float | None = None,
                 pixel_mm: float = 0.002, size: int = 64, spp: int = 256, source_radius_mm: float | None = None,
                 seed: int = 0, backend: str = "numpy") -> PointSpread:
    """Render the PSF of a point ``depth_mm`` from the film (see the module docstring).

    ``source_radius_mm`` defaults to the radius whose paraxial image is a quarter pixel.
    """
    validation.positive_length(depth_mm, "depth (mm)")
    validation.positive_length(pixel_mm, "pixel size (mm)")
    validation.samples_per_pixel(spp)
    if not (isinstance(size, int) and 1 <= size <= 4096):
        raise UserError(f"PSF window size must be 1..4096 pixels, got {size!r}")
    film_distance = film_distance_for_focus(lens, focus_mm if focus_mm is not None else depth_mm)
    para = paraxial_data(lens)
    pupil_z = film_distance + lens.track_length_mm - para.entrance_pupil_mm
    front_z = film_distance + lens.track_length_mm
    if depth_mm <= front_z:
        raise UserError(f"depth {depth_mm:g} mm is not in front of the lens (its front vertex is "
                        f"{front_z:.6g} mm from the film)")
    distance = depth_mm - pupil_z
    centre = np.array([0.0, distance * math.tan(math.radians(field_deg)), depth_mm])
    rays = trace_object_point(lens, field_deg, object_distance_mm=distance, samples_across=32)
    if len(rays.point) == 0:
        raise UserError(f"no light from a point at {field_deg:g} deg passes {lens.name}")
    landing = rays.at(film_distance).mean(axis=0)
    magnification = (film_distance - para.rear_principal_plane_mm) / distance
    radius = source_radius_mm if source_radius_mm is not None else 0.25 * pixel_mm / max(abs(magnification), 1e-12)
    validation.positive_length(radius, "source radius (mm)")

    half_w = math.ceil(abs(landing[0]) / pixel_mm) + size
    half_h = math.ceil(abs(landing[1]) / pixel_mm) + size
    width, height = 2 * half_w, 2 * half_h
    camera = LensCamera(lens, film_distance, pixel_mm * math.hypot(width, height), width, height, spp)
    # Raster position of the landing point (inverse of LensCamera.film_points), then the window's corner.
    x0 = int(round(half_w - landing[0] / pixel_mm - size / 2))
    y0 = int(round(half_h + landing[1] / pixel_mm - size / 2))
    generate = _ray_generator(camera, backend, seed)
    image = np.zeros((size, size))
    for row in range(size):
        batch = generate(SampleBlock.of_pixels((y0 + row) * width + x0, size, 0, spp))
        hit = _sphere_hits(batch.origin, batch.direction, centre, radius) & (batch.weight != 0)
        column = batch.pixel - ((y0 + row) * width + x0)
        image[row] = np.bincount(column, weights=np.where(hit, batch.weight, 0.0), minlength=size) / spp
    centre_x = -((x0 + size / 2) / width - 0.5) * width * pixel_mm
    centre_y = ((y0 + size / 2) / height - 0.5) * height * pixel_mm
    source = (float(centre[0]), float(centre[1]), float(centre[2]))
    return PointSpread(image, pixel_mm, (centre_x, centre_y), source, radius, film_distance, spp)
