"""The process's OpenCL plumbing: the only module that imports pyopencl.

A ``Device`` owns one OpenCL device's context and the programs built for it; the kernel hosts
(``camera/opencl_host``, ``renderer/shade_kernel``, ``scene/ewa_kernel``) take one and keep their
buffers and kernel objects on themselves, never on the scene, camera or texture they were made for.
``Device.for_spec`` makes one per (process, device spec), lazily.

Device choice, first match wins: the spec (``--cl-device``), then the ``PYOPENCL_CTX`` environment
variable, both either ``P`` / ``P:D`` (platform and device indices, as pyopencl reads
``PYOPENCL_CTX``) or a case-insensitive part of the platform or device name; otherwise the first
PoCL device, otherwise the first device found.
"""

from __future__ import annotations

import atexit
import math
import os
import threading
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from realistic.core import disk_cache
from realistic.core.data_files import data_file
from realistic.errors import UserError

try:
    import pyopencl as cl
except ImportError:  # reported as a UserError when a device is asked for
    # mypy gives ``cl`` the module's type from the import and cannot spell "the module or None" so that
    # annotations such as ``cl.Platform`` stay types; every use runs after ``_all_devices`` checked it.
    cl = None  # type: ignore[assignment]

NO_PLATFORM = ('no OpenCL platform found: install one with pip install "pyopencl[pocl]" '
               "(PoCL, OpenCL on the CPU), or use --backend numpy to run the numpy reference")
#: What clang says when the OpenCL driver's LLVM names the processor "generic": the PoCL that pip
#: installs (3.0, LLVM 14) does so for processors newer than LLVM 14 (AMD family 1Ah, Zen 5), and
#: then no kernel builds; PoCL 3.0 documents no setting for the name.
UNKNOWN_CPU = "unknown target CPU 'generic'"
UNKNOWN_CPU_ADVICE = ("the OpenCL driver's compiler does not know this processor (\"unknown target CPU 'generic'\": "
                      "PoCL 3.0's LLVM 14 predates it), so no kernel can be built: use --backend numpy, or an "
                      "OpenCL platform whose LLVM knows this CPU")
#: Work-group size; launches are padded to a multiple of it so every group runs the same code.
LOCAL_SIZE = 256
#: Programs kept built, per device, source and options (lens programs: one per lens, sampling and
#: filter; shading: one per scene variant; EWA: one): enough for a render, its autofocus and a bench's
#: sample counts; older ones are dropped (the disk cache's binaries make rebuilding one cheap).
PROGRAM_CACHE_SIZE = 16
#: The disk cache's kind for program binaries.
CACHE_KIND = "opencl-program"
#: What ``Device.load_compiler`` builds.
ONE_LINE_KERNEL = "__kernel void one_line(__global float* out) { out[get_global_id(0)] = 0.0f; }"


def kernel_source(name: str) -> str:
    """The text of ``kernels/<name>`` (in a checkout, else where a wheel installs it:
    ``<prefix>/share/realistic``) with its ``#include "common.cl"`` line replaced by that file.

    The host expands the include rather than the OpenCL compiler, so the program source (the binary
    cache's key) holds all of it and a change to ``common.cl`` rebuilds every kernel that uses it.
    """
    text = data_file(f"kernels/{name}").read_text(encoding="utf-8")
    lines = [data_file("kernels/common.cl").read_text(encoding="utf-8") if line.startswith('#include "common.cl"')
             else line for line in text.splitlines(keepends=True)]
    return "".join(lines)


def whole_groups(work_items: int) -> int:
    """``work_items`` rounded up to whole work groups of ``LOCAL_SIZE``: the launch size of every
    kernel, and the row stride of the outputs laid out by it."""
    return -(-work_items // LOCAL_SIZE) * LOCAL_SIZE


def _all_devices() -> list[tuple[int, int, cl.Platform, cl.Device]]:
    if cl is None:
        raise UserError(NO_PLATFORM)
    found = _list_devices()
    if not found:
        raise UserError(NO_PLATFORM)
    return found


def _list_devices() -> list[tuple[int, int, cl.Platform, cl.Device]]:
    try:
        platforms = cl.get_platforms()
    except cl.Error:  # PLATFORM_NOT_FOUND_KHR when the ICD loader finds nothing
        platforms = []
    return [(p, d, platform, device) for p, platform in enumerate(platforms)
            for d, device in enumerate(platform.get_devices())]


def _match(spec: str, found: list[tuple[int, int, cl.Platform, cl.Device]], origin: str) -> cl.Device:
    """The device named by ``spec`` (``P``, ``P:D`` or part of a name)."""
    parts = spec.split(":")
    if all(part.strip().isdigit() for part in parts) and len(parts) <= 2:
        p = int(parts[0])
        d = int(parts[1]) if len(parts) == 2 else 0
        hits = [entry for entry in found if entry[0] == p and entry[1] == d]
    else:
        needle = spec.lower()
        hits = [entry for entry in found
                if needle in entry[2].name.lower() or needle in entry[3].name.lower()]
    if not hits:
        listing = "; ".join(f"{p}:{d} {platform.name} / {device.name.strip()}" for p, d, platform, device in found)
        raise UserError(f"no OpenCL device matches {origin} {spec!r} (available: {listing})")
    return hits[0][3]


class TypedKernel:
    """A kernel object launched as ``cl.Kernel`` is (``kernel(queue, global_size, local_size, *args)``),
    whose scalar arguments' types pyopencl is told at its first launch (``Kernel.set_scalar_arg_dtypes``:
    each numpy scalar's dtype, None for anything else, a buffer), so that it packs them directly. Untold,
    pyopencl tries every scalar argument of every launch as a buffer, an SVM pointer, local memory, a
    sampler and a command queue before packing it, each refusal a C++ exception thrown and unwound.
    Every launch passes the types of the first (the kernel's signature)."""

    def __init__(self, program: cl.Program, name: str):
        self.kernel = cl.Kernel(program, name)
        self._typed = False

    def __call__(self, queue: cl.CommandQueue, global_size: tuple[int, ...], local_size: tuple[int, ...] | None,
                 *args: Any) -> cl.Event:
        if not self._typed:
            self.kernel.set_scalar_arg_dtypes([arg.dtype if isinstance(arg, np.generic) else None for arg in args])
            self._typed = True
        return self.kernel(queue, global_size, local_size, *args)


class OutputBlock:
    """Kernel outputs of the given (shape, dtype)s laid out in one host array (``block``), each starting
    at the device's sub-buffer alignment, under one buffer over its memory (USE_HOST_PTR, ``flags``
    besides): a launch writes each output through its sub-buffer (``parts``) and one read of ``block``
    (``read``) brings them all back. A read is a command of the queue, which wakes the driver's worker
    threads as a launch does; the reads copy nothing on PoCL's CPU device. An empty output gets one
    element's room (OpenCL has no empty buffers). ``release`` the buffers after the last read."""

    def __init__(self, device: Device, outputs: Sequence[tuple[tuple[int, ...], type[np.generic]]],
                 flags: int | None = None):
        align = max(1, device.devices[0].mem_base_addr_align // 8)  # bits to bytes
        spans = []
        end = 0
        for shape, dtype in outputs:
            nbytes = math.prod(shape) * np.dtype(dtype).itemsize
            spans.append((end, nbytes))
            end += -(-max(nbytes, np.dtype(dtype).itemsize) // align) * align
        self.block = np.empty(end, np.uint8)
        self.arrays = [self.block[start:start + nbytes].view(dtype).reshape(shape)
                       for (start, nbytes), (shape, dtype) in zip(spans, outputs)]
        self.buffer = device.host_buffer(self.block, cl.mem_flags.WRITE_ONLY if flags is None else flags)
        self.parts = [self.buffer.get_sub_region(start, max(nbytes, np.dtype(dtype).itemsize))
                      for (start, nbytes), (_, dtype) in zip(spans, outputs)]

    def read(self, queue: cl.CommandQueue) -> None:
        """Wait until every output is in ``arrays`` (one blocking read, after what is queued)."""
        cl.enqueue_copy(queue, self.block, self.buffer, is_blocking=True)

    def release(self) -> None:
        """Release the sub-buffers and the buffer (the arrays stay)."""
        for buffer in (*self.parts, self.buffer):
            buffer.release()


class Device:
    """One OpenCL device of this process: its context and the programs built for it.

    Made by ``Device.for_spec`` (one per process and spec); everything here is safe to share
    between threads (a caller that launches makes its own queue: ``queue()``).
    """

    def __init__(self, spec: str | None, origin: str):
        found = _all_devices()
        if spec:
            device = _match(spec, found, origin)
        else:
            pocl = [entry for entry in found if "portable computing language" in entry[2].name.lower()]
            device = (pocl or found)[0][3]
        self.spec = spec
        self.context = cl.Context([device])
        self._build_lock = threading.Lock()

    @staticmethod
    def for_spec(spec: str | None = None) -> Device:
        """The device ``spec`` names (``--cl-device``; None: ``PYOPENCL_CTX``, else the default),
        made once per process. No platform, or no device matching, is a UserError."""
        if spec:
            return _device_for(spec, "--cl-device")
        env = os.environ.get("PYOPENCL_CTX", "").strip()
        return _device_for(env or None, "PYOPENCL_CTX")

    @property
    def devices(self) -> list[cl.Device]:
        """The OpenCL devices of the context (one)."""
        return list(self.context.devices)

    def identity(self) -> tuple[str, ...]:
        """What a binary built here depends on besides its source: each device and its driver."""
        return tuple(f"{d.platform.name} {d.platform.version} | {d.name} {d.version} {d.driver_version}"
                     for d in self.devices)

    def queue(self) -> cl.CommandQueue:
        """A new command queue on this device (one per launching thread or kernel host)."""
        return cl.CommandQueue(self.context)

    def build_program(self, source: str, name: str, options: tuple[str, ...] = ()) -> cl.Program:
        """``source`` built with ``options`` (``build_program``), one program at a time: a thread
        asking for a program another is building waits for it and is handed the same, not a second
        build (``build_ahead``s start builds early). PoCL 3.0 builds one program at a time anyway."""
        with self._build_lock:
            return build_program(self, source, name, options)

    def load_compiler(self) -> None:
        """Build a one-line program, not kept: the driver loads its compiler and kernel library at a
        process's first build (PoCL 3.0: a few tenths of a second, without the GIL), and a render's
        first program then finds them loaded (``realistic.__main__`` starts this on a thread as the
        process starts, while the rest of it is imported and the scene read)."""
        with self._build_lock:
            try:
                cl.Program(self.context, ONE_LINE_KERNEL).build()
            except cl.Error:  # a driver that builds nothing: the render's first build reports it
                pass

    def wrapped_buffer(self, array: np.ndarray, dtype: np.dtype | type) -> cl.Buffer:
        """A read-only buffer over ``array`` as contiguous ``dtype``, not a copy (PoCL on the CPU reads
        host memory; a USE_HOST_PTR buffer keeps its host array alive); an empty array is wrapped as
        four zeros, since OpenCL has no empty buffers. The kernels' tables go through here."""
        data = np.ascontiguousarray(array, dtype).ravel()
        if data.size == 0:
            data = np.zeros(4, dtype)
        return cl.Buffer(self.context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=data)

    def copied_buffer(self, array: np.ndarray, dtype: np.dtype | type) -> cl.Buffer:
        """A read-only buffer holding a copy of ``array`` as contiguous ``dtype``."""
        data = np.ascontiguousarray(array, dtype)
        return cl.Buffer(self.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=data)

    def host_buffer(self, array: np.ndarray, flags: int) -> cl.Buffer:
        """A buffer over ``array``'s own memory (USE_HOST_PTR) with ``flags`` (``mem_flags``)."""
        return cl.Buffer(self.context, flags | cl.mem_flags.USE_HOST_PTR, hostbuf=array)

    def output_buffer(self, nbytes: int) -> cl.Buffer:
        """A write-only device buffer of ``nbytes``."""
        return cl.Buffer(self.context, cl.mem_flags.WRITE_ONLY, nbytes)

    def run_into(self, queue: cl.CommandQueue, kernel: cl.Kernel | TypedKernel, global_size: tuple[int, ...],
                 local_size: tuple[int, ...], args: tuple[Any, ...], outputs: tuple[np.ndarray, ...] | OutputBlock
                 ) -> None:
        """Launch ``kernel`` with ``args`` followed by one write-only buffer over each of ``outputs``'
        own memory (USE_HOST_PTR), and wait until the results are in those arrays: the reads copy
        nothing on PoCL's CPU device, where a copy out of a buffer of its own cost a fifth of a
        camera launch. ``outputs``: arrays, each read back by a command of its own (an empty one
        gets a scratch buffer the kernel does not write, as OpenCL has no empty buffers), or an
        ``OutputBlock``, whose parts are passed and read back with one command (and released).
        Callers serialise launches on one queue themselves, or give each thread its own queue and
        kernel.

        PoCL compiles a kernel for its work-group size when its first launch is submitted, which a
        non-blocking ``enqueue_copy`` queued behind it does inside that call, holding the GIL (every
        other thread of the render stood still for the lens kernel's compile). So the arrays' reads
        are queued after ``CommandQueue.finish``, which waits without the GIL; an ``OutputBlock``'s
        one blocking read is queued at once: pyopencl releases the GIL for a blocking read, and the
        in-order queue runs the launch (its compile too) before it, so a second wait would only add
        a round trip to the driver's threads."""
        if isinstance(outputs, OutputBlock):
            try:
                kernel(queue, global_size, local_size, *args, *outputs.parts)
                outputs.read(queue)
            finally:
                outputs.release()
            return
        flags = cl.mem_flags.WRITE_ONLY | cl.mem_flags.USE_HOST_PTR
        buffers = [cl.Buffer(self.context, flags, hostbuf=array) if array.nbytes else self.output_buffer(4)
                   for array in outputs]
        try:
            kernel(queue, global_size, local_size, *args, *buffers)
            queue.finish()  # a first launch compiles the kernel here, without the GIL (see above)
            for array, buffer in zip(outputs, buffers):
                if array.nbytes:
                    cl.enqueue_copy(queue, array, buffer, is_blocking=False)  # orders the read after the kernel
            queue.finish()
        finally:
            for buffer in buffers:
                buffer.release()

    def __repr__(self) -> str:
        return f"Device({self.spec!r}: {self.devices[0].name.strip()})"


#: The devices made, per (spec, origin): one per spec asked for, living as long as the process.
_devices: dict[tuple[str | None, str], Device] = {}
_devices_lock = threading.Lock()


def _device_for(spec: str | None, origin: str) -> Device:
    """The device for ``spec``, made on first use (under a lock, so render threads share one)."""
    with _devices_lock:
        if (spec, origin) not in _devices:
            _devices[spec, origin] = Device(spec, origin)
        return _devices[spec, origin]


@lru_cache(maxsize=PROGRAM_CACHE_SIZE)
def build_program(device: Device, source: str, name: str, options: tuple[str, ...] = ()) -> cl.Program:
    """``source`` (``kernels/<name>``, expanded by ``kernel_source``, perhaps behind a generated
    header) built for ``device`` with ``options``, once per process: the lens, shading and EWA
    kernels all build here. A build error names the kernel file.

    The built binaries are kept in the disk cache (``realistic.core.disk_cache``), keyed by the
    device, its driver, the options and the source, and checked against that key and their digest
    before they are loaded (a binary under another program's key is rebuilt, never run): PoCL caches
    its builds too, but a hit there still runs the preprocessor over the OpenCL headers, many times
    what loading a binary costs, and a render builds three. Asking PoCL for a program's binaries
    makes it compile every kernel once more, for any work-group size, which pays only for a program
    built again and again: so the first build leaves a mark, and the second stores the binaries as
    the process exits (``store_built_binaries``), not before its render; where this process's
    render repays compiling (``keep_first_builds``) the first build stores them at exit already, so
    the next process loads every program that render built. (pyopencl's own binary cache, which it
    leaves off for PoCL, is not used: it fails with a KeyError on an unwritable folder and waits a
    minute on a lock file left by a killed process.)
    """
    key = disk_cache.cache_key(CACHE_KIND, device.identity(), source.encode(), options)
    stored = disk_cache.load_arrays(key)
    try:
        program = _from_binaries(device, stored, options)
        if program is None:
            program = cl.Program(device.context, source).build(options=list(options))
            _remember(key, program, built_before=stored is not None)
    except cl.RuntimeError as err:
        if UNKNOWN_CPU in str(err):
            raise UserError(UNKNOWN_CPU_ADVICE) from None
        raise RuntimeError(f"building {name} failed:\n{err}") from None
    return program


def _from_binaries(device: Device, stored: dict[str, np.ndarray] | None, options: tuple[str, ...]
                   ) -> cl.Program | None:
    """The program from a cache entry's binaries, one per device (non-empty uint8 rows), or None:
    no entry, a first build's mark, anything else, or binaries the driver will not load (a cache
    entry is never an error)."""
    names = [f"device{i}" for i in range(len(device.devices))]
    if stored is None or sorted(stored) != names \
            or any(stored[n].dtype != np.uint8 or stored[n].ndim != 1 or not stored[n].size for n in names):
        return None
    try:
        return cl.Program(device.context, device.devices,
                          [stored[n].tobytes() for n in names]).build(options=list(options))
    except cl.Error:
        return None


#: Programs built from source whose binaries ``store_built_binaries`` stores: built for the second
#: time, or for the first while ``keep_first_builds`` is on.
_unstored: list[tuple[str, cl.Program]] = []
#: Whether a program's first build stores its binaries at exit (``keep_first_builds``).
_keeping_first_builds = [False]


def keep_first_builds(wanted: bool) -> None:
    """Whether programs built from source for the first time from now on store their binaries as
    the process exits, or only leave a mark (the binaries wait for a second build). Set by each
    render (``OpenCLBackend.build_ahead``): on for one that repays compiling
    (``renderer.runner.repays_compiling``), whose process already pays seconds of compiles, so that
    the next process loads every program it built; off for a small one, whose process exits
    without the compile that asking PoCL for binaries costs."""
    _keeping_first_builds[0] = wanted


def _remember(key: str, program: cl.Program, built_before: bool) -> None:
    """After a build from source: a mark the first time; the binaries at exit from the second on,
    or from the first where ``keep_first_builds`` is on. Nothing with the disk cache off."""
    if disk_cache.cache_dir() is None:
        return
    if not built_before:
        disk_cache.store_arrays(key, {"built": np.zeros(1, np.uint8)})
    if built_before or _keeping_first_builds[0]:
        _unstored.append((key, program))


def leave_binaries_unstored(program: cl.Program) -> None:
    """Store no binaries of ``program`` at exit: one built only to be timed against another and
    not used (``LensKernel``'s rays per work item), whose binaries would cost a compile of every
    kernel and never be loaded."""
    _unstored[:] = [(key, built) for key, built in _unstored if built is not program]


@atexit.register  # after pyopencl's own exit handler is registered, so it runs first
def store_built_binaries() -> None:
    """Store the binaries of the programs ``build_program`` left to store (``_remember``). Run as
    the process exits, when the image is written: asking PoCL for binaries compiles every kernel
    again. An interrupt or a driver's refusal leaves the rest unstored."""
    if cl is None:
        return
    try:
        while _unstored:
            key, program = _unstored.pop()
            binaries = program.get_info(cl.program_info.BINARIES)
            if isinstance(binaries, list) and all(binaries):  # get_info is typed as returning object
                disk_cache.store_arrays(key, {f"device{i}": np.frombuffer(b, np.uint8)
                                              for i, b in enumerate(binaries)})
    except (KeyboardInterrupt, cl.Error):
        _unstored.clear()
