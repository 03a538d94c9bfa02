"""The ``render`` subcommand, and the scene arguments it shares with ``bench``.

``python -m realistic render [SCENE]`` renders a pbrt scene file, a mesh file (OBJ, PLY, STL,
GLB/GLTF, OFF) set on a grid floor, or, without SCENE, the default scene. A thin layer over
``realistic.render``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.prescription import BUNDLED_LENSES

DESCRIPTION = """\
SCENE is a pbrt scene file (.pbrt: the classic dof-dragons homework scenes and common simple pbrt
scenes), or a mesh file (OBJ, PLY, STL, GLB/GLTF, OFF) that is set on a grid floor under a disk
light, or nothing for the default scene (a row of spheres and cones receding in depth).

For a mesh or the default scene, scene units are metres: the mesh is scaled so its largest side
is 1 m, the camera frame's origin is the film centre (pbrt-v3 convention), and --focus is the
distance in metres from the film plane to the plane in focus (thick-lens focusing), by default
the distance to the target. A pbrt scene brings its own camera, resolution and samples: --res,
--spp, --aperture, --focus (scene units from the film) and --light-samples override it.

With --dispersion on (the default for a lens whose prescription has Abbe numbers), each camera
sample carries a wavelength, the glasses' indices follow it, and the film integrates through the
CIE 1931 colour matching functions to linear sRGB: the lens's chromatic aberration shows. Off
traces at the d line in RGB.

The EXR holds the film irradiance (float32 RGB, metadata in the header); the PNG preview beside
it is sRGB.
"""

MESH_DEFAULT_RES = (300, 300)
MESH_DEFAULT_SPP = 16
MESH_ONLY = ("lens", "camera_pos", "target", "film_diagonal")


@dataclass
class RenderInputs:
    """A scene and camera ready to render, and what the EXR header says about them."""

    scene: object
    camera: object
    light_samples: int
    default_out: str
    metadata: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments that choose what to render (shared by ``render`` and ``bench``)."""
    from realistic.raygen import BACKENDS

    p.add_argument("scene", nargs="?", metavar="SCENE", help="pbrt scene or mesh file; omit for the default scene")
    p.add_argument("--lens", help=f"mesh scenes: bundled lens ({', '.join(BUNDLED_LENSES)}) or prescription file "
                                  "(default: dgauss)")
    stop = p.add_mutually_exclusive_group()
    stop.add_argument("--aperture", type=float, metavar="MM", help="stop diameter in mm (default: the scene's or lens's)")
    stop.add_argument("--fstop", type=float, metavar="N",
                      help="f-number: sizes the stop for this paraxial f-number (EFL / entrance pupil)")
    p.add_argument("--blades", type=int, metavar="N",
                   help="shape the stop as N diaphragm blades (a regular N-gon inscribed in the stop's circle)")
    p.add_argument("--blade-rotation", type=float, default=0.0, metavar="DEG",
                   help="turn the blades (default: 0, a corner on +x)")
    p.add_argument("--blade-curvature", type=float, default=0.0, metavar="C",
                   help="bow the blades: 0 straight (default) to 1 round")
    p.add_argument("--aperture-mask", metavar="IMAGE",
                   help="shape the stop by an image (PNG, EXR...) spanning its diameter; level >= 0.5 is open")
    focus = p.add_mutually_exclusive_group()
    focus.add_argument("--focus", type=float, metavar="DIST",
                       help="focus distance in scene units from the film plane (default: the target's or the scene's)")
    focus.add_argument("--focus-on", metavar="X,Y",
                       help="autofocus on what the pixel (X, Y) sees: its depth, then a real-ray search for "
                            "the sharpest film distance")
    p.add_argument("--camera-pos", metavar="X,Y,Z", help="mesh scenes: film centre position (default: framed)")
    p.add_argument("--target", metavar="X,Y,Z", help="mesh scenes: point looked at (default: the subject's centre)")
    p.add_argument("--res", metavar="WxH", help="resolution (default: the scene's, else 300x300)")
    p.add_argument("--film-diagonal", type=float, metavar="MM",
                   help="mesh scenes: film diagonal in mm (default: 43.27, full frame)")
    p.add_argument("--search-path", action="append", default=[], metavar="DIR",
                   help="pbrt scenes: where else to look for files the scene names (meshes, textures, "
                        "Includes, lenses), after the scene's own folder; repeatable")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--backend", choices=BACKENDS, default="opencl",
                   help="camera ray generation: OpenCL kernel or numpy reference (default: %(default)s)")
    p.add_argument("--lens-sampling", choices=("pupil", "rear"), default="pupil",
                   help="aim camera rays at the exit-pupil bounds or the rear element (default: %(default)s)")
    p.add_argument("--cl-device", metavar="NAME", help="OpenCL device (substring of its name, or an index)")
    p.add_argument("--light-samples", type=int, help="light samples per hit (default: the scene's, else 1)")
    p.add_argument("--dispersion", choices=("on", "off"),
                   help="spectral rendering with the glasses' dispersion (default: on when the lens has "
                        "Abbe numbers)")


def add_render_command(commands: argparse._SubParsersAction) -> None:
    """Register ``render`` on the CLI's subcommand parser."""
    p = commands.add_parser("render", help="render a pbrt scene, a mesh, or the default scene through a lens",
                            description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(p)
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's, else 16)")
    p.add_argument("--out", metavar="FILE.exr",
                   help="output EXR; the PNG preview is written beside it (default: the scene's film "
                        "file name, else render.exr)")
    p.add_argument("--exposure", type=float, metavar="EV",
                   help="PNG preview exposure in stops (default: automatic, or 0 with --shutter/--iso)")
    p.add_argument("--shutter", metavar="SECONDS",
                   help="shutter time (e.g. 1/125): with --iso, the EXR holds a photographic exposure, "
                        "calibrated so a metered middle grey reads 0.18, instead of film irradiance")
    p.add_argument("--iso", type=float, help="ISO speed (default with --shutter: 100)")
    p.set_defaults(run=cmd_render)


def parse_resolution(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise UserError(f"resolution {text!r} is not WIDTHxHEIGHT (e.g. 640x480)")
    width, height = int(parts[0]), int(parts[1])
    if width < 1 or height < 1:
        raise UserError(f"resolution must be at least 1x1, got {text}")
    return width, height


def _vector(text: str | None, name: str) -> np.ndarray | None:
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        values = np.array([])
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise UserError(f"{name} {text!r} is not three finite numbers X,Y,Z")
    return values


def check_scene_options(args: argparse.Namespace, spp: int | None) -> None:
    if spp is not None and spp < 1:
        raise UserError(f"samples per pixel must be at least 1, got {spp}")
    if args.light_samples is not None and args.light_samples < 1:
        raise UserError(f"light samples must be at least 1, got {args.light_samples}")
    for name, value in (("aperture", args.aperture), ("focus", args.focus), ("film diagonal", args.film_diagonal),
                        ("f-number", args.fstop)):
        if value is not None and not (value > 0 and np.isfinite(value)):
            raise UserError(f"{name} must be a positive finite number, got {value:g}")
    if args.scene and args.scene.lower().endswith(".pbrt"):
        given = [f"--{name.replace('_', '-')}" for name in MESH_ONLY if getattr(args, name) is not None]
        if given:
            raise UserError(f"{', '.join(given)} apply to mesh scenes; {args.scene} sets its own camera")
    elif args.search_path:
        raise UserError("--search-path applies to pbrt scenes")


def _lens_metadata(camera) -> dict:
    from realistic.camera import Camera
    from realistic.paraxial import focus_distance_for_film, paraxial_data

    if not isinstance(camera, Camera):
        return {"lens": "thin lens (pbrt perspective)", "fovDegrees": float(camera.fov_deg),
                "lensRadius": float(camera.lens_radius), "focusDistanceSceneUnits": float(camera.focal_distance)}
    lens = camera.lens
    return {"lens": lens.name, "lensSource": lens.source, "apertureDiameterMm": float(lens.stop_diameter_mm),
            "fNumber": float(paraxial_data(lens).f_number),
            "focusDistanceMm": float(focus_distance_for_film(lens, camera.film_distance_mm)),
            "filmDistanceMm": float(camera.film_distance_mm), "filmDiagonalMm": float(camera.film_diagonal_mm),
            "lensSampling": camera.lens_sampling,
            "stopShape": lens.stop_shape.describe() if lens.stop_shape else "circle"}


def _stop_edit(args: argparse.Namespace):
    """The change to the lens's stop that --aperture, --fstop, --blades... ask for (None: none)."""
    from realistic.aperture import bladed_stop, mask_stop
    from realistic.paraxial import stop_diameter_for_f_number

    if args.blades and args.aperture_mask:
        raise UserError("--blades and --aperture-mask both shape the stop: give one")
    shape = (bladed_stop(args.blades, args.blade_rotation, args.blade_curvature) if args.blades
             else mask_stop(args.aperture_mask) if args.aperture_mask else None)
    if args.aperture is None and args.fstop is None and shape is None:
        return None

    def edit(lens):
        if args.aperture is not None:
            lens = lens.with_stop_diameter(args.aperture)
        if args.fstop is not None:
            lens = lens.with_stop_diameter(stop_diameter_for_f_number(lens, args.fstop))
        return lens.with_stop_shape(shape) if shape is not None else lens

    return edit


def _pbrt_inputs(args: argparse.Namespace, spp: int | None) -> RenderInputs:
    from realistic.pbrt_import import import_pbrt

    width, height = parse_resolution(args.res) if args.res else (None, None)
    imported = import_pbrt(args.scene, width, height, spp, args.lens_sampling, lens_edit=_stop_edit(args),
                           focus_scene_units=args.focus, search_paths=[Path(p) for p in args.search_path])
    out = Path(imported.output_name).name if imported.output_name else "render.exr"
    if Path(out).suffix.lower() != ".exr":
        out = str(Path(out).with_suffix(".exr"))
    return RenderInputs(imported.scene, imported.camera, args.light_samples or imported.light_samples, out,
                        {"scene": str(args.scene)}, imported.warnings)


def _mesh_inputs(args: argparse.Namespace, spp: int | None) -> RenderInputs:
    from realistic.meshes import load_mesh_file
    from realistic.prescription import load_lens
    from realistic.setups import MM_PER_UNIT, auto_eye, camera_for_view, default_setup, mesh_setup

    width, height = parse_resolution(args.res) if args.res else MESH_DEFAULT_RES
    film_diagonal = args.film_diagonal or 43.27
    eye, target = _vector(args.camera_pos, "camera position"), _vector(args.target, "target")
    lens = load_lens(args.lens or "dgauss")
    edit = _stop_edit(args)
    if edit is not None:
        lens = edit(lens)
    setup = mesh_setup(load_mesh_file(args.scene)) if args.scene else default_setup()
    target = setup.target if target is None else target
    if eye is None:
        film_short_mm = film_diagonal * min(width, height) / np.hypot(width, height)
        eye = setup.eye if setup.eye is not None and args.target is None else auto_eye(setup, lens, film_short_mm)
    camera = camera_for_view(lens, eye, target, args.focus, film_diagonal, width, height,
                             spp or MESH_DEFAULT_SPP, args.lens_sampling)
    metadata = {"scene": str(args.scene or "default"), "mmPerSceneUnit": MM_PER_UNIT,
                "cameraPosition": ",".join(f"{v:g}" for v in eye),
                "cameraTarget": ",".join(f"{v:g}" for v in target)}
    return RenderInputs(setup.scene, camera, args.light_samples or 1, "render.exr", metadata)


def load_render_inputs(args: argparse.Namespace, spp: int | None) -> RenderInputs:
    """The scene and camera the arguments describe; ``spp`` None keeps the scene's own."""
    check_scene_options(args, spp)
    inputs = _scene_inputs(args, spp)
    if args.focus_on:
        inputs = _autofocused(args, spp, inputs)
    return _with_dispersion(inputs, args.dispersion)


def _scene_inputs(args: argparse.Namespace, spp: int | None) -> RenderInputs:
    if args.scene and args.scene.lower().endswith(".pbrt"):
        return _pbrt_inputs(args, spp)
    return _mesh_inputs(args, spp)


def _autofocused(args: argparse.Namespace, spp: int | None, inputs: RenderInputs) -> RenderInputs:
    """The inputs again, focused where ``--focus-on`` points (``realistic.autofocus``)."""
    from realistic.autofocus import autofocus_distance_mm
    from realistic.camera import Camera

    x, y = _pixel(args.focus_on)
    if not isinstance(inputs.camera, Camera):
        raise UserError("--focus-on needs a lens camera; this scene's camera is pbrt's perspective")
    focus_mm = autofocus_distance_mm(inputs.scene, inputs.camera, x, y)
    mm_per_unit = 1.0 / float(np.linalg.norm(inputs.camera.world_from_lens[:3, 0]))
    focused = argparse.Namespace(**{**vars(args), "focus": focus_mm / mm_per_unit, "focus_on": None})
    refocused = _scene_inputs(focused, spp)
    refocused.metadata["focusOn"] = args.focus_on
    return refocused


def _pixel(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--focus-on {text!r} is not a pixel X,Y (e.g. 150,120)") from None
    return x, y


def _with_dispersion(inputs: RenderInputs, choice: str | None) -> RenderInputs:
    """Make the camera spectral as ``--dispersion`` says (``None``: when the lens has V numbers)."""
    from realistic.camera import Camera, with_spectral

    if not isinstance(inputs.camera, Camera):
        if choice == "on":
            raise UserError("--dispersion on needs a lens camera; this scene's camera is pbrt's perspective")
        return inputs
    spectral = inputs.camera.lens.has_dispersion if choice is None else choice == "on"
    inputs.camera = with_spectral(inputs.camera, spectral)
    inputs.metadata["dispersion"] = "on" if spectral else "off"
    return inputs


def report_warnings(warnings: list[str]) -> None:
    for warning in warnings:
        print(f"realistic: {warning}", file=sys.stderr)


def _photographic(image: np.ndarray, camera, args: argparse.Namespace) -> tuple[np.ndarray, dict]:
    """The film irradiance exposed for ``--shutter`` at ``--iso``, and what the header says of it."""
    from realistic.camera import Camera
    from realistic.exposure import exposure_scale, exposure_value, parse_shutter
    from realistic.paraxial import paraxial_data

    shutter = parse_shutter(args.shutter or "1/60")
    iso = args.iso if args.iso is not None else 100.0
    scale = exposure_scale(shutter, iso)
    header = {"shutterSeconds": shutter, "iso": iso, "exposureScale": scale}
    if isinstance(camera, Camera):
        header["exposureValue"] = exposure_value(paraxial_data(camera.lens).f_number, shutter)
    return (image * np.float32(scale)).astype(np.float32), header


def cmd_render(args: argparse.Namespace) -> int:
    from realistic.image_io import auto_exposure, check_writable, write_exr, write_png
    from realistic.render import render_passes

    if args.out is not None and Path(args.out).suffix.lower() != ".exr":
        raise UserError(f"{args.out}: the output must be an .exr file (the PNG preview goes beside it)")
    inputs = load_render_inputs(args, args.spp)
    report_warnings(inputs.warnings)
    out = Path(args.out or inputs.default_out)
    png = out.with_suffix(".png")
    check_writable(out)
    check_writable(png)
    camera = inputs.camera
    result = render_passes(inputs.scene, camera, args.backend, args.seed, args.cl_device, inputs.light_samples,
                           progress=True)
    metadata = {**_lens_metadata(camera), **inputs.metadata,
                "spp": int(camera.spp), "seed": int(args.seed), "lightSamples": int(inputs.light_samples),
                "backend": args.backend, "renderSeconds": float(result.seconds),
                "samplesDone": int(result.samples_done), "samplesTotal": int(result.samples_total),
                "interrupted": int(result.interrupted)}
    image = result.image
    if args.shutter or args.iso:
        image, photographic = _photographic(image, camera, args)
        metadata.update(photographic)
    write_exr(out, image, metadata)
    exposure = args.exposure if args.exposure is not None else (0.0 if args.shutter or args.iso
                                                                   else auto_exposure(image))
    write_png(png, image, exposure)
    rays = result.primary_rays + result.shadow_rays
    if result.interrupted:
        print(f"realistic: interrupted: wrote the {result.samples_done} of {result.samples_total} samples "
              f"taken to {out}", file=sys.stderr)
        return 130
    print(f"{out} and {png}: {camera.width}x{camera.height}, {camera.spp} spp, {result.seconds:.1f} s, "
          f"{rays / max(result.seconds, 1e-9) / 1e6:.2f} M rays/s, preview exposure {exposure:+.2f} EV")
    return 0
