"""Writing output files so that a failure leaves no partial file, and checking writability first."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from realistic.errors import UserError


def check_writable(path: Path) -> None:
    """Raise UserError now, before any work, if ``path`` cannot be written."""
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise UserError(f"{path}: cannot write the image: it is a directory")
    if not folder.is_dir():
        raise UserError(f"{path}: cannot write the image: directory {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UserError(f"{path}: cannot write the image: permission denied")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomically(path: Path, write: Callable[[str], None]) -> None:
    """Call ``write(temporary_path)`` next to ``path``, then rename; no partial file is left on error."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix,
                                         dir=path.parent if str(path.parent) else ".")
    os.close(handle)
    try:
        write(temporary)
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes 0600: give the file ordinary permissions
        os.replace(temporary, path)
    except BaseException as err:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(err, OSError):
            raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
        raise


def write_text_atomically(path: Path, text: str) -> None:
    """``text`` as UTF-8 at ``path``, written atomically."""
    write_atomically(Path(path), lambda temporary: Path(temporary).write_text(text, encoding="utf-8"))
