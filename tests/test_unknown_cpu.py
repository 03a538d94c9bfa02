"""A processor the OpenCL driver's LLVM cannot name: the build failure PoCL 3.0 (LLVM 14) gives on
CPUs newer than LLVM 14 becomes a one-line UserError that says what to do."""

import pytest

from realistic.errors import UserError

opencl = pytest.importorskip("realistic.device.opencl")

pytestmark = pytest.mark.usefixtures("opencl_platform")


def test_a_cpu_llvm_calls_generic_is_a_user_error():
    """The build fails with clang's message for that processor (here from an #error, the same build
    log PoCL gives), and the user is told to use the numpy backend."""
    source = f'#error "{opencl.UNKNOWN_CPU}"\n__kernel void k(__global float *x) {{ x[0] = 1.0f; }}\n'
    with pytest.raises(UserError) as raised:
        opencl.Device.for_spec().build_program(source, "simulated.cl")
    assert "--backend numpy" in str(raised.value)
    assert "\n" not in str(raised.value)


def test_other_build_errors_keep_their_log():
    source = "__kernel void k(__global float *x) { x[0] = undeclared; }\n"
    with pytest.raises(RuntimeError, match="(?s)building broken.cl failed:.*undeclared"):
        opencl.Device.for_spec().build_program(source, "broken.cl")
