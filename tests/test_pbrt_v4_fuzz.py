"""Property-based tests of the pbrt-v4 parse paths (Attribute, Option, ColorSpace, media,
ActiveTransform, TransformTimes, Import, unquoted bools, bilinearmesh, plymesh displacement, Film
types, the v4 realistic camera): whatever a file holds, importing it gives a scene or one line of
UserError naming the file (and line); nothing else."""

import re
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.scene.pbrt.importer import import_pbrt

WARNING = re.compile(r"^.+?(:\d+)?: unsupported: .+$")
NUMBERS = st.one_of(st.floats(-5, 5).map(lambda x: f"{x:.3g}"), st.sampled_from(["0", "-1", "1e300", "1e-300"]))
WORDS = st.sampled_from(["true", "false", "All", "EndTime", "StartTime", "Sometimes", "WorldBegin", "Shape"])
STRINGS = st.sampled_from(['"srgb"', '"aces2065-1"', '""', '"fog"', '"shape"', '"light"', '"material"', '"texture"',
                           '"medium"', '"camera"', '"part.pbrt"', '"missing.pbrt"', '"float radius"',
                           '"bool twosided"', '"rgb L"', '"box.ply"'])
VALUE = st.one_of(NUMBERS, WORDS, STRINGS)


@st.composite
def params(draw):
    out = []
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(st.sampled_from(["float", "integer", "bool", "rgb", "string", "point3", "spectrum", "texture"]))
        name = draw(st.sampled_from(["radius", "L", "reflectance", "twosided", "P", "indices", "uv", "scale",
                                     "displacement", "filename", "iso", "sensor", "whitebalance"]))
        values = draw(st.lists(VALUE, max_size=5))
        out.append(f'"{kind} {name}" ' + (values[0] if len(values) == 1 and draw(st.booleans())
                                          else f"[ {' '.join(values)} ]"))
    return " ".join(out)


@st.composite
def v4_lines(draw):
    kind = draw(st.sampled_from(["Attribute", "Option", "ColorSpace", "MakeNamedMedium", "MediumInterface",
                                 "ActiveTransform", "TransformTimes", "Import", "Include", "Shape", "Translate",
                                 "AttributeBegin", "AttributeEnd", "TransformBegin", "TransformEnd", "AreaLightSource",
                                 "Material"]))
    if kind in ("Attribute", "MakeNamedMedium", "AreaLightSource", "Material"):
        return f"{kind} {draw(STRINGS)} {draw(params())}"
    if kind == "Option":
        return f"Option {draw(STRINGS)} {draw(VALUE)}"
    if kind in ("ColorSpace", "Import", "Include"):
        return f"{kind} {draw(STRINGS)}"
    if kind == "MediumInterface":
        return "MediumInterface " + " ".join(draw(st.lists(STRINGS, max_size=2)))
    if kind == "ActiveTransform":
        return f"ActiveTransform {draw(st.one_of(WORDS, NUMBERS))}"
    if kind in ("TransformTimes", "Translate"):
        return f"{kind} " + " ".join(draw(st.lists(NUMBERS, min_size=1, max_size=4)))
    if kind == "Shape":
        shape = draw(st.sampled_from(['"sphere"', '"disk"', '"bilinearmesh"', '"plymesh"', '"curve"', '"loopsubdiv"']))
        return f"Shape {shape} {draw(params())}"
    return kind


def check_error(err: UserError, folder: str) -> None:
    message = str(err)
    assert "\n" not in message and message.startswith(folder), message


def import_in(folder: str, text: str):
    Path(folder, "scene.pbrt").write_text(text)
    try:
        imported = import_pbrt(Path(folder) / "scene.pbrt")
    except UserError as err:
        check_error(err, folder)
        return None
    for warning in imported.warnings:
        assert WARNING.match(warning) and "\n" not in warning, warning
    return imported


HEADER = 'Film "rgb" "integer xresolution" 4 "integer yresolution" 4\nCamera "perspective"\nWorldBegin\n'


def with_files(folder: str) -> None:
    Path(folder, "part.pbrt").write_text('Material "conductor"\nAttributeBegin\nShape "sphere" "float radius" 0.5\n')
    import trimesh

    trimesh.creation.box().export(Path(folder, "box.ply"))


@given(st.lists(v4_lines(), max_size=12))
def test_v4_directives_give_a_scene_or_a_one_line_error(lines):
    with tempfile.TemporaryDirectory() as folder:
        with_files(folder)
        import_in(folder, HEADER + "\n".join(lines) + "\n")


POINT_VALUES = st.lists(st.sampled_from(["0", "1", "-1", "2.5", "1e300", "nan"]), max_size=18)
INDEX_VALUES = st.lists(st.sampled_from(["0", "1", "2", "3", "4", "-1", "1.5"]), max_size=10)


@given(POINT_VALUES, st.one_of(st.none(), INDEX_VALUES))
def test_bilinear_meshes_give_two_triangles_per_patch_or_an_error(points, indices):
    given_indices = "" if indices is None else f' "integer indices" [ {" ".join(indices)} ]'
    with tempfile.TemporaryDirectory() as folder:
        imported = import_in(folder, HEADER + f'Shape "bilinearmesh" "point3 P" [ {" ".join(points)} ]'
                                              f"{given_indices}\n")
        if imported is None or not imported.scene.meshes:
            return
        (mesh,) = imported.scene.meshes
        patches = 1 if indices is None else len(indices) // 4
        assert len(mesh.faces) == 2 * patches
        assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)


CAMERA_VALUES = st.one_of(NUMBERS, st.sampled_from(["1000", "17.1", "0.001"]))
APERTURES = st.sampled_from(['""', '"gaussian"', '"square"', '"pentagon"', '"star"', '"circle"', '"stop.exr"',
                             '"black.exr"', '"part.pbrt"', '"missing.png"'])


@given(st.one_of(st.none(), CAMERA_VALUES), st.one_of(st.none(), CAMERA_VALUES), st.one_of(st.none(), APERTURES),
       st.sampled_from(["rgb", "gbuffer", "spectral", "image"]))
def test_v4_realistic_cameras_give_a_camera_or_a_one_line_error(diameter, focus, aperture, film):
    from realistic.core.image_files import write_exr

    camera = 'Camera "realistic" "string lensfile" "dgauss.50mm.dat"'
    for kind, name, value in (("float", "aperturediameter", diameter), ("float", "focusdistance", focus),
                              ("string", "aperture", aperture)):
        if value is not None:
            camera += f' "{kind} {name}" {value}'
    with tempfile.TemporaryDirectory() as folder:
        write_exr(Path(folder, "stop.exr"), np.ones((16, 16, 3), np.float32))
        write_exr(Path(folder, "black.exr"), np.zeros((16, 16, 3), np.float32))
        Path(folder, "part.pbrt").write_text("not an image\n")
        imported = import_in(folder, f'Film "{film}" "integer xresolution" 4 "integer yresolution" 4\n{camera}\n'
                                     f"WorldBegin\n")
        if imported is not None:
            lens = imported.scene.camera.lens
            assert 0 < lens.stop_diameter_mm <= 17.1  # clamped to the file's stop, as pbrt-v4 does


@given(st.binary(max_size=64), st.integers(0, 64))
def test_any_gzip_file_imports_or_gives_a_one_line_error(data, cut):
    import gzip

    with tempfile.TemporaryDirectory() as folder:
        Path(folder, "raw.pbrt.gz").write_bytes(data)
        Path(folder, "cut.pbrt.gz").write_bytes(gzip.compress(data)[:cut])
        import_in(folder, HEADER + 'Import "raw.pbrt.gz"\nImport "cut.pbrt.gz"\n')
