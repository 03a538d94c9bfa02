"""Property-based tests of the pbrt front end (lexer, parser, importer): whatever the scene files
hold, reading them gives a scene or raises a one-line UserError naming a file and line; nothing else,
and never a hang (Include cycles are found)."""

import re
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.lexer import PbrtSyntaxError, tokenize
from realistic.scene.pbrt.parser import PbrtScene, parse_pbrt

WARNING = re.compile(r"^.+?(:\d+)?: unsupported: .+$")


def check_error(err: UserError, folder: str | None = None) -> None:
    """One line, beginning with a file name (and usually a line)."""
    message = str(err)
    assert "\n" not in message
    if folder is not None:
        assert message.startswith(folder), message


def check_scene(scene: PbrtScene) -> None:
    for warning in scene.warnings:
        assert WARNING.match(warning), warning
    for shape in [*scene.shapes, *(s for shapes in scene.objects.values() for s in shapes)]:
        assert np.all(np.isfinite(shape.transform))
    for name, transform, _ in scene.instances:
        assert name in scene.objects and np.all(np.isfinite(transform))


# ---- lexer ---------------------------------------------------------------------------------------

PBRT_CHARACTERS = st.sampled_from(list('abcXYZ019.-+e"[] \t\n\r#_') + ["1e999", "é", "\x00", "\\"])


@given(st.one_of(st.text(max_size=200), st.lists(PBRT_CHARACTERS, max_size=80).map("".join)))
def test_tokenize_gives_tokens_with_lines_in_order_or_a_syntax_error(text):
    path = Path("fuzz.pbrt")
    try:
        tokens = list(tokenize(text, path))
    except PbrtSyntaxError as err:
        check_error(err, "fuzz.pbrt:")
        return
    lines = [t.line for t in tokens]
    assert lines == sorted(lines)
    assert all(1 <= line <= text.count("\n") + 1 for line in lines)
    for token in tokens:
        assert token.kind in ("string", "number", "word", "[", "]")
        if token.kind == "number":
            assert np.isfinite(token.value)


# ---- parser --------------------------------------------------------------------------------------

DIRECTIVES = ["AttributeBegin", "AttributeEnd", "TransformBegin", "TransformEnd", "ObjectBegin", "ObjectEnd",
              "ObjectInstance", "WorldBegin", "WorldEnd", "Identity", "Translate", "Scale", "Rotate", "LookAt",
              "Transform", "ConcatTransform", "CoordinateSystem", "CoordSysTransform", "Camera", "Film", "Sampler",
              "Shape", "Material", "MakeNamedMaterial", "NamedMaterial", "Texture", "LightSource",
              "AreaLightSource", "ReverseOrientation", "Include", "Import", "PixelFilter", "Integrator", "Foo"]
PARAMETERS = ['"float radius"', '"point P"', '"integer indices"', '"rgb Kd"', '"string filename"', '"bool twosided"',
              '"texture Kd"', '"float uv"', '"normal N"', '"spectrum Kd"', '"float fov"', '"floaty x"', '"float"']
NUMBER_TEXT = st.one_of(st.integers(-5, 5).map(str), st.floats(-1e3, 1e3).map(lambda x: f"{x:.4g}"),
                        st.sampled_from(["0", "1e300", "-1e300", "1e-320", "1e999", ".5"]))
STRINGS = st.sampled_from(['"sphere"', '"trianglemesh"', '"o"', '"matte"', '"true"', '"false"', '"x"', '""',
                           '"camera"', '"world"', '"perspective"', '"inc.pbrt"', '"nope.pbrt"'])


@st.composite
def token_streams(draw):
    parts = draw(st.lists(st.one_of(st.sampled_from(DIRECTIVES), st.sampled_from(PARAMETERS), STRINGS, NUMBER_TEXT,
                                    st.sampled_from(["[", "]", "# comment\n", "\n"])), max_size=40))
    return " ".join(parts)


@st.composite
def nested_blocks(draw):
    """Begin/End directives, mostly balanced, with transforms and shapes between them."""
    lines = [draw(st.sampled_from(["", 'Camera "perspective"'])), draw(st.sampled_from(["WorldBegin", ""]))]
    open_blocks = []
    for _ in range(draw(st.integers(0, 20))):
        choice = draw(st.integers(0, 6))
        if choice == 0:
            kind = draw(st.sampled_from(["Attribute", "Transform", "Object"]))
            lines.append(f'{kind}Begin "o{len(lines)}"' if kind == "Object" else f"{kind}Begin")
            open_blocks.append(kind)
        elif choice == 1 and open_blocks and draw(st.integers(0, 9)):
            lines.append(f"{open_blocks.pop()}End")
        elif choice == 1:
            lines.append(f"{draw(st.sampled_from(['Attribute', 'Transform', 'Object']))}End")
        elif choice == 2:
            lines.append(draw(st.sampled_from(['Shape "sphere"', 'Shape "disk" "float radius" 2', "WorldEnd"])))
        elif choice == 3:
            lines.append(draw(st.sampled_from(["Translate 1 2 3", "Scale 2 2 2", "Rotate 30 0 1 0", "Scale 0 1 1"])))
        elif choice == 4:
            names = [line.split('"')[1] for line in lines if line.startswith("ObjectBegin")]
            lines.append(f'ObjectInstance "{draw(st.sampled_from(names))}"' if names else "ReverseOrientation")
        elif choice == 5:
            lines.append('Material "matte" "rgb Kd" [.1 .2 .3]')
        else:
            lines.append(draw(st.sampled_from(['AreaLightSource "diffuse" "rgb L" [1 1 1]', 'CoordinateSystem "c"',
                                               'CoordSysTransform "c"'])))
    if draw(st.booleans()):
        lines.append("WorldEnd")
    return "\n".join(lines) + "\n"


def parse_in(folder: str, text: str, name: str = "scene.pbrt") -> PbrtScene | None:
    path = Path(folder) / name
    path.write_text(text)
    try:
        scene = parse_pbrt(path)
    except UserError as err:
        check_error(err, folder)
        return None
    check_scene(scene)
    return scene


@given(st.one_of(token_streams(), nested_blocks()))
def test_parse_gives_a_scene_or_a_user_error(text):
    with tempfile.TemporaryDirectory() as folder:
        Path(folder, "inc.pbrt").write_text('Shape "sphere"\nInclude "scene.pbrt"\n')
        parse_in(folder, text)


@given(nested_blocks())
def test_every_block_left_open_is_reported_at_its_line(text):
    with tempfile.TemporaryDirectory() as folder:
        scene = parse_in(folder, text)
        if scene is None:
            return
        stack = []  # what the parser should have left open (balanced input parsed: no mismatches)
        reported = []  # (kind, line, when closed)
        for number, line in enumerate(text.splitlines(), start=1):
            word = line.split(" ")[0]
            if word.endswith("Begin") and word != "WorldBegin":
                stack.append((word, number))
            elif word.endswith("End") and word != "WorldEnd":
                stack.pop()
            elif word == "WorldEnd":
                reported += [(kind, number, "before WorldEnd") for kind, number in stack]
                stack = []
        reported += [(kind, number, "by the end of the file") for kind, number in stack]
        groups = {(kind, when) for kind, _, when in reported}  # warnings are reported once per message
        for kind, when in groups:
            lines = [number for k, number, w in reported if (k, w) == (kind, when)]
            assert any(w.startswith(f"{folder}/scene.pbrt:{number}: unsupported: {kind} without") and when in w
                       for w in scene.warnings for number in lines), (kind, lines, scene.warnings)
        assert len([w for w in scene.warnings if "Begin without a matching" in w]) == len(groups)


@st.composite
def include_graphs(draw):
    """Up to 4 files, each a sequence of shapes and Includes of the others (cycles included)."""
    count = draw(st.integers(1, 4))
    files = []
    for _ in range(count):
        body = draw(st.lists(st.one_of(st.just(-1), st.integers(0, count)), max_size=4))  # -1: a shape; count: none
        files.append(body)
    return files


def expected_shapes(files, start, chain=()):
    """Shapes reading file ``start`` yields, or None when an Include makes a cycle."""
    total = 0
    for item in files[start]:
        if item == -1:
            total += 1
        elif item == len(files):
            continue  # a missing file: skipped with a warning
        elif item in (*chain, start):
            return None
        else:
            inner = expected_shapes(files, item, (*chain, start))
            if inner is None:
                return None
            total += inner
    return total


@given(include_graphs())
def test_include_graphs_expand_or_report_their_cycle(files):
    with tempfile.TemporaryDirectory() as folder:
        for i, body in enumerate(files):
            lines = ['Shape "sphere"' if item == -1 else f'Include "f{item}.pbrt"' for item in body]
            Path(folder, f"f{i}.pbrt").write_text("\n".join(lines) + "\n")
        expected = expected_shapes(files, 0)
        try:
            scene = parse_pbrt(Path(folder) / "f0.pbrt")
        except UserError as err:
            check_error(err, folder)
            assert expected is None and "makes a cycle" in str(err), str(err)
            return
        assert len(scene.shapes) == expected


@st.composite
def parameter_lists(draw):
    params = []
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["float", "integer", "point", "normal", "rgb", "color", "string", "bool",
                                     "texture", "spectrum", "point2", "blackbody"]))
        name = draw(st.sampled_from(["radius", "P", "indices", "uv", "st", "N", "Kd", "L", "height", "fov",
                                     "filename", "twosided", "nsamples", "innerradius", "zmin", "zmax", "phimax",
                                     "xresolution", "pixelsamples", "lensradius", "focaldistance", "scale"]))
        values = draw(st.lists(st.one_of(NUMBER_TEXT, STRINGS), max_size=10))
        bracket = draw(st.booleans()) or len(values) != 1
        params.append(f'"{kind} {name}" ' + (f"[ {' '.join(values)} ]" if bracket else values[0]))
    return " ".join(params)


@given(st.sampled_from(["Shape", "Material", "LightSource", "AreaLightSource", "Film", "Camera", "Texture"]),
       st.sampled_from(['"sphere"', '"trianglemesh"', '"disk"', '"perspective"', '"matte"', '"diffuse"']),
       parameter_lists())
def test_random_parameters_parse_or_give_a_syntax_error(directive, kind, params):
    extra = ' "t" "color"' if directive == "Texture" else ""
    with tempfile.TemporaryDirectory() as folder:
        parse_in(folder, f"WorldBegin\n{directive}{extra} {kind} {params}\nWorldEnd\n")


# ---- importer ------------------------------------------------------------------------------------
# Each part comes "sane" (what a real scene holds, sizes from tiny to huge) or "wild" (any lengths and
# values), so that both whole imports and their errors are explored.

WILD_SIZES = st.sampled_from(["0", "-1", "-1e300", "1e-300", "2.5"])
SANE_SIZES = st.one_of(st.floats(0.01, 10).map(lambda x: f"{x:.3g}"), st.sampled_from(["1e-300", "1e20", "1e300"]))
MESH_NUMBERS = st.one_of(st.floats(-10, 10).map(lambda x: f"{x:.4g}"), st.sampled_from(["0", "1e300", "-1e30"]))


@st.composite
def triangle_meshes(draw, sane):
    points = draw(st.integers(1 if sane else 0, 5))
    p = " ".join(draw(st.lists(MESH_NUMBERS, min_size=3 * points, max_size=3 * points)))
    if not sane and draw(st.booleans()):
        p += draw(st.sampled_from([" 1", " 1 2"]))
    good = st.integers(0, max(points - 1, 0))
    indices = draw(st.lists(good if sane else st.integers(-1, points + 1), min_size=3 if sane else 0, max_size=9))
    if sane or draw(st.booleans()):
        indices = indices[:len(indices) - len(indices) % 3]
    line = f'Shape "trianglemesh" "point P" [ {p} ]'
    if indices or draw(st.booleans()):
        line += f' "integer indices" [ {" ".join(map(str, indices))} ]'
    for name, width in (("uv", 2), ("st", 2), ("N", 3)):
        if draw(st.integers(0, 2)) == 0:
            count = draw(st.one_of(st.just(points * width), st.integers(0, 12)))
            values = " ".join(draw(st.lists(MESH_NUMBERS, min_size=count, max_size=count)))
            line += f' "{"normal" if name == "N" else "float"} {name}" [ {values} ]'
    return line


@st.composite
def analytic_shapes(draw, sane):
    kinds = ["sphere", "disk", "cone", "cylinder"] + ([] if sane else ["curve", "plymesh"])
    kind = draw(st.sampled_from(kinds))
    sizes = SANE_SIZES if sane else st.one_of(SANE_SIZES, WILD_SIZES)
    names = draw(st.lists(st.sampled_from(["radius", "height", "zmin", "zmax", "innerradius", "phimax"]),
                          unique=True, max_size=3))
    return f'Shape "{kind}" ' + " ".join(f'"float {name}" {draw(sizes)}' for name in names)


SANE_STATE = ['Material "matte" "rgb Kd" [.2 .3 .4]', 'Material "plastic" "rgb Kd" [1]',
              'Material "matte" "rgb Kd" [1 2]', 'Material "matte" "spectrum Kd" [400 1 500 2]', 'Material "glass"',
              'Texture "c" "color" "checkerboard" "float uscale" 4 "rgb tex1" [1 1 1] "rgb tex2" [0 0 0]\n'
              'Material "matte" "texture Kd" "c"',
              'Texture "k" "color" "constant" "rgb value" [1 0 0]\n'
              'Texture "s" "color" "scale" "texture tex1" "k" "color tex2" [.5 .5 .5]\n'
              'Material "matte" "texture Kd" "s"',
              'Texture "w" "float" "wrinkled"\nMaterial "matte" "texture Kd" "w"',
              'MakeNamedMaterial "m" "string type" "matte" "rgb Kd" [.5 .5 .5]\nNamedMaterial "m"',
              'AreaLightSource "diffuse" "rgb L" [4 4 4] "integer nsamples" 4\nShape "disk" "float radius" 0.5',
              'AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" "true"', 'AreaLightSource "area" "float L" 2',
              'AreaLightSource "diffuse" "blackbody L" [5500 1] "float scale" 3', 'LightSource "point"',
              "ReverseOrientation", "AttributeBegin", "AttributeEnd", "Translate 0 0 1", "Scale 1e10 1e10 1e10",
              "Scale 1e-10 1 1", "Rotate 45 1 1 0",
              'AttributeBegin\nObjectBegin "o"\nShape "sphere"\nObjectEnd\nAttributeEnd\nObjectInstance "o"']
WILD_STATE = ['Material "matte" "texture Kd" "missing"', "AttributeEnd", "ObjectEnd", 'ObjectBegin "p"',
              "Translate 1e300 0 0", 'Texture "s" "color" "scale" "texture tex1" "s"',
              'Material "matte" "texture Kd" "s"', 'NamedMaterial "nope"', "Scale 0 1 1",
              'AreaLightSource "diffuse" "integer nsamples" 1e12', 'Material "matte" "rgb Kd" "red"']


@st.composite
def cameras(draw, sane):
    kind = draw(st.sampled_from(["perspective", "v3", "homework"]))
    if kind == "perspective":
        fov = draw(st.sampled_from(["40", "90"] if sane else ["0", "180", "-5", "1e300"]))
        return f'Camera "perspective" "float fov" {fov}'
    values = st.sampled_from(["1", "10", "2", "36.77", "0.5"] if sane else ["0", "-1", "1e300", "1e-300"])
    if kind == "v3":
        line = 'Camera "realistic" "string lensfile" "dgauss.50mm.dat"'
        names = ["aperturediameter", "focusdistance", "filmdiag"]
    else:
        line = 'Camera "realistic" "string specfile" "dgauss.50mm.dat" "float filmdistance" ' + draw(values)
        names = ["aperture_diameter", "filmdiag"]
    for name in draw(st.lists(st.sampled_from(names), unique=True)):
        line += f' "float {name}" {draw(values)}'
    return line


@st.composite
def scenes(draw):
    wild = draw(st.integers(0, 3)) == 0  # which parts may be wild: none, or each with probability 1/3

    def sane() -> bool:
        return not wild or draw(st.integers(0, 2)) > 0

    lines = ['Film "image" "integer xresolution" [ 8 ] "integer yresolution" [ 6 ]',
             draw(st.sampled_from(["LookAt 0 0 -5  0 0 0  0 1 0", "", "Scale -1 1 1"] if sane() else
                                  ["Translate 1e300 0 0", "Scale 0 1 1", "LookAt 0 0 0 0 0 0 0 1 0"])),
             draw(cameras(sane())), 'Sampler "random" "integer pixelsamples" 1', "WorldBegin"]
    for _ in range(draw(st.integers(0, 8))):
        ok = sane()
        part = draw(st.sampled_from(["mesh", "analytic", "state", "state"]))
        if part == "mesh":
            lines.append(draw(triangle_meshes(ok)))
        elif part == "analytic":
            lines.append(draw(analytic_shapes(ok)))
        else:
            lines.append(draw(st.sampled_from(SANE_STATE if ok else WILD_STATE)))
    if draw(st.booleans()):
        lines.append("WorldEnd")
    return "\n".join(lines) + "\n"


@given(scenes())
def test_import_gives_a_scene_and_camera_or_a_user_error(text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "scene.pbrt"
        path.write_text(text)
        try:
            imported = import_pbrt(path)
        except UserError as err:
            check_error(err, folder)
            return
        scene = imported.scene
        assert scene.camera is not None
        for warning in imported.warnings:
            assert WARNING.match(warning), warning
        for instance in scene.instances:
            assert np.all(np.isfinite(instance.transform))
            mesh = scene.meshes[instance.mesh]
            assert np.all(np.isfinite(mesh.vertices)) and len(mesh.faces)
            assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)
            assert mesh.uv is None or mesh.uv.shape == (len(mesh.vertices), 2)
            assert mesh.normals is None or np.allclose(np.linalg.norm(mesh.normals, axis=1), 1)
        for light in scene.area_lights:
            assert light.area() > 0 and np.all(np.isfinite(light.frame()[3]))
