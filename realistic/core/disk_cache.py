"""A cache of computed arrays on disk, keyed by a hash of what they were computed from.

Used for results that take a noticeable fraction of a small render to compute and depend only on
a few numbers or a text: the exit-pupil table, the OpenCL programs' binaries. Entries live in
``$REALISTIC_CACHE_DIR``, else ``$XDG_CACHE_HOME/realistic``, else ``~/.cache/realistic``;
``REALISTIC_CACHE_DIR=off`` turns the cache off. The cache is an optimisation only: an unreadable,
corrupt or unwritable entry is recomputed, never an error.

Every entry carries its full key and a sha256 digest of its arrays (names, dtypes, shapes and
bytes), checked before use: an entry copied under another key, truncated or altered reads as
absent, so what is run or used is always what was stored under that key.
"""

from __future__ import annotations

import hashlib
import io
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from realistic.core.atomic_files import write_atomically
from realistic.errors import UserError

OFF = "off"
#: Names of the arrays every entry carries besides its own: its key and its content's digest.
KEY_FIELD, DIGEST_FIELD = "__key__", "__digest__"


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
    """A file-name-safe hash of ``parts`` (bytes, numbers, strings, tuples of them) under ``kind``:
    the whole sha256, which is also what the entry carries inside (``KEY_FIELD``)."""
    digest = hashlib.sha256(kind.encode())
    for part in parts:
        digest.update(part if isinstance(part, bytes) else repr(part).encode())
        digest.update(b"\0")
    return f"{kind}-{digest.hexdigest()}"


def content_digest(arrays: dict[str, np.ndarray]) -> str:
    """sha256 (hex) of ``arrays``: each name, dtype, shape and bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}\0{array.dtype.str}\0{array.shape}\0".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def _text(array: np.ndarray) -> str:
    """A key or digest stored as uint8 bytes, back as text ('' for anything else)."""
    return array.tobytes().decode("ascii", "replace") if array.dtype == np.uint8 and array.ndim == 1 else ""


def load_arrays(key: str) -> dict[str, np.ndarray] | None:
    """The arrays stored under ``key``, or None when absent, unreadable, or not verified: the key
    inside is not ``key``, or the content's digest is not the one stored with it."""
    folder = cache_dir()
    if folder is None:
        return None
    try:
        with np.load(folder / f"{key}.npz", allow_pickle=False) as stored:
            arrays = {name: stored[name] for name in stored.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    stored_key, stored_digest = arrays.pop(KEY_FIELD, None), arrays.pop(DIGEST_FIELD, None)
    if stored_key is None or stored_digest is None or _text(stored_key) != key \
            or _text(stored_digest) != content_digest(arrays):
        return None
    return arrays


def store_arrays(key: str, arrays: dict[str, np.ndarray]) -> None:
    """Store ``arrays`` under ``key`` (atomically) with the key and their digest; a folder or disk
    that cannot take it (unwritable, full) is skipped: a cache is never an error, at exit neither."""
    folder = cache_dir()
    if folder is None:
        return
    if KEY_FIELD in arrays or DIGEST_FIELD in arrays:
        raise ValueError(f"{KEY_FIELD} and {DIGEST_FIELD} are the cache's own array names")
    buffer = io.BytesIO()
    entries: dict[str, Any] = {**arrays, KEY_FIELD: np.frombuffer(key.encode("ascii"), np.uint8),
                               DIGEST_FIELD: np.frombuffer(content_digest(arrays).encode("ascii"), np.uint8)}
    np.savez(buffer, **entries)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_atomically(folder / f"{key}.npz", lambda temporary: Path(temporary).write_bytes(buffer.getvalue()))
    except (OSError, UserError):  # a full or unwritable disk: the entry is skipped, as a cache may be
        return
