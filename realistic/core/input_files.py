"""Input files as the command line names them: one check of what a path is before it is opened,
and one reader of JSON documents that turns every malformed document into a one-line error.

Opening a FIFO blocks until something writes to it, and a directory or a device is no prescription,
scene or mesh: ``input_file`` looks at the path (without opening it) and says which it is, so that
a missing file, a directory and a named pipe each get their own words instead of "not found" or a
hang. ``read_input`` then reads at most ``MAX_INPUT_BYTES`` of it.
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Callable
from pathlib import Path

from realistic.errors import UserError

#: Largest input text read whole (lens files, rays JSON): far beyond any real prescription or ray list.
MAX_INPUT_BYTES = 256 * 2**20

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def file_error(path: str, line: int | None, message: str) -> UserError:
    """A UserError ``path:line: message`` (the default kind of error of this module's functions)."""
    return UserError(f"{path}:{line}: {message}" if line is not None else f"{path}: {message}")


#: Makes the error for a file, a line (or None) and a message: ``file_error``, or ``LensFileError``.
ErrorKind = Callable[[str, int | None, str], UserError]


def input_file(path: str | Path, what: str, missing: str = "", error: ErrorKind = file_error) -> Path:
    """``path`` when it names a regular file (links followed), else ``error`` saying what it is:
    missing (``missing`` is added to "no such WHAT"), a directory, a FIFO, a device or a socket
    (``what`` names the expected file)."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise error(str(path), None, f"no such {what}{missing}") from None
    except (OSError, ValueError) as err:  # a name too long, a NUL byte, a folder we may not enter
        raise error(str(path), None, f"cannot read {what}: {getattr(err, 'strerror', None) or err}") from None
    if not stat.S_ISREG(mode):
        kind = next((words for test, words in _KINDS if test(mode)), "a special file")
        article = "an" if what[:1] in "aeiou" else "a"
        raise error(str(path), None, f"is {kind}, not {article} {what}")
    return path


def read_input(path: str | Path, what: str, missing: str = "", error: ErrorKind = file_error,
               limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of the regular file ``path`` (``input_file``), at most ``limit`` of them."""
    path = input_file(path, what, missing, error)
    try:
        with open(path, "rb") as stream:
            data = stream.read(limit + 1)
    except OSError as err:
        raise error(str(path), None, f"cannot read {what}: {err.strerror or err}") from None
    if len(data) > limit:
        raise error(str(path), None, f"{what} is larger than {limit // 2**20} MiB")
    return data


def decode_text(data: bytes, path: str | Path, what: str, error: ErrorKind = file_error) -> str:
    """UTF-8 text (a byte-order mark dropped), or ``error`` naming the first byte that is not UTF-8."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise error(str(path), line, f"{what} is not UTF-8 text (byte 0x{data[err.start]:02x})") from None


class _NumberOutOfRange(ValueError):
    """A JSON number beyond a double's range (``1e400``, a 400-digit integer)."""

    def __init__(self, literal: str):
        super().__init__(literal)
        self.literal = literal


def _double(literal: str) -> float:
    """A JSON number as a float, refusing what a double cannot hold (``float`` would give inf)."""
    value = float(literal)  # a decimal string of any length converts in linear time
    if value in (float("inf"), float("-inf")):
        raise _NumberOutOfRange(literal)
    return value


def _line_of(text: str, literal: str) -> int:
    match = re.search(r"(?<![\w.])" + re.escape(literal) + r"(?![\w.])", text)
    return text.count("\n", 0, match.start()) + 1 if match else 1


def parse_json(text: str, path: str | Path, error: ErrorKind = file_error) -> object:
    """The JSON document ``text`` from ``path``, numbers as floats, or ``error(path, line, message)``
    (a lens reader passes ``LensFileError``): invalid JSON, nesting too deep for the reader, or a
    number a double cannot hold (``1e400``, a 400-digit integer) rather than a silent infinity.
    ``Infinity`` and ``NaN``, which isetlens writes and Python reads, stay for the caller's checks of
    each quantity."""
    try:
        return json.loads(text, parse_int=_double, parse_float=_double)
    except json.JSONDecodeError as err:
        raise error(str(path), err.lineno, f"not valid JSON: {err.msg}") from None
    except _NumberOutOfRange as err:
        shown = err.literal[:24] + ("..." if len(err.literal) > 24 else "")
        raise error(str(path), _line_of(text, err.literal), f"the number {shown} is beyond a double's range") from None
    except RecursionError:
        raise error(str(path), None, "not valid JSON: nested too deeply") from None
