"""Errors that reach the user as one line and exit status 2 (never a traceback)."""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user: the CLI prints the message alone and exits with status 2."""


class LensFileError(UserError):
    """A prescription that cannot be read; the message names the file, the line and the value."""

    def __init__(self, path: str, line: int | None, message: str):
        self.path, self.line, self.message = path, line, message
        where = f"{path}:{line}" if line is not None else path
        super().__init__(f"{where}: {message}")
