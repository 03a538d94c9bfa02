"""The ``lens`` subcommands that judge lenses: ``list``, ``spot``, ``mtf`` and ``psf``.

Argument definitions and output; the numbers come from ``realistic.optics`` (library, spot, mtf)
and ``realistic.camera.psf``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from realistic.camera.lens_camera import MM_PER_METRE
from realistic.cli.values import LENS_HELP, checked, checked_exr, checked_plot, positive
from realistic.core import validation
from realistic.core.atomic_files import check_writable, write_text_atomically
from realistic.errors import UserError
from realistic.optics.formats import bundled_lens_files, load_lens
from realistic.optics.lens import LensSystem


def parse_fields(text: str) -> list[float]:
    """``"0,10,20"`` -> field angles in degrees, each in (-90, 90)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) and abs(v) < 90 for v in values):
        raise UserError(f"--field {text!r} is not a comma-separated list of angles in degrees between -90 and 90")
    return values


def _load(args: argparse.Namespace) -> LensSystem:
    lens = load_lens(args.lens)
    return lens.with_stop_diameter(args.aperture) if args.aperture else lens


def _outputs(args: argparse.Namespace, default_plot: str) -> Path:
    """The plot's path; both outputs are checked before any tracing, so a bad path fails at once."""
    out = checked_plot(Path(args.out or default_plot))
    if args.json:
        check_writable(Path(args.json))
    return out


def _warn_dispersion(lens: LensSystem, wavelengths_nm: list[float]) -> None:
    warning = lens.dispersion_warning(wavelengths_nm)
    if warning:
        print(f"realistic: warning: {warning}", file=sys.stderr)


def _write(path: str | None, text: str) -> None:
    if path:
        write_text_atomically(Path(path), text)


def cmd_lens_list(args: argparse.Namespace) -> int:
    from realistic.optics.library import library_entry

    entries = [library_entry(name) for name in bundled_lens_files()]
    if args.json:
        print(json.dumps(entries, indent=1))
        return 0
    print(f"{'name':<20} {'EFL mm':>8} {'f/#':>6} {'circle mm':>9} {'elem':>4} {'asph':>4}  source")
    for e in entries:
        print(f"{e['name']:<20} {e['focal_length_mm']:8.2f} {e['f_number']:6.2f} {e['image_circle_mm']:9.1f} "
              f"{e['elements']:4d} {e['aspheres']:4d}  {e['source'][:90]}")
    return 0


def cmd_lens_spot(args: argparse.Namespace) -> int:
    from realistic.optics.judge_drawing import plot_spots
    from realistic.optics.spot import spot_diagram

    lens = _load(args)
    out = _outputs(args, f"{lens.name}-spot.png")
    _warn_dispersion(lens, args.wavelengths)
    report = spot_diagram(lens, args.field, args.wavelengths, args.focus, args.samples)
    _write(args.json, json.dumps(report.as_dict(), indent=1) + "\n")
    plot_spots(report, out)
    print(f"{lens.name}: film {report.film_distance_mm:.4f} mm behind the rear vertex ({report.focus} focus)")
    print("field deg  RMS radius um  geometric radius um  centroid y mm")
    for s in report.spots:
        print(f"{s.field_deg:9g}  {s.rms_radius_mm * 1000:13.3f}  {s.geometric_radius_mm * 1000:19.3f}  "
              f"{s.centroid_mm[1]:13.4f}")
    print("wrote " + ", ".join(str(p) for p in (out, args.json) if p))
    return 0


def cmd_lens_mtf(args: argparse.Namespace) -> int:
    from realistic.optics.judge_drawing import plot_mtf
    from realistic.optics.mtf import lens_mtf

    lens = _load(args)
    out = _outputs(args, f"{lens.name}-mtf.png")
    _warn_dispersion(lens, args.wavelengths)
    report = lens_mtf(lens, args.field, args.wavelengths, args.max_frequency, args.focus, args.samples)
    _write(args.json, json.dumps(report.as_dict(), indent=1) + "\n")
    plot_mtf(report, out)
    nu = report.frequencies_lp_mm
    picks = sorted({min(range(len(nu)), key=lambda i: abs(nu[i] - f * nu[-1])) for f in (0.1, 0.3, 0.5, 1.0)})
    print(f"{lens.name}: geometric MTF, film {report.film_distance_mm:.4f} mm behind the rear vertex")
    print("field deg  " + "  ".join(f"S/T@{nu[i]:g}" for i in picks))
    for field, s, t in zip(report.fields_deg, report.sagittal, report.tangential):
        print(f"{field:9g}  " + "  ".join(f"{s[i]:.3f}/{t[i]:.3f}" for i in picks))
    print("wrote " + ", ".join(str(p) for p in (out, args.json) if p))
    return 0


def cmd_lens_psf(args: argparse.Namespace) -> int:
    from realistic.camera.psf import point_spread
    from realistic.core.image_files import write_exr

    lens = _load(args)
    out = checked_exr(Path(args.out or f"{lens.name}-psf.exr"))
    psf = point_spread(lens, args.depth * MM_PER_METRE, args.field,
                       None if args.focus is None else args.focus * MM_PER_METRE,
                       args.pixel_um / 1000.0, args.size, args.spp, seed=args.seed, backend=args.backend)
    image = psf.image[:, :, None].repeat(3, axis=2)
    write_exr(out, image, {
        "lens": lens.name, "content": "film irradiance per unit source radiance (point spread function)",
        "pixelMm": psf.pixel_mm, "windowCentreFilmMm": f"{psf.centre_film_mm[0]:.6g},{psf.centre_film_mm[1]:.6g}",
        "sourceCentreMm": ",".join(f"{v:.6g}" for v in psf.source_centre_mm), "sourceRadiusMm": psf.source_radius_mm,
        "filmDistanceMm": psf.film_distance_mm, "spp": psf.spp, "fluxMm2": psf.flux})
    peak = float(psf.image.max())
    print(f"{lens.name}: PSF of a point {args.depth:g} m from the film at {args.field:g} deg, film "
          f"{psf.film_distance_mm:.4f} mm; window centre ({psf.centre_film_mm[0]:.4f}, "
          f"{psf.centre_film_mm[1]:.4f}) mm, "
          f"{args.size} px of {args.pixel_um:g} um; flux {psf.flux:.6g} mm^2, peak {peak:.6g}")
    print(f"wrote {out}")
    return 0


def add_judge_commands(lens_commands: argparse._SubParsersAction) -> None:
    """Register ``list``, ``spot``, ``mtf`` and ``psf`` under ``lens``."""
    from realistic.optics.spot import parse_wavelengths

    listing = lens_commands.add_parser("list", help="the bundled lens library: focal length, f-number, image "
                                                    "circle, elements, aspheres, source")
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    listing.set_defaults(run=cmd_lens_list)

    def common(parser: argparse.ArgumentParser, samples: int) -> None:
        parser.add_argument("lens", metavar="LENS", help=LENS_HELP)
        parser.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                            help="stop diameter in mm (default: the file's)")
        parser.add_argument("--field", type=checked(str, parse_fields), default=[0.0, 10.0, 20.0],
                            metavar="DEG,...", help="field angles in degrees (default: 0,10,20)")
        parser.add_argument("--wavelengths", type=checked(str, parse_wavelengths), default=parse_wavelengths("F,d,C"),
                            metavar="F,d,C", help="Fraunhofer line names or nm (default: F,d,C)")
        parser.add_argument("--focus", type=checked(str, _judge_focus), default="paraxial", metavar="M|paraxial|best",
                            help="the film focused this many metres from the film plane (or inf), as render's "
                                 "--focus on a mesh; or at the d line's paraxial focus, or the best (least RMS) "
                                 "focus, of the objects at infinity (default: paraxial)")
        parser.add_argument("--samples", type=checked(int, _pupil_samples), default=samples, metavar="N",
                            help=f"pupil grid samples across the diameter (default {samples})")
        parser.add_argument("--json", metavar="JSON", help="also write the numbers as JSON")

    spot = lens_commands.add_parser("spot", help="spot diagrams of objects at infinity (plot, RMS and "
                                                 "geometric radii)")
    common(spot, 64)
    spot.add_argument("--out", metavar="PNG", help="plot (default: LENS-spot.png)")
    spot.set_defaults(run=cmd_lens_spot)

    mtf = lens_commands.add_parser("mtf", help="geometric MTF, sagittal and tangential, from the traced spot")
    common(mtf, 128)
    mtf.add_argument("--max-frequency", type=positive("maximum frequency (lp/mm)"), default=100.0, metavar="LP/MM",
                     help="highest spatial frequency plotted (default 100 lp/mm)")
    mtf.add_argument("--out", metavar="PNG", help="plot (default: LENS-mtf.png)")
    mtf.set_defaults(run=cmd_lens_mtf)

    psf = lens_commands.add_parser("psf", help="point-spread function on the film, rendered with camera rays (EXR)")
    psf.add_argument("lens", metavar="LENS", help=LENS_HELP)
    psf.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                     help="stop diameter in mm (default: the file's)")
    psf.add_argument("--depth", type=positive("depth (m)"), required=True, metavar="M",
                     help="distance of the point from the film, in metres")
    psf.add_argument("--field", type=checked(float, _field_angle), default=0.0, metavar="DEG",
                     help="angle of the point off the axis, seen from the entrance pupil (default 0)")
    psf.add_argument("--focus", type=checked(float, validation.focus_distance), metavar="M",
                     help="focus distance in metres from the film plane, or inf (default: the point's depth)")
    psf.add_argument("--pixel-um", type=positive("pixel size (um)"), default=2.0, metavar="UM",
                     help="pixel pitch in micrometres (default 2)")
    psf.add_argument("--size", type=checked(int, _window_size), default=64, metavar="PX",
                     help="window side in pixels (default 64)")
    psf.add_argument("--spp", type=checked(int, validation.samples_per_pixel), default=256, metavar="N",
                     help="camera samples per pixel (default 256)")
    psf.add_argument("--seed", type=checked(int, validation.seed), default=0, help="random seed (default 0)")
    psf.add_argument("--backend", choices=("numpy", "opencl"), default="numpy",
                     help="camera rays from the float64 reference or the OpenCL kernel (default numpy)")
    psf.add_argument("--out", metavar="EXR", help="output image (default: LENS-psf.exr)")
    psf.set_defaults(run=cmd_lens_psf)


def _judge_focus(text: str) -> str | float:
    """``--focus`` of spot and mtf: a mode of ``optics.spot.FOCUS_MODES``, else metres (or inf) as mm."""
    from realistic.optics.spot import FOCUS_MODES

    if text in FOCUS_MODES:
        return text
    try:
        metres = float(text)
    except ValueError:
        raise UserError(f"focus {text!r} is not a distance in metres, inf, or one of {', '.join(FOCUS_MODES)}") \
            from None
    return validation.focus_distance(metres) * MM_PER_METRE


def _pupil_samples(n: int) -> int:
    if not 2 <= n <= 1024:
        raise UserError(f"pupil samples {n} must be 2..1024")
    return n


def _field_angle(deg: float) -> float:
    if not (math.isfinite(deg) and abs(deg) < 90):
        raise UserError(f"field angle {deg:g} deg must be between -90 and 90")
    return deg


def _window_size(n: int) -> int:
    if not 1 <= n <= 4096:
        raise UserError(f"PSF window size {n} must be 1..4096 pixels")
    return n
