"""``python -m realistic``: the command-line interface.

A render on the OpenCL backend starts loading the driver's compiler on a thread before anything
else is imported (``load_compiler``): the driver does it without the GIL, on a core that the
imports and the scene's reading leave idle, and the render's first program build no longer waits
for it.

A render's process asks OpenBLAS for one thread (``one_blas_thread``) before numpy is imported.
"""

import os
import sys
import threading


def renders_on_opencl(argv: list[str]) -> bool:
    """Whether ``argv`` (the command line's words) asks for a render that builds OpenCL programs: the
    render command, without --help and without the numpy backend. A guess made before argparse
    reads the line, which costs at most an unused compiler load where it is wrong."""
    return argv[:1] == ["render"] and not set(argv) & {"-h", "--help", "--backend=numpy"} \
        and ("--backend", "numpy") not in zip(argv, argv[1:])


def device_spec(argv: list[str]) -> str | None:
    """The ``--cl-device`` value in ``argv`` (the last given, as argparse keeps), or None."""
    spec = None
    for word, following in zip(argv, [*argv[1:], None]):
        if word == "--cl-device" and following is not None:
            spec = following
        elif word.startswith("--cl-device="):
            spec = word.split("=", 1)[1]
    return spec


def one_blas_thread(argv: list[str]) -> None:
    """For the render command, ``OPENBLAS_NUM_THREADS=1`` unless the user set it: numpy's and scipy's
    OpenBLAS each read it as they load and otherwise start a pool whose threads spin a while on the
    cores the render needs, and no render calls a product large enough to
    use them (tests/test_blas_threads.py). Child processes inherit it."""
    if argv[:1] == ["render"]:
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def load_compiler(spec: str | None) -> None:
    """Load the OpenCL driver's compiler on the device the render will use (``Device.load_compiler``:
    ``spec``, else ``PYOPENCL_CTX``, else the default). A device that cannot be had is left to the
    render, which meets it again and reports it in one line."""
    from realistic.device.opencl import Device
    from realistic.errors import UserError

    try:
        Device.for_spec(spec).load_compiler()
    except UserError:  # no platform, or no device matching: the render says so
        pass


if __name__ == "__main__":
    one_blas_thread(sys.argv[1:])
    if renders_on_opencl(sys.argv[1:]):
        threading.Thread(target=load_compiler, args=(device_spec(sys.argv[1:]),), name="load-compiler").start()
    try:
        from realistic.cli import main
    except KeyboardInterrupt:  # interrupted while starting up: nothing was begun
        print("realistic: interrupted while starting: nothing written", file=sys.stderr)
        raise SystemExit(130) from None

    raise SystemExit(main())
