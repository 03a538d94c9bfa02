"""What to render: a scene and its camera assembled from typed options (the CLI's and the API's).

``RenderOptions`` holds parsed values (numbers, tuples, paths), never command-line strings;
``build_render_inputs`` turns them into a ``Scene`` whose ``camera`` and ``light_samples`` are
ready to render, with what the image header should say about them. SCENE is a pbrt file (it
brings its own camera and film, read as the file says), a mesh file set on a grid floor
(``realistic.scene.staging``), or None for the default scene; ``apply_overrides`` then applies
the options to either, in one place.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.lens_camera import MM_PER_METRE, LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.core import validation
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM, film_size_mm
from realistic.core.pixel_filter import filter_name
from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.lens import LensSystem
from realistic.optics.paraxial import stop_diameter_for_f_number
from realistic.optics.stop_shape import bladed_stop, mask_stop
from realistic.renderer.integrators import INTEGRATORS
from realistic.renderer.output import OUTPUT_SUFFIXES
from realistic.scene.intersect import Intersector
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import Scene
from realistic.scene.pbrt.dialect import Dialect
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.staging import auto_eye, default_setup, mesh_setup

MESH_DEFAULT_RES = (300, 300)
MESH_DEFAULT_SPP = 16
#: Whose default filter parameters ``--filter`` takes on a mesh scene: the newest pbrt's.
MESH_FILTER_DIALECT = Dialect("v4", "--filter on a mesh scene")
DEFAULT_LENS = "dgauss"
#: Options that only a mesh or the default scene can use (a pbrt scene sets its own camera).
MESH_ONLY = {"lens": "--lens", "camera_position": "--camera-pos", "target": "--target",
             "film_diagonal_mm": "--film-diagonal"}


@dataclass
class RenderOptions:
    """What the user asked for; None keeps the scene's own value (or the mesh scenes' default).

    Lengths: ``aperture_mm`` and ``film_diagonal_mm`` in mm; ``focus_distance``, ``camera_position``
    and ``target`` in scene units (metres for meshes and the default scene), the focus measured
    from the film plane.
    """

    scene: str | None = None  # (the Python API may pass an os.PathLike: ``__post_init__`` makes it a str)
    lens: str | None = None
    aperture_mm: float | None = None
    f_number: float | None = None
    blades: int | None = None
    blade_rotation_deg: float = 0.0
    blade_curvature: float = 0.0
    aperture_mask: str | None = None
    focus_distance: float | None = None
    focus_on: tuple[float, float] | None = None
    camera_position: np.ndarray | None = None
    target: np.ndarray | None = None
    resolution: tuple[int, int] | None = None
    film_diagonal_mm: float | None = None
    spp: int | None = None
    light_samples: int | None = None
    integrator: str | None = None  # "directlighting" or "path" (realistic.renderer.integrators)
    max_depth: int | None = None
    lens_sampling: str = "pupil"
    dispersion: bool | None = None  # None: off for pbrt and the default scene, else on when the lens has Abbe numbers
    wavelengths_per_sample: int | None = None  # spectral renders: rays per sample (None: the camera's default)
    pbrt_dialect: str = "auto"  # pbrt scenes: which pbrt's conventions (realistic.scene.pbrt.dialect)
    pixel_filter: str | None = None  # a filter name replacing the scene's, at pbrt's default parameters
    search_paths: list[Path] = field(default_factory=list)  # (str folders too: made Paths)

    def __post_init__(self) -> None:
        """Each value through its one check (``realistic.core.validation``), as the CLI's are."""
        # the Python API may pass str or os.PathLike where the CLI passes Path
        self.scene = None if self.scene is None else str(self.scene)
        self.search_paths = [Path(folder) for folder in self.search_paths]
        if self.spp is not None:
            validation.samples_per_pixel(self.spp)
        if self.light_samples is not None:
            validation.light_samples(self.light_samples)
        if self.wavelengths_per_sample is not None:
            validation.wavelengths_per_sample(self.wavelengths_per_sample)
        if self.integrator is not None and self.integrator not in INTEGRATORS:
            raise UserError(f"unknown integrator {self.integrator!r} (choose {', '.join(INTEGRATORS)})")
        if self.max_depth is not None:
            validation.max_depth(self.max_depth)
        if self.resolution is not None:
            validation.resolution(*self.resolution)
        if self.film_diagonal_mm is not None:
            validation.film_diagonal_mm(self.film_diagonal_mm)
        if self.blades is not None:
            validation.blades(self.blades)
        if self.pixel_filter is not None:
            self.pixel_filter = filter_name(self.pixel_filter)
        if self.aperture_mm is not None:
            validation.stop_diameter_mm(self.aperture_mm)
        for name, value in (("focus distance", self.focus_distance), ("f-number", self.f_number)):
            if value is not None:
                validation.positive_length(value, name)
        if self.aperture_mm is not None and self.f_number is not None:
            raise UserError("--aperture and --fstop both size the stop: give one")
        if self.focus_distance is not None and self.focus_on is not None:
            raise UserError("--focus and --focus-on both set the focus: give one")
        if not self.is_pbrt and self.search_paths:
            raise UserError("--search-path applies to pbrt scenes")
        if not self.is_pbrt and self.pbrt_dialect != "auto":
            raise UserError("--pbrt-dialect applies to pbrt scenes")

    @property
    def is_pbrt(self) -> bool:
        return self.scene is not None and self.scene.lower().endswith((".pbrt", ".pbrt.gz"))

    def stop_edit(self) -> Callable[[LensSystem], LensSystem] | None:
        """The change to the lens's stop that the aperture, f-number and shape options ask for (None: none)."""
        if self.blades is not None and self.aperture_mask:
            raise UserError("--blades and --aperture-mask both shape the stop: give one")
        shape = (bladed_stop(self.blades, self.blade_rotation_deg, self.blade_curvature) if self.blades is not None
                 else mask_stop(self.aperture_mask) if self.aperture_mask else None)
        if self.aperture_mm is None and self.f_number is None and shape is None:
            return None

        def edit(lens: LensSystem) -> LensSystem:
            if self.aperture_mm is not None:
                lens = lens.with_stop_diameter(self.aperture_mm)
            if self.f_number is not None:
                lens = lens.with_stop_diameter(stop_diameter_for_f_number(lens, self.f_number))
            return lens.with_stop_shape(shape) if shape is not None else lens

        return edit


@dataclass
class RenderInputs:
    """A scene whose ``camera`` and ``light_samples`` are ready to render, the output name the
    scene suggests, what the EXR header says about them (also the scene's ``metadata``), what the
    scene could not honour, what ``apply_overrides`` needs to know of where they came from, and the
    embree scene already built for it (by ``focus_on``), if any."""

    scene: Scene
    default_out: str
    metadata: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    #: whose default parameters a pixel filter named by the user takes: the file's pbrt, or the newest
    filter_dialect: Dialect = MESH_FILTER_DIALECT
    camera_where: str = ""  # a pbrt scene's Camera directive (file:line), for errors about the camera
    mm_per_unit: float | None = None  # the scene's unit where it fixes one (meshes: metres); None: the camera's
    intersector: Intersector | None = None

    @property
    def camera(self) -> Camera:
        """The scene's camera, which both scene builders here set."""
        if self.scene.camera is None:
            raise ValueError("render inputs whose scene has no camera")
        return self.scene.camera

    @property
    def light_samples(self) -> int:
        return self.scene.light_samples


def build_render_inputs(options: RenderOptions) -> RenderInputs:
    """The scene and camera ``options`` describe, focused and made spectral as they ask."""
    if options.scene is not None and options.is_pbrt:
        return apply_overrides(_pbrt_inputs(options, options.scene), options)
    return apply_overrides(_mesh_inputs(options), options)


def apply_overrides(inputs: RenderInputs, options: RenderOptions) -> RenderInputs:
    """The user's options applied to the scene, camera and film that a scene file (or the mesh
    staging) gives, the one place they are, for every kind of scene: the film's resolution, samples
    per pixel and pixel filter, the lens's stop, sampling and focus, the light samples, integrator
    and depth, and dispersion. Each value was checked once, in ``RenderOptions``."""
    if options.is_pbrt:
        given = [flag for name, flag in MESH_ONLY.items() if getattr(options, name) is not None]
        if given:
            raise UserError(f"{', '.join(given)} apply to mesh scenes; {options.scene} sets its own camera")
    scene = inputs.scene
    camera = inputs.camera
    edit = options.stop_edit()
    if isinstance(camera, ThinLensCamera) and (edit is not None or options.focus_distance is not None):
        raise UserError(f"{inputs.camera_where}: the stop and focus options apply to realistic cameras, not "
                        f'Camera "perspective"')
    if options.resolution is not None:
        camera = dataclasses.replace(camera, width=options.resolution[0], height=options.resolution[1])
    if options.spp is not None:
        camera = dataclasses.replace(camera, spp=options.spp)
    if options.pixel_filter is not None:  # at the default parameters of the scene's pbrt
        camera = dataclasses.replace(camera, pixel_filter=inputs.filter_dialect.pixel_filter(options.pixel_filter))
    if isinstance(camera, LensCamera):
        camera = dataclasses.replace(camera, lens_sampling=options.lens_sampling)
        if edit is not None:  # the film stays where the scene's lens focused it
            camera = dataclasses.replace(camera, lens=edit(camera.lens))
        if options.focus_distance is not None:
            mm_per_unit = camera.mm_per_unit if inputs.mm_per_unit is None else inputs.mm_per_unit
            camera = camera.refocused(options.focus_distance * mm_per_unit)
    if options.light_samples is not None:
        scene.light_samples = options.light_samples
    if options.integrator is not None:
        scene.integrator = options.integrator
    if options.max_depth is not None:
        scene.max_depth = options.max_depth
    if options.focus_on is not None:
        x, y = options.focus_on
        inputs.intersector = Intersector(scene)  # the render reuses it (``passes.ThreadPasses``)
        camera = camera.autofocused(x, y, inputs.intersector.hit_distance)
        inputs.metadata["focusOn"] = np.array([x, y], np.float32)  # a V2f in the EXR header
    # a pbrt scene renders as pbrt would: dispersion only when asked for, even where a bundled lens
    # with Abbe numbers stands in for the scene's lens file; so does the default scene, which is
    # scenes/default.pbrt and renders as that file does
    pbrt_like = options.is_pbrt or not options.scene
    dispersion = False if options.dispersion is None and pbrt_like else options.dispersion
    camera = camera.with_dispersion(dispersion)
    if options.wavelengths_per_sample is not None:
        if not getattr(camera, "spectral", False):
            raise UserError("--wavelengths-per-sample applies to spectral renders (--dispersion on)")
        camera = dataclasses.replace(camera, wavelengths_per_sample=options.wavelengths_per_sample)
    scene.camera = camera
    scene.metadata = inputs.metadata
    return inputs


def _pbrt_inputs(options: RenderOptions, path: str) -> RenderInputs:
    """The pbrt file ``path``'s scene and camera as the file says (``apply_overrides`` applies the options)."""
    imported = import_pbrt(path, options.search_paths, options.pbrt_dialect)
    out = Path(imported.output_name).name if imported.output_name else "render.exr"
    if Path(out).suffix.lower() not in OUTPUT_SUFFIXES:  # pbrt-v4 writes the file named, of a type it knows
        out = str(Path(out).with_suffix(".exr"))
    metadata = {"scene": str(options.scene), "pbrtDialect": imported.dialect.describe()}
    return RenderInputs(imported.scene, out, metadata, imported.warnings, imported.dialect, imported.camera_where)


def _mesh_inputs(options: RenderOptions) -> RenderInputs:
    """A mesh file (or the default scene) staged on a floor, with a camera placed by the options that
    only these scenes take (lens, position, target, film diagonal) and framing the subject for the
    film the options ask for; ``apply_overrides`` applies the rest."""
    width, height = options.resolution or MESH_DEFAULT_RES
    film_diagonal = options.film_diagonal_mm or FULL_FRAME_DIAGONAL_MM
    lens = load_lens(options.lens or DEFAULT_LENS)
    setup = mesh_setup(load_mesh_file(options.scene)) if options.scene else default_setup()
    target = setup.target if options.target is None else options.target
    eye = options.camera_position
    if eye is None:
        film_short_mm = min(film_size_mm(film_diagonal, width, height))
        eye = setup.eye if setup.eye is not None and options.target is None else auto_eye(setup, lens, film_short_mm)
    # focused on the target, or (when the options give a focus, which apply_overrides sets) at infinity,
    # which every lens reaches however near the target is
    focus = None if options.focus_distance is None else math.inf
    setup.scene.camera = LensCamera.looking_at(lens, eye, target, focus, film_diagonal, width, height,
                                               MESH_DEFAULT_SPP)
    metadata = {"scene": str(options.scene or "default"), "mmPerSceneUnit": MM_PER_METRE,
                "cameraPosition": ",".join(f"{v:g}" for v in eye),
                "cameraTarget": ",".join(f"{v:g}" for v in target)}
    return RenderInputs(setup.scene, "render.exr", metadata, mm_per_unit=MM_PER_METRE)
