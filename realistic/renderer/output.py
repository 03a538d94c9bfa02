"""Writing a finished render: the image file its name's suffix asks for, its header, and the rescue.

``save(result, path)`` writes what the ``render`` command writes, by ``path``'s suffix:

- ``.exr``: the image (the film irradiance, or a ``Photographic`` exposure of it) as float32 RGB,
  with a header (``image_metadata``) holding the camera's metadata, where the scene came from
  (``Scene.metadata``), the job's settings, the render's statistics, for a frame of a sweep the
  sweep and frame number, and the standard attributes below; and an sRGB PNG preview beside it;
- ``.png``: that PNG alone, exposed (``--exposure``, by default metered: ``camera.exposure``),
  8 bits per sample as pbrt-v4 writes PNGs, or 16 (``png_bits``) through imageio;
- ``.pfm``: the float image alone, as pbrt-v4 writes it (no header: PFM has none).

pbrt-v4 writes only the file it is asked for; so does a ``.png`` or ``.pfm`` render here (a PNG has
8 or 16 bits and no header, so it is the image to look at, not to compute with).

The EXR header's standard attributes (OpenEXR's names, pbrt-v4's conventions in ``Image::WriteEXR``,
src/pbrt/util/image.cpp, and ``ProjectiveCamera::InitMetadata``, src/pbrt/cameras.cpp):

- ``chromaticities``: linear sRGB / Rec. 709 primaries, D65 white (``image_files.write_exr``);
- ``worldToCamera`` (M44f): pbrt's camera space, world units, +z toward the scene, +x image right,
  +y image up, its origin where the scene format puts the camera (the film centre, or the front
  lens vertex for the classic homework scenes); pbrt-v4's ``cameraFromWorld``;
- ``worldToNDC`` (M44f): pbrt-v4's ``Translate(.5, .5, .5) Scale(.5, .5, .5) Perspective(fov, 0.01,
  1000) cameraFromWorld``: after the divide by w, NDC = (screen + 1) / 2 with pbrt's screen window
  (the shorter image side spans screen [-1, 1], the longer [-a, a] with a the aspect ratio, y up), so
  raster x = (2 ndc_x - 1 + a_x) / (2 a_x) * width and raster y = (a_y - 2 ndc_y + 1) / (2 a_y) *
  height. pbrt-v4 writes it for projective cameras only; a lens camera here gets its paraxial
  equivalent: a pinhole at the entrance pupil (where chief rays aim, so points at any depth land
  where their blur is centred), scaled so that the plane in focus has the thick lens's Gaussian
  magnification; off by the lens's distortion only;
- both matrices as pbrt-v4 stores them: its column-vector matrix (p' = M p) row by row, m[i][j] =
  M[i][j]; Imath, which multiplies row vectors, reads the transpose;
- ``renderTimeSeconds`` (float) and ``samplesPerPixel`` (int) as pbrt-v4 names them;
- ``software`` (the renderer and its version), ``lens`` and ``lensSha256`` (``prescription_sha256``);
- OpenEXR's photographic ``aperture`` (f-number), ``focus`` (metres), ``expTime`` and ``isoSpeed``.

Finished work is never lost:

- interrupts wait until the files are written (``atomic_files.signals_deferred``);
- if the file cannot be written when the render ends (its folder was removed meanwhile, the disk
  filled), it goes to the temporary folder instead, and a UserError says where;
- an interrupted render does not replace an image of at least as many samples (``BetterImageKept``):
  an EXR says how many it holds; a PNG or PFM says nothing, so an interrupted render replaces none
  (its samples stay in the checkpoint);
- the job's checkpoint is removed only once the complete image has been written where it was asked.
"""

from __future__ import annotations

import hashlib
import math
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.exposure import AUTO, exposure_scale, exposure_value, metered_stops
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import validation
from realistic.core.atomic_files import signals_deferred
from realistic.core.image_files import Metadata, check_png_bits, read_exr, write_exr, write_pfm, write_png
from realistic.core.transforms import scale, translate
from realistic.core.version import __version__
from realistic.errors import UserError
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import focus_distance_for_film, paraxial_data, thick_lens
from realistic.renderer.job import RenderResult

#: The image files a render writes, by suffix (lower case).
OUTPUT_SUFFIXES = (".exr", ".png", ".pfm")
#: pbrt-v4's perspective camera's near and far planes (``PerspectiveCamera``, src/pbrt/cameras.h),
#: which its ``worldToNDC`` carries in z.
NDC_NEAR, NDC_FAR = 1e-2, 1000.0
#: ``--exposure``: stops, ``"auto"`` (metered), or None (metered, or 0 for a photographic image).
Exposure = float | str | None


@dataclass(frozen=True)
class Photographic:
    """A photographic exposure: the film irradiance times ``exposure_scale(shutter, iso)``, so that a
    metered middle grey reads 0.18 (``camera.exposure``), instead of the irradiance itself."""

    shutter_seconds: float = 1 / 60
    iso: float = 100.0

    def __post_init__(self) -> None:
        validation.shutter_seconds(self.shutter_seconds)
        validation.iso_speed(self.iso)

    @property
    def scale(self) -> float:
        return exposure_scale(self.shutter_seconds, self.iso)

    def header(self, camera: Camera) -> Metadata:
        """What the EXR header says of this exposure (its EV where the camera has an f-number), also
        as OpenEXR's standard ``expTime`` (seconds) and ``isoSpeed``."""
        header: Metadata = {"shutterSeconds": float(self.shutter_seconds), "iso": float(self.iso),
                            "exposureScale": self.scale, "expTime": float(self.shutter_seconds),
                            "isoSpeed": float(self.iso)}
        f_number = camera.metadata().get("fNumber")
        if f_number is not None:
            header["exposureValue"] = exposure_value(float(f_number), self.shutter_seconds)
        return header


def prescription_sha256(lens: LensSystem) -> str:
    """sha256 (hex) of the lens's surface table, which names a prescription whatever its file or
    name: per surface (front first) radius, thickness, index, Abbe number, aperture diameter, conic
    constant and the 9 aspheric coefficients as little-endian float64, row by row, then the stop's
    surface index as a little-endian int64. The aperture column holds the stop's diameter, so a
    different f-stop hashes differently; a stop shape (a mask) does not count. A lens with paraxial
    surfaces adds their two powers per row (other lenses keep the hashes they had)."""
    columns = [lens.radius_mm, lens.thickness_mm, lens.index_d, lens.abbe_v, lens.aperture_mm, lens.conic,
               lens.aspheric_coefficients] + ([lens.paraxial_power_per_mm] if lens.paraxial.any() else [])
    table = np.column_stack(columns).astype("<f8")
    return hashlib.sha256(table.tobytes() + np.array([lens.stop], "<i8").tobytes()).hexdigest()


def _projection(camera: Camera) -> tuple[np.ndarray, float, float]:
    """(world-from-camera in world units, field of view across the shorter image side in degrees,
    camera-space z of the projection centre) of ``camera`` (module docstring): a lens camera's frame
    is in mm (its ``mm_per_unit`` is taken out) and its projection is its paraxial pinhole at the
    entrance pupil, focal length the image distance times the plane in focus's distance from the
    pupil over its distance from the front principal plane."""
    if isinstance(camera, ThinLensCamera):
        return camera.world_from_camera, camera.fov_deg, 0.0
    if not isinstance(camera, LensCamera):
        raise UserError(f"no camera transform is known for a {type(camera).__name__}")
    lens, pupil = thick_lens(camera.lens), paraxial_data(camera.lens)
    image_distance = camera.film_distance_mm + lens.rear_principal_from_rear_vertex_mm
    front_principal = camera.film_distance_mm + lens.front_principal_from_rear_vertex_mm
    entrance_pupil = camera.film_distance_mm + pupil.track_length_mm - pupil.entrance_pupil_mm
    focus = focus_distance_for_film(camera.lens, camera.film_distance_mm)
    # seen from the entrance pupil, the plane in focus keeps its Gaussian magnification
    focal = image_distance if math.isinf(focus) else \
        image_distance * (focus - entrance_pupil) / (focus - front_principal)
    fov_deg = math.degrees(2 * math.atan(min(camera.film_size_mm) / 2 / focal))
    centre_mm = entrance_pupil - camera.camera_origin_mm
    return camera.world_from_camera @ scale(camera.mm_per_unit), fov_deg, centre_mm / camera.mm_per_unit


def camera_from_world(camera: Camera) -> np.ndarray:
    """(4, 4) pbrt-v4's ``cameraFromWorld`` of ``camera``: to its camera space, in world units."""
    return np.linalg.inv(_projection(camera)[0])


def ndc_from_world(camera: Camera) -> np.ndarray:
    """(4, 4) pbrt-v4's ``NDCFromWorld`` (module docstring) of ``camera``: a perspective camera's as
    pbrt-v4 makes it; a lens camera's paraxial pinhole at its entrance pupil."""
    world_from_camera, fov_deg, centre = _projection(camera)
    inverse_tan = 1 / math.tan(math.radians(fov_deg) / 2)
    perspective = np.array([[1.0, 0, 0, 0], [0, 1, 0, 0],
                            [0, 0, NDC_FAR / (NDC_FAR - NDC_NEAR), -NDC_FAR * NDC_NEAR / (NDC_FAR - NDC_NEAR)],
                            [0, 0, 1, 0]])
    screen_from_camera = scale(inverse_tan, inverse_tan, 1.0) @ perspective @ translate(0.0, 0.0, -centre)
    return translate(0.5, 0.5, 0.5) @ scale(0.5) @ screen_from_camera @ np.linalg.inv(world_from_camera)


def standard_metadata(camera: Camera) -> Metadata:
    """The EXR attributes other tools know (module docstring): the camera's matrices, the
    renderer, and for a lens camera the prescription's hash and OpenEXR's standard ``aperture``
    (the f-number) and ``focus`` (the focus distance from the film, metres)."""
    metadata: Metadata = {"software": f"realistic {__version__}",
                          "worldToCamera": camera_from_world(camera).astype(np.float32),
                          "worldToNDC": ndc_from_world(camera).astype(np.float32)}
    if isinstance(camera, LensCamera):
        metadata.update({"lensSha256": prescription_sha256(camera.lens),
                         "aperture": float(paraxial_data(camera.lens).f_number),
                         "focus": float(focus_distance_for_film(camera.lens, camera.film_distance_mm)) / 1000.0})
    return metadata


def image_metadata(result: RenderResult) -> Metadata:
    """The EXR header of ``result``: camera, scene source, job settings, statistics, sweep frame,
    and the standard attributes (``standard_metadata``)."""
    job, camera = result.job, result.camera
    if job is None:  # result.camera has already refused this
        raise UserError("this result carries no render job")
    scene = job.scene
    metadata: Metadata = {**camera.metadata(), **scene.metadata, **standard_metadata(camera),
                          "spp": int(camera.spp), "samplesPerPixel": int(camera.spp), "seed": int(job.seed),
                          "lightSamples": int(job.settings.light_samples),
                          "integrator": scene.integrator, "maxDepth": int(scene.max_depth),
                          "backend": job.backend, "renderSeconds": float(result.seconds),
                          "renderTimeSeconds": float(result.seconds),
                          "exitPupilSeconds": float(result.stage_seconds.get("exit pupil", 0.0)),
                          "samplesDone": int(result.samples_done), "samplesTotal": int(result.samples_total),
                          "interrupted": int(result.interrupted)}
    if job.sweep is not None:
        metadata.update({"sweep": job.sweep, "frame": result.frame + 1, "frames": len(job.cameras)})
    return metadata


def exposed(image: np.ndarray, photographic: Photographic | None) -> np.ndarray:
    """The image to write: ``image`` as is, or its photographic exposure (float32)."""
    if photographic is None:
        return image
    return (image * np.float32(photographic.scale)).astype(np.float32)


def preview_stops(image: np.ndarray, photographic: Photographic | None, exposure: Exposure) -> float:
    """A PNG's exposure in stops: ``exposure``; ``"auto"``: metered (``exposure.metered_stops``);
    None: 0 for a photographic image (exposed already), else metered."""
    if exposure == AUTO or (exposure is None and photographic is None):
        return metered_stops(image)
    if exposure is None:
        return 0.0
    if isinstance(exposure, str):
        raise UserError(f"exposure {exposure!r} is neither a number of stops nor 'auto'")
    return validation.exposure_stops(exposure)


def write_preview(path: Path, image: np.ndarray, photographic: Photographic | None = None,
                  exposure: Exposure = None, png_bits: int = 8) -> float:
    """Write the PNG preview of a film image (in progress or finished) to ``path``; its stops."""
    image = exposed(image, photographic)
    stops = preview_stops(image, photographic, exposure)
    write_png(Path(path), image, stops, check_png_bits(png_bits))
    return stops


class BetterImageKept(UserError):
    """An interrupted render was not written: the file there already holds at least as many samples,
    or is a PNG or PFM, which cannot say how many it holds."""


def samples_in(path: Path) -> int | None:
    """The ``samplesDone`` an existing EXR at ``path`` says it holds (None: no such file, or not a
    render of ours)."""
    if not path.is_file():
        return None
    try:
        done = read_exr(path)[1].get("samplesDone")
    except UserError:
        return None
    return int(done) if isinstance(done, (int, np.integer)) else None


def render_output(path: str | os.PathLike) -> Path:
    """``path`` as a render's output: an ``.exr`` (with a PNG preview beside it), ``.png`` or ``.pfm``."""
    path = Path(path)
    if path.suffix.lower() not in OUTPUT_SUFFIXES:
        raise UserError(f"{path}: the output must be an .exr file (the PNG preview goes beside it), a .png or a .pfm")
    return path


def written_files(path: Path) -> list[Path]:
    """The files a render to ``path`` writes: an EXR and its PNG preview, or the PNG or PFM alone."""
    path = render_output(path)
    return [path, path.with_suffix(".png")] if path.suffix.lower() == ".exr" else [path]


@dataclass(frozen=True)
class _Image:
    """What a save writes, whatever the file: the image, its EXR header, its PNG's stops and bits."""

    pixels: np.ndarray
    metadata: Metadata
    stops: float
    png_bits: int
    window: tuple[int, int, int, int] | None  # a crop's place in its full image (``write_exr``)
    layers: dict[str, np.ndarray]  # EXR channels beside R, G, B (``layer_channels``)


def save(result: RenderResult, path: str | os.PathLike, photographic: Photographic | None = None,
         exposure: Exposure = None, png_bits: int = 8) -> float:
    """Write ``result`` to ``path`` as its suffix says (module docstring): an EXR with its header
    (``image_metadata``) and the PNG preview beside it, a PNG, or a PFM; returns the PNG's exposure
    in stops (``preview_stops``; 0 for a PFM, written unexposed). ``png_bits``: 8 or 16 per sample.

    An interrupted ``result`` does not replace an EXR at ``path`` that holds as many samples or
    more, nor any PNG or PFM there: BetterImageKept (a UserError) says so and nothing is written.
    When ``path`` cannot be written, the files are saved in the temporary folder and a UserError
    names them. Interrupts wait until the files are written. Once a complete image is at ``path``,
    the job's checkpoint (``job.checkpoint``) is removed.
    """
    path = render_output(path)
    pixels = exposed(result.image, photographic)
    report_image_problems(path, pixels, result.samples_done)
    metadata = image_metadata(result)
    if photographic is not None:
        metadata.update(photographic.header(result.camera))
    kind = path.suffix.lower()
    stops = 0.0 if kind == ".pfm" else preview_stops(pixels, photographic, exposure)
    image = _Image(pixels, metadata, stops, check_png_bits(png_bits), _window(result),
                   layer_channels(result, photographic))
    job = result.job
    checkpoint = job.checkpoint if job is not None else None
    with signals_deferred():
        if result.interrupted:
            _refuse_to_replace_better(path, result, checkpoint.path if checkpoint is not None else None)
        try:
            _write(path, image)
        except UserError as err:
            kept = f"; the checkpoint {checkpoint.path} is kept" if checkpoint is not None else ""
            raise UserError(f"{err}; {_rescue(path, image)}{kept}") from None
        if checkpoint is not None and not result.interrupted:
            checkpoint.path.unlink(missing_ok=True)
    return stops


def _refuse_to_replace_better(path: Path, result: RenderResult, checkpoint: Path | None) -> None:
    """BetterImageKept when the file at ``path`` may hold more than the interrupted ``result``: an
    EXR that says it holds as many samples or more, or any PNG or PFM (they cannot say)."""
    kept = f"; the checkpoint {checkpoint} keeps this render's" if checkpoint is not None else ""
    if path.suffix.lower() == ".exr":
        theirs = samples_in(path)
        if theirs is not None and theirs >= result.samples_done:
            raise BetterImageKept(f"{path} holds {theirs} samples, this interrupted render {result.samples_done}: "
                                  f"kept it{kept}")
    elif path.is_file():
        raise BetterImageKept(f"{path} is there and cannot say how many samples it holds, this interrupted render "
                              f"{result.samples_done}: kept it{kept}")


def report_image_problems(path: Path, image: np.ndarray, samples_done: int = 1) -> int:
    """Warn on stderr, in one line, when ``image`` has NaN or infinite pixels (a scene's numbers or an
    exposure beyond float32; they are written as they are), or when every pixel is black although
    ``samples_done`` samples were taken (no light reached the film: a scene without lights, a lens
    that passes nothing, a camera inside an object). Returns how many pixels are not finite."""
    bad = int(np.count_nonzero(~np.all(np.isfinite(image), axis=-1)))
    pixels = image.shape[0] * image.shape[1]
    if bad:
        print(f"realistic: warning: {path}: {bad} of {pixels} pixels are NaN or infinite (written as they are)",
              file=sys.stderr)
    elif samples_done > 0 and pixels and not np.any(image):
        print(f"realistic: warning: {path}: every pixel is black after {samples_done} samples: no light reached "
              f"the film (are there lights, does the lens pass light, is the camera inside something?)",
              file=sys.stderr)
    return bad


def _window(result: RenderResult) -> tuple[int, int, int, int] | None:
    """Where a cropped result lies in its full image (``write_exr``'s ``window``); None uncropped."""
    crop = result.job.crop if result.job is not None else None
    return None if crop is None else (crop.x0, crop.y0, result.camera.width, result.camera.height)


def layer_channels(result: RenderResult, photographic: Photographic | None) -> dict[str, np.ndarray]:
    """The EXR channels written beside R, G, B: the AOVs (``renderer.aov``) as they are, and for a
    denoised image the film's own as "Noisy.R", "Noisy.G", "Noisy.B", exposed as the image is."""
    layers = dict(result.aovs)
    if result.noisy is not None:
        noisy = exposed(result.noisy, photographic)
        layers.update({f"Noisy.{name}": noisy[..., index] for index, name in enumerate("RGB")})
    return layers


def _rescue(path: Path, image: _Image) -> str:
    """Write the image to the temporary folder; what became of it, for the error line."""
    try:
        handle, name = tempfile.mkstemp(prefix=f"realistic-{path.stem[:64]}-", suffix=path.suffix.lower())
    except OSError as err:
        return f"the rescue copy in {tempfile.gettempdir()} failed too ({err.strerror or err})"
    os.close(handle)
    rescue = Path(name)
    try:
        _write(rescue, image)
    except UserError as err:
        rescue.unlink(missing_ok=True)
        return f"the rescue copy failed too ({err})"
    beside = " (and its .png)" if rescue.suffix == ".exr" else ""
    return f"the render was saved as {rescue}{beside} instead"


def _write(path: Path, image: _Image) -> None:
    kind = path.suffix.lower()
    if kind == ".exr":
        write_exr(path, image.pixels, image.metadata, image.window, image.layers)
        write_png(path.with_suffix(".png"), image.pixels, image.stops, image.png_bits)
    elif kind == ".png":
        write_png(path, image.pixels, image.stops, image.png_bits)
    else:
        write_pfm(path, image.pixels)
