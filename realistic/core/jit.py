"""Loops compiled by numba on first use: ``nogil`` (several render threads run them at once) and
cached on disk where numba finds a writable cache directory (``$NUMBA_CACHE_DIR``, else
``__pycache__`` beside the module, else the user's cache), as ``realistic.scene.packet_loop``'s
loops are. numba is imported on the first call, not with the package, so ``import realistic`` and
``--help`` stay quick."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

_compiled: dict[Callable[..., Any], Callable[..., Any]] = {}
_lock = threading.Lock()


def compiled(loop: Callable[..., Any]) -> Callable[..., Any]:
    """``loop`` as a numba dispatcher (``njit(nogil=True, cache=True)``; uncached where no cache
    directory is writable), made once per process; it compiles, or loads from numba's cache, on its
    first call."""
    with _lock:
        if loop not in _compiled:
            import numba

            try:
                _compiled[loop] = numba.njit(nogil=True, cache=True)(loop)
            except RuntimeError:  # numba found no writable cache directory
                _compiled[loop] = numba.njit(nogil=True)(loop)
        return _compiled[loop]
