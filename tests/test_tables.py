"""Kernel tables declared once (``realistic.device.tables``): the host's packing puts each field at
the offset the kernel's generated ``#define`` names, and every table name a kernel uses is declared."""

import re

import numpy as np
import pytest

from realistic.core.data_files import data_file
from realistic.device.tables import Table, constant_defines

opencl_host = pytest.importorskip("realistic.camera.opencl_host")
ewa_kernel = pytest.importorskip("realistic.scene.ewa_kernel")
shade_kernel = pytest.importorskip("realistic.renderer.shade_kernel")


def defined(header: str) -> dict[str, int]:
    return {name: int(value) for name, value in re.findall(r"^#define (\w+) (\d+)$", header, re.MULTILINE)}


def test_pack_puts_each_field_at_its_defined_offset():
    table = Table("T", np.float32, (("a", 1), ("b", 3), ("c", 2)), tail="rest")
    names = defined(table.defines())
    assert names == {"T_WIDTH": 6, "T_A": 0, "T_B": 1, "T_C": 4, "T_REST": 6}
    rows = table.pack(2, a=np.array([1.0, 2.0]), b=np.array([[3, 4, 5], [6, 7, 8]]), c=(9.0, 10.0))
    assert rows.dtype == np.float32 and rows.shape == (2, 6)
    assert rows[1, names["T_A"]] == 2 and list(rows[1, names["T_B"]:names["T_B"] + 3]) == [6, 7, 8]
    assert list(rows[0, names["T_C"]:]) == [9, 10]
    with pytest.raises(ValueError, match="no field d"):
        table.pack(1, d=1.0)
    assert constant_defines("K", ("x", "y")) == "#define K_X 0\n#define K_Y 1\n"


@pytest.mark.parametrize(("kernel", "header", "prefixes"), [
    ("shade.cl", shade_kernel.HEADER, ("GEOM_INT_", "GEOM_FLOAT_", "MATERIAL_", "LIGHT_", "KIND_")),
    ("ewa.cl", ewa_kernel.HEADER, ("MAPPING_", "LUT_SIZE")),
    ("lens.cl", opencl_host.SETTINGS.defines(), ("SET_",))])
def test_every_table_name_a_kernel_uses_is_declared_by_its_host(kernel, header, prefixes):
    source = data_file(f"kernels/{kernel}").read_text(encoding="utf-8")
    code = re.sub(r"/\*.*?\*/", "", source, flags=re.DOTALL)  # names in comments are not uses
    used = {name for name in re.findall(r"\b[A-Z][A-Z0-9_]*\b", code) if name.startswith(prefixes)}
    assert used and used <= set(defined(header)), used - set(defined(header))
    assert not re.search(r"^#define (" + "|".join(prefixes) + ")", code, re.MULTILINE)  # not kept in the kernel too


def test_light_rows_hold_each_light_at_the_kernels_offsets():
    lights = shade_kernel.LIGHTS
    rows = lights.pack(2, centre=np.ones((2, 3)), radiance=np.array([[1, 2, 3], [4, 5, 6]]), scale=[7.0, 8.0],
                       two_sided=np.array([False, True]))
    names = defined(lights.defines())
    assert rows.shape == (2, names["LIGHT_WIDTH"])
    assert list(rows[1, names["LIGHT_RADIANCE"]:names["LIGHT_RADIANCE"] + 3]) == [4, 5, 6]
    assert rows[1, names["LIGHT_SCALE"]] == 8 and rows[1, names["LIGHT_TWO_SIDED"]] == 1
    assert rows[0, names["LIGHT_DISK"]] == 0


def test_settings_hold_the_stop_and_film_where_the_kernel_reads_them():
    from kernel_reference import reference_camera

    camera = reference_camera("dgauss", "pupil")
    values = opencl_host.setting_values(camera)
    names = defined(opencl_host.SETTINGS.defines())
    radius = float(camera.lens.aperture_mm[camera.lens.stop]) / 2
    assert values[names["SET_STOP_R2"]] == np.float32(radius**2)
    assert values[names["SET_REAR_W"]] == np.float32(-camera.film_distance_mm)
    assert len(values) == names["SET_PUPIL"] + 5 * len(camera.pupil.bounds)
