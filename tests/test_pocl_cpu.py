"""PoCL's CPU device named by its x86-64 level where LLVM calls the CPU "generic" (realistic.device.pocl_cpu)."""

import ctypes
import mmap
import platform
import re
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import built_from_source
from realistic.device import pocl_cpu

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
def test_cpuinfo_of_any_text_names_a_cpu_llvm_14_knows(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("cpuinfo") / "cpuinfo"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    assert pocl_cpu.cpu_name(pocl_cpu.cpuinfo_fields(path)) in LEVEL_NAMES + [pocl_cpu.WIDE_AMD_CPU]


def test_cpuinfo_fields_are_the_first_processors(tmp_path):
    path = tmp_path / "cpuinfo"
    path.write_text("processor\t: 0\nflags\t\t: fpu avx2 fma\n\nprocessor\t: 1\nflags\t\t: fpu\n")
    assert pocl_cpu.cpuinfo_fields(path)["flags"] == "fpu avx2 fma"
    assert pocl_cpu.cpuinfo_fields(tmp_path / "absent") == {}


@pytest.mark.parametrize("vendor, level, name", [
    ("AuthenticAMD", 3, pocl_cpu.WIDE_AMD_CPU),  # AVX-512 on AMD: 16-lane kernels
    ("GenuineIntel", 3, "x86-64-v4"),  # LLVM's own Intel tunings prefer 256-bit vectors: keep the level's
    ("AuthenticAMD", 2, "x86-64-v3"),  # no AVX-512: the level
    ("", 3, "x86-64-v4"),
])
def test_only_an_amd_processor_with_avx512_gets_the_wide_name(vendor, level, name):
    fields = {"vendor_id": vendor, "flags": " ".join(sorted(flags_through(level)))}
    assert pocl_cpu.cpu_name(fields) == name


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
    import pyopencl as cl

    from realistic.device.opencl import Device

    device = Device.for_spec()
    ctx, queue = device.context, device.queue()
    program = device.build_program("__kernel void square(__global double *a) "
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


def skip_unless_given_the_wide_name(output: str) -> None:
    """Skip where the script's ``given <name>`` line shows this CPU was not given ``WIDE_AMD_CPU``."""
    if f"given {pocl_cpu.WIDE_AMD_CPU}" not in output:
        pytest.skip(f"this CPU is not given {pocl_cpu.WIDE_AMD_CPU!r} ({output.strip()})")


#: Knights Landing's own instructions (AVX512ER, AVX512PF, PREFETCHWT1), which no AMD processor has.
KNIGHTS_LANDING_ONLY = re.compile(
    r"\b(vexp2p[sd]|vrcp28[ps][sd]|vrsqrt28[ps][sd]|v(gather|scatter)pf[01][dq]p[sd]|prefetchwt1)\b")


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs objdump")
def test_kernels_built_for_the_wide_name_are_16_lanes_wide_and_use_no_knights_landing_instruction(
        opencl_platform, tmp_path):
    """Every kind of kernel (lens: spherical and aspheric, pupil and rear sampling, spectral; shading;
    EWA), built from source where ``name_unknown_cpu`` gave this CPU ``WIDE_AMD_CPU``: the code uses
    512-bit registers and none of the instructions Knights Landing has and AMD's processors lack."""
    script = (
        "import dataclasses\nimport numpy as np\n"
        "from kernel_reference import aspherised_dgauss, camera_for_lens\n"
        "from test_shade_kernel import busy_scene\n"
        "from realistic import load_lens\nfrom realistic.device import pocl_cpu\n"
        "from realistic.camera.base import SampleBlock\nfrom realistic.device.opencl import Device\n"
        "from realistic.renderer.backends import backend_for\n"
        "from realistic.renderer.direct_lighting import DirectLighting\n"
        "from realistic.scene.intersect import Intersector\n"
        "from realistic.scene.mipmap import MipMap\n"
        "print('given', pocl_cpu.given_name(Device.for_spec().devices[0]))\n"
        "for lens in (load_lens('dgauss'), aspherised_dgauss()):\n"
        "    for sampling in ('pupil', 'rear'):\n"
        "        camera = dataclasses.replace(camera_for_lens(lens), lens_sampling=sampling)\n"
        "        backend_for('opencl').ray_generator(camera, 1)(SampleBlock(0, 4096, camera.spp))\n"
        "camera = camera_for_lens(load_lens('dgauss100'), spectral=True)\n"
        "backend_for('opencl').ray_generator(camera, 1)(SampleBlock(0, 4096, camera.spp))\n"
        "scene = busy_scene()[0]\n"
        "integrator = DirectLighting(scene, Intersector(scene), 2, backend='opencl')\n"
        "ray = np.array([[0.0, 1.0, 4.0]], np.float32)\n"
        "integrator.radiance(ray, np.array([[0.0, -0.2, -1.0]], np.float32), np.zeros(1, np.int32), "
        "np.zeros(1, np.int64))\n"
        "st = np.full((4, 2), 0.5)\n"
        "backend_for('opencl').ewa(MipMap(np.ones((8, 8, 3))), st, st * 0.1, st * 0.05)\n")
    skip_unless_given_the_wide_name(built_from_source(script, tmp_path))
    code = {path: subprocess.run(["objdump", "-d", str(path)], capture_output=True, text=True, check=True).stdout
            for path in tmp_path.glob("pocl/kcache/**/*.so")}  # kcache/../<kernel>/<launch shape>/<kernel>.so
    assert {"generate_rays", "shade", "ewa"} <= {path.stem for path in code}
    for path, text in code.items():
        found = KNIGHTS_LANDING_ONLY.search(text)
        assert found is None, f"{path.stem} uses {found.group()}"
    assert sum(text.count("%zmm") for path, text in code.items() if path.stem == "generate_rays") > 500, \
        "the lens kernel is not 16 lanes wide"


def test_the_wide_name_changes_the_speed_not_the_image(opencl_platform, tmp_path):
    """A render through the lens kernel, the shading kernel and EWA (the busy scene seen through
    dgauss) is bit for bit the same built for ``WIDE_AMD_CPU`` as for x86-64-v4, where this CPU is
    given the former (each build from source, in a process of its own)."""
    script = (
        "import sys\nimport numpy as np\nfrom realistic.device import pocl_cpu\n"
        "wanted = sys.argv[1]\n"
        "if wanted != 'default':\n"
        "    pocl_cpu.cpu_name = lambda fields: wanted\n"
        "from test_shade_kernel import busy_scene\n"
        "from realistic import load_lens\nfrom realistic.camera.lens_camera import LensCamera\n"
        "from realistic.device.opencl import Device\n"
        "from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM\n"
        "from realistic.renderer.job import RenderJob\nfrom realistic.renderer.passes import render\n"
        "print('given', pocl_cpu.given_name(Device.for_spec().devices[0]))\n"
        "scene, eye, target = busy_scene()\n"
        "camera = LensCamera.looking_at(load_lens('dgauss'), eye, target, None, FULL_FRAME_DIAGONAL_MM, 48, 32, 8)\n"
        "job = RenderJob(scene, (camera,), 'opencl', 3, light_samples=2, pass_samples=2048)\n"
        "np.save(sys.argv[2], render(job)[0].image)\n")
    images = {}
    for name in ("default", "x86-64-v4"):
        output = built_from_source(script, tmp_path / name, name, str(tmp_path / f"{name}.npy"))
        if name == "default":
            skip_unless_given_the_wide_name(output)
        assert f"given {pocl_cpu.WIDE_AMD_CPU if name == 'default' else name}" in output
        images[name] = np.load(tmp_path / f"{name}.npy")
    assert images["default"].max() > 0
    assert np.array_equal(images["default"], images["x86-64-v4"])
