"""Loops compiled by numba on first use: ``nogil`` (several render threads run them at once) and
cached on disk where numba finds a writable cache directory (``$NUMBA_CACHE_DIR``, else
``__pycache__`` beside the module, else the user's cache), as ``realistic.scene.packet_loop``'s
loops are. numba is imported on the first call, not with the package, so ``import realistic`` and
``--help`` stay quick."""

from __future__ import annotations

import threading
from collections.abc import Callable
from functools import partial
from typing import Any

#: Whether the loops run compiled (``compiled_loops``): one flag for the process, set per render.
_use_compiled = [True]
#: Each loop's dispatcher and the signature it was made for (None: the types of each call).
_compiled: dict[Callable[..., Any], tuple[Callable[..., Any], str | None]] = {}
_lock = threading.Lock()


def compiled(loop: Callable[..., Any], signature: str | None = None) -> Callable[..., Any]:
    """``loop`` as a numba dispatcher (``njit(nogil=True, cache=True)``; uncached where no cache
    directory is writable), made once per process; it compiles, or loads from numba's cache, on its
    first call, for the argument types of each call, or, given a ``signature`` (numba's string form),
    once, now, for that signature alone: a call with arrays of another layout (a strided view, a
    transposed one, a contiguous one) converts to it rather than compiling the loop again."""
    with _lock:
        if loop not in _compiled:
            import numba

            jit = numba.njit if signature is None else partial(numba.njit, signature)
            try:
                _compiled[loop] = jit(nogil=True, cache=True)(loop), signature
            except RuntimeError:  # numba found no writable cache directory
                _compiled[loop] = jit(nogil=True)(loop), signature
        dispatcher, made_for = _compiled[loop]
        if made_for != signature:
            raise ValueError(f"{loop.__qualname__} was compiled for {made_for!r}, not {signature!r}")
        return dispatcher


def use_compiled_loops(wanted: bool) -> None:
    """Run the loops compiled from now on where ``wanted`` or where numba has made any already in
    this process (they are then cheap); otherwise their numpy forms, each giving the same bits.
    A render too small to repay numba's import and first compiles (a second or so of one core,
    holding the GIL) asks for the numpy forms (``renderer.passes.ThreadPasses.open``)."""
    with _lock:
        _use_compiled[0] = wanted or bool(_compiled)


def compiled_loops() -> bool:
    """Whether the loops run compiled (``use_compiled_loops``; True until a render says otherwise)."""
    return _use_compiled[0]
