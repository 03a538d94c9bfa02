"""The ``render`` subcommand: render a pbrt scene, a mesh or the default scene to EXR and PNG.

Argument definitions and output only; the scene and camera come from ``realistic.renderer.inputs``.
The renderer is imported when the command runs, so ``--help`` and the lens commands start fast.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from functools import partial
from pathlib import Path

import numpy as np

from realistic.camera.base import Camera
from realistic.camera.exposure import exposure_scale, exposure_value, parse_shutter
from realistic.cli.scene_arguments import add_scene_arguments, options_from_args
from realistic.cli.values import checked, positive
from realistic.core import validation
from realistic.core.atomic_files import check_writable
from realistic.core.image_files import auto_exposure, write_exr, write_png
from realistic.errors import UserError

DESCRIPTION = """\
SCENE is a pbrt scene file (.pbrt: the classic dof-dragons homework scenes and common simple pbrt
scenes), or a mesh file (OBJ, PLY, STL, GLB/GLTF, OFF) that is set on a grid floor under a disk
light, or nothing for the default scene (a row of spheres and cones receding in depth).

For a mesh or the default scene, scene units are metres: the mesh is scaled so its largest side
is 1 m, the camera frame's origin is the film centre (pbrt-v3 convention), and --focus is the
distance in metres from the film plane to the plane in focus (thick-lens focusing), by default
the distance to the target. A pbrt scene brings its own camera, resolution and samples: --res,
--spp, --aperture, --focus (scene units from the film) and --light-samples override it.

With --dispersion on (the default for a mesh or the default scene through a lens whose prescription
has Abbe numbers; pbrt scenes render without it unless asked, as pbrt does), each camera
sample carries a wavelength, the glasses' indices follow it, and the film integrates through the
CIE 1931 colour matching functions to linear sRGB: the lens's chromatic aberration shows. Off
traces at the d line in RGB.

The EXR holds the film irradiance (float32 RGB, metadata in the header); the PNG preview beside
it is sRGB.
"""


def add_render_command(commands: argparse._SubParsersAction) -> None:
    """Register ``render`` on the CLI's subcommand parser."""
    parser = commands.add_parser("render", help="render a pbrt scene, a mesh, or the default scene through a lens",
                                 description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--spp", type=checked(int, validation.samples_per_pixel), metavar="N",
                        help=f"samples per pixel, 1 to {validation.MAX_SPP} (default: the scene's, else 16)")
    parser.add_argument("--out", metavar="FILE.exr",
                        help="output EXR; the PNG preview is written beside it (default: the scene's film "
                             "file name, else render.exr)")
    parser.add_argument("--exposure", type=checked(float, partial(validation.finite, name="exposure")), metavar="EV",
                        help="PNG preview exposure in stops (default: automatic, or 0 with --shutter/--iso)")
    parser.add_argument("--shutter", metavar="SECONDS",
                        help="shutter time (e.g. 1/125): with --iso, the EXR holds a photographic exposure, "
                             "calibrated so a metered middle grey reads 0.18, instead of film irradiance")
    parser.add_argument("--iso", type=positive("ISO speed"),
                        help="ISO speed (default with --shutter: 100)")
    parser.set_defaults(run=cmd_render)


def report_warnings(warnings: list[str]) -> None:
    for warning in warnings:
        print(f"realistic: {warning}", file=sys.stderr)


def _photographic(image: np.ndarray, camera: Camera, args: argparse.Namespace) -> tuple[np.ndarray, dict]:
    """The film irradiance exposed for ``--shutter`` at ``--iso``, and what the header says of it."""
    shutter = parse_shutter(args.shutter or "1/60")
    iso = args.iso if args.iso is not None else 100.0
    scale = exposure_scale(shutter, iso)
    header = {"shutterSeconds": shutter, "iso": iso, "exposureScale": scale}
    f_number = camera.metadata().get("fNumber")
    if f_number is not None:
        header["exposureValue"] = exposure_value(f_number, shutter)
    return (image * np.float32(scale)).astype(np.float32), header


def _write_images(out: Path, image: np.ndarray, metadata: dict, exposure: float) -> None:
    """Write the EXR and its PNG preview; if ``out`` cannot be written now (its folder was removed
    during the render, the disk filled), save them in the temporary folder instead, so a finished
    render is never lost, and raise the error saying where they went."""
    try:
        write_exr(out, image, metadata)
        write_png(out.with_suffix(".png"), image, exposure)
    except UserError as err:
        handle, rescue = tempfile.mkstemp(prefix=f"realistic-{out.stem}-", suffix=".exr")
        os.close(handle)
        rescue = Path(rescue)
        write_exr(rescue, image, metadata)
        write_png(rescue.with_suffix(".png"), image, exposure)
        raise UserError(f"{err}; the render was saved as {rescue} (and its .png) instead") from None


def cmd_render(args: argparse.Namespace) -> int:
    from realistic.renderer.inputs import build_render_inputs
    from realistic.renderer.passes import render_passes

    if args.out is not None and Path(args.out).suffix.lower() != ".exr":
        raise UserError(f"{args.out}: the output must be an .exr file (the PNG preview goes beside it)")
    inputs = build_render_inputs(options_from_args(args, args.spp))
    report_warnings(inputs.warnings)
    if "pbrtDialect" in inputs.metadata:
        print(f"realistic: {args.scene}: read as {inputs.metadata['pbrtDialect']}", file=sys.stderr)
    out = Path(args.out or inputs.default_out)
    png = out.with_suffix(".png")
    check_writable(out)
    check_writable(png)
    camera = inputs.camera
    result = render_passes(inputs.scene, camera, args.backend, args.seed, args.cl_device, inputs.light_samples,
                           progress=True, max_memory_bytes=args.max_memory)
    metadata = {**camera.metadata(), **inputs.metadata,
                "spp": int(camera.spp), "seed": int(args.seed), "lightSamples": int(inputs.light_samples),
                "integrator": inputs.scene.integrator, "maxDepth": int(inputs.scene.max_depth),
                "backend": args.backend, "renderSeconds": float(result.seconds),
                "exitPupilSeconds": float(result.stage_seconds.get("exit pupil", 0.0)),
                "samplesDone": int(result.samples_done), "samplesTotal": int(result.samples_total),
                "interrupted": int(result.interrupted)}
    image = result.image
    if args.shutter or args.iso:
        image, photographic = _photographic(image, camera, args)
        metadata.update(photographic)
    exposure = args.exposure if args.exposure is not None else (0.0 if args.shutter or args.iso
                                                                   else auto_exposure(image))
    _write_images(out, image, metadata, exposure)
    rays = result.primary_rays + result.shadow_rays
    if result.interrupted:
        print(f"realistic: interrupted: wrote the {result.samples_done} of {result.samples_total} samples "
              f"taken to {out}", file=sys.stderr)
        return 130
    print(f"{out} and {png}: {camera.width}x{camera.height}, {camera.spp} spp, "
          f"{metadata['pixelFilter']} filter, {result.seconds:.1f} s "
          f"(exit pupil {result.stage_seconds.get('exit pupil', 0.0):.2f} s), "
          f"{rays / max(result.seconds, 1e-9) / 1e6:.2f} M rays/s, preview exposure {exposure:+.2f} EV")
    return 0
