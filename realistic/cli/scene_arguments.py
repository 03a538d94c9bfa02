"""The arguments that choose what to render, shared by ``render`` and ``bench``, and their
conversion into the library's ``RenderOptions`` (the CLI builds no scene itself)."""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from realistic.camera.base import BACKENDS
from realistic.camera.lens_camera import AUTO_FILM, LENS_SAMPLINGS, film_diagonal_value
from realistic.cli.values import LENS_HELP, checked, parse_pixel, parse_resolution, parse_vector
from realistic.core import validation
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.core.input_files import input_file
from realistic.core.pixel_filter import FILTER_ALIASES, FILTER_NAMES, filter_name
from realistic.core.spectrum import DEFAULT_WAVELENGTHS_PER_SAMPLE
from realistic.core.validation import finite
from realistic.optics.coating import COATINGS
from realistic.optics.ghosts import DEFAULT_THRESHOLD
from realistic.renderer.memory import parse_size
from realistic.scene.pbrt.dialect import DIALECTS

if TYPE_CHECKING:
    from realistic.renderer.inputs import RenderOptions


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments that choose what to render (shared by ``render`` and ``bench``)."""
    parser.add_argument("scene", nargs="?", metavar="SCENE", help="pbrt scene or mesh file; omit for the default scene")
    parser.add_argument("--lens", help=f"{LENS_HELP}; on a pbrt scene it replaces the camera's lens at the same "
                                       "pose (a perspective camera's field of view is kept) (default: the scene's, "
                                       "else dgauss)")
    stop = parser.add_mutually_exclusive_group()
    stop.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                      help="stop diameter in mm (default: the scene's or lens's)")
    stop.add_argument("--fstop", type=checked(float, validation.f_number), metavar="N",
                      help="f-number: sizes the stop for this paraxial f-number (EFL / entrance pupil)")
    parser.add_argument("--blades", type=checked(int, validation.blades), metavar="N",
                        help="shape the stop as N diaphragm blades (a regular N-gon inscribed in the stop's circle; "
                             f"{validation.MIN_BLADES} to {validation.MAX_BLADES})")
    parser.add_argument("--blade-rotation", type=checked(float, partial(finite, name="blade rotation")), default=0.0,
                        metavar="DEG",
                        help="turn the blades (default: 0, a corner on +x)")
    parser.add_argument("--blade-curvature", type=float, default=0.0, metavar="C",
                        help="bow the blades: 0 straight (default) to 1 round")
    parser.add_argument("--aperture-mask", metavar="IMAGE",
                        help="shape the stop by an image (PNG, EXR...) spanning its diameter; level >= 0.5 is open")
    focus = parser.add_mutually_exclusive_group()
    focus.add_argument("--focus", type=checked(float, validation.focus_distance), metavar="DIST",
                       help="focus distance in scene units (metres for meshes and the default scene) from the film "
                            "plane, or inf (default: the target's or the scene's)")
    focus.add_argument("--film-distance-mm", type=checked(float, validation.film_distance_mm), metavar="MM",
                       help="rear lens vertex to film distance in mm, instead of --focus")
    focus.add_argument("--focus-on", metavar="X,Y",
                       help="autofocus on what the pixel (X, Y) sees: its depth, then a real-ray search for "
                            "the sharpest film distance")
    parser.add_argument("--camera-pos", metavar="X,Y,Z", help="mesh scenes: film centre position (default: framed)")
    parser.add_argument("--target", metavar="X,Y,Z",
                        help="mesh scenes: point looked at (default: the subject's centre)")
    parser.add_argument("--res", metavar="WxH",
                        help=f"resolution, each side 1 to {validation.MAX_IMAGE_SIDE} "
                             "(default: the scene's, else 300x300)")
    parser.add_argument("--film-diagonal", type=checked(_film_diagonal_text, film_diagonal_value), metavar="MM|auto",
                        help="film diagonal in mm, or auto: the lens's image circle, at most "
                             f"{FULL_FRAME_DIAGONAL_MM} mm (full frame) (default: a pbrt scene's film, else auto; "
                             "auto also where a new --lens leaves most of a pbrt scene's film dark)")
    parser.add_argument("--search-path", action="append", default=[], metavar="DIR",
                        help="pbrt scenes: where else to look for files the scene names (meshes, textures, "
                             "Includes, lenses), after the scene's own folder; repeatable")
    parser.add_argument("--seed", type=checked(int, validation.seed), default=0,
                        help=f"random seed, 0 to {validation.MAX_SEED} (default: %(default)s)")
    parser.add_argument("--backend", choices=BACKENDS, default="opencl",
                        help="camera rays and direct-lighting shading: OpenCL kernels or numpy references "
                             "(default: %(default)s)")
    parser.add_argument("--lens-sampling", choices=LENS_SAMPLINGS, default="pupil",
                        help="aim camera rays at the exit-pupil bounds or the rear element (default: %(default)s)")
    parser.add_argument("--cl-device", metavar="NAME", help="OpenCL device (substring of its name, or an index)")
    parser.add_argument("--light-samples", type=checked(int, validation.light_samples), metavar="N",
                        help=f"light samples per hit, 1 to {validation.MAX_LIGHT_SAMPLES} "
                             "(default: the scene's, else 1)")
    parser.add_argument("--integrator", choices=("directlighting", "path"),
                        help="directlighting (light and BSDF samples combined by MIS; specular bounces followed) "
                             "or path (path tracing with next-event estimation, MIS and Russian roulette) "
                             "(default: the pbrt scene's Integrator, else directlighting)")
    parser.add_argument("--maxdepth", type=checked(int, validation.max_depth), metavar="N",
                        help=f"bounces of a path, 0 to {validation.MAX_DEPTH} (default: the scene's, else 5)")
    parser.add_argument("--pbrt-dialect", choices=DIALECTS, default="auto",
                        help="pbrt scenes: read with this pbrt version's conventions (texture orientation); auto "
                             "decides from the directives and parameters the file uses (default: %(default)s)")
    parser.add_argument("--filter", type=checked(str, filter_name), metavar="NAME",
                        help=f"pixel filter ({', '.join(FILTER_NAMES + tuple(FILTER_ALIASES))}) with pbrt's default "
                             "parameters (the pbrt scene's version's; pbrt-v4's for other scenes), replacing the "
                             "scene's (default: the pbrt scene's PixelFilter or its version's default; a 0.5-pixel "
                             "box for other scenes)")
    parser.add_argument("--max-memory", type=checked(str, parse_size), metavar="SIZE",
                        help="refuse renders estimated to need more memory than this, e.g. 8G or 512M "
                             "(default: the memory the system has available)")
    parser.add_argument("--dispersion", choices=("on", "off"),
                        help="spectral rendering with the glasses' dispersion (default: off for pbrt scenes, as "
                             "pbrt renders them, and the default scene; for meshes on when the lens has Abbe numbers)")
    parser.add_argument("--coating", choices=COATINGS,
                        help="lens surfaces' coating: ideal transmits everything, none loses the Fresnel "
                             "reflection of bare glass at each surface, mgf2 a single-layer quarter-wave MgF2 "
                             "anti-reflection coating on each glass-air surface (default: ideal)")
    parser.add_argument("--flare", choices=("on", "off"), default="off",
                        help="lens flare: light traced from the lights through the lens's ghosts (two reflections "
                             "inside the lens) to the film; a coating other than ideal is needed, and none is used "
                             "unless --coating is given (default: %(default)s)")
    parser.add_argument("--flare-threshold", type=checked(float, validation.ghost_threshold), metavar="T",
                        help="with --flare on: render the ghosts whose on-axis throughput is at least T, a "
                             f"fraction of the light, 0 to 1 (default: {DEFAULT_THRESHOLD:g})")
    parser.add_argument("--starburst", choices=("on", "off"), default="off",
                        help="the diffraction starburst of the aperture blades: the stop's diffraction pattern "
                             "(at 610, 550 and 465 nm) spread around the pixels above the metered exposure's white, "
                             "light moved, not added; needs a real lens (default: %(default)s)")
    parser.add_argument("--wavelengths-per-sample", type=checked(int, validation.wavelengths_per_sample), metavar="K",
                        help="spectral renders: trace each camera sample at K wavelengths, one per 1/K of the "
                             "wavelength density, sharing its film, lens and light samples (less colour noise, "
                             f"K times the camera rays), 1 to {validation.MAX_WAVELENGTHS_PER_SAMPLE} "
                             f"(default: {DEFAULT_WAVELENGTHS_PER_SAMPLE})")


def _film_diagonal_text(text: str) -> float | str:
    """``--film-diagonal``'s text: ``auto``, else a number (``film_diagonal_value`` checks it)."""
    return AUTO_FILM if text.strip().lower() == AUTO_FILM else float(text)


def options_from_args(args: argparse.Namespace, spp: int | None) -> RenderOptions:
    """The parsed command line as ``RenderOptions``; ``spp`` None keeps the scene's own."""
    from realistic.renderer.inputs import RenderOptions  # the renderer loads only when a command runs

    scene = "scene file" if args.scene and args.scene.lower().endswith((".pbrt", ".pbrt.gz")) else "mesh file"
    for path, what in ((args.scene, scene), (args.aperture_mask, "aperture mask image")):
        if path:
            input_file(path, what)  # a FIFO would block, a directory is no scene: each says what it is
    return RenderOptions(
        scene=args.scene, lens=args.lens, aperture_mm=args.aperture, f_number=args.fstop, blades=args.blades,
        blade_rotation_deg=args.blade_rotation, blade_curvature=args.blade_curvature,
        aperture_mask=args.aperture_mask, focus_distance=args.focus, film_distance_mm=args.film_distance_mm,
        focus_on=parse_pixel(args.focus_on) if args.focus_on else None,
        camera_position=parse_vector(args.camera_pos, "camera position") if args.camera_pos else None,
        target=parse_vector(args.target, "target") if args.target else None,
        resolution=parse_resolution(args.res) if args.res else None, film_diagonal_mm=args.film_diagonal,
        spp=spp, light_samples=args.light_samples, integrator=args.integrator, max_depth=args.maxdepth,
        lens_sampling=args.lens_sampling,
        dispersion=None if args.dispersion is None else args.dispersion == "on",
        wavelengths_per_sample=args.wavelengths_per_sample,
        search_paths=[Path(p) for p in args.search_path], pbrt_dialect=args.pbrt_dialect,
        pixel_filter=args.filter, coating=args.coating, flare=args.flare == "on", flare_threshold=args.flare_threshold,
        starburst=args.starburst == "on")
