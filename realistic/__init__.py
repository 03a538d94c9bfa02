"""realistic: a physically based renderer whose camera is a real multi-element lens.

The Python API, in the order a script uses it::

    import realistic as rl

    scene = rl.load_scene("dragon.ply")     # a mesh on a grid floor, lit, framed by scene.camera
    image = rl.render(scene, spp=16)        # (H, W, 3) float32 film irradiance
    camera = rl.LensCamera.looking_at(rl.load_lens("telephoto"), eye=(4, 1, 4), target=(0, 0.3, 0),
                                      width=320, height=240)
    rl.write_exr("dragon.exr", rl.render(scene, camera, spp=16))
    scene = rl.load_dict({"shapes": [{"type": "sphere", "radius": 0.5}],
                          "lights": [{"type": "distant", "direction": (1, 1, 1)}],
                          "camera": {"type": "lens", "lens": "dgauss", "eye": (0, 0, 4), "target": (0, 0, 0)}})
    rl.show(rl.render(scene, spp=4))        # or leave the image last in a notebook cell

- ``load_lens(name_or_path)``: a bundled prescription (``BUNDLED_LENSES``) or a lens file.
- ``load_scene(path=None, **options)``: a pbrt scene (with its camera), a mesh file, or (None) the
  default scene; ``options`` are ``RenderOptions`` fields (``lens``, ``aperture_mm``, ``spp``...).
- ``LensCamera`` (a real lens) and ``ThinLensCamera`` (pbrt's perspective) implement ``Camera``.
- ``PixelFilter``: pbrt's pixel filters, for a camera's ``pixel_filter`` (default: a 0.5-pixel box);
  ``load_scene(..., pixel_filter="gaussian")`` picks one by name at pbrt's defaults.
- ``load_dict(description)``: a scene and its camera from one plain dict (shapes, meshes,
  materials, lights, camera; ``realistic.renderer.from_dict`` lists the keys).
- ``render(scene, camera=None, spp=None, ...)``: the image, an ``Image``: the (H, W, 3) float32
  array that a notebook displays tone-mapped; ``show(image_or_result, exposure=None)`` draws one
  with matplotlib.
- ``render_job(RenderJob(scene, cameras, ...), executor=None, observer=None, spp=None)``: one ``RenderResult``
  (image and statistics) per camera, on ``ThreadPasses`` (threads here) or ``DaskPasses`` (a Dask
  cluster); ``RenderObserver`` reports passes, frames and previews.
- ``save(result, path, photographic=None)``: the EXR and PNG the ``render`` command writes (header,
  ``Photographic`` exposure, rescue to the temporary folder); ``write_exr(path, image, metadata=None)``
  and ``read_exr(path)`` write and read bare images.

Subpackages, lowest layer first (each may import only those above it): ``core`` (random numbers,
transforms, spectra, files), ``optics`` (the lens and its analysis), ``camera``, ``scene`` (model,
meshes, embree, pbrt import), ``renderer`` (passes, shading, film), ``cli``. Names are loaded on first
use, so ``import realistic`` stays fast.
"""

from __future__ import annotations

import importlib
import warnings
from typing import TYPE_CHECKING, Any

from realistic.core.version import __version__ as __version__
from realistic.errors import LensFileError, UserError

#: Public name -> module that defines it (imported on first use).
_EXPORTS = {
    "BUNDLED_LENSES": "realistic.optics.formats",
    "load_lens": "realistic.optics.formats",
    "parse_prescription": "realistic.optics.formats.pbrt_dat",
    "LensSystem": "realistic.optics.lens",
    "Camera": "realistic.camera.base",
    "LensCamera": "realistic.camera.lens_camera",
    "ThinLensCamera": "realistic.camera.thin_lens",
    "PixelFilter": "realistic.core.pixel_filter",
    "Scene": "realistic.scene.model",
    "RenderOptions": "realistic.renderer.inputs",
    "RenderJob": "realistic.renderer.job",
    "RenderObserver": "realistic.renderer.job",
    "RenderResult": "realistic.renderer.job",
    "Checkpointing": "realistic.renderer.job",
    "ThreadPasses": "realistic.renderer.passes",
    "DaskPasses": "realistic.renderer.farm",
    "Image": "realistic.renderer.image",
    "show": "realistic.renderer.image",
    "load_dict": "realistic.renderer.from_dict",
    "Photographic": "realistic.renderer.output",
    "save": "realistic.renderer.output",
    "write_exr": "realistic.core.image_files",
    "read_exr": "realistic.core.image_files",
}

__all__ = ["BUNDLED_LENSES", "Camera", "Checkpointing", "DaskPasses", "Image", "LensCamera", "LensFileError",
           "LensSystem", "Photographic", "PixelFilter", "RenderJob", "RenderObserver", "RenderOptions", "RenderResult",
           "Scene", "ThinLensCamera", "ThreadPasses", "UserError", "load_dict", "load_lens", "load_scene",
           "parse_prescription", "read_exr", "render", "render_job", "save", "show", "write_exr"]

if TYPE_CHECKING:
    from realistic.camera.base import Camera
    from realistic.camera.lens_camera import LensCamera
    from realistic.camera.thin_lens import ThinLensCamera
    from realistic.core.image_files import read_exr, write_exr
    from realistic.core.pixel_filter import PixelFilter
    from realistic.optics.formats import BUNDLED_LENSES, load_lens
    from realistic.optics.formats.pbrt_dat import parse_prescription
    from realistic.optics.lens import LensSystem
    from realistic.renderer.farm import DaskPasses
    from realistic.renderer.from_dict import load_dict
    from realistic.renderer.image import Image, show
    from realistic.renderer.inputs import RenderOptions
    from realistic.renderer.job import Checkpointing, PassExecutor, RenderJob, RenderObserver, RenderResult
    from realistic.renderer.output import Photographic, save
    from realistic.renderer.passes import ThreadPasses
    from realistic.scene.model import Scene


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'realistic' has no attribute {name!r}")
    module, _, attribute = _EXPORTS[name].partition(":")
    value = getattr(importlib.import_module(module), attribute or name)
    globals()[name] = value
    return value


def load_scene(path: str | None = None, **options: Any) -> Scene:
    """The scene at ``path`` (pbrt file or mesh; None: the default scene), with ``Scene.camera`` and
    ``Scene.light_samples`` set as the file and ``options`` (``RenderOptions`` fields) say.

    What a pbrt file asks for that cannot be honoured is reported once each as a ``UserWarning``.
    """
    from realistic.renderer.inputs import RenderOptions, build_render_inputs

    inputs = build_render_inputs(RenderOptions(scene=None if path is None else str(path), **options))
    for message in inputs.warnings:
        warnings.warn(message, stacklevel=2)
    return inputs.scene


def render(scene: Scene, camera: Camera | None = None, backend: str = "opencl", seed: int = 0, *,
           spp: int | None = None, client: Any = None, threads: int | None = None, pin_threads: bool = False,
           task_samples: int | None = None, **job: Any) -> Image:
    """The film image (H, W, 3) float32: film irradiance per pixel in units of scene radiance, as an
    ``Image`` (an ndarray that a notebook displays tone-mapped).

    ``camera`` None renders through the scene's own camera (``Scene.camera``: a pbrt file's, or the
    framing of a loaded mesh); ``spp`` overrides the camera's samples per pixel. ``client`` (a
    ``dask.distributed.Client``) renders on its workers in tasks of about ``task_samples`` samples,
    bit-identically; else ``threads`` threads here (None: one per core), each kept on one CPU when
    ``pin_threads``. ``job`` takes the other ``RenderJob`` fields (``light_samples``, the scene's by
    default; ``pass_samples``, ``cl_device``, ``max_memory_bytes``, ...). A spectral camera renders
    through the colour matching functions to linear sRGB (``realistic.core.spectrum``), each sample
    the mean of its ``wavelengths_per_sample`` rays; others render RGB directly.
    ``render_job`` returns the statistics too.
    """
    from realistic.renderer.image import Image
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import ThreadPasses

    camera = camera if camera is not None else scene.camera
    if camera is None:
        raise UserError("no camera: pass one, or load a scene that brings its own")
    if client is not None:
        from realistic.renderer.farm import DaskPasses

        executor: PassExecutor = DaskPasses(client, task_samples)
    else:
        executor = ThreadPasses(threads, pin_threads)
    return Image.of(render_job(RenderJob(scene, (camera,), backend, seed, **job), executor, spp=spp)[0].image)


def render_job(job: RenderJob, executor: PassExecutor | None = None, observer: RenderObserver | None = None, *,
               spp: int | None = None) -> list[RenderResult]:
    """Every frame of ``job`` rendered on ``executor`` (None: ``ThreadPasses()``), one ``RenderResult``
    each, as ``realistic.renderer.passes.render`` explains; ``spp`` overrides every camera's samples
    per pixel."""
    import dataclasses

    from realistic.core import validation
    from realistic.renderer.passes import render as run

    if spp is not None:
        spp = validation.samples_per_pixel(spp)
        job = dataclasses.replace(job, cameras=tuple(dataclasses.replace(camera, spp=spp) for camera in job.cameras))
    return run(job, executor, observer)
