"""The ``lens`` subcommands: ``info``, ``trace``, ``plot`` and ``curves`` of a prescription.

Argument definitions and output; the numbers come from ``realistic.optics``.
"""

from __future__ import annotations

import argparse
import json
import math
from functools import partial
from pathlib import Path

import numpy as np

from realistic.camera.lens_camera import MM_PER_METRE
from realistic.cli.lens_convert import add_convert_command
from realistic.cli.lens_ghosts import add_ghosts_command
from realistic.cli.lens_judge import add_judge_commands
from realistic.cli.values import LENS_HELP, checked, checked_exr, checked_plot, parse_resolution
from realistic.core import validation
from realistic.core.atomic_files import check_writable, write_text_atomically
from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.formats import load_lens
from realistic.optics.lens import MAX_LENGTH_MM, LensSystem

#: ``--film-distance-mm``: a positive length within the lens model's range (``optics.lens.MAX_LENGTH_MM``).
FILM_DISTANCE = checked(float, partial(validation.positive_length, name="film distance (mm)", maximum=MAX_LENGTH_MM))
#: ``--film-distance-mm`` and its old name, kept as an alias.
FILM_DISTANCE_FLAGS = ("--film-distance-mm", "--film-distance")
#: ``--focus`` of the lens commands: metres from the film (a lens command's scene unit), or inf.
FOCUS_HELP = "distance in focus, in metres from the film plane (the unit of render's --focus on a mesh), or inf"


def _load_lens_with_stop(args: argparse.Namespace) -> LensSystem:
    lens = load_lens(args.lens)
    return lens.with_stop_diameter(args.aperture) if args.aperture else lens


def cmd_lens_info(args: argparse.Namespace) -> int:
    from realistic.optics.report import format_summary, lens_summary

    summary = lens_summary(_load_lens_with_stop(args), args.wavelength, args.film_distance, args.sampling)
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary))
    return 0


def cmd_lens_trace(args: argparse.Namespace) -> int:
    from realistic.optics.ray_json import rays_to_json, read_rays
    from realistic.optics.tracer import trace_from_film

    output = None if args.output in (None, "-") else Path(args.output)
    if output is not None:
        check_writable(output)
    lens = _load_lens_with_stop(args)
    origins, directions = read_rays(args.input)
    result = trace_from_film(lens, args.film_distance, origins, directions, args.wavelength)
    rays = rays_to_json(result)["rays"]
    text = '{"rays": [\n' + ",\n".join(json.dumps(ray) for ray in rays) + "\n]}"
    if output is None:
        print(text)
    else:
        write_text_atomically(output, text + "\n")
    return 0


def _film_distance(args: argparse.Namespace, lens: LensSystem) -> float:
    """Film distance for ``--focus`` (metres from the film; default infinity)."""
    from realistic.optics.paraxial import film_distance_for_focus

    return film_distance_for_focus(lens, args.focus * MM_PER_METRE, args.wavelength)


def cmd_lens_plot(args: argparse.Namespace) -> int:
    from realistic.optics.drawing import plot_cross_section

    lens = _load_lens_with_stop(args)
    out = checked_plot(Path(args.out or f"{lens.name}.png"))
    plot_cross_section(lens, _film_distance(args, lens), out, args.film_diagonal)
    print(f"wrote {out}")
    return 0


def cmd_lens_curves(args: argparse.Namespace) -> int:
    from realistic.optics.drawing import plot_field_curves
    from realistic.optics.field_curves import field_curves, vignetting_map

    lens = _load_lens_with_stop(args)
    out = checked_plot(Path(args.out or f"{lens.name}-curves.png"))
    if args.json:
        check_writable(Path(args.json))
    map_size = parse_resolution(args.map_res)
    if args.vignetting_map:
        checked_exr(Path(args.vignetting_map))
    rows = field_curves(lens, args.film_diagonal, _film_distance(args, lens))
    plot_field_curves(lens.name, rows, out)
    if args.json:
        write_text_atomically(Path(args.json), json.dumps({"lens": lens.name, "curves": rows}, indent=1) + "\n")
    if args.vignetting_map:
        _write_vignetting_map(Path(args.vignetting_map), lens,
                              vignetting_map(rows, *map_size, args.film_diagonal), args.film_diagonal)
    print("film radius mm  field angle deg  rel. illumination  vignetting  distortion %")
    for r in rows:
        angle = "-" if r["field_angle_deg"] is None else f"{r['field_angle_deg']:.2f}"
        distortion = "-" if r["distortion_percent"] is None else f"{r['distortion_percent']:.3f}"
        print(f"{r['film_radius_mm']:14.3f}  {angle:>15}  {r['relative_illumination']:17.4f}  "
              f"{r['vignetting']:10.4f}  {distortion:>12}")
    print("wrote " + ", ".join(str(p) for p in (out, args.json, args.vignetting_map) if p))
    return 0


def _write_vignetting_map(path: Path, lens: LensSystem, relative: np.ndarray, film_diagonal_mm: float) -> None:
    """The relative illumination (H, W) over the film as an EXR (the same value in R, G and B)."""
    from realistic.core.image_files import write_exr

    image = np.repeat(relative[:, :, None], 3, axis=2)
    write_exr(path, image, {"lens": lens.name, "filmDiagonalMm": float(film_diagonal_mm),
                            "content": "relative illumination (vignetting x cos^4), 1 at the film centre"})


def add_lens_commands(commands: argparse._SubParsersAction) -> None:
    """Register ``lens`` and its subcommands on the CLI's subcommand parser."""
    lens = commands.add_parser("lens", help="analyse and trace lens prescriptions")
    lens_commands = lens.add_subparsers(dest="lens_command", required=True, metavar="LENS_COMMAND")

    def lens_arguments(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("lens", metavar="LENS", help=LENS_HELP)
        parser.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                            help="stop diameter in mm (default: the file's)")
        parser.add_argument("--wavelength", type=checked(float, validation.wavelength_nm), default=D_LINE_NM,
                            metavar="NM",
                            help="wavelength in nm (default: the d line, %(default).2f)")

    info = lens_commands.add_parser("info", help="surface table, paraxial data, pupils and focusing")
    lens_arguments(info)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.add_argument(*FILM_DISTANCE_FLAGS, dest="film_distance", type=FILM_DISTANCE, metavar="MM",
                      help="rear vertex to film distance in mm: also report the object distance in focus")
    info.add_argument("--sampling", type=checked(float, validation.film_diagonal_mm), metavar="FILM_DIAGONAL_MM",
                      nargs="?", const=FULL_FRAME_DIAGONAL_MM,
                      help="also report the fraction of rays that pass with rear-element and exit-pupil "
                           f"sampling at the centre, middle and corner of a film of this diagonal (default "
                           f"{FULL_FRAME_DIAGONAL_MM}, full frame)")
    info.set_defaults(run=cmd_lens_info)

    trace = lens_commands.add_parser(
        "trace", help="trace rays from the film through the lens (float64 reference)",
        description="Frame: film plane z = 0, +z toward the scene, rear lens vertex at z = film distance. "
                    'Input {"rays": [{"origin": [x,y,z], "direction": [dx,dy,dz]}, ...]}; output the ray '
                    'leaving the front surface or {"blocked_by": {"surface": i, "reason": ...}} per ray, '
                    "surfaces counted from 0 at the front.")
    lens_arguments(trace)
    trace.add_argument(*FILM_DISTANCE_FLAGS, dest="film_distance", type=FILM_DISTANCE, required=True, metavar="MM",
                       help="rear vertex to film distance in mm")
    trace.add_argument("--input", required=True, metavar="RAYS.json", help="rays to trace")
    trace.add_argument("--output", metavar="OUT.json", help="where to write the result (default: stdout)")
    trace.set_defaults(run=cmd_lens_trace)

    def field_arguments(parser: argparse.ArgumentParser) -> None:
        lens_arguments(parser)
        parser.add_argument("--focus", type=checked(float, validation.focus_distance), default=math.inf, metavar="M",
                            help=f"{FOCUS_HELP} (default: inf)")
        parser.add_argument("--film-diagonal", type=checked(float, validation.film_diagonal_mm),
                            default=FULL_FRAME_DIAGONAL_MM, metavar="MM",
                            help="film diagonal in mm (default: %(default)s, full frame)")

    plot = lens_commands.add_parser("plot", help="draw the lens cross-section with ray fans (PNG)")
    field_arguments(plot)
    plot.add_argument("--out", metavar="PNG", help="output image (default: LENS.png)")
    plot.set_defaults(run=cmd_lens_plot)

    curves = lens_commands.add_parser("curves", help="relative illumination and distortion against field height")
    field_arguments(curves)
    curves.add_argument("--out", metavar="PNG", help="plot of the curves (default: LENS-curves.png)")
    curves.add_argument("--json", metavar="JSON", help="also write the curves as JSON")
    curves.add_argument("--vignetting-map", metavar="EXR", help="also write the film's relative illumination as EXR")
    curves.add_argument("--map-res", default="512x512", metavar="WxH",
                        help="resolution of the vignetting map (default: %(default)s)")
    curves.set_defaults(run=cmd_lens_curves)
    add_convert_command(lens_commands)
    add_judge_commands(lens_commands)
    add_ghosts_command(lens_commands)
