"""Tokens of the pbrt scene language (v1 to v4), each with the file and line it came from."""

from __future__ import annotations

import gzip
import math
import re
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from realistic.errors import UserError

_TOKEN = re.compile(r'''
    (?P<space>[ \t\r]+) | (?P<newline>\n) | (?P<comment>\#[^\n]*)
  | (?P<string>"(?:[^"\\\n]|\\.)*") | (?P<open>\[) | (?P<close>\])
  | (?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![A-Za-z_]))
  | (?P<word>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<bad>.)
''', re.VERBOSE)


#: Backslash escapes inside strings: pbrt-v2 ``src/core/pbrtlex.ll`` and pbrt-v3/v4 ``parser.cpp``
#: (``decodeEscaped``) agree on these; any other escaped character stands for itself (pbrt-v2's rule).
_ESCAPES = {"b": "\b", "f": "\f", "n": "\n", "r": "\r", "t": "\t"}
_ESCAPED = re.compile(r"\\(.)")


def _unescape(text: str) -> str:
    return _ESCAPED.sub(lambda m: _ESCAPES.get(m.group(1), m.group(1)), text) if "\\" in text else text


class PbrtSyntaxError(UserError):
    """A scene file that cannot be read: the message names the file, the line and what was expected."""

    def __init__(self, path: str | Path, line: int, message: str):
        super().__init__(f"{path}:{line}: {message}")


@dataclass(frozen=True)
class Token:
    kind: str  # "string", "number", "word", "[" or "]"
    text: str
    path: Path
    line: int

    @property
    def value(self) -> str | float:
        if self.kind == "string":
            return _unescape(self.text[1:-1])
        if self.kind == "number":
            return float(self.text)
        return self.text

    def where(self) -> str:
        return f"{self.path}:{self.line}"


#: Most text a gzip-compressed scene file may inflate to (a few hundred MB is a very large scene).
MAX_GZIP_TEXT_BYTES = 1 << 30


def read_scene_text(path: Path) -> str:
    """The text of a scene file (gzip-compressed when its name ends in .gz, as pbrt-v4's
    ``Tokenizer::CreateFromFile`` reads it), or a UserError naming it."""
    try:
        if path.suffix.lower() == ".gz":  # read only up to the cap: a small file can inflate to gigabytes
            with gzip.open(path) as stream:
                data = stream.read(MAX_GZIP_TEXT_BYTES + 1)
            if len(data) > MAX_GZIP_TEXT_BYTES:
                raise UserError(f"{path}: decompresses to more than {MAX_GZIP_TEXT_BYTES >> 30} GiB of scene text")
        else:
            data = path.read_bytes()
    except OSError as err:  # gzip.BadGzipFile is one
        raise UserError(f"{path}: cannot read scene file: {err.strerror or err}") from None
    except (EOFError, zlib.error) as err:
        raise UserError(f"{path}: cannot read scene file: a damaged gzip stream ({err or 'cut short'})") from None
    return data.decode("utf-8", errors="replace")


def tokenize(text: str, path: Path) -> Iterator[Token]:
    """Tokens of ``text``; a stray character or a number beyond a double's range is a syntax error at its line."""
    line = 1
    for match in _TOKEN.finditer(text):
        kind = match.lastgroup or "bad"  # never None: every alternative of _TOKEN is a named group
        if kind == "newline":
            line += 1
        elif kind in ("space", "comment"):
            continue
        elif kind == "bad":
            if match.group() == '"':
                raise PbrtSyntaxError(path, line, "unterminated string")
            raise PbrtSyntaxError(path, line, f"unexpected character {match.group()!r}")
        elif kind == "open":
            yield Token("[", "[", path, line)
        elif kind == "close":
            yield Token("]", "]", path, line)
        else:
            if kind == "number" and not math.isfinite(float(match.group())):
                text = match.group()
                shown = text if len(text) <= 24 else f"{text[:16]}... ({len(text)} characters)"
                raise PbrtSyntaxError(path, line, f"number {shown} is too large for a double")
            yield Token(kind, match.group(), path, line)
