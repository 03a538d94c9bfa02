"""Regression tests for bad mesh files: one clear line naming the file and what is wrong, status 2 from
the CLI with no output written, never a raw internal error or numpy warning, never a silently wrong image."""

import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from realistic.cli import main
from realistic.errors import UserError
from realistic.scene.meshes import MAX_COORDINATE, load_mesh_file
from realistic.scene.staging import MESH_SIZE, mesh_setup

REPO = Path(__file__).resolve().parents[1]
TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def write(tmp_path, name, content):
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


def refused(path, *fragments):
    """Loading and staging ``path`` raises one UserError line naming it and each fragment; no warning escapes."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(UserError) as err:
            mesh_setup(load_mesh_file(path))
    message = str(err.value)
    assert str(path) in message and "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, message
    for leaked in ("No module named", "charset", "list index out of range", "out of bounds", "Errno"):
        assert leaked not in message, message
    assert not caught, [str(w.message) for w in caught]
    return message


def staged_points(setup):
    subject = setup.scene.instances[0]
    vertices = setup.scene.meshes[subject.mesh].vertices
    return vertices @ subject.transform[:3, :3].T + subject.transform[:3, 3]


def binary_stl(triangles) -> bytes:
    return b"\0" * 80 + struct.pack("<I", len(triangles)) + b"".join(
        struct.pack("<12fH", 0, 0, 1, *np.ravel(t), 0) for t in triangles)


# 1. A missing optional module is never the reason ---------------------------------------------------

@pytest.mark.parametrize("content", [b"solid junk\n\x80\x81 not \xfe an \xff stl\n",
                                     np.random.default_rng(0).bytes(300)], ids=["solid-junk", "random"])
def test_garbage_stl_is_not_a_readable_stl(tmp_path, content):
    refused(write(tmp_path, "garbage.stl", content), "not a readable STL mesh", "nor ASCII STL (not UTF-8 text)")


@pytest.mark.parametrize("name", ["latin1.obj", "latin1.off"])
def test_text_that_is_not_utf8_says_so(tmp_path, name):
    content = b"OFF\n3 1 0\n" if name.endswith("off") else TRIANGLE.encode()
    refused(write(tmp_path, name, content + b"# caf\xe9\n"), "the text is not valid UTF-8")


@pytest.mark.parametrize(("name", "content", "fragment"), [
    ("garbage.stl", b"solid junk\n\x80\x81 not \xfe an \xff stl\n", "nor ASCII STL (not UTF-8 text)"),
    ("latin1.obj", TRIANGLE.encode() + b"# caf\xe9\n", "the text is not valid UTF-8")])
def test_a_file_read_as_empty_gets_its_own_diagnosis(tmp_path, monkeypatch, name, content, fragment):
    """With ``charset_normalizer`` installed (requests brings it), trimesh decodes text that is not UTF-8
    and garbage STL and reads no triangles instead of failing: the message still says what is wrong
    with the file (here trimesh is made to read nothing, as it then does)."""
    monkeypatch.setattr(trimesh, "load", lambda *args, **kwargs: trimesh.Scene())
    refused(write(tmp_path, name, content), fragment)


# 2. Truncated or malformed PLY -------------------------------------------------------------------------

def test_truncated_ply_header(tmp_path):
    path = write(tmp_path, "cut.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n")
    refused(path, "not a readable PLY mesh (truncated or malformed header")


def test_malformed_ply_header_line_is_located(tmp_path):
    path = write(tmp_path, "bad.ply", "ply\nformat ascii 1.0\nelement vertex\nproperty float x\nend_header\n")
    refused(path, f"{path}:3: not a readable PLY mesh (an element line must be 'element NAME COUNT'")


def test_truncated_binary_ply_data(tmp_path):
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
    path = write(tmp_path, "short.ply", header.encode() + bytes(20))
    refused(path, "declares at least 37 bytes of data, the file has 20")


# 3. A directory -----------------------------------------------------------------------------------------

def test_a_directory_is_not_a_mesh(tmp_path):
    (tmp_path / "folder.obj").mkdir()
    refused(tmp_path / "folder.obj", "is a directory")


# 4. Files that used to render a wrong image with status 0 -------------------------------------------------

@pytest.mark.parametrize("faces", ["f 1 2 3\n", "f 1 1 2\nf 2 2 2\n"], ids=["collinear", "repeated"])
def test_only_degenerate_triangles_are_refused(tmp_path, faces):
    path = write(tmp_path, "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\n" + faces)
    refused(path, "no triangle has a non-zero area")


def test_degenerate_binary_stl_is_refused(tmp_path):
    path = write(tmp_path, "flat.stl", binary_stl([[[0, 0, 0], [1, 1, 1], [2, 2, 2]]] * 2))
    refused(path, "no triangle has a non-zero area")


@pytest.mark.parametrize("face", ["f 0 1 2", "f 1/1 2/0 3/1", "f 1//1 2//1 -0//1", "f 1 2 00"])
def test_obj_face_index_zero_is_refused(tmp_path, face):
    path = write(tmp_path, "zero.obj", TRIANGLE + "vt 0 0\nvn 0 0 1\n" + face + "\n")
    refused(path, f"{path}:6: invalid face index 0 (OBJ indices start at 1)")


def test_zeros_that_are_not_face_indices_load(tmp_path):
    text = "# f 0 1 2\nv 0 0 0\nv 10 0 0\nv 0 10.0 0\nv 0 0 10\n" + "vt 0.5 0\n" * 30
    path = write(tmp_path, "ok.obj", text + "f 1 2 3\nf 1/10 2/20 4/30\nf 3 4 2\n")
    assert [len(o.mesh.faces) for o in load_mesh_file(path)] == [3]


@pytest.mark.parametrize("line", [" v 0 0 10", "v\t0 0 10", "vn\t0 0 1", "\tf 1 2 3"])
def test_obj_lines_trimesh_would_skip_are_refused(tmp_path, line):
    path = write(tmp_path, "skips.obj", TRIANGLE + line + "\nf 1 2 3\n")  # trimesh drops or shifts these silently
    refused(path, f"{path}:4: not a readable OBJ mesh (an indented statement, or a tab after its keyword")


def test_obj_comment_after_a_statement_is_located(tmp_path):
    path = write(tmp_path, "comment.obj", TRIANGLE + "f 1 2 3 # the only face\n")
    refused(path, f"{path}:4: not a readable OBJ mesh (a comment after a f statement")


def test_obj_face_index_beyond_the_vertices_is_located(tmp_path):
    path = write(tmp_path, "far.obj", TRIANGLE + "f 1 2 4\n")
    refused(path, f"{path}:4: not a readable OBJ mesh (face index 4, but the file has 3 vertices)")


@pytest.mark.parametrize("value", ["1e30", "-1e13", "1e300"])
def test_absurd_coordinates_are_refused(tmp_path, value):
    path = write(tmp_path, "huge.obj", TRIANGLE + f"v {value} 0 0\nf 1 2 3\nf 1 2 4\n")
    refused(path, "has a vertex coordinate of", f"beyond the ±{MAX_COORDINATE:.0e} accepted")


def test_absurd_ply_coordinate_is_refused(tmp_path):
    path = write(tmp_path, "huge.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
                                       "property double z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                       "end_header\n0 0 0\n1e300 0 0\n0 1 0\n3 0 1 2\n")
    refused(path, "has a vertex coordinate of 1e+300")


def test_coordinates_up_to_the_limit_are_staged(tmp_path):
    path = write(tmp_path, "big.obj", f"v 0 0 0\nv {MAX_COORDINATE:g} 0 0\nv 0 {MAX_COORDINATE:g} 0\nf 1 2 3\n")
    points = staged_points(mesh_setup(load_mesh_file(path)))
    assert np.ptp(points, axis=0).max() == pytest.approx(MESH_SIZE)


def test_a_far_vertex_in_a_degenerate_face_does_not_shrink_the_subject(tmp_path):
    path = write(tmp_path, "stray.obj", TRIANGLE + "v 1e11 0 0\nv 1e9 1e9 1e9\nf 1 2 3\nf 1 2 4\n")
    points = staged_points(mesh_setup(load_mesh_file(path)))
    used = points[:3]  # the triangle; the stray vertices are in no face with an area
    assert np.ptp(used, axis=0).max() == pytest.approx(MESH_SIZE)


def test_a_bounding_box_too_large_for_float32_is_refused(tmp_path):
    path = write(tmp_path, "sliver.obj", TRIANGLE + "v 1e11 1 0\nf 1 2 3\nf 1 2 4\n")  # a 1e11-long sliver
    refused(path, "no triangle is large enough to resolve", "far from the rest")


def test_tiny_meshes_are_staged_and_specks_refused(tmp_path):
    tiny = write(tmp_path, "tiny.obj", "v 0 0 0\nv 1e-9 0 0\nv 0 1e-9 0\nf 1 2 3\n")
    assert np.ptp(staged_points(mesh_setup(load_mesh_file(tiny))), axis=0).max() == pytest.approx(MESH_SIZE)
    speck = write(tmp_path, "speck.obj", "v 0 0 0\nv 1e-14 0 0\nv 0 1e-14 0\nf 1 2 3\n")
    refused(speck, "smaller than the 1e-12 that can be staged")


@pytest.mark.parametrize("transform, message", [
    (np.diag([1.0, 1.0, 0.0, 1.0]), "singular transform"),
    (trimesh.transformations.translation_matrix([1e20, 0, 0]), "placed by the file's transforms beyond"),
])
def test_glb_node_transforms_are_checked(tmp_path, transform, message):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), geom_name="box", transform=transform)
    path = tmp_path / "placed.glb"
    scene.export(path)
    refused(path, message)


def test_ascii_stl_facets_that_would_shift_vertices_are_refused(tmp_path):
    def facet(*vertices):
        return "facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {v}\n" for v in vertices) + "endloop\nendfacet\n"

    shifted = write(tmp_path, "shift.stl", "solid s\n" + facet("0 0 0", "1 0 0") + facet("0 1 0", "0 0 1", "1 1 0",
                                                                                        "2 2 2") + "endsolid s\n")
    refused(shifted, f"{shifted}:3: not a readable STL mesh (a facet without exactly three vertex lines)")
    numbers = write(tmp_path, "numbers.stl", "solid s\n" + facet("0 0", "1 0 0 0", "0 1 0") + "endsolid s\n")
    refused(numbers, f"{numbers}:4: not a readable STL mesh (a vertex line needs three numbers)")
    cut = write(tmp_path, "cut.stl", "solid s\n" + facet("0 0 0", "1 0 0", "0 1 0"))
    refused(cut, "without an 'endsolid' line")


def test_gltf_buffers_must_be_files_beside_it(tmp_path):
    missing = write(tmp_path, "missing.gltf", '{"asset": {"version": "2.0"}, "buffers": [{"uri": "gone.bin", '
                                              '"byteLength": 10}]}')
    refused(missing, "it refers to 'gone.bin', which is missing")
    outside = write(tmp_path, "outside.gltf", '{"asset": {"version": "2.0"}, "buffers": [{"uri": "/dev/zero", '
                                              '"byteLength": 10}]}')
    refused(outside, "it refers to '/dev/zero', outside the file's folder")


# Through the command line ---------------------------------------------------------------------------

CLI_CASES = {
    "garbage.stl": (b"solid junk\n\x80\x81\xfe\xff\n", "not a readable STL mesh"),
    "cut.ply": ("ply\nformat ascii 1.0\nelement vertex 3\n", "truncated or malformed header"),
    "folder.obj": (None, "is a directory"),
    "flat.obj": ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "no triangle has a non-zero area"),
    "zero.obj": (TRIANGLE + "f 0 1 2\n", "invalid face index 0"),
    "huge.obj": (TRIANGLE + "v 1e30 0 0\nf 1 2 3\nf 1 2 4\n", "beyond the"),
    "overflow.obj": (TRIANGLE + "v 1e300 1e300 1e300\nf 1 2 3\nf 1 2 4\n", "beyond the"),
}


@pytest.mark.parametrize("name", sorted(CLI_CASES))
def test_cli_refuses_bad_meshes_with_one_line(tmp_path, capsys, name):
    content, message = CLI_CASES[name]
    path = tmp_path / name
    if content is None:
        path.mkdir()
    else:
        write(tmp_path, name, content)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status = main(["render", str(path), "--res", "8x8", "--spp", "1", "--backend", "numpy",
                       "--out", str(tmp_path / "o.exr")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith(f"realistic: error: {path}") and err.count("\n") == 1 and message in err, err
    assert "Traceback" not in err and not [w for w in caught if issubclass(w.category, RuntimeWarning)]
    assert not (tmp_path / "o.exr").exists() and not (tmp_path / "o.png").exists()


def test_overflowing_coordinates_print_no_numpy_warning(tmp_path):
    path = write(tmp_path, "overflow.obj", TRIANGLE + "v 1e300 -1e300 1e300\nf 1 2 3\nf 1 2 4\n")
    result = subprocess.run([sys.executable, "-m", "realistic", "render", str(path), "--res", "8x8",
                             "--spp", "1", "--backend", "numpy", "--out", str(tmp_path / "o.exr")],
                            capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "beyond the" in result.stderr
    assert "RuntimeWarning" not in result.stderr and "Traceback" not in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overflow.obj"]


def test_a_mesh_path_that_is_a_fifo_says_so_without_opening_it(tmp_path):
    """A FIFO named as the mesh is said to be one (``core.input_files``), not opened (that blocks)."""
    import os

    from realistic.scene.meshes import load_mesh_file

    fifo = tmp_path / "mesh.obj"
    os.mkfifo(fifo)
    with pytest.raises(UserError, match=r"mesh\.obj: is a named pipe \(FIFO\), not a mesh file$"):
        load_mesh_file(fifo)
