"""Command-line interface: a thin layer over the library (``python -m realistic --help``)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from realistic.cli_bench import add_bench_command
from realistic.cli_render import add_render_command, parse_resolution
from realistic.dispersion import D_LINE_NM
from realistic.errors import UserError
from realistic.prescription import BUNDLED_LENSES, load_lens

LENS_HELP = f"bundled lens name ({', '.join(BUNDLED_LENSES)}) or path to a prescription file"


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive finite number")
    return value


def _load_lens_with_stop(args: argparse.Namespace):
    lens = load_lens(args.lens)
    return lens.with_stop_diameter(args.aperture) if args.aperture else lens


def cmd_lens_info(args: argparse.Namespace) -> int:
    from realistic.lens_report import format_summary, lens_summary

    summary = lens_summary(_load_lens_with_stop(args), args.wavelength, args.film_distance, args.sampling)
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary))
    return 0


def cmd_lens_trace(args: argparse.Namespace) -> int:
    from realistic.lens_trace_io import rays_to_json, read_rays
    from realistic.reference import trace_from_film

    lens = _load_lens_with_stop(args)
    origins, directions = read_rays(args.input)
    result = trace_from_film(lens, args.film_distance, origins, directions, args.wavelength)
    rays = rays_to_json(result)["rays"]
    text = '{"rays": [\n' + ",\n".join(json.dumps(ray) for ray in rays) + "\n]}"
    if args.output in (None, "-"):
        print(text)
    else:
        _write_text_atomically(Path(args.output), text + "\n")
    return 0


def _film_distance(args: argparse.Namespace, lens) -> float:
    """Film distance for ``--focus`` (mm from the film; default infinity)."""
    from realistic.paraxial import film_distance_for_focus

    return film_distance_for_focus(lens, args.focus if args.focus else float("inf"), args.wavelength)


def cmd_lens_plot(args: argparse.Namespace) -> int:
    from realistic.lens_plot import plot_cross_section

    lens = _load_lens_with_stop(args)
    out = Path(args.out or f"{lens.name}.png")
    plot_cross_section(lens, _film_distance(args, lens), out, args.film_diagonal)
    print(f"wrote {out}")
    return 0


def cmd_lens_curves(args: argparse.Namespace) -> int:
    from realistic.lens_curves import field_curves
    from realistic.lens_plot import plot_field_curves

    lens = _load_lens_with_stop(args)
    rows = field_curves(lens, args.film_diagonal, _film_distance(args, lens))
    out = Path(args.out or f"{lens.name}-curves.png")
    plot_field_curves(lens.name, rows, out)
    if args.json:
        _write_text_atomically(Path(args.json), json.dumps({"lens": lens.name, "curves": rows}, indent=1) + "\n")
    if args.vignetting_map:
        _write_vignetting_map(Path(args.vignetting_map), lens, rows, args.film_diagonal, args.map_res)
    print("film radius mm  field angle deg  rel. illumination  vignetting  distortion %")
    for r in rows:
        angle = "-" if r["field_angle_deg"] is None else f"{r['field_angle_deg']:.2f}"
        distortion = "-" if r["distortion_percent"] is None else f"{r['distortion_percent']:.3f}"
        print(f"{r['film_radius_mm']:14.3f}  {angle:>15}  {r['relative_illumination']:17.4f}  "
              f"{r['vignetting']:10.4f}  {distortion:>12}")
    print("wrote " + ", ".join(str(p) for p in (out, args.json, args.vignetting_map) if p))
    return 0


def _write_vignetting_map(path: Path, lens, rows: list[dict], film_diagonal_mm: float, res: str) -> None:
    """The relative illumination over the film as an EXR (the same value in R, G and B)."""
    import numpy as np

    from realistic.image_io import check_writable, write_exr
    from realistic.lens_curves import vignetting_map

    width, height = parse_resolution(res)
    check_writable(path)
    image = np.repeat(vignetting_map(rows, width, height, film_diagonal_mm)[:, :, None], 3, axis=2)
    write_exr(path, image, {"lens": lens.name, "filmDiagonalMm": float(film_diagonal_mm),
                            "content": "relative illumination (vignetting x cos^4), 1 at the film centre"})


def _write_text_atomically(path: Path, text: str) -> None:
    from realistic.image_io import check_writable, write_atomically

    check_writable(path)
    write_atomically(path, lambda temporary: Path(temporary).write_text(text, encoding="utf-8"))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="realistic", description="Render through real multi-element lenses.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    lens = commands.add_parser("lens", help="analyse and trace lens prescriptions")
    lens_commands = lens.add_subparsers(dest="lens_command", required=True, metavar="LENS_COMMAND")

    def lens_arguments(p: argparse.ArgumentParser) -> None:
        p.add_argument("lens", metavar="LENS", help=LENS_HELP)
        p.add_argument("--aperture", type=positive_float, metavar="MM",
                       help="stop diameter in mm (default: the file's)")
        p.add_argument("--wavelength", type=positive_float, default=D_LINE_NM, metavar="NM",
                       help="wavelength in nm (default: the d line, %(default).2f)")

    info = lens_commands.add_parser("info", help="surface table, paraxial data, pupils and focusing")
    lens_arguments(info)
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.add_argument("--film-distance", type=positive_float, metavar="MM",
                      help="rear vertex to film distance: also report the object distance in focus")
    info.add_argument("--sampling", type=positive_float, metavar="FILM_DIAGONAL_MM", nargs="?", const=35.0,
                      help="also report the fraction of rays that pass with rear-element and exit-pupil "
                           "sampling at the centre, middle and corner of a film of this diagonal (default 35)")
    info.set_defaults(run=cmd_lens_info)

    trace = lens_commands.add_parser(
        "trace", help="trace rays from the film through the lens (float64 reference)",
        description="Frame: film plane z = 0, +z toward the scene, rear lens vertex at z = film distance. "
                    'Input {"rays": [{"origin": [x,y,z], "direction": [dx,dy,dz]}, ...]}; output the ray '
                    'leaving the front surface or {"blocked_by": {"surface": i, "reason": ...}} per ray, '
                    "surfaces counted from 0 at the front.")
    lens_arguments(trace)
    trace.add_argument("--film-distance", type=positive_float, required=True, metavar="MM",
                       help="rear vertex to film distance in mm")
    trace.add_argument("--input", required=True, metavar="RAYS.json", help="rays to trace")
    trace.add_argument("--output", metavar="OUT.json", help="where to write the result (default: stdout)")
    trace.set_defaults(run=cmd_lens_trace)

    def field_arguments(p: argparse.ArgumentParser) -> None:
        lens_arguments(p)
        p.add_argument("--focus", type=positive_float, metavar="MM",
                       help="object distance in focus, mm from the film (default: infinity)")
        p.add_argument("--film-diagonal", type=positive_float, default=43.27, metavar="MM",
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
    add_render_command(commands)
    add_bench_command(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except UserError as err:
        print(f"realistic: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("realistic: interrupted", file=sys.stderr)
        return 130
