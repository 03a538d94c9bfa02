"""EWA MIP-map lookups on the OpenCL device (``kernels/ewa.cl``), for the "opencl" backend.

The numpy ``MipMap.ewa`` expands every (lookup, texel) tap into flat arrays: about 0.07 M lookups/s,
the largest cost of a homework render's floor. The kernel runs the same mathematics per lookup in
double precision (one work-item loops over its ellipse), so it agrees with the reference to float32
rounding; ``tests/test_ewa_kernel.py`` checks that.
"""

from __future__ import annotations

import threading

import numpy as np
import pyopencl as cl

from realistic.camera.opencl_host import LOCAL_SIZE, build_program, context, kernel_source
from realistic.core.validation import TEXTURE_WRAPS
from realistic.scene.mipmap import EWA_WEIGHTS, MipMap

KERNEL_FILE = "ewa.cl"


class EwaKernel:
    """One MIP map's texels on the device, and EWA lookups over them (thread-safe: one lock)."""

    def __init__(self, mipmap: MipMap, device: str | None = None):
        self.context = context(device)
        self.queue = cl.CommandQueue(self.context)
        self._kernel = cl.Kernel(build_program(self.context, kernel_source(KERNEL_FILE), KERNEL_FILE), "ewa")
        mf = cl.mem_flags

        def constant(array: np.ndarray, dtype) -> cl.Buffer:
            # wrapped, not copied (PoCL on the CPU reads host memory), so the texels are not held twice;
            # a USE_HOST_PTR buffer keeps its host array alive
            return cl.Buffer(self.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=np.ascontiguousarray(array, dtype))

        self._tables = [constant(mipmap.texels, np.float32)] + [
            constant(a, np.int64) for a in (mipmap.level_base, mipmap.level_width, mipmap.level_height)]
        self._wrap, self._levels = np.int32(TEXTURE_WRAPS.index(mipmap.wrap)), np.int32(mipmap.level_count)
        self._max_anisotropy = np.float64(mipmap.max_anisotropy)
        self._lut = constant(EWA_WEIGHTS, np.float64)
        self._lock = threading.Lock()

    def __call__(self, st: np.ndarray, axis0: np.ndarray, axis1: np.ndarray) -> np.ndarray:
        """Filtered colours (N, 3) float32 at (s, t) (N, 2) over ellipses with axes (N, 2) each."""
        count = len(st)
        out = np.empty((count, 3), np.float32)
        if count == 0:
            return out
        mf = cl.mem_flags
        inputs = [cl.Buffer(self.context, mf.READ_ONLY | mf.COPY_HOST_PTR,
                            hostbuf=np.ascontiguousarray(a, dtype=np.float64)) for a in (st, axis0, axis1)]
        result = cl.Buffer(self.context, mf.WRITE_ONLY, out.nbytes)
        padded = -(-count // LOCAL_SIZE) * LOCAL_SIZE
        with self._lock:
            self._kernel(self.queue, (padded,), (LOCAL_SIZE,), *self._tables, self._wrap, self._levels,
                         self._max_anisotropy, self._lut, *inputs, np.int32(count), result)
            cl.enqueue_copy(self.queue, out, result)
        return out
