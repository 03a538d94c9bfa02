"""The numpy reader of plain binary PLY files gives what trimesh gives; a mesh file named by several
pbrt shapes is loaded and stored once."""

import numpy as np
import pytest

from realistic.scene import meshes
from realistic.scene.meshes import load_mesh_file, read_plain_binary_ply
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
        m.setattr(meshes, "read_plain_binary_ply", lambda _path: None)
        return load_mesh_file(path)


@pytest.mark.parametrize("order, vertex_type, index_type", [("<", "float", "int"), (">", "float", "int"),
                                                            ("<", "double", "uint"), (">", "double", "uint")])
def test_plain_binary_ply_reads_as_trimesh_reads_it(tmp_path, monkeypatch, order, vertex_type, index_type):
    vertices, faces = grid_mesh()
    path = write_ply(tmp_path / "grid.ply", vertices, faces, order, vertex_type, index_type)
    assert read_plain_binary_ply(path) is not None
    [fast], [slow] = load_mesh_file(path), trimesh_objects(path, monkeypatch)
    for field in ("vertices", "faces"):
        a, b = getattr(fast.mesh, field), getattr(slow.mesh, field)
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert fast.mesh.normals is slow.mesh.normals is None and fast.mesh.uv is slow.mesh.uv is None
    assert fast.mesh.name == slow.mesh.name and fast.colour == slow.colour and fast.source == slow.source
    assert np.array_equal(fast.transform, slow.transform)


def test_other_ply_layouts_go_to_trimesh(tmp_path):
    vertices, faces = grid_mesh(4)
    normals = write_ply(tmp_path / "n.ply", vertices, faces, extra_header="")
    text = normals.read_bytes().replace(b"property float z\n", b"property float z\nproperty float nx\n", 1)
    (tmp_path / "extra.ply").write_bytes(text)
    assert read_plain_binary_ply(tmp_path / "extra.ply") is None  # an extra vertex property
    quads = write_ply(tmp_path / "q.ply", vertices, faces, counts=4)
    assert read_plain_binary_ply(quads) is None  # not triangles: the sizes do not add up either
    (tmp_path / "tail.ply").write_bytes(normals.read_bytes() + b"\0")
    assert read_plain_binary_ply(tmp_path / "tail.ply") is None
    (tmp_path / "a.ply").write_text("ply\nformat ascii 1.0\nelement vertex 0\nend_header\n")
    assert read_plain_binary_ply(tmp_path / "a.ply") is None


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
