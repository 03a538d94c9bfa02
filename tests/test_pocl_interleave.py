"""PoCL's work-item loops interleaved through LLVM's options (realistic.device.pocl_interleave)."""

import ctypes
import ctypes.util
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import built_from_source
from realistic.device import pocl_interleave
from realistic.device.opencl import Device


def mapped_base(library: Path) -> int:
    """Where ``library`` is loaded: the start of its mapping at file offset 0 (``/proc/self/maps``)."""
    for line in Path("/proc/self/maps").read_text().splitlines():
        fields = line.split(maxsplit=5)
        if len(fields) == 6 and fields[5] == str(library) and int(fields[2], 16) == 0:
            return int(fields[0].split("-")[0], 16)
    raise AssertionError(f"{library} is not mapped")


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs /proc")
def test_symbol_values_place_exported_functions_where_the_dynamic_linker_put_them():
    """The value read from libc's symbol table plus the address libc is mapped at (from
    ``/proc/self/maps``) is the address ``dlsym`` gives, for functions libc exports."""
    libc_path = pocl_interleave.loaded_library("libc.so")
    if libc_path is None:
        pytest.skip("no libc.so mapped in this process")
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    names = ["malloc", "free", "qsort", "abort"]  # plain functions: no IFUNC (memcpy)
    values = pocl_interleave.symbol_values(libc_path, names)
    assert set(values) == set(names)
    base = mapped_base(libc_path)
    for name in names:
        assert base + values[name] == ctypes.cast(getattr(libc, name), ctypes.c_void_p).value, name


def test_the_loaded_pocl_places_llvm_where_its_symbol_table_says(opencl_platform):
    """PoCL's own LLVM options parser and interleave count: in its static symbol table (pip's PoCL)
    or exported; the exported anchor's symbol value agrees with where the library is mapped, and
    the count is back with the cost model (0) outside ``interleaved()``, ``INTERLEAVE`` inside."""
    Device.for_spec()
    library = pocl_interleave.loaded_library("libpocl")
    if library is None or pocl_interleave._count is None:
        pytest.skip("the OpenCL platform is not a PoCL whose LLVM options can be set")
    values = pocl_interleave.symbol_values(library, [pocl_interleave.ANCHOR])
    loaded = ctypes.CDLL(str(library))
    anchor = ctypes.cast(getattr(loaded, pocl_interleave.ANCHOR), ctypes.c_void_p).value
    assert mapped_base(library) + values[pocl_interleave.ANCHOR] == anchor
    assert pocl_interleave._count.value == 0
    with pocl_interleave.interleaved():
        assert pocl_interleave._count.value == pocl_interleave.INTERLEAVE
    assert pocl_interleave._count.value == 0
    assert pocl_interleave.build_options() == (f"-DREALISTIC_INTERLEAVE={pocl_interleave.INTERLEAVE}",)


@given(st.binary(max_size=512), st.integers(0, 63))
def test_any_file_gives_symbols_or_nothing(tmp_path_factory, data, cut):
    """Arbitrary bytes, and an ELF header made to point anywhere, give a dict or {}, never an error."""
    folder = tmp_path_factory.mktemp("elf")
    header = bytearray(b"\x7fELF\x02\x01" + bytes(58))
    header[0x28:0x30] = (len(header) + cut).to_bytes(8, "little")
    header[0x3A:0x3E] = (64).to_bytes(2, "little") + (1 + cut % 7).to_bytes(2, "little")
    for content in (data, bytes(header) + data, bytes(header[:cut])):
        path = folder / "library.so"
        path.write_bytes(content)
        found = pocl_interleave.symbol_values(path, ["malloc"])
        assert isinstance(found, dict) and all(isinstance(v, int) for v in found.values())
    assert pocl_interleave.symbol_values(folder / "missing.so", ["malloc"]) == {}


RENDER = (
    "import sys\nimport numpy as np\nfrom realistic.device import pocl_interleave\n"
    "if sys.argv[1] == 'off':\n"
    "    pocl_interleave.interleave_work_items = lambda device: False\n"
    "from test_shade_kernel import busy_scene\n"
    "from realistic import load_lens\nfrom realistic.camera.lens_camera import LensCamera\n"
    "from realistic.core.film_geometry import FULL_FRAME_DIAGONAL_MM\n"
    "from realistic.renderer.job import RenderJob\nfrom realistic.renderer.passes import render\n"
    "scene, eye, target = busy_scene()\n"
    "camera = LensCamera.looking_at(load_lens('dgauss'), eye, target, None, FULL_FRAME_DIAGONAL_MM, 48, 32, 64)\n"
    "job = RenderJob(scene, (camera,), 'opencl', 3, light_samples=2, pass_samples=2048)\n"
    "np.save(sys.argv[2], render(job)[0].image)\n"
    "print('options', pocl_interleave.build_options())\n")


def square_roots(folder: Path, kernel: str) -> dict[str, int]:
    """Square-root instructions in the machine code of each of PoCL's variants of ``kernel`` built
    into ``folder``'s kernel cache (.../<kernel>/<variant>/<kernel>.so), by variant."""
    roots = {}
    for path in folder.glob("pocl/kcache/**/*.so"):
        if path.stem == kernel:
            text = subprocess.run(["objdump", "-d", str(path)], capture_output=True, text=True, check=True).stdout
            roots[path.parent.name] = len(re.findall(r"\bvsqrtp[sd]\b", text))
    return roots


def test_interleaving_changes_the_code_not_the_image(opencl_platform, tmp_path):
    """A render through the lens, shading and EWA kernels, each built from source in a process of
    its own, is bit for bit the same with and without interleaving; with it, the machine code of
    the lens kernel (compiled as the kernel is made) holds ``INTERLEAVE`` times the square roots,
    the shading kernel's as many as without (where objdump is at hand). The lens kernel is compiled
    once: every launch of it is too large for PoCL's small-launch variant (``opencl_host.launch_size``),
    even in this render's passes of 2048 samples, whose shading launches are small."""
    outputs, images = {}, {}
    for mode in ("off", "on"):
        outputs[mode] = built_from_source(RENDER, tmp_path / mode, mode, str(tmp_path / f"{mode}.npy"))
        images[mode] = np.load(tmp_path / f"{mode}.npy")
    if "()" in outputs["on"]:
        pytest.skip(f"interleaving is not set on this platform ({outputs['on'].strip()})")
    assert "()" in outputs["off"]
    assert images["on"].max() > 0
    assert np.array_equal(images["on"], images["off"])
    if shutil.which("objdump") is None:
        return
    roots = {(mode, kernel): square_roots(tmp_path / mode, kernel)
             for mode in ("off", "on") for kernel in ("generate_rays", "shade")}
    assert set(roots["on", "generate_rays"]) == set(roots["off", "generate_rays"]) == {"256-1-1-goffs0"}, roots
    for kernel in ("generate_rays", "shade"):
        for variant, off in roots["off", kernel].items():
            expected = pocl_interleave.INTERLEAVE * off if kernel == "generate_rays" else off
            assert roots["on", kernel][variant] == expected and off > 0, roots


RAYS = (
    "import sys\nimport numpy as np\nfrom realistic.device import pocl_interleave\n"
    "if sys.argv[1] == 'off':\n"
    "    pocl_interleave.interleave_work_items = lambda device: False\n"
    "from kernel_reference import aspherised_dgauss, camera_for_lens\n"
    "from realistic.camera.base import SampleBlock\nfrom realistic.renderer.backends import backend_for\n"
    "camera = camera_for_lens(aspherised_dgauss())\n"
    "rays = backend_for('opencl').ray_generator(camera, 5)(SampleBlock(0, camera.sample_count, camera.spp))\n"
    "np.save(sys.argv[2], np.column_stack([rays.origin, rays.direction, rays.weight]))\n"
    "print('options', pocl_interleave.build_options(pocl_interleave.ASPHERIC_INTERLEAVE))\n")


def test_a_lens_with_aspheres_is_interleaved_less_and_traces_the_same_rays(opencl_platform, tmp_path):
    """The longer kernel of a lens with aspheres is interleaved ``ASPHERIC_INTERLEAVE`` times and
    makes the same rays, bit for bit (each build from source in a process of its own)."""
    rays = {}
    for mode in ("off", "on"):
        output = built_from_source(RAYS, tmp_path / mode, mode, str(tmp_path / f"{mode}.npy"))
        rays[mode] = np.load(tmp_path / f"{mode}.npy")
    if "()" in output:
        pytest.skip(f"interleaving is not set on this platform ({output.strip()})")
    assert np.count_nonzero(rays["on"][:, 6]) > 1000
    assert np.array_equal(rays["on"], rays["off"])
    if shutil.which("objdump") is None:
        return
    on, off = square_roots(tmp_path / "on", "generate_rays"), square_roots(tmp_path / "off", "generate_rays")
    assert on["256-1-1-goffs0"] == pocl_interleave.ASPHERIC_INTERLEAVE * off["256-1-1-goffs0"] > 0, (on, off)
