"""Writing output files so that a failure leaves no partial file, and checking writability first.

A file is written as a hidden temporary beside it, ``.NAME.PID.XXXX.tmp.EXT``, then renamed into
place. A process killed mid-write (SIGKILL, power loss) can strand its temporary; the next write
of the same name removes temporaries whose process is gone.
"""

from __future__ import annotations

import glob
import os
import re
import tempfile
from collections.abc import Callable
from pathlib import Path

from realistic.errors import UserError


def check_writable(path: Path) -> None:
    """Raise UserError now, before any work, if ``path`` cannot be written (a file is created and
    removed beside it, so places that refuse files whatever their permissions say, such as /proc,
    are caught too)."""
    folder = _folder(path)
    if path.is_dir():
        raise UserError(f"{path}: cannot write the image: it is a directory")
    if not folder.is_dir():
        raise UserError(f"{path}: cannot write the image: directory {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UserError(f"{path}: cannot write the image: permission denied")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=_temporary_prefix(path), suffix=".probe"):
            pass
    except OSError as err:
        raise UserError(f"{path}: cannot write the image: {err.strerror or err}") from None


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _temporary_prefix(path: Path) -> str:
    return f".{path.name}.{os.getpid()}."


def _process_is_gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # exists, but belongs to someone else
        return False
    return False


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Remove ``.NAME.PID.*.tmp*`` temporaries of ``path`` left by processes that no longer run."""
    removed = []
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.(\d+)\..+\.(tmp\b.*|probe)$")
    for candidate in _folder(path).glob(f".{glob.escape(path.name)}.*"):
        match = pattern.match(candidate.name)
        if match and _process_is_gone(int(match.group(1))):
            candidate.unlink(missing_ok=True)
            removed.append(candidate)
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomically(path: Path, write: Callable[[str], object]) -> None:
    """Call ``write(temporary_path)`` (its result is ignored) next to ``path``, then rename; no partial file is
    left on error."""
    path = Path(path)
    remove_stale_temporaries(path)
    try:
        handle, temporary = tempfile.mkstemp(prefix=_temporary_prefix(path), suffix=".tmp" + path.suffix,
                                             dir=_folder(path))
    except OSError as err:
        raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
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
