"""Writing a finished render: the EXR with its header, the PNG preview beside it, and the rescue.

``save(result, path)`` writes what the ``render`` command writes: the image (the film irradiance,
or a ``Photographic`` exposure of it), a header with the camera's metadata, where the scene came
from (``Scene.metadata``), the job's settings, the render's statistics and, for a frame of a sweep,
the sweep and frame number; and an sRGB PNG preview beside it. Finished work is never lost:

- interrupts wait until both files are written (``atomic_files.signals_deferred``);
- if the file cannot be written when the render ends (its folder was removed meanwhile, the disk
  filled), both go to the temporary folder instead, and a UserError says where;
- an interrupted render does not replace an image of at least as many samples (``BetterImageKept``);
- the job's checkpoint is removed only once the complete image has been written where it was asked.
"""

from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.exposure import exposure_scale, exposure_value
from realistic.core import validation
from realistic.core.atomic_files import signals_deferred
from realistic.core.image_files import Metadata, auto_exposure, read_exr, write_exr, write_png
from realistic.errors import UserError
from realistic.renderer.job import RenderResult


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
        """What the EXR header says of this exposure (its EV where the camera has an f-number)."""
        header: Metadata = {"shutterSeconds": float(self.shutter_seconds), "iso": float(self.iso),
                            "exposureScale": self.scale}
        f_number = camera.metadata().get("fNumber")
        if f_number is not None:
            header["exposureValue"] = exposure_value(float(f_number), self.shutter_seconds)
        return header


def image_metadata(result: RenderResult) -> Metadata:
    """The EXR header of ``result``: camera, scene source, job settings, statistics, sweep frame."""
    job, camera = result.job, result.camera
    if job is None:  # result.camera has already refused this
        raise UserError("this result carries no render job")
    scene = job.scene
    metadata: Metadata = {**camera.metadata(), **scene.metadata,
                          "spp": int(camera.spp), "seed": int(job.seed),
                          "lightSamples": int(job.settings.light_samples),
                          "integrator": scene.integrator, "maxDepth": int(scene.max_depth),
                          "backend": job.backend, "renderSeconds": float(result.seconds),
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


def preview_stops(image: np.ndarray, photographic: Photographic | None, exposure: float | None) -> float:
    """The PNG preview's exposure in stops: ``exposure``, else 0 for a photographic image (it is
    exposed already), else automatic (``image_files.auto_exposure``)."""
    if exposure is not None:
        return validation.exposure_stops(exposure)
    return 0.0 if photographic is not None else auto_exposure(image)


def write_preview(path: Path, image: np.ndarray, photographic: Photographic | None = None,
                  exposure: float | None = None) -> float:
    """Write the PNG preview of a film image (in progress or finished) to ``path``; its stops."""
    image = exposed(image, photographic)
    stops = preview_stops(image, photographic, exposure)
    write_png(Path(path), image, stops)
    return stops


class BetterImageKept(UserError):
    """An interrupted render was not written: the file there already holds at least as many samples."""


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


def exr_output(path: str | os.PathLike) -> Path:
    """``path`` as a render's output: an ``.exr`` file (the PNG preview goes beside it)."""
    path = Path(path)
    if path.suffix.lower() != ".exr":
        raise UserError(f"{path}: the output must be an .exr file (the PNG preview goes beside it)")
    return path


def save(result: RenderResult, path: str | os.PathLike, photographic: Photographic | None = None,
         exposure: float | None = None) -> float:
    """Write ``result`` to the EXR ``path`` with its header (``image_metadata``) and the PNG preview
    beside it (``exposure`` stops, None: as ``preview_stops``); returns the preview's stops.

    An interrupted ``result`` does not replace an image at ``path`` that holds as many samples or
    more: BetterImageKept (a UserError) says so and nothing is written. When ``path`` cannot be
    written, both files are saved in the temporary folder and a UserError names them. Interrupts
    wait until the files are written. Once a complete image is at ``path``, the job's checkpoint
    (``job.checkpoint``) is removed.
    """
    path = exr_output(path)
    image = exposed(result.image, photographic)
    report_non_finite(path, image)
    metadata = image_metadata(result)
    if photographic is not None:
        metadata.update(photographic.header(result.camera))
    stops = preview_stops(image, photographic, exposure)
    layers = layer_channels(result, photographic)
    job = result.job
    checkpoint = job.checkpoint if job is not None else None
    with signals_deferred():
        theirs = samples_in(path) if result.interrupted else None
        if theirs is not None and theirs >= result.samples_done:
            kept = f"; the checkpoint {checkpoint.path} keeps this render's" if checkpoint is not None else ""
            raise BetterImageKept(f"{path} holds {theirs} samples, this interrupted render {result.samples_done}: "
                                  f"kept it{kept}")
        try:
            _write(path, image, metadata, stops, layers)
        except UserError as err:
            kept = f"; the checkpoint {checkpoint.path} is kept" if checkpoint is not None else ""
            raise UserError(f"{err}; {_rescue(path, image, metadata, stops, layers)}{kept}") from None
        if checkpoint is not None and not result.interrupted:
            checkpoint.path.unlink(missing_ok=True)
    return stops


def report_non_finite(path: Path, image: np.ndarray) -> int:
    """Warn on stderr, in one line, when ``image`` has NaN or infinite pixels (a scene's numbers or an
    exposure beyond float32); they are written as they are. Returns how many there are."""
    bad = int(np.count_nonzero(~np.all(np.isfinite(image), axis=-1)))
    if bad:
        pixels = image.shape[0] * image.shape[1]
        print(f"realistic: warning: {path}: {bad} of {pixels} pixels are NaN or infinite (written as they are)",
              file=sys.stderr)
    return bad


def layer_channels(result: RenderResult, photographic: Photographic | None) -> dict[str, np.ndarray]:
    """The EXR channels written beside R, G, B: the AOVs (``renderer.aov``) as they are, and for a
    denoised image the film's own as "Noisy.R", "Noisy.G", "Noisy.B", exposed as the image is."""
    layers = dict(result.aovs)
    if result.noisy is not None:
        noisy = exposed(result.noisy, photographic)
        layers.update({f"Noisy.{name}": noisy[..., index] for index, name in enumerate("RGB")})
    return layers


def _rescue(path: Path, image: np.ndarray, metadata: Metadata, stops: float,
            layers: dict[str, np.ndarray] | None = None) -> str:
    """Write the image to the temporary folder; what became of it, for the error line."""
    try:
        handle, name = tempfile.mkstemp(prefix=f"realistic-{path.stem[:64]}-", suffix=".exr")
    except OSError as err:
        return f"the rescue copy in {tempfile.gettempdir()} failed too ({err.strerror or err})"
    os.close(handle)
    rescue = Path(name)
    try:
        _write(rescue, image, metadata, stops, layers)
    except UserError as err:
        rescue.unlink(missing_ok=True)
        return f"the rescue copy failed too ({err})"
    return f"the render was saved as {rescue} (and its .png) instead"


def _write(path: Path, image: np.ndarray, metadata: Metadata, stops: float,
           layers: dict[str, np.ndarray] | None = None) -> None:
    write_exr(path, image, metadata, layers)
    write_png(path.with_suffix(".png"), image, stops)
