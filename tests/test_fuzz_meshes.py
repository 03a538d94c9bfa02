"""Property-based fuzzing of ``load_mesh_file`` and ``mesh_setup``: valid headers over random bodies.

Each generator writes a file that is mostly well formed (so loading gets deep into trimesh and past it)
with random counts, indices and numbers (nan, inf, huge, not numbers), counts that disagree with the
body, junk lines and truncation. Whatever the file holds, loading it either gives MeshObjects the
renderer can use (finite coordinates within ``MAX_COORDINATE``, face indices inside the vertex list, a
triangle with area), which ``mesh_setup`` stages or refuses, or raises a one-line ``UserError`` naming
the file. Any other exception, or a warning that would reach the user, fails. The "ci" hypothesis
profile (tests/conftest.py) keeps this short and repeatable; ``--hypothesis-profile=long`` digs deeper.
"""

import io
import json
import struct
import warnings

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.scene.meshes import FORMATS, MAX_COORDINATE, MeshObject, load_mesh_file
from realistic.scene.staging import Setup, mesh_setup

# Numbers as a file might spell them: ordinary, extreme, non-finite, and not numbers at all.
SPECIAL_NUMBERS = ["0", "-0", "1", "-1", "0.5", "1e30", "-1e30", "1e300", "1e400", "-1e308", "1e-320", "nan",
                   "NaN", "inf", "-inf", "+inf", "1e12", "1e13", "3.4e38", "0x10", "1,5", "--1", "abc", "", "1.2.3"]
small_float = st.floats(-10, 10).map(lambda x: f"{x:.6g}")
number_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    small_float,
    st.integers(-(10**20), 10**20).map(str),
    st.sampled_from(SPECIAL_NUMBERS),
)
coordinate_text = st.sampled_from([False] * 9 + [True]).flatmap(lambda odd: number_text if odd else small_float)
small_index = st.integers(-12, 12).map(str)
index_text = st.one_of(small_index, small_index, st.integers(-(2**63), 2**64).map(str), st.sampled_from(["x", "1.5"]))
junk_line = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=["Cs"]), max_size=20)
float32_value = st.floats(width=32, allow_nan=True, allow_infinity=True)
float32_coordinate = st.sampled_from([False] * 9 + [True]).flatmap(
    lambda odd: float32_value if odd else st.floats(-10, 10, width=32))
count_delta = st.sampled_from([0, 0, 0, 0, 0, 0, 0, -1, 1, 2, -5, 10**12])
cuts = st.sampled_from([False] * 5 + [True]).flatmap(lambda cut: st.integers(0, 10**6) if cut else st.none())

TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def check_outcome(path):
    """Loading gives usable MeshObjects or one UserError; nothing else, and no warning escapes."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            objects = load_mesh_file(path)
        except UserError as err:
            check_message(err, path)
            objects = None
        if objects is not None:
            check_objects(objects)
            try:
                assert isinstance(mesh_setup(objects), Setup)
            except UserError as err:
                check_message(err, path)
    assert not caught, [str(w.message) for w in caught]


def check_message(err, path):
    message = str(err)
    assert str(path) in message and "\n" not in message and len(message) < 400, message
    assert "No module named" not in message and "charset" not in message, message


def check_objects(objects):
    assert isinstance(objects, list) and objects
    any_area = False
    for obj in objects:
        assert isinstance(obj, MeshObject)
        vertices, faces = obj.mesh.vertices, obj.mesh.faces
        assert vertices.ndim == 2 and vertices.shape[1] == 3 and faces.ndim == 2 and faces.shape[1] == 3
        assert np.all(np.isfinite(vertices)) and np.abs(vertices).max() <= MAX_COORDINATE
        assert len(faces) and faces.min() >= 0 and faces.max() < len(vertices)
        assert obj.transform.shape == (4, 4) and np.all(np.isfinite(obj.transform))
        if obj.mesh.normals is not None:
            assert obj.mesh.normals.shape == vertices.shape and np.all(np.isfinite(obj.mesh.normals))
        if obj.mesh.uv is not None:
            assert obj.mesh.uv.shape == (len(vertices), 2) and np.all(np.isfinite(obj.mesh.uv))
        if obj.colour is not None:
            assert len(obj.colour) == 3 and all(0 <= c <= 1 for c in obj.colour)
        triangles = vertices[faces] / max(np.ptp(vertices, axis=0).max(), 1e-300)  # relative: no underflow
        any_area |= bool(np.any(np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])))
    assert any_area


def rarely(draw, value, weird):
    """``value`` most of the time, else a draw from the strategy ``weird``."""
    return draw(weird) if draw(st.sampled_from([False] * 7 + [True])) else value


def truncate(data: bytes, cut: int | None) -> bytes:
    return data if cut is None else data[: cut % (len(data) + 1)]


def vertex_index(n, noisy=True):
    """A 0-based index into n vertices: valid, or in a noisy file sometimes just outside or absurd."""
    valid = st.integers(0, n - 1) if n > 0 else st.just(0)
    weird = st.sampled_from([-1, n, n + 1, 2**31 - 1, -(2**31)])
    return st.sampled_from([False] * 9 + [noisy]).flatmap(lambda odd: weird if odd else valid)


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


# OBJ ---------------------------------------------------------------------------------------------

def _obj_face(indices, style):
    if style == 0:
        return "f " + " ".join(indices)
    if style == 1:
        return "f " + " ".join(f"{i}/{i}/{i}" for i in indices)
    return "f " + " ".join(f"{i}//{i}" for i in indices)


obj_line = st.one_of(
    st.lists(coordinate_text, min_size=3, max_size=3).map(lambda xs: " ".join(["v", *xs])),
    st.lists(number_text, min_size=0, max_size=5).map(lambda xs: " ".join(["v", *xs])),
    st.lists(number_text, min_size=0, max_size=4).map(lambda xs: " ".join(["vn", *xs])),
    st.lists(number_text, min_size=0, max_size=3).map(lambda xs: " ".join(["vt", *xs])),
    st.builds(_obj_face, st.lists(index_text, min_size=0, max_size=6), st.integers(0, 2)),
    st.builds(_obj_face, st.lists(st.integers(1, 6).map(str), min_size=3, max_size=4), st.just(0)),
    st.sampled_from(["o a", "o b", "g group", "usemtl red", "mtllib missing.mtl", "s off", "s 1", "l 1 2", "#",
                     " v 1 2 3", "v\t1 2 3", "\tf 1 2 3", "f\t1 2 3", "f 1 2 3 # c", "v 1 2 3 4 5 6"]),
    junk_line,
)


@given(valid_start=st.booleans(), lines=st.lists(obj_line, max_size=30), cut=cuts)
def test_fuzz_obj(fuzz_dir, valid_start, lines, cut):
    path = fuzz_dir / "fuzz.obj"
    text = (TRIANGLE_OBJ if valid_start else "") + "\n".join(lines) + "\n"
    path.write_bytes(truncate(text.encode(), cut))
    check_outcome(path)


# PLY ---------------------------------------------------------------------------------------------

SCALAR_TYPES = {"float": "f", "double": "d", "int": "i", "uchar": "B", "short": "h", "float32": "f"}
LIST_TYPES = ["uchar int", "uchar int", "uchar uint", "int int", "uint8 int32", "uchar float", "short short"]


@st.composite
def ply_layout(draw):
    """Header text and what it declares: vertex properties (name, type) and the face list types."""
    n, m = rarely(draw, draw(st.integers(3, 8)), st.just(0)), rarely(draw, draw(st.integers(1, 6)), st.just(0))
    declared_n, declared_m = n + draw(count_delta), m + draw(count_delta)
    xyz = rarely(draw, "float", st.sampled_from(["double", "int", "uchar", "bogus"]))
    properties = [(axis, xyz) for axis in rarely(draw, "xyz", st.sampled_from(["xy", "zyx"]))]
    if draw(st.booleans()):
        properties += [(name, "float") for name in ("nx", "ny", "nz")]
    if draw(st.booleans()):
        properties += [(name, "uchar") for name in ("red", "green", "blue")]
    face_types = rarely(draw, LIST_TYPES[0], st.sampled_from(LIST_TYPES))
    lines = [f"element vertex {declared_n}", *(f"property {t} {name}" for name, t in properties)]
    if declared_m != 0 or draw(st.booleans()):
        lines += [f"element face {declared_m}", f"property list {face_types} vertex_indices"]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), f"comment {draw(junk_line)}")
    return lines, n, m, properties, face_types.split()


def _ply_value(draw, kind, binary, noisy):
    if kind in ("float", "double", "float32") and not noisy:
        return draw(st.floats(-10, 10, width=32)) if binary else draw(small_float)
    if kind in ("float", "double", "float32"):
        return draw(float32_coordinate) if binary else draw(coordinate_text)
    if kind in ("uchar", "uint8"):
        return draw(st.integers(0, 255)) if binary else rarely(draw, str(draw(st.integers(0, 255))), number_text)
    return draw(st.integers(-(2**15), 2**15 - 1)) if binary else rarely(draw, draw(small_index), index_text)


@given(data=st.data(), cut=cuts)
def test_fuzz_ply_ascii(fuzz_dir, data, cut):
    lines, n, m, properties, (_, index_type) = data.draw(ply_layout())
    noisy = data.draw(st.booleans())
    rows = [[_ply_value(data.draw, kind, False, noisy) for _, kind in properties] for _ in range(n)]
    for _ in range(m):
        count = rarely(data.draw, 3, st.sampled_from([4, 0, 2]))
        indices = [str(data.draw(vertex_index(n, noisy))) for _ in range(count)]
        rows.append([rarely(data.draw, str(count), st.sampled_from(["3", "x"])), *indices])
    if rows and rarely(data.draw, False, st.just(True)):  # one junk row, or a row one value short
        at = data.draw(st.integers(0, len(rows) - 1))
        rows[at] = data.draw(st.sampled_from([rows[at][:-1], [data.draw(junk_line)], rows[at] + ["1"]]))
    header = "\n".join(["ply", "format ascii 1.0", *lines, "end_header"]) + "\n"
    body = "\n".join(" ".join(r) for r in rows) + "\n"
    path = fuzz_dir / "fuzz.ply"
    path.write_bytes(truncate((header + body).encode(), cut))
    check_outcome(path)


@given(data=st.data(), cut=cuts)
def test_fuzz_ply_binary(fuzz_dir, data, cut):
    lines, n, m, properties, (count_type, index_type) = data.draw(ply_layout())
    noisy = data.draw(st.booleans())
    codes = {**SCALAR_TYPES, "uint": "I", "int32": "i", "uint8": "B", "bogus": "f"}
    out = io.BytesIO()
    if rarely(data.draw, False, st.just(True)):
        out.write(data.draw(st.binary(max_size=600)))
    else:
        for _ in range(n):
            for _, kind in properties:
                value = _ply_value(data.draw, kind, True, noisy)
                out.write(struct.pack("<" + codes[kind], int(value) if codes[kind] in "BhiI" else value))
        for _ in range(m):
            count = rarely(data.draw, 3, st.sampled_from([4, 0, 2]))
            out.write(struct.pack("<" + codes[count_type], count))
            for _ in range(count):
                index = data.draw(vertex_index(n, noisy))
                code = codes[index_type]
                out.write(struct.pack("<" + code, float(index) if code == "f" else
                                      np.array(index).astype({"h": np.int16, "I": np.uint32}.get(code, np.int32))))
    header = "\n".join(["ply", "format binary_little_endian 1.0", *lines, "end_header"]) + "\n"
    path = fuzz_dir / "fuzz.ply"
    tail = rarely(data.draw, b"", st.binary(max_size=8))
    path.write_bytes(truncate(header.encode() + out.getvalue() + tail, cut))
    check_outcome(path)


# STL ---------------------------------------------------------------------------------------------

@st.composite
def stl_facet(draw, noisy):
    coordinate = coordinate_text if noisy else small_float
    lines = ["facet normal " + " ".join(draw(st.lists(coordinate, min_size=3, max_size=3))), "outer loop"]
    for _ in range(rarely(draw, 3, st.sampled_from([0, 1, 2, 4]))):
        values = draw(st.lists(coordinate, min_size=3, max_size=3))
        values = rarely(draw, values, st.lists(number_text, max_size=4))
        lines.append(" ".join(["vertex", *values]))
    if rarely(draw, False, st.just(True)):
        lines.append(draw(junk_line))
    return "\n".join([*lines, "endloop", "endfacet"])


@given(facets=st.booleans().flatmap(lambda noisy: st.lists(stl_facet(noisy), max_size=8)),
       end=st.sampled_from([True] * 7 + [False]), cut=cuts)
def test_fuzz_stl_ascii(fuzz_dir, facets, end, cut):
    path = fuzz_dir / "fuzz.stl"
    text = "solid fuzz\n" + "\n".join(facets) + ("\nendsolid fuzz\n" if end else "\n")
    path.write_bytes(truncate(text.encode(), cut))
    check_outcome(path)


@given(header=st.binary(min_size=80, max_size=80) | st.just(b"solid " + bytes(74)),
       triangles=st.sampled_from([st.floats(-10, 10, width=32), float32_coordinate]).flatmap(
           lambda value: st.lists(st.lists(value, min_size=12, max_size=12), max_size=8)),
       count=st.sampled_from([False] * 5 + [True]).flatmap(lambda odd: st.integers(0, 2**32 - 1) if odd else st.none()),
       tail=st.sampled_from([b""] * 5 + [b"x"]).flatmap(lambda t: st.binary(max_size=60) if t else st.just(b"")),
       cut=cuts)
def test_fuzz_stl_binary(fuzz_dir, header, triangles, count, tail, cut):
    path = fuzz_dir / "fuzz.stl"
    body = b"".join(struct.pack("<12fH", *t, 0) for t in triangles)
    count = len(triangles) if count is None else count
    path.write_bytes(truncate(header + struct.pack("<I", count) + body + tail, cut))
    check_outcome(path)


# OFF ---------------------------------------------------------------------------------------------

@given(data=st.data(), cut=cuts)
def test_fuzz_off(fuzz_dir, data, cut):
    n, m = rarely(data.draw, data.draw(st.integers(3, 8)), st.just(0)), data.draw(st.integers(1, 6))
    noisy = data.draw(st.booleans())
    coordinate = coordinate_text if noisy else small_float
    counts = [str(n + data.draw(count_delta)), str(m + data.draw(count_delta)), "0"]
    counts = rarely(data.draw, counts, st.lists(index_text, max_size=4))
    rows = [" ".join(data.draw(st.lists(coordinate, min_size=3, max_size=3))) for _ in range(n)]
    for _ in range(m):
        count = rarely(data.draw, 3, st.sampled_from([4, 0, 2]))
        indices = [str(data.draw(vertex_index(n, noisy))) for _ in range(count)]
        rows.append(" ".join([rarely(data.draw, str(count), st.sampled_from(["3", "x", "-1"])), *indices]))
    if rows and rarely(data.draw, False, st.just(True)):
        rows[data.draw(st.integers(0, len(rows) - 1))] = " ".join(data.draw(st.lists(number_text, max_size=5)))
    text = data.draw(st.sampled_from(["OFF\n", "OFF\n", "COFF\n", "OFF ", "# comment\nOFF\n"])) + " ".join(counts)
    path = fuzz_dir / "fuzz.off"
    path.write_bytes(truncate((text + "\n" + "\n".join(rows) + "\n").encode(), cut))
    check_outcome(path)


# GLB ---------------------------------------------------------------------------------------------

COMPONENT_TYPES = [5126, 5125, 5123, 5121, 5120, 5122, 1]
json_number = st.one_of(st.integers(-5, 5), st.floats(-10, 10), st.sampled_from([1e30, 1e300, -1e300, 0.0, 1e-300]))
json_weird_number = json_number | st.sampled_from([float("nan"), float("inf")])


GLB_FIELDS = ["binary", "offset0", "length0", "buffer0", "offset1", "length1", "buffer1", "component0", "count0",
              "type0", "view1", "component1", "count1", "type1", "mode", "no indices", "mesh", "transform",
              "parent", "buffer length", "file length"]


@st.composite
def glb_document(draw):
    """A GLB mesh whose JSON is consistent with its binary chunk, then with at most one field made wrong
    (and, in a noisy file, odd coordinates and indices)."""
    broken = draw(st.sampled_from([None] * 8 + GLB_FIELDS))

    def field(name, value, weird):
        return draw(weird) if name == broken else value

    coordinate = float32_coordinate if draw(st.booleans()) else st.floats(-10, 10, width=32)
    positions = draw(st.lists(st.tuples(coordinate, coordinate, coordinate), min_size=3, max_size=8))
    n = len(positions)
    indices = [draw(vertex_index(n)) % 2**32 for _ in range(3 * draw(st.integers(1, 4)))]
    position_bytes = b"".join(struct.pack("<3f", *p) for p in positions)
    index_bytes = b"".join(struct.pack("<I", i) for i in indices)
    binary = field("binary", position_bytes + index_bytes, st.binary(max_size=200))
    views = [{"buffer": field(f"buffer{i}", 0, st.sampled_from([1, -1, "0"])),
              "byteOffset": field(f"offset{i}", offset, st.integers(-4, 300)),
              "byteLength": field(f"length{i}", len(part), st.integers(-4, 300))}
             for i, (offset, part) in enumerate([(0, position_bytes), (len(position_bytes), index_bytes)])]
    accessors = [
        {"bufferView": 0, "componentType": field("component0", 5126, st.sampled_from(COMPONENT_TYPES)),
         "count": field("count0", n, st.integers(-1, 40)),
         "type": field("type0", "VEC3", st.sampled_from(["VEC2", "X"]))},
        {"bufferView": field("view1", 1, st.sampled_from([0, 7])),
         "componentType": field("component1", 5125, st.sampled_from(COMPONENT_TYPES)),
         "count": field("count1", len(indices), st.integers(-1, 60)),
         "type": field("type1", "SCALAR", st.just("VEC3"))},
    ]
    if draw(st.booleans()):
        accessors[0]["min"], accessors[0]["max"] = [-1, -1, -1], [1, 1, 1]
    primitive = {"attributes": {"POSITION": 0}, "indices": 1}
    if broken == "mode":
        primitive["mode"] = draw(st.sampled_from([0, 1, 4, 5, 6, 9]))
    if broken == "no indices":
        del primitive["indices"]
    node = {"mesh": field("mesh", 0, st.sampled_from([3, -1]))}
    transform = field("transform", draw(st.sampled_from(["none", "scale", "translation"])),
                      st.sampled_from(["matrix", "scale", "translation", "rotation"]))
    if transform == "matrix":
        identity = [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
        node["matrix"] = [rarely(draw, v, json_weird_number) for v in identity]
    elif transform != "none":
        size = 4 if transform == "rotation" else 3
        node[transform] = draw(st.lists(json_weird_number if broken == "transform" else json_number,
                                        min_size=size, max_size=size))
    nodes = [node]
    if broken == "parent":  # a parent, possibly a cycle
        nodes.append({"children": draw(st.lists(st.integers(0, 2), min_size=1, max_size=2)), "scale": [2, 2, 2]})
    document = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [len(nodes) - 1]}], "nodes": nodes,
        "meshes": [{"primitives": [primitive]}], "accessors": accessors, "bufferViews": views,
        "buffers": [{"byteLength": field("buffer length", len(binary), st.integers(-1, 500))}],
    }
    chunk = json.dumps(document).encode()
    chunk += b" " * (-len(chunk) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<I4s", len(chunk), b"JSON") + chunk + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    length = field("file length", 12 + len(body), st.sampled_from([0, 12, 2**31]))
    return struct.pack("<4sII", b"glTF", 2, length) + body


@given(document=glb_document(), cut=cuts)
def test_fuzz_glb(fuzz_dir, document, cut):
    path = fuzz_dir / "fuzz.glb"
    path.write_bytes(truncate(document, cut))
    check_outcome(path)


# Any format: random bytes, and random edits of a valid file -----------------------------------------

MAGIC = [b"", b"ply\n", b"ply\nformat ascii 1.0\n", b"solid ", b"OFF\n", b"glTF", b"v 1 2 3\n", b"\xef\xbb\xbf", b"{"]


@given(extension=st.sampled_from(FORMATS), magic=st.sampled_from(MAGIC), data=st.binary(max_size=1500))
def test_fuzz_random_bytes(fuzz_dir, extension, magic, data):
    path = fuzz_dir / f"bytes.{extension}"
    path.write_bytes(magic + data)
    check_outcome(path)


def _valid_file(extension: str, encoding: str | None = None) -> bytes:
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    if extension == "gltf":
        return box.export(file_type="gltf", embed_buffers=True)["model.gltf"]  # buffers as data: URIs
    data = box.export(file_type=extension, **({"encoding": encoding} if encoding else {}))
    return data.encode() if isinstance(data, str) else data


VALID = {(e, enc or ""): _valid_file(e, enc) for e, enc in [
    ("obj", None), ("ply", "ascii"), ("ply", "binary"), ("stl", None), ("stl_ascii", None), ("off", None),
    ("glb", None), ("gltf", None)]}


@given(which=st.sampled_from(sorted(VALID)), edits=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)),
                                                           min_size=1, max_size=8), cut=cuts)
def test_fuzz_edited_valid_files(fuzz_dir, which, edits, cut):
    data = bytearray(VALID[which])
    for position, value in edits:
        data[position % len(data)] = value
    path = fuzz_dir / f"edited.{which[0].removesuffix('_ascii')}"
    path.write_bytes(truncate(bytes(data), cut))
    check_outcome(path)


@pytest.mark.parametrize("which", sorted(VALID))
def test_unedited_valid_files_load(fuzz_dir, which):
    path = fuzz_dir / f"valid.{which[0].removesuffix('_ascii')}"
    path.write_bytes(VALID[which])
    check_outcome(path)
    assert sum(len(o.mesh.faces) for o in load_mesh_file(path)) == 12
