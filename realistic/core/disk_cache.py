"""A cache of computed arrays on disk, keyed by a hash of what they were computed from.

Used for results that take a noticeable fraction of a small render to compute and depend only on
a few numbers or a text: the exit-pupil table, the OpenCL programs' binaries. Entries live in
``$REALISTIC_CACHE_DIR``, else ``$XDG_CACHE_HOME/realistic``, else ``~/.cache/realistic``;
``REALISTIC_CACHE_DIR=off`` turns the cache off. The cache is an optimisation only: an unreadable,
corrupt or unwritable entry is recomputed, never an error.
"""

from __future__ import annotations

import hashlib
import io
import os
import zipfile
from pathlib import Path

import numpy as np

from realistic.core.atomic_files import write_atomically

OFF = "off"


def cache_dir() -> Path | None:
    """The cache folder, or None when the cache is turned off: ``$REALISTIC_CACHE_DIR``, else the
    platform's user cache folder for "realistic" (platformdirs; on Linux ``$XDG_CACHE_HOME/realistic``,
    else ``~/.cache/realistic``)."""
    chosen = os.environ.get("REALISTIC_CACHE_DIR")
    if chosen == OFF:
        return None
    if chosen:
        return Path(chosen)
    import platformdirs

    return Path(platformdirs.user_cache_dir("realistic", appauthor=False))


def cache_key(kind: str, *parts: object) -> str:
    """A file-name-safe hash of ``parts`` (bytes, numbers, strings, tuples of them) under ``kind``."""
    digest = hashlib.sha256(kind.encode())
    for part in parts:
        digest.update(part if isinstance(part, bytes) else repr(part).encode())
        digest.update(b"\0")
    return f"{kind}-{digest.hexdigest()[:32]}"


def load_arrays(key: str) -> dict[str, np.ndarray] | None:
    """The arrays stored under ``key``, or None when absent or unreadable."""
    folder = cache_dir()
    if folder is None:
        return None
    try:
        with np.load(folder / f"{key}.npz", allow_pickle=False) as stored:
            return {name: stored[name] for name in stored.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None


def store_arrays(key: str, arrays: dict[str, np.ndarray]) -> None:
    """Store ``arrays`` under ``key`` (atomically); a folder that cannot be written is skipped."""
    folder = cache_dir()
    if folder is None:
        return
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_atomically(folder / f"{key}.npz", lambda temporary: Path(temporary).write_bytes(buffer.getvalue()))
    except OSError:
        return
