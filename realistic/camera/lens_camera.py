"""The realistic camera: a real lens between the film and the scene, traced surface by surface.

``LensCamera.generate_rays`` is the float64 numpy reference of the OpenCL kernel's ray generation
(``realistic.camera.opencl_host``, reached through a render backend: ``realistic.renderer.backends``):
same random numbers (``realistic.core.rng``), same film
mapping, same samplers, same tracing rules.

Film mapping (lens frame, film at z = 0): the film is the resolution's aspect ratio with the given
diagonal; raster (x right, y down) maps to film x = -(x / W - 1/2) w, film y = (y / H - 1/2) h.
The lens inverts the image, so this flip makes it come out upright and unmirrored.

Camera space is the lens frame, in mm, with its origin moved along the axis to where the scene
format puts it (``origin``): the film centre (pbrt-v3, meshes) or the front lens vertex (the
classic homework). ``world_from_camera`` carries the scene's unit; refocusing moves the film and,
with the front-vertex convention, the whole camera frame with it.

A camera is adjusted as a photographer would, each change a new frozen camera at the same pose:
``with_lens`` (another lens; the film kept unless most of it falls outside the new lens's image
circle, or given, or ``"auto"``: sized to the lens), ``with_focus`` (scene units from the film
plane, as ``--focus``), ``with_stop`` (f-number or diameter, and shape). The CLI's options call the
same methods (``realistic.renderer.inputs.apply_overrides``).

The film position of a sample is drawn from the camera's pixel filter (``pixel_filter``,
``realistic.core.pixel_filter``: filter importance sampling), and the filter's sign-and-normalisation
factor multiplies the sample's weight; the default 0.5-pixel box is plain jittering in the pixel.

A *spectral* camera traces each sample at ``wavelengths_per_sample`` (K) wavelengths, one ray per
wavelength (``realistic.core.spectrum``: importance sampled over 380-780 nm). The sample's R5 number
u4 (``realistic.core.rng``: stratified within the pixel jointly with the film and lens positions)
gives the K wavelengths invCDF((u4 + j) / K), j = 0 .. K - 1: one in each 1/K of the density's
probability (``rng.spectral_rays``; the hero-wavelength scheme of Wilkie et al. 2014 and pbrt-v4's
``SampledWavelengths``, except that a dispersive lens bends each wavelength its own way, so each
gets its own ray). The K rays share the sample's film position, lens position and sample index, so
the renderer draws the same light samples for them (``rng.light_uniforms(pixel, sample, ...)``):
their spectral values add up to a nearly constant colour, and what noise is left is luminance noise
like an RGB render's rather than colour speckle. Sharing them out instead (ray j taking light
samples j, j + K, ...: K times fewer shadow rays, still unbiased) loses that: each channel's
response is concentrated on the one or two of the K wavelengths nearest its peak, so each channel
would see about L / K light samples (``bench/spectral_noise.py`` measured 1.5x and 1.8x the relative
RMSE of shared light samples at 16 and 64 spp on its dragons, L = 4, K = 3). For the same reason
each wavelength needs its own camera ray and hit: a sample costs about K RGB samples for an RGB
sample's noise, which only sharing one scene path among the K wavelengths (hero-wavelength path
reuse through the lens) would avoid. Each ray is traced with the glasses' indices at its wavelength,
so the lens's chromatic aberration reaches the image. ``generate_rays`` returns the K rays of a
sample consecutively (sample-major: N K rays for N samples); the film adds each with 1/K of the
sample's weight (``realistic.renderer.runner``), so a pixel's value stays the mean over its samples.
A non-spectral camera traces one ray per sample at the d line and ignores K.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from realistic.camera.autofocus import autofocus_distance_mm
from realistic.camera.base import HitDistance, Metadata, RayBatch, SampleBlock
from realistic.core import rng, validation
from realistic.core.film_geometry import (
    FULL_FRAME_DIAGONAL_MM,
    MOSTLY_OUTSIDE,
    film_size_mm,
    fraction_outside_circle,
    pixel_pitch_mm,
)
from realistic.core.pixel_filter import PIXEL_BOX, PixelFilter
from realistic.core.spectrum import DEFAULT_WAVELENGTHS_PER_SAMPLE, LAMBDA_MAX_NM, LAMBDA_MIN_NM, wavelengths_nm
from realistic.core.transforms import look_at, scale, transform_points, transform_vectors
from realistic.errors import UserError
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.formats import load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.library import image_circle_mm
from realistic.optics.paraxial import (
    film_distance_for_focus,
    focus_distance_for_film,
    nearest_focus_mm,
    paraxial_data,
    stop_diameter_for_f_number,
    thick_lens,
)
from realistic.optics.sampling import (
    PUPIL_INTERVALS,
    ExitPupilTable,
    camera_weight,
    exit_pupil_table,
    rear_element_sampler,
)
from realistic.optics.stop_shape import StopShape
from realistic.optics.tracer import trace_from_film

LENS_SAMPLINGS = ("pupil", "rear")
#: Where camera space's origin sits on the axis: the film centre, or the front lens vertex.
ORIGINS = ("film", "front_vertex")
#: World units of the mesh scenes and the Python API's default: metres.
MM_PER_METRE = 1000.0
#: ``film_diagonal_mm="auto"`` (``--film-diagonal auto``): the film sized to the lens (``auto_film_diagonal_mm``).
AUTO_FILM = "auto"
#: A film diagonal as the API and the options take it: mm, ``AUTO_FILM``, or None (the camera's own).
FilmDiagonal = float | str | None
#: How far beyond its nearest focus a lens is focused when it replaces one that focused nearer.
NEAREST_FOCUS_MARGIN = 1.01


def auto_film_diagonal_mm(lens: LensSystem) -> float:
    """The film a lens covers: its image circle's diameter (``optics.library.image_circle_mm``, where
    the relative illumination is still a tenth of the centre's) as the film diagonal, at most full
    frame: a lens drawing a larger circle (a medium- or large-format design) renders the full-frame
    part of it, as a 35 mm camera would show it, rather than its darkened rim."""
    return min(image_circle_mm(lens), FULL_FRAME_DIAGONAL_MM)


def film_diagonal_for_fov_mm(lens: LensSystem, film_distance_mm: float, fov_deg: float, width: int,
                             height: int) -> float:
    """The diagonal of a ``width`` x ``height`` film whose shorter side spans ``fov_deg`` through
    ``lens`` at ``film_distance_mm``, as pbrt's perspective camera's ``fov`` spans its shorter image
    side (pbrt-v3 src/cameras/perspective.cpp, ``CreatePerspectiveCamera``: the screen window's
    shorter side is [-1, 1], which ``Perspective(fov, ...)`` maps to tan(fov / 2); pbrt-v4 keeps
    it): half that side is the image distance (film to rear principal plane, thick-lens model)
    times tan(fov / 2), exact for a distortion-free lens."""
    image_distance_mm = film_distance_mm + thick_lens(lens).rear_principal_from_rear_vertex_mm
    short_mm = 2 * image_distance_mm * math.tan(math.radians(fov_deg) / 2)
    return short_mm * math.hypot(width, height) / min(width, height)


def film_diagonal_value(value: FilmDiagonal) -> FilmDiagonal:
    """A film diagonal option checked: None, ``AUTO_FILM``, or a diagonal in mm (``validation``)."""
    if value is None or value == AUTO_FILM:
        return value
    if isinstance(value, str):
        raise UserError(f"film diagonal must be a number of mm or {AUTO_FILM!r}, got {value!r}")
    return validation.film_diagonal_mm(value)


@dataclass(frozen=True, eq=False)
class LensCamera:
    """Everything ray generation needs; validated on construction.

    ``world_from_camera`` maps camera space (mm, origin as ``origin`` says, +z toward the scene)
    to world units. ``wavelengths_per_sample``: rays (wavelengths) per camera sample when
    ``spectral`` (see the module docstring); ignored otherwise.
    """

    lens: LensSystem
    film_distance_mm: float
    film_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM
    width: int = 300
    height: int = 300
    spp: int = 16
    world_from_camera: np.ndarray = field(default_factory=lambda: np.eye(4))
    origin: str = "film"
    lens_sampling: str = "pupil"
    spectral: bool = False
    pixel_filter: PixelFilter = PIXEL_BOX
    wavelengths_per_sample: int = DEFAULT_WAVELENGTHS_PER_SAMPLE

    def __post_init__(self) -> None:
        if not isinstance(self.pixel_filter, PixelFilter):
            raise UserError(f"pixel_filter must be a PixelFilter, got {self.pixel_filter!r}")
        validation.resolution(self.width, self.height)
        validation.samples_per_pixel(self.spp)
        validation.wavelengths_per_sample(self.wavelengths_per_sample)
        validation.film_diagonal_mm(self.film_diagonal_mm)
        validation.positive_length(self.film_distance_mm, "film distance (mm)")
        if self.lens_sampling not in LENS_SAMPLINGS:
            raise UserError(f"lens sampling must be one of {', '.join(LENS_SAMPLINGS)}, got {self.lens_sampling!r}")
        if self.origin not in ORIGINS:
            raise UserError(f"camera origin must be one of {', '.join(ORIGINS)}, got {self.origin!r}")
        object.__setattr__(self, "world_from_camera", np.asarray(self.world_from_camera, dtype=np.float64))

    @classmethod
    def looking_at(cls, lens: LensSystem, eye: np.ndarray, target: np.ndarray, focus_distance: float | None = None,
                   film_diagonal_mm: float = FULL_FRAME_DIAGONAL_MM, width: int = 300, height: int = 300,
                   spp: int = 16, lens_sampling: str = "pupil", mm_per_unit: float = MM_PER_METRE) -> LensCamera:
        """A camera with its film centre at ``eye`` looking at ``target`` (world units, +y up),
        focused ``focus_distance`` world units from the film (None: on the target's distance)."""
        eye, target = np.asarray(eye, float), np.asarray(target, float)
        if np.allclose(eye, target):
            raise UserError("the camera position and the target coincide")
        if focus_distance is None:
            focus_distance = float(np.linalg.norm(target - eye))
        film_distance = film_distance_for_focus(lens, focus_distance * mm_per_unit)
        return cls(lens, film_distance, film_diagonal_mm, width, height, spp,
                   look_at(eye, target) @ scale(1.0 / mm_per_unit), "film", lens_sampling)

    def __repr__(self) -> str:
        """One line, no arrays: lens, film, focus (scene units from the film) and f-number."""
        focus = focus_distance_for_film(self.lens, self.film_distance_mm) / self.mm_per_unit
        spectral = ", spectral" if self.spectral else ""
        return (f"LensCamera({self.lens.name!r}, {self.width}x{self.height}, {self.spp} spp, focus {focus:.4g}, "
                f"f/{paraxial_data(self.lens).f_number:.3g}, film {self.film_diagonal_mm:.4g} mm{spectral})")

    @property
    def camera_origin_mm(self) -> float:
        """Distance from the film to camera space's origin, toward the scene."""
        return self.film_distance_mm + self.lens.track_length_mm if self.origin == "front_vertex" else 0.0

    @property
    def world_from_lens(self) -> np.ndarray:
        """(4, 4) from the lens frame (film at z = 0, mm) to world units."""
        shift = np.eye(4)
        shift[2, 3] = -self.camera_origin_mm
        return self.world_from_camera @ shift

    @property
    def mm_per_unit(self) -> float:
        """Millimetres of camera space per world unit."""
        return 1.0 / float(np.linalg.norm(self.world_from_camera[:3, 0]))

    @property
    def pupil(self) -> ExitPupilTable:
        """Exit-pupil bounds for this lens, focus and film, built on first use (then cached); a
        spectral camera's boxes hold what passes at either end of the wavelength range as well as
        at the d line. Its ``PUPIL_INTERVALS`` film intervals are the count the lens kernel is built for."""
        wavelengths = (LAMBDA_MIN_NM, D_LINE_NM, LAMBDA_MAX_NM) if self.spectral else (D_LINE_NM,)
        return exit_pupil_table(self.lens, self.film_distance_mm, self.sampled_film_diagonal_mm, PUPIL_INTERVALS,
                                wavelengths_nm=wavelengths)

    @property
    def sampled_film_diagonal_mm(self) -> float:
        """Diagonal of the film area the samples land on: the film grown by how far the pixel filter
        reaches past the corner pixels' edges (a 0.5-pixel box keeps every sample on the film), so
        the exit-pupil table bounds every sample's pupil."""
        beyond_px = math.hypot(max(self.pixel_filter.radius_x - 0.5, 0.0), max(self.pixel_filter.radius_y - 0.5, 0.0))
        return self.film_diagonal_mm + 2 * beyond_px * pixel_pitch_mm(self.film_diagonal_mm, self.width, self.height)

    def prepare(self) -> None:
        """Build the exit-pupil table when this camera samples the pupil (memory, disk or traced)."""
        if self.lens_sampling == "pupil":
            self.pupil  # noqa: B018 (built and cached by the property)

    @property
    def film_size_mm(self) -> tuple[float, float]:
        return film_size_mm(self.film_diagonal_mm, self.width, self.height)

    @property
    def sample_count(self) -> int:
        return self.width * self.height * self.spp

    @property
    def rays_per_sample(self) -> int:
        """Camera rays per sample: ``wavelengths_per_sample`` for a spectral camera, else 1."""
        return self.wavelengths_per_sample if self.spectral else 1

    def film_points(self, pixel: np.ndarray, u_x: np.ndarray, u_y: np.ndarray) -> np.ndarray:
        """Film points (N, 2) in mm for pixels and raster offsets from their corner (pixels; [0, 1)
        inside the pixel)."""
        w_mm, h_mm = self.film_size_mm
        x = (pixel % self.width) + u_x.astype(np.float64)
        y = (pixel // self.width) + u_y.astype(np.float64)
        return np.column_stack([-(x / self.width - 0.5) * w_mm, (y / self.height - 0.5) * h_mm])

    def filtered_film_points(self, pixel: np.ndarray, u_x: np.ndarray,
                             u_y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film points (N, 2) in mm drawn from the pixel filter around each pixel's centre with
        uniform ``u_x``, ``u_y``, and each sample's filter weight (N,) (1 for box and triangle)."""
        dx, dy, weight = self.pixel_filter.offsets(u_x, u_y)
        return self.film_points(pixel, 0.5 + dx, 0.5 + dy), weight

    def generate_rays(self, block: SampleBlock, seed: int = 0) -> RayBatch:
        """Camera rays for the block's samples, in its order (reference implementation): one per
        sample, or for a spectral camera ``rays_per_sample`` consecutive rays per sample that share
        its film and lens positions, at its K stratified wavelengths."""
        pixel, sample = block.ids()
        if self.spectral:
            u = rng.spectral_rays(pixel, sample, seed, self.wavelengths_per_sample)
            pixel = np.repeat(pixel, self.wavelengths_per_sample)
        else:
            u = rng.stratified4(pixel, sample, seed)
        count = len(pixel)
        u_x, u_y, u_lens, v_lens = u[:4]
        film_xy, filter_weight = self.filtered_film_points(pixel, u_x, u_y)
        sampler = self.pupil if self.lens_sampling == "pupil" else rear_element_sampler(self.lens,
                                                                                         self.film_distance_mm)
        targets, area = sampler.sample(film_xy, u_lens.astype(np.float64), v_lens.astype(np.float64))
        film = np.column_stack([film_xy, np.zeros(count)])
        wavelength = wavelengths_nm(u[4]) if self.spectral else None
        traced = trace_from_film(self.lens, self.film_distance_mm, film, targets - film,
                                 D_LINE_NM if wavelength is None else wavelength.astype(np.float64))
        weight = np.where(traced.passed, camera_weight(film, targets, area, sampler.plane_z_mm) * filter_weight
                          * traced.transmittance, 0.0)
        to_world = self.world_from_lens
        passed = traced.passed[:, None]
        origin = np.where(passed, transform_points(to_world, traced.origin), 0.0)
        direction = np.where(passed, transform_vectors(to_world, traced.direction), 0.0)
        length = np.linalg.norm(direction, axis=1, keepdims=True)
        direction = np.divide(direction, length, out=np.zeros_like(direction), where=length > 0)
        return RayBatch(origin, direction, weight, pixel, wavelength)

    def metadata(self) -> Metadata:
        lens = self.lens
        coating = lens.coating[0] if len(set(lens.coating)) == 1 else ",".join(lens.coating)  # one, or per surface
        return {"lens": lens.name, "lensSource": lens.source, "apertureDiameterMm": float(lens.stop_diameter_mm),
                "fNumber": float(paraxial_data(lens).f_number),
                "focusDistanceMm": float(focus_distance_for_film(lens, self.film_distance_mm)),
                "focusDistanceSceneUnits": float(self.focus_distance),
                "filmDistanceMm": float(self.film_distance_mm), "filmDiagonalMm": float(self.film_diagonal_mm),
                "lensSampling": self.lens_sampling,
                **({"coating": coating} if coating != "ideal" else {}),
                "stopShape": lens.stop_shape.describe() if lens.stop_shape else "circle",
                "dispersion": "on" if self.spectral else "off", "pixelFilter": self.pixel_filter.describe(),
                **({"wavelengthsPerSample": int(self.wavelengths_per_sample)} if self.spectral else {})}

    def pixel_spread_radians(self) -> float:
        """Angle one pixel subtends in object space: pixel pitch over the image distance (film to
        rear principal plane, thick-lens model), what a texture footprint grows by per unit distance."""
        image_distance_mm = self.film_distance_mm + thick_lens(self.lens).rear_principal_from_rear_vertex_mm
        return self.film_size_mm[0] / self.width / max(image_distance_mm, self.film_distance_mm)

    def with_coating(self, coating: str | Sequence[str]) -> LensCamera:
        """The camera with ``coating`` on every lens surface, or one per surface (``LensSystem.with_coating``)."""
        return dataclasses.replace(self, lens=self.lens.with_coating(coating))

    def with_dispersion(self, spectral: bool | None) -> LensCamera:
        """Spectral sampling on or off; None: on when the lens has Abbe numbers (its exit-pupil
        bounds follow)."""
        return dataclasses.replace(self, spectral=self.lens.has_dispersion if spectral is None else spectral)

    def refocused_mm(self, focus_distance_mm: float) -> LensCamera:
        """The camera with its film moved (thick-lens model) to focus ``focus_distance_mm`` from the
        film (the lens frame's unit; ``with_focus`` takes scene units)."""
        return dataclasses.replace(self, film_distance_mm=film_distance_for_focus(self.lens, focus_distance_mm))

    @property
    def focus_distance(self) -> float:
        """Distance in focus, in scene units from the film plane (inf at the rear focal point)."""
        return focus_distance_for_film(self.lens, self.film_distance_mm) / self.mm_per_unit

    def with_focus(self, distance: float) -> LensCamera:
        """The camera focused ``distance`` scene units from the film plane (``math.inf``: infinity),
        the unit of ``--focus``; the film moves (thick-lens model), the pose stays."""
        return self.refocused_mm(validation.focus_distance(distance) * self.mm_per_unit)

    def with_stop(self, *, f_number: float | None = None, aperture_mm: float | None = None,
                  shape: StopShape | None = None) -> LensCamera:
        """The camera with its lens's stop sized for paraxial ``f_number`` (EFL over the entrance
        pupil) or to ``aperture_mm`` (one of them at most), and cut to ``shape`` when given; the
        film stays where it was, so the focus does too."""
        if f_number is not None and aperture_mm is not None:
            raise UserError("f_number (--fstop) and aperture_mm (--aperture) both size the stop: give one")
        if f_number is None and aperture_mm is None and shape is None:
            raise UserError("with_stop needs f_number, aperture_mm or shape")
        lens = self.lens
        if aperture_mm is not None:
            lens = lens.with_stop_diameter(aperture_mm)
        if f_number is not None:
            lens = lens.with_stop_diameter(stop_diameter_for_f_number(lens, f_number))
        if shape is not None:
            lens = lens.with_stop_shape(shape)
        return dataclasses.replace(self, lens=lens)

    def with_lens(self, lens: LensSystem | str, *, film_diagonal_mm: FilmDiagonal = None) -> LensCamera:
        """The same pose, resolution, sampling and focus distance (from the film plane) through
        ``lens`` (a LensSystem, or a bundled name or file for ``load_lens``); camera space keeps its
        origin convention, so a homework scene's front lens vertex stays where the scene put it.
        The film: ``film_diagonal_mm`` in mm, ``"auto"`` (``auto_film_diagonal_mm``), or None: this
        camera's, unless most of it lies outside the new lens's image circle, then "auto". A focus
        nearer than the new lens reaches becomes its nearest."""
        lens = load_lens(lens) if isinstance(lens, str) else lens
        focus_mm = max(self.focus_distance * self.mm_per_unit, NEAREST_FOCUS_MARGIN * nearest_focus_mm(lens))
        camera = dataclasses.replace(self, lens=lens, film_distance_mm=film_distance_for_focus(lens, focus_mm))
        film = film_diagonal_value(film_diagonal_mm)
        if film is None:
            return camera.with_film(AUTO_FILM) if camera.frame_outside_image_circle() > MOSTLY_OUTSIDE else camera
        return camera.with_film(film)

    def with_film(self, film_diagonal_mm: float | str) -> LensCamera:
        """The camera with a film of ``film_diagonal_mm`` (mm, or ``"auto"``: ``auto_film_diagonal_mm``)."""
        film = film_diagonal_value(film_diagonal_mm)
        diagonal = auto_film_diagonal_mm(self.lens) if film == AUTO_FILM else float(film)  # type: ignore[arg-type]
        return dataclasses.replace(self, film_diagonal_mm=diagonal)

    def frame_outside_image_circle(self) -> float:
        """Fraction of the frame outside the lens's image circle (``optics.library.image_circle_mm``)."""
        return fraction_outside_circle(self.film_diagonal_mm, self.width, self.height, image_circle_mm(self.lens))

    def coverage_warning(self) -> str | None:
        """A warning, with the film diagonal to use, when most of the frame lies outside the image circle."""
        outside = self.frame_outside_image_circle()
        if outside <= MOSTLY_OUTSIDE:
            return None
        return (f"{outside:.0%} of the {self.film_diagonal_mm:g} mm film lies outside the image circle of "
                f"{self.lens.name} ({image_circle_mm(self.lens):.3g} mm) and renders dark: try --film-diagonal "
                f"{auto_film_diagonal_mm(self.lens):.3g} (or auto)")

    def autofocused(self, x: float, y: float, hit_distance: HitDistance) -> LensCamera:
        """Refocused on what raster point (x, y) sees; ``hit_distance(origin, direction)`` (world
        space) gives the distance to the scene along a ray, None for a miss."""
        return self.refocused_mm(autofocus_distance_mm(self, x, y, hit_distance))

