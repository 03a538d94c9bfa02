"""Writing output files so that a failure leaves no partial file, and checking writability first.

A file is written as a hidden temporary beside it, ``.NAME.PID.XXXX.tmp.EXT``, then renamed into
place. A process killed mid-write (SIGKILL, power loss) can strand its temporary; the next write
of the same name removes temporaries whose process is gone. The rename would replace whatever the
name is, so only regular files (or new names) are written: a device, pipe or socket is refused
(``check_writable`` before the work, ``write_atomically`` again at the rename). Ctrl-C, SIGTERM and
SIGHUP wait until a write has finished (``signals_deferred``), so finished work is never cut off
half written.
"""

from __future__ import annotations

import glob
import os
import re
import signal
import stat
import tempfile
import threading
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Protocol

from realistic.errors import UserError

#: The signals that stop a render (Ctrl-C and the CLI's SIGTERM and SIGHUP): held while a write runs.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
_held = {"depth": 0}


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold ``STOP_SIGNALS`` while the block runs and deliver the first that came once it ends, to
    the handler that was there before: a write that has begun completes, then the interrupt acts.

    Only the main thread handles signals, so elsewhere (and inside an outer block) this does nothing."""
    if threading.current_thread() is not threading.main_thread() or _held["depth"]:
        yield
        return
    received: list[int] = []

    def hold(signum: int, frame: object) -> None:
        received.append(signum)

    previous = {number: signal.signal(number, hold) for number in STOP_SIGNALS}
    _held["depth"] = 1
    try:
        yield
    finally:
        _held["depth"] = 0
        for number, handler in previous.items():
            signal.signal(number, handler if handler is not None else signal.SIG_DFL)
        if received:
            signal.raise_signal(received[0])


def check_writable(path: Path, suffixes: Collection[str] | None = None) -> None:
    """Raise UserError now, before any work, if ``path`` cannot be written: its folder is missing or
    refuses files (one is created and removed beside it, so places that refuse files whatever their
    permissions say, such as /proc, are caught too), it is not a regular file, or its name does not
    end in one of ``suffixes`` (lower case, with the dot) when they are given."""
    path = Path(path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise UserError(f"{path}: cannot be written: the name must end in {', '.join(sorted(suffixes))}")
    folder = _folder(path)
    try:
        if path.is_dir():
            raise UserError(f"{path}: cannot be written: it is a directory")
        if not folder.is_dir():
            raise UserError(f"{path}: cannot be written: directory {folder} does not exist")
        refuse_unless_regular(path)
        if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
            raise UserError(f"{path}: cannot be written: permission denied")
        with tempfile.NamedTemporaryFile(dir=folder, prefix=_temporary_prefix(path), suffix=".probe"):
            pass
    except OSError as err:
        raise UserError(f"{path}: cannot be written: {err.strerror or err}") from None


def refuse_unless_regular(path: Path) -> None:
    """UserError unless ``path`` is missing or a regular file (symbolic links followed): the rename
    into place would replace a device, pipe or socket with a file."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as err:
        raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
    if not stat.S_ISREG(mode):
        raise UserError(f"{path}: cannot write: it is not a regular file (a device, pipe or socket); name a file")


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
    left on error, a non-regular ``path`` is refused, and interrupts wait until the write is done
    (``signals_deferred``)."""
    path = Path(path)
    with signals_deferred():
        try:
            remove_stale_temporaries(path)
            refuse_unless_regular(path)
            handle, temporary = tempfile.mkstemp(prefix=_temporary_prefix(path), suffix=".tmp" + path.suffix,
                                                 dir=_folder(path))
        except OSError as err:
            raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
        os.close(handle)
        try:
            write(temporary)
            os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes 0600: give the file ordinary permissions
            refuse_unless_regular(path)  # again: the name may have been replaced meanwhile
            os.replace(temporary, path)
        except BaseException as err:
            Path(temporary).unlink(missing_ok=True)
            if isinstance(err, OSError):
                raise UserError(f"{path}: cannot write: {err.strerror or err}") from None
            raise


class Figure(Protocol):
    """What ``save_figure`` needs of a matplotlib figure."""

    def savefig(self, fname: str, *, dpi: int, format: str) -> object: ...  # noqa: A002 (matplotlib's name)


def save_figure(figure: Figure, path: Path, dpi: int) -> None:
    """A matplotlib ``figure`` written to ``path`` as ``write_atomically`` writes (no partial file, no
    non-regular target replaced, interrupts wait), in the format the path's suffix names."""
    path = Path(path)
    write_atomically(path, lambda temporary: figure.savefig(temporary, dpi=dpi, format=path.suffix[1:].lower()))


def write_text_atomically(path: Path, text: str) -> None:
    """``text`` as UTF-8 at ``path``, written atomically."""
    write_atomically(Path(path), lambda temporary: Path(temporary).write_text(text, encoding="utf-8"))
