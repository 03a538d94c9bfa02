"""The plyfile reader of PLY files (binary and ASCII; normals, uv, polygons) gives what trimesh gives,
without importing trimesh; what it does not read goes to trimesh; a mesh file named by several pbrt
shapes is loaded and stored once."""

import numpy as np
import pytest

from conftest import run_fresh, shared_file
from realistic.scene import meshes
from realistic.scene.meshes import load_mesh_file, read_ply
from realistic.scene.pbrt.importer import import_world


def write_ply(path, vertices, faces, order="<", vertex_type="float", index_type="int", extra_header="",
              counts=None):
    codes = {"float": "f4", "double": "f8", "int": "i4", "uint": "u4"}
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    header = (f"ply\nformat {fmt} 1.0\ncomment made by a test\nelement vertex {len(vertices)}\n"
              + "".join(f"property {vertex_type} {axis}\n" for axis in "xyz")
              + f"{extra_header}element face {len(faces)}\n"
              + f"property list uchar {index_type} vertex_indices\nend_header\n")
    face = np.zeros(len(faces), [("n", "u1"), ("i", order + codes[index_type], 3)])
    face["n"] = 3 if counts is None else counts
    face["i"] = faces
    path.write_bytes(header.encode() + np.asarray(vertices, order + codes[vertex_type]).tobytes() + face.tobytes())
    return path


def grid_mesh(n=12):
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 2, n))
    vertices = np.column_stack([x.ravel(), y.ravel(), np.sin(3 * x.ravel()) * 0.1])
    cells = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.concatenate([np.column_stack([cells, cells + 1, cells + n]),
                            np.column_stack([cells + 1, cells + n + 1, cells + n])])
    return vertices, faces


def trimesh_objects(path, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(meshes, "read_ply", lambda _path: None)
        return load_mesh_file(path)


@pytest.mark.parametrize("order, vertex_type, index_type", [("<", "float", "int"), (">", "float", "int"),
                                                            ("<", "double", "uint"), (">", "double", "uint")])
def test_binary_ply_reads_as_trimesh_reads_it(tmp_path, monkeypatch, order, vertex_type, index_type):
    vertices, faces = grid_mesh()
    path = write_ply(tmp_path / "grid.ply", vertices, faces, order, vertex_type, index_type)
    assert read_ply(path) is not None
    [fast], [slow] = load_mesh_file(path), trimesh_objects(path, monkeypatch)
    for field in ("vertices", "faces"):
        a, b = getattr(fast.mesh, field), getattr(slow.mesh, field)
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert fast.mesh.normals is slow.mesh.normals is None and fast.mesh.uv is slow.mesh.uv is None
    assert fast.mesh.name == slow.mesh.name and fast.colour == slow.colour and fast.source == slow.source
    assert np.array_equal(fast.transform, slow.transform)


def write_ascii_ply(path, vertices, polygons, vertex_properties=("x", "y", "z"), face_extra=""):
    """An ASCII PLY: ``vertices`` rows under ``vertex_properties`` (float unless "TYPE NAME"), ``polygons``
    as index lists."""
    header = (f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\n"
              + "".join(f"property {name if ' ' in name else 'float ' + name}\n" for name in vertex_properties)
              + f"element face {len(polygons)}\nproperty list uchar int vertex_indices\n{face_extra}end_header\n")
    rows = [" ".join(f"{v:.17g}" for v in row) for row in vertices]
    rows += [" ".join(str(i) for i in [len(polygon), *polygon]) for polygon in polygons]
    path.write_text(header + "\n".join(rows) + "\n")
    return path


def write_binary_polygons(path, vertices, polygons, order="<"):
    """A binary PLY of float x, y, z and faces of any lengths (uchar count, int indices)."""
    header = (f"ply\nformat binary_{'little' if order == '<' else 'big'}_endian 1.0\nelement vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(polygons)}\nproperty list uchar int vertex_indices\nend_header\n")
    body = np.asarray(vertices, order + "f4").tobytes()
    body += b"".join(np.uint8(len(p)).tobytes() + np.asarray(p, order + "i4").tobytes() for p in polygons)
    path.write_bytes(header.encode() + body)
    return path


def assert_same_mesh(fast, slow):
    """The same triangles, corner by corner: positions and, where given, normals and uv."""
    assert fast.mesh.faces.dtype == slow.mesh.faces.dtype == np.int64
    assert fast.mesh.vertices.dtype == slow.mesh.vertices.dtype == np.float64
    np.testing.assert_array_equal(fast.mesh.vertices[fast.mesh.faces], slow.mesh.vertices[slow.mesh.faces])
    for field in ("normals", "uv"):
        a, b = getattr(fast.mesh, field), getattr(slow.mesh, field)
        assert (a is None) == (b is None), field
        if a is not None:
            np.testing.assert_array_equal(a[fast.mesh.faces], b[slow.mesh.faces])
    assert fast.mesh.name == slow.mesh.name and fast.colour == slow.colour and fast.source == slow.source


#: Triangles, quads, a pentagon and a hexagon, and lists too short to be a face (trimesh drops them).
POLYGONS = [[0, 1, 5], [1, 2, 6, 5], [2, 3, 7, 6], [4, 5, 9, 8], [5, 6, 10, 9, 8], [6, 7, 11, 10, 9, 5],
            [0, 4], [], [3, 7, 11]]
POLYGON_VERTICES = np.array([[x, y, 0.1 * x * y] for y in range(3) for x in range(4)])


@pytest.mark.parametrize("kind", ["ascii", "binary <", "binary >"])
@pytest.mark.parametrize("polygons", [POLYGONS, [p for p in POLYGONS if len(p) == 4]], ids=["mixed", "quads"])
def test_polygons_are_triangulated_as_trimesh_does(tmp_path, monkeypatch, kind, polygons):
    """trimesh's reference is the ASCII file: it cannot read binary faces of mixed lengths."""
    text = write_ascii_ply(tmp_path / "p.ply", POLYGON_VERTICES, polygons)
    path = text if kind == "ascii" else write_binary_polygons(tmp_path / "b.ply", POLYGON_VERTICES, polygons, kind[-1])
    assert read_ply(path) is not None
    [fast], [slow] = load_mesh_file(path), trimesh_objects(text, monkeypatch)
    np.testing.assert_array_equal(fast.mesh.faces, slow.mesh.faces)  # the same triangles in the same order
    np.testing.assert_array_equal(fast.mesh.vertices, slow.mesh.vertices)


@pytest.mark.parametrize("uv_names", [None, ("u", "v"), ("s", "t"), ("texture_u", "texture_v")])
@pytest.mark.parametrize("with_normals", [False, True])
def test_ascii_ply_with_normals_and_uv_reads_as_trimesh_reads_it(tmp_path, monkeypatch, uv_names, with_normals):
    vertices, faces = grid_mesh(5)
    columns, names = [vertices], ["x", "y", "z"]
    if with_normals:
        normals = np.column_stack([-vertices[:, 2], vertices[:, 0], np.ones(len(vertices))])
        columns.append(normals / np.linalg.norm(normals, axis=1)[:, None])
        names += ["nx", "ny", "nz"]
    if uv_names:
        columns.append(vertices[:, :2] / [1, 2])
        names += list(uv_names)
    columns.append(np.arange(len(vertices))[:, None])  # a property neither reader uses, as scanners add
    path = write_ascii_ply(tmp_path / "a.ply", np.hstack(columns), faces, (*names, "confidence"))
    mesh = read_ply(path)
    assert (mesh.normals is not None) == with_normals and (mesh.uv is not None) == bool(uv_names)
    [fast], [slow] = load_mesh_file(path), trimesh_objects(path, monkeypatch)
    assert_same_mesh(fast, slow)


def test_the_dragon_reads_as_trimesh_reads_it(monkeypatch):
    path = shared_file("meshes/dragon.ply")
    [fast], [slow] = load_mesh_file(path), trimesh_objects(path, monkeypatch)
    np.testing.assert_array_equal(fast.mesh.vertices, slow.mesh.vertices)
    np.testing.assert_array_equal(fast.mesh.faces, slow.mesh.faces)


def test_reading_a_ply_does_not_import_trimesh(tmp_path):
    vertices, faces = grid_mesh(4)
    write_ascii_ply(tmp_path / "a.ply", vertices, faces)
    write_binary_polygons(tmp_path / "b.ply", vertices, [*faces.tolist(), [0, 1, 5, 4]])
    script = ("import sys\nfrom realistic.scene.meshes import load_mesh_file\n"
              "for name in sys.argv[1:]:\n    assert len(load_mesh_file(name)[0].mesh.faces) > 0\n"
              "print(sorted(m for m in ('trimesh', 'scipy', 'plyfile') if m in sys.modules))")
    out = run_fresh(script, str(tmp_path / "a.ply"), str(tmp_path / "b.ply")).stdout
    assert out.split() == ["['plyfile']"]


def test_other_ply_layouts_go_to_trimesh(tmp_path, monkeypatch):
    vertices, faces = grid_mesh(4)
    colours = np.hstack([vertices, np.tile([200, 100, 50], (len(vertices), 1))])
    names = ("x", "y", "z", "uchar red", "uchar green", "uchar blue")
    path = write_ascii_ply(tmp_path / "c.ply", colours, faces, names)
    assert read_ply(path) is None  # colours: trimesh reads them
    [obj] = load_mesh_file(path)
    assert obj.colour == pytest.approx((200 / 255, 100 / 255, 50 / 255))
    edges = write_ascii_ply(tmp_path / "e.ply", vertices, faces, face_extra="element edge 0\n"
                            "property int vertex1\nproperty int vertex2\n")
    assert read_ply(edges) is None  # another element
    (tmp_path / "points.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                         "property float y\nproperty float z\nend_header\n0 0 0\n")
    assert read_ply(tmp_path / "points.ply") is None  # no faces


def test_malformed_ply_goes_to_trimeshs_diagnosis(tmp_path):
    vertices, faces = grid_mesh(4)
    whole = write_ply(tmp_path / "whole.ply", vertices, faces).read_bytes()
    (tmp_path / "cut.ply").write_bytes(whole[:-5])
    assert read_ply(tmp_path / "cut.ply") is None
    with pytest.raises(meshes.UserError, match=r"cut\.ply.*not a readable PLY mesh") as err:
        load_mesh_file(tmp_path / "cut.ply")
    assert "\n" not in str(err.value)
    text = write_ascii_ply(tmp_path / "bad.ply", vertices, faces).read_text().replace("\n3 ", "\n3 x ", 1)
    (tmp_path / "bad.ply").write_text(text)
    assert read_ply(tmp_path / "bad.ply") is None


def test_a_bad_plain_ply_is_refused_as_before(tmp_path):
    vertices, faces = grid_mesh(4)
    faces[0, 0] = 99
    with pytest.raises(meshes.UserError, match="face indices outside its vertex list"):
        load_mesh_file(write_ply(tmp_path / "bad.ply", vertices, faces))
    flat = np.zeros_like(vertices)
    with pytest.raises(meshes.UserError, match="no triangle has a non-zero area"):
        load_mesh_file(write_ply(tmp_path / "flat.ply", flat, grid_mesh(4)[1]))


def test_a_mesh_file_named_by_two_shapes_is_stored_once(tmp_path):
    vertices, faces = grid_mesh()
    write_ply(tmp_path / "thing.ply", vertices, faces)
    (tmp_path / "scene.pbrt").write_text('''WorldBegin
ObjectBegin "a"
Shape "plymesh" "string filename" "thing.ply"
ObjectEnd
ObjectBegin "b"
Rotate 10 0 1 0
Shape "plymesh" "string filename" "thing.ply"
ObjectEnd
ObjectInstance "a"
Translate 2 0 0
ObjectInstance "b"
Translate 2 0 0
ObjectInstance "a"
WorldEnd
''')
    scene = import_world(tmp_path / "scene.pbrt")[0]
    assert len(scene.meshes) == 1 and len(scene.instances) == 3
    assert {inst.mesh for inst in scene.instances} == {0}
    assert not np.allclose(scene.instances[0].transform, scene.instances[1].transform)
