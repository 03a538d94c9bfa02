"""``lens convert IN OUT``: rewrite a prescription in another format, chosen by OUT's extension.

Formats: pbrt-style ``.dat``, isetlens/omni ``.json``, Zemax ``.zmx`` and CODE V ``.seq``
(``realistic.optics.formats``). Every writer prints floats exactly, so a lens read back from the
output equals the input to rounding (a radius written as a Zemax curvature is the one inexact
step, about 1e-16 relative). A lens a format cannot hold (aspheres in ``.dat``, r^18 terms in
``.zmx``) is refused in one line rather than written approximately.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from realistic.cli.values import LENS_HELP
from realistic.core.atomic_files import check_writable, write_text_atomically
from realistic.optics.formats import WRITERS, format_lens, load_lens


def cmd_lens_convert(args: argparse.Namespace) -> int:
    out = Path(args.output)
    lens = load_lens(args.lens)
    text = format_lens(lens, out.suffix.lower())
    check_writable(out)
    write_text_atomically(out, text)
    print(f"wrote {out} ({lens.surface_count} surfaces, {lens.asphere_count} aspheric)")
    return 0


def add_convert_command(lens_commands: argparse._SubParsersAction) -> None:
    """Register ``lens convert`` on the ``lens`` subcommand parser."""
    convert = lens_commands.add_parser(
        "convert", help="rewrite a prescription in another format (.dat, .json, .zmx, .seq)",
        description="Read LENS (a bundled name or a file; its format from its extension) and write it to "
                    f"OUT in the format of OUT's extension ({', '.join(WRITERS)}). Values are written "
                    "exactly; a lens the output format cannot hold is refused.")
    convert.add_argument("lens", metavar="LENS",
                         help=LENS_HELP)
    convert.add_argument("output", metavar="OUT", help="output file; its extension picks the format")
    convert.set_defaults(run=cmd_lens_convert)
