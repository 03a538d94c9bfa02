"""The ``lens ghosts`` subcommand: the ghost paths of a prescription, brightest first.

Argument definitions and output; the numbers come from ``realistic.optics.ghosts``.
"""

from __future__ import annotations

import argparse
import math

from realistic.camera.lens_camera import MM_PER_METRE
from realistic.cli.values import LENS_HELP, checked
from realistic.core import validation
from realistic.optics.dispersion import D_LINE_NM
from realistic.optics.formats import load_lens
from realistic.optics.ghosts import DEFAULT_THRESHOLD, GhostSummary, ghost_paths, summarise
from realistic.optics.paraxial import film_distance_for_focus


def _row(row: GhostSummary, direct_light: float) -> str:
    """One line of the table; ``light`` relative to the direct image's ``direct_light``."""
    path = row.path
    name = "direct" if path is None else f"{path.second} then {path.first}"
    throughput = "" if path is None else f"{path.throughput:.3e}"
    y = round(row.centroid_mm[1], 3) + 0.0  # no "-0.000" for a centred spot
    return (f"{name:>10} {throughput:>10} {row.focus_mm:>11.3f} {row.spot_rms_mm:>9.3f} {y:>9.3f} "
            f"{row.light / direct_light:>9.2e}")


def cmd_lens_ghosts(args: argparse.Namespace) -> int:
    lens = load_lens(args.lens)
    lens = (lens.with_stop_diameter(args.aperture) if args.aperture else lens).with_coating(args.coating)
    paths = ghost_paths(lens, wavelength_nm=args.wavelength, threshold=args.threshold)
    film = film_distance_for_focus(lens, args.focus * MM_PER_METRE, args.wavelength)
    rows = summarise(lens, film, paths, args.field, args.wavelength)
    print(f"{lens.name}, coating {args.coating}: {len(paths)} ghosts with on-axis throughput >= {args.threshold:g} "
          f"(reflected at the second surface, then the first; surfaces from 0 at the front); film focused at "
          f"{args.focus:g} m, {film:.3f} mm behind the rear vertex; spot of a light at infinity at {args.field:g} deg")
    print(f"{'reflects':>10} {'throughput':>10} {'focus (mm)':>11} {'rms (mm)':>9} {'y (mm)':>9} {'light':>9}")
    direct_light = rows[0].light if rows[0].light > 0 else 1.0
    for row in rows:
        print(_row(row, direct_light))
    glare = sum(row.light for row in rows[1:]) / direct_light
    print(f"veiling glare: the {len(paths)} ghosts together bring {glare:.3g} of the direct image's light "
          f"({100 * glare / (1 + glare):.3g} % of the light reaching the film along these paths)")
    print("focus: where an on-axis point at infinity is sharpest along the path, mm from the film (+ toward the "
          "scene); rms and y: the spot's radius and centre on the film; light: relative to the direct image's")
    return 0


def add_ghosts_command(lens_commands: argparse._SubParsersAction) -> None:
    """Register ``lens ghosts``."""
    ghosts = lens_commands.add_parser("ghosts", help="the lens's ghosts: light reflected twice inside it")
    ghosts.add_argument("lens", metavar="LENS", help=LENS_HELP)
    ghosts.add_argument("--coating", choices=("none", "mgf2"), default="none",
                        help="every surface bare (none, the default) or with a quarter-wave MgF2 layer on "
                             "glass-air surfaces (mgf2)")
    ghosts.add_argument("--threshold", type=checked(float, validation.ghost_threshold), default=DEFAULT_THRESHOLD,
                        metavar="T", help="leave out ghosts whose on-axis throughput is below T "
                                          "(default: %(default)g)")
    ghosts.add_argument("--field", type=checked(float, validation.field_angle_deg), default=0.0, metavar="DEG",
                        help="field angle of the light whose ghost spots are reported (default: 0)")
    ghosts.add_argument("--focus", type=checked(float, validation.focus_distance), default=math.inf, metavar="M",
                        help="distance in focus, in metres from the film plane, or inf (default: inf)")
    ghosts.add_argument("--aperture", type=checked(float, validation.stop_diameter_mm), metavar="MM",
                        help="stop diameter in mm (default: the file's)")
    ghosts.add_argument("--wavelength", type=checked(float, validation.wavelength_nm), default=D_LINE_NM,
                        metavar="NM", help="wavelength in nm (default: the d line, %(default).2f)")
    ghosts.set_defaults(run=cmd_lens_ghosts)
