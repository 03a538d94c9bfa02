"""The ``lens`` subcommands that judge lenses: ``list``, ``spot``, ``mtf``, ``psf`` and ``wavefront``.

Argument definitions and output; the numbers come from ``realistic.optics`` (library, spot, mtf,
wavefront, diffraction) and ``realistic.camera.psf``.
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
from realistic.optics.dispersion import D_LINE_NM
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


#: Fraction of pupil-sample steps over half a wave above which the FFT model warns.
MAX_UNDERSAMPLED = 0.02


def _warn_pupil_sampling(undersampled: float, where: str) -> None:
    if undersampled > MAX_UNDERSAMPLED:
        print(f"realistic: warning: the wavefront changes by more than half a wave between {undersampled:.0%} of "
              f"neighbouring pupil samples {where}: the FFT aliases; raise --samples", file=sys.stderr)


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
    report = lens_mtf(lens, args.field, args.wavelengths, args.max_frequency, args.focus, args.samples,
                      model=args.model, weights=args.weights)
    _write(args.json, json.dumps(report.as_dict(), indent=1) + "\n")
    plot_mtf(report, out)
    nu = report.frequencies_lp_mm
    picks = sorted({min(range(len(nu)), key=lambda i: abs(nu[i] - f * nu[-1])) for f in (0.1, 0.3, 0.5, 1.0)})
    print(f"{lens.name}: {report.model} MTF, film {report.film_distance_mm:.4f} mm behind the rear vertex")
    print("field deg  " + "  ".join(f"S/T@{nu[i]:g}" for i in picks))
    for field, s, t in zip(report.fields_deg, report.sagittal, report.tangential):
        print(f"{field:9g}  " + "  ".join(f"{s[i]:.3f}/{t[i]:.3f}" for i in picks))
    for field, step in zip(report.fields_deg, report.undersampled):
        _warn_pupil_sampling(step, f"at {field:g} deg")
    if report.diffraction_limit is not None:
        print("diff. lim  " + "  ".join(f"{report.diffraction_limit[i]:11.3f}" for i in picks))
    print("wrote " + ", ".join(str(p) for p in (out, args.json) if p))
    return 0


def cmd_lens_psf(args: argparse.Namespace) -> int:
    from realistic.camera.psf import point_spread
    from realistic.core.image_files import write_exr

    lens = _load(args)
    out = checked_exr(Path(args.out or f"{lens.name}-psf.exr"))
    if args.model in ("fft", "huygens"):
        return _fft_psf(args, lens, out)
    if args.wavelengths is not None or args.weights is not None:
        raise UserError("--wavelengths and --weights are the FFT model's (--model fft)")
    psf = point_spread(lens, args.depth * MM_PER_METRE, args.field, _psf_focus_mm(args), args.pixel_um / 1000.0,
                       args.size, args.spp, seed=args.seed, backend=args.backend)
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


def _psf_focus_mm(args: argparse.Namespace) -> float | None:
    """``lens psf --focus`` in mm from the film (None: focused on the point)."""
    return None if args.focus is None else args.focus * MM_PER_METRE


def _polychromatic_psf(args: argparse.Namespace, lens: LensSystem, out: Path) -> int:
    """``lens psf --model fft --wavelengths ...``: the wavelengths' diffraction PSFs summed by power, as an EXR."""
    from realistic.camera.psf import polychromatic_point_spread
    from realistic.core.image_files import write_exr

    _warn_dispersion(lens, args.wavelengths)
    psf = polychromatic_point_spread(lens, args.depth * MM_PER_METRE, args.field, _psf_focus_mm(args),
                                     args.pixel_um / 1000.0, args.size, args.wavelengths, args.weights, args.samples)
    first = psf.parts[0]
    listed = ",".join(f"{w:.6g}" for w in args.wavelengths)
    write_exr(out, psf.image[:, :, None].repeat(3, axis=2), {
        "lens": lens.name, "content": "polychromatic diffraction PSF (FFT): film irradiance per unit power reaching "
        "the film", "pixelMm": first.pixel_mm,
        "windowCentreFilmMm": f"{first.centre_film_mm[0]:.6g},{first.centre_film_mm[1]:.6g}",
        "filmDistanceMm": first.film_distance_mm, "wavelengthsNm": listed,
        "weights": ",".join(f"{w:.6g}" for w in psf.weights),
        "strehls": ",".join(f"{p.strehl:.6g}" for p in psf.parts), "enclosed": psf.enclosed})
    for part in psf.parts:
        _warn_pupil_sampling(part.undersampled, f"at {args.field:g} deg, {part.wavelength_nm:g} nm")
    print(f"{lens.name}: FFT PSF of a point {args.depth:g} m from the film at {args.field:g} deg, {listed} nm "
          f"weighted {', '.join(f'{w:.3g}' for w in psf.weights)}, film {first.film_distance_mm:.4f} mm; window centre "
          f"({first.centre_film_mm[0]:.4f}, {first.centre_film_mm[1]:.4f}) mm, {args.size} px of {args.pixel_um:g} um; "
          f"Strehl per wavelength {', '.join(f'{p.strehl:.4f}' for p in psf.parts)}, {psf.enclosed:.4f} of the "
          f"light in the window")
    print(f"wrote {out}")
    return 0


def _fft_psf(args: argparse.Namespace, lens: LensSystem, out: Path) -> int:
    """``lens psf --model fft|huygens``: the diffraction PSF at ``--wavelength`` (or, FFT, ``--wavelengths``)
    as an EXR."""
    from realistic.camera.psf import fft_point_spread, huygens_point_spread
    from realistic.core.image_files import Metadata, write_exr

    if args.wavelengths is not None and args.model == "fft":
        return _polychromatic_psf(args, lens, out)
    if args.wavelengths is not None or args.weights is not None:
        raise UserError("--wavelengths and --weights go together, with --model fft")

    _warn_dispersion(lens, [args.wavelength])
    spread = fft_point_spread if args.model == "fft" else huygens_point_spread
    psf = spread(lens, args.depth * MM_PER_METRE, args.field, _psf_focus_mm(args),
                 args.pixel_um / 1000.0, args.size, args.wavelength, args.samples)
    model = "FFT" if args.model == "fft" else "Huygens-Fresnel sum over the reference sphere"
    sampling: Metadata = ({"fftSize": psf.fft_size, "fftSpacingMm": ",".join(f"{v:.6g}" for v in psf.fft_spacing_mm)}
                          if args.model == "fft" else {"sampleSpacingMm": psf.fft_spacing_mm[0]})
    write_exr(out, psf.image[:, :, None].repeat(3, axis=2), {
        "lens": lens.name, "content": f"diffraction PSF ({model}): film irradiance per unit power reaching the film",
        "pixelMm": psf.pixel_mm, "windowCentreFilmMm": f"{psf.centre_film_mm[0]:.6g},{psf.centre_film_mm[1]:.6g}",
        "filmDistanceMm": psf.film_distance_mm, "wavelengthNm": psf.wavelength_nm, **sampling, "strehl": psf.strehl,
        "opdRmsWaves": psf.opd_rms_waves,
        "enclosed": psf.enclosed})
    _warn_pupil_sampling(psf.undersampled, f"at {args.field:g} deg")
    print(f"{lens.name}: {args.model} PSF of a point {args.depth:g} m from the film at {args.field:g} deg, "
          f"{psf.wavelength_nm:g} nm, film {psf.film_distance_mm:.4f} mm; window centre "
          f"({psf.centre_film_mm[0]:.4f}, {psf.centre_film_mm[1]:.4f}) mm, {args.size} px of {args.pixel_um:g} um; "
          f"OPD RMS {psf.opd_rms_waves:.4f} waves, Strehl {psf.strehl:.4f}, {psf.enclosed:.4f} of the light "
          f"in the window")
    print(f"wrote {out}")
    return 0


def cmd_lens_wavefront(args: argparse.Namespace) -> int:
    from realistic.optics.diffraction import pupil_function, strehl_ratio
    from realistic.optics.spot import film_distance_for, trace_fields
    from realistic.optics.wavefront import noll_indices, term_name, wavefront, zernike_fit

    lens = _load(args)
    if args.json:
        check_writable(Path(args.json))
    _warn_dispersion(lens, [args.wavelength])
    traced = trace_fields(lens, [args.field], [args.wavelength], args.samples) if args.focus == "best" else []
    film = film_distance_for(lens, traced, args.focus)
    front = wavefront(lens, args.field, args.wavelength, film, args.samples)
    coefficients = zernike_fit(front, args.terms)
    strehl = strehl_ratio(pupil_function(front.opd_waves))
    _warn_pupil_sampling(front.undersampled_fraction, f"at {args.field:g} deg")
    summary = {"lens": lens.name, "field_deg": args.field, "wavelength_nm": args.wavelength,
               "film_distance_mm": film, "reference_mm": list(front.reference_mm),
               "opd_rms_waves": front.rms_waves, "opd_peak_to_valley_waves": front.peak_to_valley_waves,
               "strehl": strehl, "marechal_strehl": math.exp(-(2 * math.pi * front.rms_waves) ** 2),
               "zernike_ordering": "Noll, unit RMS over the unit disk",
               "zernike_waves": {str(j + 1): float(c) for j, c in enumerate(coefficients)}}
    _write(args.json, json.dumps(summary, indent=1) + "\n")
    print(f"{lens.name}: wavefront at {args.field:g} deg, {args.wavelength:g} nm, film {film:.4f} mm behind the "
          f"rear vertex, reference sphere about ({front.reference_mm[0]:.5f}, {front.reference_mm[1]:.5f}) mm")
    print(f"OPD RMS {front.rms_waves:.4f} waves, P-V {front.peak_to_valley_waves:.4f} waves, Strehl {strehl:.4f} "
          f"(Marechal {summary['marechal_strehl']:.4f})")
    print("Noll j  n  m  term                  waves")
    for j, c in enumerate(coefficients, start=1):
        n, m = noll_indices(j)
        print(f"{j:6d} {n:2d} {m:2d}  {term_name(j):<20} {c:9.5f}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


def add_judge_commands(lens_commands: argparse._SubParsersAction) -> None:
    """Register ``list``, ``spot``, ``mtf`` and ``psf`` under ``lens``."""
    from realistic.optics.spot import parse_wavelengths, parse_weights

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

    mtf = lens_commands.add_parser("mtf", help="MTF, sagittal and tangential: by diffraction of the wavefront "
                                               "(FFT, with the diffraction limit) or from the traced spot")
    common(mtf, 256)
    mtf.add_argument("--model", choices=("fft", "geometric"), default="fft",
                     help="FFT of the pupil function with the diffraction limit, or geometric from the spot "
                          "(default fft)")
    mtf.add_argument("--weights", type=checked(str, parse_weights), metavar="W,...",
                     help="FFT model: relative power of each wavelength (default: equal)")
    mtf.add_argument("--max-frequency", type=positive("maximum frequency (lp/mm)"), default=100.0, metavar="LP/MM",
                     help="highest spatial frequency plotted (default 100 lp/mm)")
    mtf.add_argument("--out", metavar="PNG", help="plot (default: LENS-mtf.png)")
    mtf.set_defaults(run=cmd_lens_mtf)

    psf = lens_commands.add_parser("psf", help="point-spread function on the film (EXR): by diffraction (FFT) "
                                               "or rendered with camera rays")
    psf.add_argument("lens", metavar="LENS", help=LENS_HELP)
    psf.add_argument("--model", choices=("fft", "huygens", "geometric"), default="fft",
                     help="FFT of the pupil function at --wavelength, the Huygens-Fresnel sum over the reference "
                          "sphere (slower, no Fraunhofer approximation), or rendered with camera rays (default fft)")
    colour = psf.add_mutually_exclusive_group()
    colour.add_argument("--wavelength", type=checked(float, validation.wavelength_nm), default=D_LINE_NM,
                        metavar="NM", help="wavelength of the FFT model in nm (default: the d line, %(default).2f)")
    colour.add_argument("--wavelengths", type=checked(str, parse_wavelengths), metavar="F,d,C",
                        help="FFT model: several wavelengths (Fraunhofer line names or nm), their PSFs summed")
    psf.add_argument("--weights", type=checked(str, parse_weights), metavar="W,...",
                     help="with --wavelengths: relative power of each (default: equal)")
    psf.add_argument("--samples", type=checked(int, _pupil_samples), default=64, metavar="N",
                     help="FFT model: pupil samples across the diameter, at least (default 64)")
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
                     help="geometric model: camera samples per pixel (default 256)")
    psf.add_argument("--seed", type=checked(int, validation.seed), default=0,
                     help="geometric model: random seed (default 0)")
    psf.add_argument("--backend", choices=("numpy", "opencl"), default="numpy",
                     help="geometric model: camera rays from the float64 reference or the OpenCL kernel "
                          "(default numpy)")
    psf.add_argument("--out", metavar="EXR", help="output image (default: LENS-psf.exr)")
    psf.set_defaults(run=cmd_lens_psf)

    front = lens_commands.add_parser("wavefront", help="OPD over the pupil of one field and wavelength from real "
                                                       "rays: RMS, Strehl and the Zernike (Noll) fit")
    front.add_argument("lens", metavar="LENS", help=LENS_HELP)
    front.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                       help="stop diameter in mm (default: the file's)")
    front.add_argument("--field", type=checked(float, _field_angle), default=0.0, metavar="DEG",
                       help="field angle of the object at infinity in degrees (default 0)")
    front.add_argument("--wavelength", type=checked(float, validation.wavelength_nm), default=D_LINE_NM,
                       metavar="NM", help="wavelength in nm (default: the d line, %(default).2f)")
    front.add_argument("--focus", type=checked(str, _judge_focus), default="paraxial", metavar="M|paraxial|best",
                       help="film plane, as spot's --focus (default: paraxial)")
    front.add_argument("--samples", type=checked(int, _pupil_samples), default=128, metavar="N",
                       help="pupil samples across the diameter (default 128)")
    front.add_argument("--terms", type=checked(int, _zernike_terms), default=22, metavar="J",
                       help="Noll Zernike terms fitted (default 22, through secondary spherical)")
    front.add_argument("--json", metavar="JSON", help="also write the numbers as JSON")
    front.set_defaults(run=cmd_lens_wavefront)


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


def _zernike_terms(j: int) -> int:
    if not 1 <= j <= 66:
        raise UserError(f"Zernike terms {j} must be 1..66")
    return j


def _field_angle(deg: float) -> float:
    if not (math.isfinite(deg) and abs(deg) < 90):
        raise UserError(f"field angle {deg:g} deg must be between -90 and 90")
    return deg


def _window_size(n: int) -> int:
    if not 1 <= n <= 4096:
        raise UserError(f"PSF window size {n} must be 1..4096 pixels")
    return n
