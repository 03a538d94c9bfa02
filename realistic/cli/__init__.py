"""Command-line interface: a thin layer over the library (``python -m realistic --help``).

One module per command group, each holding argument definitions and output only:

- ``lens``: ``lens info | trace | plot | curves`` (``realistic.optics``).
- ``render``: render a scene to EXR and PNG (``realistic.renderer``).
- ``bench``: render a scene at several sample counts, time and convergence.
- ``scene_arguments``: the arguments ``render`` and ``bench`` share, turned into ``RenderOptions``.
- ``values``: text to numbers, resolutions, vectors; one-line errors.
"""

from __future__ import annotations

import argparse
import sys

from realistic.cli.bench import add_bench_command
from realistic.cli.lens import add_lens_commands
from realistic.cli.render import add_render_command
from realistic.errors import UserError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="realistic", description="Render through real multi-element lenses.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_lens_commands(commands)
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
