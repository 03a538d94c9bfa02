"""The ``render`` subcommand: ``python -m realistic render [MESH]`` (a thin layer over ``realistic.render``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from realistic.errors import UserError
from realistic.prescription import BUNDLED_LENSES

DESCRIPTION = """\
Render a mesh file (OBJ, PLY, STL, GLB/GLTF, OFF) standing on a grid floor under a disk light, or,
without MESH, the default scene (a row of spheres and cones receding in depth). Scene units are
metres: the mesh is scaled so its largest side is 1 m. The camera frame's origin is the film
centre (pbrt-v3 convention); --focus is the distance in metres from the film plane to the plane
in focus (thick-lens focusing), by default the distance to the target. The EXR holds the film
irradiance (float32 RGB, metadata in the header); the PNG preview beside it is sRGB.
"""


def add_render_command(commands: argparse._SubParsersAction) -> None:
    """Register ``render`` on the CLI's subcommand parser."""
    from realistic.raygen import BACKENDS

    p = commands.add_parser("render", help="render a mesh (or the default scene) through a lens",
                            description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mesh", nargs="?", metavar="MESH", help="mesh file; omit for the default scene")
    p.add_argument("--lens", default="dgauss",
                   help=f"bundled lens ({', '.join(BUNDLED_LENSES)}) or prescription file (default: %(default)s)")
    p.add_argument("--aperture", type=float, metavar="MM", help="stop diameter in mm (default: the lens file's)")
    p.add_argument("--focus", type=float, metavar="M",
                   help="focus distance in scene units (m) from the film plane (default: the target's distance)")
    p.add_argument("--camera-pos", metavar="X,Y,Z", help="film centre position in scene units (default: framed)")
    p.add_argument("--target", metavar="X,Y,Z", help="point looked at (default: the subject's centre)")
    p.add_argument("--res", default="300x300", metavar="WxH", help="resolution (default: %(default)s)")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel (default: %(default)s)")
    p.add_argument("--film-diagonal", type=float, default=43.27, metavar="MM",
                   help="film diagonal in mm (default: %(default)s, full frame)")
    p.add_argument("--out", default="render.exr", metavar="FILE.exr",
                   help="output EXR; the PNG preview is written beside it (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--exposure", type=float, metavar="EV",
                   help="PNG preview exposure in stops (default: automatic); the EXR is never scaled")
    p.add_argument("--backend", choices=BACKENDS, default="opencl",
                   help="camera ray generation: OpenCL kernel or numpy reference (default: %(default)s)")
    p.add_argument("--lens-sampling", choices=("pupil", "rear"), default="pupil",
                   help="aim camera rays at the exit-pupil bounds or the rear element (default: %(default)s)")
    p.add_argument("--cl-device", metavar="NAME", help="OpenCL device (substring of its name)")
    p.add_argument("--light-samples", type=int, default=1, help="light samples per hit (default: %(default)s)")
    p.set_defaults(run=cmd_render)


def _resolution(text: str) -> tuple[int, int]:
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


def _check_options(args: argparse.Namespace) -> None:
    if args.spp < 1:
        raise UserError(f"samples per pixel must be at least 1, got {args.spp}")
    if args.light_samples < 1:
        raise UserError(f"light samples must be at least 1, got {args.light_samples}")
    for name, value in (("aperture", args.aperture), ("focus", args.focus), ("film diagonal", args.film_diagonal)):
        if value is not None and not (value > 0 and np.isfinite(value)):
            raise UserError(f"{name} must be a positive finite number, got {value:g}")
    if Path(args.out).suffix.lower() != ".exr":
        raise UserError(f"{args.out}: the output must be an .exr file (the PNG preview goes beside it)")


def cmd_render(args: argparse.Namespace) -> int:
    from realistic.image_io import auto_exposure, check_writable, write_exr, write_png
    from realistic.meshes import load_mesh_file
    from realistic.paraxial import focus_distance_for_film, paraxial_data
    from realistic.prescription import load_lens
    from realistic.render import render_passes
    from realistic.setups import MM_PER_UNIT, auto_eye, camera_for_view, default_setup, mesh_setup

    _check_options(args)
    width, height = _resolution(args.res)
    eye, target = _vector(args.camera_pos, "camera position"), _vector(args.target, "target")
    out = Path(args.out)
    png = out.with_suffix(".png")
    check_writable(out)
    check_writable(png)
    lens = load_lens(args.lens)
    if args.aperture:
        lens = lens.with_stop_diameter(args.aperture)
    setup = mesh_setup(load_mesh_file(args.mesh)) if args.mesh else default_setup()
    target = setup.target if target is None else target
    if eye is None:
        film_short_mm = args.film_diagonal * min(width, height) / np.hypot(width, height)
        eye = setup.eye if setup.eye is not None and args.target is None else auto_eye(setup, lens, film_short_mm)
    camera = camera_for_view(lens, eye, target, args.focus, args.film_diagonal, width, height, args.spp,
                             args.lens_sampling)
    result = render_passes(setup.scene, camera, args.backend, args.seed, args.cl_device, args.light_samples,
                           progress=True)
    focus_mm = focus_distance_for_film(lens, camera.film_distance_mm)
    metadata = {
        "lens": lens.name, "lensSource": lens.source, "apertureDiameterMm": float(lens.stop_diameter_mm),
        "fNumber": float(paraxial_data(lens).f_number), "focusDistanceMm": float(focus_mm),
        "focusDistanceSceneUnits": float(focus_mm / MM_PER_UNIT), "mmPerSceneUnit": MM_PER_UNIT,
        "filmDistanceMm": float(camera.film_distance_mm), "filmDiagonalMm": float(args.film_diagonal),
        "spp": int(args.spp), "seed": int(args.seed), "lightSamples": int(args.light_samples),
        "backend": args.backend, "lensSampling": args.lens_sampling, "renderSeconds": float(result.seconds),
        "samplesDone": int(result.samples_done), "samplesTotal": int(result.samples_total),
        "interrupted": int(result.interrupted), "scene": str(args.mesh or "default"),
        "cameraPosition": ",".join(f"{v:g}" for v in eye), "cameraTarget": ",".join(f"{v:g}" for v in target),
    }
    write_exr(out, result.image, metadata)
    exposure = auto_exposure(result.image) if args.exposure is None else args.exposure
    write_png(png, result.image, exposure)
    rays = result.primary_rays + result.shadow_rays
    summary = (f"{out} and {png}: {width}x{height}, {args.spp} spp, {result.seconds:.1f} s, "
               f"{rays / max(result.seconds, 1e-9) / 1e6:.2f} M rays/s, preview exposure {exposure:+.2f} EV")
    if result.interrupted:
        print(f"realistic: interrupted: wrote the {result.samples_done} of {result.samples_total} samples "
              f"taken to {out}", file=sys.stderr)
        return 130
    print(summary)
    return 0
