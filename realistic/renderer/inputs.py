"""What to render: a scene and its camera assembled from typed options (the CLI's and the API's).

``RenderOptions`` holds parsed values (numbers, tuples, paths), never command-line strings;
``build_render_inputs`` turns them into a ``Scene`` whose ``camera`` and ``light_samples`` are
ready to render, with what the image header should say about them. SCENE is a pbrt file (it
brings its own camera and film, read as the file says), a mesh file set on a grid floor
(``realistic.scene.staging``), or None for the default scene; ``apply_overrides`` then applies
the options to either, in one place.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.lens_camera import (
    AUTO_FILM,
    MM_PER_METRE,
    FilmDiagonal,
    LensCamera,
    auto_film_diagonal_mm,
    film_diagonal_value,
)
from realistic.core import validation
from realistic.core.film_geometry import film_size_mm
from realistic.core.pixel_filter import filter_name
from realistic.errors import UserError
from realistic.optics.coating import COATINGS
from realistic.optics.formats import load_lens
from realistic.optics.ghosts import DEFAULT_THRESHOLD, ghost_paths
from realistic.optics.paraxial import FasterThanLens
from realistic.optics.stop_shape import StopShape, bladed_stop, mask_stop
from realistic.renderer.integrators import INTEGRATORS
from realistic.renderer.output import OUTPUT_SUFFIXES
from realistic.renderer.passes import scene_intersector
from realistic.renderer.starburst import STARBURST_NEEDS_LENS, WAVELENGTHS_NM
from realistic.scene.intersect import Intersector
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import Scene
from realistic.scene.pbrt.dialect import Dialect
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.values import located
from realistic.scene.staging import auto_eye, default_setup, mesh_setup

MESH_DEFAULT_RES = (300, 300)
MESH_DEFAULT_SPP = 16
#: Whose default filter parameters ``--filter`` takes on a mesh scene: the newest pbrt's.
MESH_FILTER_DIALECT = Dialect("v4", "--filter on a mesh scene")
DEFAULT_LENS = "dgauss"
#: Options that only a mesh or the default scene can use (a pbrt scene places its own camera).
MESH_ONLY = {"camera_position": "--camera-pos", "target": "--target"}


@dataclass
class RenderOptions:
    """What the user asked for; None keeps the scene's own value (or the mesh scenes' default).

    Lengths: ``aperture_mm``, ``film_diagonal_mm`` and ``film_distance_mm`` in mm;
    ``focus_distance`` (``inf`` allowed), ``camera_position`` and ``target`` in scene units (metres
    for meshes and the default scene), the focus measured from the film plane.
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
    film_distance_mm: float | None = None  # rear lens vertex to film, mm (focuses as --focus does)
    focus_on: tuple[float, float] | None = None
    camera_position: np.ndarray | None = None
    target: np.ndarray | None = None
    resolution: tuple[int, int] | None = None
    film_diagonal_mm: FilmDiagonal = None  # mm, "auto" (sized to the lens), or None: the scene's (meshes: auto)
    spp: int | None = None
    light_samples: int | None = None
    integrator: str | None = None  # "directlighting" or "path" (realistic.renderer.integrators)
    max_depth: int | None = None
    lens_sampling: str = "pupil"
    dispersion: bool | None = None  # None: off for pbrt and the default scene, else on when the lens has Abbe numbers
    wavelengths_per_sample: int | None = None  # spectral renders: rays per sample (None: the camera's default)
    pbrt_dialect: str = "auto"  # pbrt scenes: which pbrt's conventions (realistic.scene.pbrt.dialect)
    pixel_filter: str | None = None  # a filter name replacing the scene's, at pbrt's default parameters
    coating: str | None = None  # every lens surface's coating (realistic.optics.coating), None: the lens's own
    flare: bool = False  # lens flare through the lens's ghost paths (realistic.renderer.flare)
    flare_threshold: float | None = None  # the least on-axis throughput of a ghost rendered (None: the default)
    starburst: bool = False  # the stop's diffraction spread around the brightest pixels (realistic.renderer.starburst)
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
        self.film_diagonal_mm = film_diagonal_value(self.film_diagonal_mm)
        if self.blades is not None:
            validation.blades(self.blades)
        if self.pixel_filter is not None:
            self.pixel_filter = filter_name(self.pixel_filter)
        if self.coating is not None and self.coating not in COATINGS:
            raise UserError(f"unknown coating {self.coating!r} (choose {', '.join(COATINGS)})")
        if self.flare_threshold is not None:
            validation.ghost_threshold(self.flare_threshold)
            if not self.flare:
                raise UserError("--flare-threshold applies with --flare on")
        if self.aperture_mm is not None:
            validation.stop_diameter_mm(self.aperture_mm)
        if self.focus_distance is not None:
            validation.focus_distance(self.focus_distance)
        if self.f_number is not None:
            validation.f_number(self.f_number)
        if self.film_distance_mm is not None:
            validation.film_distance_mm(self.film_distance_mm)
        if self.aperture_mm is not None and self.f_number is not None:
            raise UserError("--aperture and --fstop both size the stop: give one")
        focus_given = [flag for flag, value in (("--focus", self.focus_distance), ("--focus-on", self.focus_on),
                                                ("--film-distance-mm", self.film_distance_mm)) if value is not None]
        if len(focus_given) > 1:
            raise UserError(f"{' and '.join(focus_given)} each set the focus: give one")
        if not self.is_pbrt and self.search_paths:
            raise UserError("--search-path applies to pbrt scenes")
        if not self.is_pbrt and self.pbrt_dialect != "auto":
            raise UserError("--pbrt-dialect applies to pbrt scenes")

    @property
    def is_pbrt(self) -> bool:
        return self.scene is not None and self.scene.lower().endswith((".pbrt", ".pbrt.gz"))

    def stop_shape(self) -> StopShape | None:
        """The stop's shape the blade or mask options ask for (None: the lens's own)."""
        if self.blades is not None and self.aperture_mask:
            raise UserError("--blades and --aperture-mask both shape the stop: give one")
        if self.blades is not None:
            return bladed_stop(self.blades, self.blade_rotation_deg, self.blade_curvature)
        return mask_stop(self.aperture_mask) if self.aperture_mask else None


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
    intersector: Intersector | None = None
    flare: bool = False  # render lens flare (``RenderJob.flare``), through ghosts of at least this throughput:
    flare_threshold: float = DEFAULT_THRESHOLD
    starburst: bool = False  # the finished image gets the stop's diffraction starburst (``RenderJob.starburst``)

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
    per pixel and pixel filter, the lens (a pbrt scene's camera keeps its pose), the film, the stop,
    sampling and focus (through the cameras' ``with_lens``, ``with_stop`` and ``with_focus``, as
    the API calls them), the light samples, integrator and depth, and dispersion. Each value was
    checked once, in ``RenderOptions``."""
    if options.is_pbrt:
        given = [flag for name, flag in MESH_ONLY.items() if getattr(options, name) is not None]
        if given:
            raise UserError(f"{', '.join(given)} apply to mesh scenes; {options.scene} places its own camera")
    scene = inputs.scene
    camera = inputs.camera
    if options.resolution is not None:
        camera = dataclasses.replace(camera, width=options.resolution[0], height=options.resolution[1])
    if options.spp is not None:
        camera = dataclasses.replace(camera, spp=options.spp)
    if options.pixel_filter is not None:  # at the default parameters of the scene's pbrt
        camera = dataclasses.replace(camera, pixel_filter=inputs.filter_dialect.pixel_filter(options.pixel_filter))
    with located(inputs.camera_where) if inputs.camera_where else contextlib.nullcontext():
        if options.is_pbrt:
            camera = _lens_and_film(inputs, camera, options)
        shape = options.stop_shape()
        if options.aperture_mm is not None or options.f_number is not None or shape is not None:
            camera = _with_stop(camera, options, shape, inputs.warnings)
        if isinstance(camera, LensCamera):
            camera = dataclasses.replace(camera, lens_sampling=options.lens_sampling)
        if options.coating is not None:
            if not isinstance(camera, LensCamera):
                raise UserError("--coating needs a real lens (--lens)")
            camera = camera.with_coating(options.coating)
        if options.flare:
            camera = _flare_camera(camera, options, inputs)
        if options.starburst:
            if not isinstance(camera, LensCamera):
                raise UserError(STARBURST_NEEDS_LENS)
            inputs.starburst = True
            inputs.metadata["starburst"] = f"stop diffraction at {', '.join(f'{w:g}' for w in WAVELENGTHS_NM)} nm"
        if options.focus_distance is not None:
            camera = camera.with_focus(options.focus_distance)
        if options.film_distance_mm is not None:
            if not isinstance(camera, LensCamera):
                raise UserError('--film-distance-mm needs a real lens (--lens): Camera "perspective" has none')
            camera = dataclasses.replace(camera, film_distance_mm=options.film_distance_mm)
    if options.light_samples is not None:
        scene.light_samples = options.light_samples
    if options.integrator is not None:
        scene.integrator = options.integrator
    if options.max_depth is not None:
        scene.max_depth = options.max_depth
    if options.focus_on is not None:
        x, y = options.focus_on
        inputs.intersector = scene_intersector(scene)  # the render reuses it (``passes.ThreadPasses``)
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
    if isinstance(camera, LensCamera):
        coverage = camera.coverage_warning()
        if coverage is not None:
            inputs.warnings.append(coverage)
    scene.camera = camera
    scene.metadata = inputs.metadata
    return inputs


def _flare_camera(camera: Camera, options: RenderOptions, inputs: RenderInputs) -> LensCamera:
    """The camera of a render with lens flare, which ``inputs`` now asks for: a real lens, and
    under the ``ideal`` coating (which reflects nothing, so has no ghosts) one with bare surfaces
    unless ``--coating`` was given, with a line saying so."""
    if not isinstance(camera, LensCamera):
        raise UserError("--flare on needs a real lens (--lens): a thin-lens or perspective camera has no ghosts")
    inputs.flare = True
    if options.flare_threshold is not None:
        inputs.flare_threshold = options.flare_threshold
    inputs.metadata["flare"] = f"ghosts >= {inputs.flare_threshold:g}"  # the image header says how it was made
    if options.coating is None and set(camera.lens.coating) == {"ideal"}:
        inputs.warnings.append("--flare on: the ideal coating reflects nothing, so its lens has no ghosts: rendering "
                               "with --coating none (bare glass; --coating mgf2 for coated surfaces)")
        camera = camera.with_coating("none")
    ghosts = ghost_paths(camera.lens, threshold=0.0)
    if ghosts and ghosts[0].throughput < inputs.flare_threshold:
        inputs.warnings.append(f"--flare on: no ghost of {camera.lens.name} reaches the threshold "
                               f"{inputs.flare_threshold:g} (the brightest carries {ghosts[0].throughput:.2g} of the "
                               "light): lower --flare-threshold to see them")
    return camera


def _with_stop(camera: Camera, options: RenderOptions, shape: StopShape | None, warnings: list[str]) -> Camera:
    """``camera.with_stop`` with the options' stop; where ``--fstop`` asks for more than the lens
    opens, the lens's widest, with a line in ``warnings`` (a camera set to f/4 with an f/5.6 lens
    takes f/5.6; pbrt clamps an ``aperturediameter`` wider than the lens's stop alike). The API's
    ``with_stop`` refuses it."""
    try:
        return camera.with_stop(f_number=options.f_number, aperture_mm=options.aperture_mm, shape=shape)
    except FasterThanLens as err:
        warnings.append(f"--fstop {options.f_number:g} is faster than {err.lens_name} opens: f/{err.widest:.3g} is "
                        f"used")
        return camera.with_stop(f_number=err.widest, aperture_mm=options.aperture_mm, shape=shape)


def _lens_and_film(inputs: RenderInputs, camera: Camera, options: RenderOptions) -> Camera:
    """A pbrt scene's camera with the lens and film the options give (``with_lens``: same pose);
    where a new lens leaves most of the scene's film outside its image circle, the film is sized
    to the lens, and a line says so."""
    if options.lens is None:
        if options.film_diagonal_mm is None:
            return camera
        if not isinstance(camera, LensCamera):
            raise UserError('--film-diagonal needs a real lens (--lens): Camera "perspective" has a field of view, '
                            "not a film")
        return camera.with_film(options.film_diagonal_mm)
    replaced = camera.with_lens(options.lens, film_diagonal_mm=options.film_diagonal_mm)
    if (options.film_diagonal_mm is None and isinstance(camera, LensCamera) and isinstance(replaced, LensCamera)
            and replaced.film_diagonal_mm != camera.film_diagonal_mm):
        inputs.warnings.append(f"the scene's {camera.film_diagonal_mm:g} mm film lies mostly outside the image "
                               f"circle of {replaced.lens.name}: the film is sized to the lens "
                               f"({replaced.film_diagonal_mm:.3g} mm; --film-diagonal sets it)")
    return replaced


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
    lens = load_lens(options.lens or DEFAULT_LENS)
    film = options.film_diagonal_mm
    film_diagonal = auto_film_diagonal_mm(lens) if film is None or film == AUTO_FILM else float(film)
    setup = mesh_setup(load_mesh_file(options.scene)) if options.scene else default_setup()
    target = setup.target if options.target is None else options.target
    eye = options.camera_position
    if eye is None:
        film_short_mm = min(film_size_mm(film_diagonal, width, height))
        eye = setup.eye if setup.eye is not None and options.target is None else auto_eye(setup, lens, film_short_mm)
    # focused on the target, or (when the options give a focus, which apply_overrides sets) at infinity,
    # which every lens reaches however near the target is
    focus = None if options.focus_distance is None and options.film_distance_mm is None else math.inf
    setup.scene.camera = LensCamera.looking_at(lens, eye, target, focus, film_diagonal, width, height,
                                               MESH_DEFAULT_SPP)
    metadata = {"scene": str(options.scene or "default"), "mmPerSceneUnit": MM_PER_METRE,
                "cameraPosition": ",".join(f"{v:g}" for v in eye),
                "cameraTarget": ",".join(f"{v:g}" for v in target)}
    return RenderInputs(setup.scene, "render.exr", metadata)
