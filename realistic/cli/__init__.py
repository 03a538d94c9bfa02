"""Command-line interface: a thin layer over the library (``python -m realistic --help``).

One module per command group, each holding argument definitions and output only:

- ``lens``: ``lens info | trace | plot | curves`` (``realistic.optics``).
- ``render``: render a scene to EXR and PNG (``realistic.renderer``), with pbrt-v4's option names.
- ``bench``: render a scene at several sample counts, time and convergence.
- ``scene_arguments``: the arguments ``render`` and ``bench`` share, turned into ``RenderOptions``.
- ``values``: text to numbers, resolutions, vectors; one-line errors.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from typing import NoReturn, TextIO

from realistic import __version__
from realistic.cli.bench import add_bench_command
from realistic.cli.lens import add_lens_commands
from realistic.cli.render import add_render_command
from realistic.errors import UserError


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a bad command line as one UserError line (no usage dump)."""

    def error(self, message: str) -> NoReturn:
        raise UserError(f"{message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="realistic", description="Render through real multi-element lenses.")
    parser.add_argument("--version", action="version", version=f"realistic {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_lens_commands(commands)
    add_render_command(commands)
    add_bench_command(commands)
    return parser


#: Options whose value may look like an option (``--res -64x48``, ``--target -1,0,2``): such a value
#: is joined to its option so that the value's own check, not argparse, says what is wrong.
VALUE_OPTIONS = ("--res", "--map-res", "--camera-pos", "--target", "--focus-on", "--exposure")
#: Signals that stop a render the way Ctrl-C does: finish the passes in flight, write what is done.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


#: Options of four values that pbrt-v4 takes as one comma-separated word (``--cropwindow 0,.5,0,1``,
#: its ``cmd/pbrt.cpp``) and pbrt-v3 as four words: the word is split into the four.
FOUR_VALUE_OPTIONS = ("--cropwindow", "--pixelbounds")


def _join_dash_values(argv: list[str]) -> list[str]:
    joined: list[str] = []
    for token in argv:
        if joined and joined[-1] in VALUE_OPTIONS and token[:1] == "-" and token[1:2].isdigit():
            joined[-1] = f"{joined[-1]}={token}"
        elif joined and joined[-1] in FOUR_VALUE_OPTIONS and "," in token:
            joined.extend(token.split(","))
        else:
            joined.append(token)
    return joined


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


class _StdoutFailed(Exception):
    """Standard output refused a write or flush (``error``): not an OSError, so that only ``main``
    takes it for what it is."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


class _GuardedStdout:
    """``sys.stdout`` while a command runs: the stream itself, except that its write and flush
    failing (``| head`` closed the pipe, ``> /dev/full``) raise ``_StdoutFailed``."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as err:
            raise _StdoutFailed(err) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as err:
            raise _StdoutFailed(err) from None

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


def _stdout_lost(stream: TextIO, err: OSError) -> int:
    """After standard output failed: point it at /dev/null, so that its flush at exit does not fail
    again, and say so unless the reader just stopped reading (a broken pipe); exit status 1."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)
    except (OSError, AttributeError, ValueError):  # not a file descriptor (an embedding's stream)
        pass
    if not isinstance(err, BrokenPipeError):
        print(f"realistic: error: cannot write to standard output: {err.strerror or err}", file=sys.stderr)
    return 1


def main(argv: list[str] | None = None) -> int:
    """Run one command; a user error is one line and exit status 2, an interrupt exit status 130,
    standard output failing (a closed pipe, a full disk) exit status 1, never a traceback."""
    argv = _join_dash_values(sys.argv[1:] if argv is None else list(argv))
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = {number: signal.signal(number, _interrupt) for number in STOP_SIGNALS} if in_main_thread else {}
    stdout = sys.stdout
    if stdout is not None:
        sys.stdout = _GuardedStdout(stdout)
    try:
        args = build_parser().parse_args(argv)
        status = args.run(args)
        if sys.stdout is not None:
            sys.stdout.flush()  # here, not at exit, where a failure would be a traceback
        return status
    except UserError as err:
        print(f"realistic: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if threading.active_count() > 1:  # interrupted again while passes finish: stop at once
            print("\nrealistic: stopped at once: nothing written", file=sys.stderr, flush=True)
            os._exit(130)
        print("realistic: interrupted before the image was written: nothing written", file=sys.stderr)
        return 130
    except _StdoutFailed as failed:
        return _stdout_lost(stdout, failed.error)
    finally:
        if sys.stdout is not None and isinstance(sys.stdout, _GuardedStdout):
            sys.stdout = stdout
        for number, handler in previous.items():
            signal.signal(number, handler)
