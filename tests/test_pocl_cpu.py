"""PoCL's CPU device named by its x86-64 level where LLVM calls the CPU "generic" (realistic.camera.pocl_cpu)."""

import ctypes
import mmap
import platform

import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.camera import pocl_cpu

LEVEL_NAMES = ["x86-64"] + [name for name, _ in pocl_cpu.X86_64_LEVELS]
LIBC = ctypes.CDLL(None)
LIBC.malloc.restype = ctypes.c_void_p
LIBC.malloc.argtypes = [ctypes.c_size_t]
LIBC.free.argtypes = [ctypes.c_void_p]


def flags_through(level: int) -> set[str]:
    """Every flag of the levels up to ``level`` (1 = v2, 3 = v4)."""
    return set().union(*(added for _, added in pocl_cpu.X86_64_LEVELS[:level]))


@pytest.mark.parametrize("level", range(4))
def test_each_levels_flags_give_that_level(level):
    assert pocl_cpu.x86_64_level(flags_through(level) | {"fpu", "sse", "sse2"}) == LEVEL_NAMES[level]


@given(st.integers(1, 3), st.data(), st.sets(st.sampled_from(["aes", "sha_ni", "avx512_bf16", "rdrand"])))
def test_a_missing_flag_drops_below_its_level_and_extra_flags_change_nothing(level, data, extra):
    flags = flags_through(level) | extra
    assert pocl_cpu.x86_64_level(flags) == LEVEL_NAMES[level]
    missing = data.draw(st.sampled_from(sorted(pocl_cpu.X86_64_LEVELS[level - 1][1])))
    assert LEVEL_NAMES.index(pocl_cpu.x86_64_level(flags - {missing})) < level


@given(st.text())
def test_cpuinfo_of_any_text_reads_as_a_set_of_flags(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("cpuinfo") / "cpuinfo"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    flags = pocl_cpu.host_cpu_flags(path)
    assert isinstance(flags, set) and all(isinstance(flag, str) and flag for flag in flags)


def test_cpuinfo_flags_are_the_first_processors(tmp_path):
    path = tmp_path / "cpuinfo"
    path.write_text("processor\t: 0\nflags\t\t: fpu avx2 fma\n\nprocessor\t: 1\nflags\t\t: fpu\n")
    assert pocl_cpu.host_cpu_flags(path) == {"fpu", "avx2", "fma"}
    assert pocl_cpu.host_cpu_flags(tmp_path / "absent") == set()


def heap_string(text: bytes) -> int:
    address = LIBC.malloc(len(text) + 1)
    ctypes.memmove(address, text + b"\0", len(text) + 1)
    return address


linux_only = pytest.mark.skipif(platform.system() != "Linux", reason="reads /proc/self/maps")


@linux_only
def test_only_the_pointer_to_a_heap_generic_string_is_rewritten():
    unknown, longer = heap_string(b"generic"), heap_string(b"generics")
    try:
        # a struct of: a small integer (not an address), a pointer to "generics", then the one to rewrite
        struct = (ctypes.c_uint64 * 4)(12345, longer, unknown, 0)
        assert pocl_cpu.rewrite_cpu_name(ctypes.addressof(struct), ctypes.sizeof(struct), "x86-64-v3")
        assert ctypes.string_at(unknown) == b"x86-64-v3"
        assert ctypes.string_at(longer) == b"generics"
        assert list(struct) == [12345, longer, unknown, 0]
        assert not pocl_cpu.rewrite_cpu_name(ctypes.addressof(struct), ctypes.sizeof(struct), "x86-64-v3")
    finally:
        LIBC.free(unknown)
        LIBC.free(longer)


@linux_only
def test_a_generic_string_outside_the_heap_is_left_alone(tmp_path):
    path = tmp_path / "name"
    path.write_bytes(b"generic\0".ljust(mmap.PAGESIZE, b"\0"))
    LIBC.mmap.restype = ctypes.c_void_p
    LIBC.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_long]
    LIBC.munmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t]
    with open(path, "rb") as file:
        address = LIBC.mmap(None, mmap.PAGESIZE, mmap.PROT_READ, mmap.MAP_PRIVATE, file.fileno(), 0)
    try:
        struct = (ctypes.c_uint64 * 2)(address, 0)
        assert not pocl_cpu.rewrite_cpu_name(ctypes.addressof(struct), ctypes.sizeof(struct), "x86-64-v3")
        assert ctypes.string_at(address) == b"generic"
    finally:
        LIBC.munmap(address, mmap.PAGESIZE)


def test_the_opencl_device_builds_kernels(opencl_platform):
    """Whatever LLVM calls this machine's CPU, PoCL builds and runs a kernel (on a CPU LLVM 14 does not
    know, only after ``name_unknown_cpu``)."""
    import numpy as np
    import pyopencl as cl

    ctx = opencl_platform.context()
    queue = cl.CommandQueue(ctx)
    program = opencl_platform.build_program(ctx, "__kernel void square(__global double *a) "
                                            "{ int i = get_global_id(0); a[i] = a[i] * a[i]; }", "square.cl")
    values = np.arange(64, dtype=np.float64)
    buffer = cl.Buffer(ctx, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=values)
    cl.Kernel(program, "square")(queue, values.shape, None, buffer)
    cl.enqueue_copy(queue, values, buffer)
    assert np.array_equal(values, np.arange(64.0) ** 2)


def test_without_proc_maps_nothing_is_read_or_written(monkeypatch):
    unknown = heap_string(b"generic")
    try:
        def unreadable(self, *args, **kwargs):
            raise PermissionError(13, "Permission denied", str(self))

        monkeypatch.setattr(pocl_cpu.Path, "read_text", unreadable)
        struct = (ctypes.c_uint64 * 1)(unknown)
        assert not pocl_cpu.rewrite_cpu_name(ctypes.addressof(struct), ctypes.sizeof(struct), "x86-64-v3")
        assert ctypes.string_at(unknown) == b"generic"
    finally:
        LIBC.free(unknown)
