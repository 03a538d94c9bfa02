"""Scene model, tessellated shapes, textures, mesh files of every format, and bad mesh files."""

import math

import numpy as np
import pytest
import trimesh

from realistic.core.image_files import read_linear_rgb
from realistic.core.transforms import rotate, scale, translate
from realistic.errors import UserError
from realistic.scene.intersect import Intersector
from realistic.scene.meshes import load_mesh_file
from realistic.scene.model import AreaLight, CheckerTexture, GridTexture, ImageTexture, Material, Scene
from realistic.scene.shapes import cone, disk, quad, sphere
from realistic.scene.staging import MESH_SIZE, mesh_setup
from realistic.scene.textures import albedo, evaluate


def face_normals(mesh):
    v = mesh.vertices[mesh.faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n, np.linalg.norm(n, axis=1)


@pytest.mark.parametrize("make", [lambda: sphere(0.5), lambda: cone(0.3, 0.8), lambda: disk(0.4), lambda: quad(1, 2)])
def test_shapes_wind_outward_and_have_unit_normals(make):
    mesh = make()
    n, area = face_normals(mesh)
    good = area > 1e-12  # a cone's apex row and a sphere's poles have degenerate triangles
    vertex_normal = mesh.normals[mesh.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n[good], vertex_normal[good]) > 0)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1, atol=1e-12)


def test_tessellation_is_fine_enough():
    r = 1.0
    ball = sphere(r)
    centres = ball.vertices[ball.faces].mean(axis=1)
    assert np.linalg.norm(centres, axis=1).min() > r * (1 - 2e-4)  # facets within 0.02 % of the sphere
    n, area = face_normals(disk(r))
    assert area.sum() / 2 == pytest.approx(math.pi * r * r, rel=2e-4)
    n, area = face_normals(cone(0.5, 2.0))
    assert area.sum() / 2 == pytest.approx(math.pi * 0.5 * math.hypot(0.5, 2.0), rel=2e-4)


def test_area_light_frame_follows_its_transform():
    light = AreaLight("disk", (2.0, 2.0), (1, 1, 1), translate(0, 5, 0) @ rotate(90, (1, 0, 0)) @ scale(1.5))
    centre, a, b, normal = light.frame()
    np.testing.assert_allclose(centre, [0, 5, 0])
    np.testing.assert_allclose(normal, [0, -1, 0], atol=1e-12)  # pbrt's Rotate 90 about x: +z -> -y
    assert light.area() == pytest.approx(math.pi * 3.0**2)
    flipped = AreaLight("quad", (2.0, 4.0), (1, 1, 1), reverse_orientation=True)
    assert flipped.area() == pytest.approx(8.0)
    np.testing.assert_allclose(flipped.frame()[3], [0, 0, -1])


def test_an_instanced_mesh_is_stored_once_and_hit_everywhere():
    scene = Scene()
    index = scene.add_mesh(sphere(0.5))
    for x in (-2.0, 0.0, 2.0):
        scene.add(index, translate(x, 0, 0))
    assert len(scene.meshes) == 1 and len(scene.instances) == 3
    hits = Intersector(scene).closest(np.array([[-2, 0.01, -5], [0, 0.01, -5], [2, 0.01, -5], [1, 0, -5]], np.float32),
                                      np.tile(np.float32([0, 0, 1]), (4, 1)))
    np.testing.assert_array_equal(hits.geom, [0, 1, 2, -1])
    np.testing.assert_allclose(hits.t[:3], 4.5, rtol=1e-3)


def test_procedural_textures():
    grid = GridTexture(base=(1, 1, 1), line=(0, 0, 0), cells=10, line_width=0.1)
    uv = np.array([[0.05, 0.05], [0.001, 0.05], [0.05, 0.299]])
    np.testing.assert_array_equal(evaluate(grid, uv)[:, 0], [1, 0, 0])
    checker = CheckerTexture((1, 1, 1), (0, 0, 0), cells=2)
    np.testing.assert_array_equal(evaluate(checker, np.array([[0.1, 0.1], [0.6, 0.1], [0.6, 0.6]]))[:, 0], [1, 0, 1])


def test_image_texture_is_upright_and_tinted_by_the_colour():
    pixels = np.zeros((2, 2, 3), np.float32)
    pixels[0, :, 0] = 1.0  # top row red
    pixels[1, :, 2] = 1.0  # bottom row blue
    texture = ImageTexture(pixels)
    colour = evaluate(texture, np.array([[0.25, 0.75], [0.25, 0.25]]))  # v up: top row at v = 0.75
    np.testing.assert_allclose(colour, [[1, 0, 0], [0, 0, 1]], atol=1e-6)
    tinted = albedo(Material((0.5, 0.5, 0.5), texture), np.array([[0.25, 0.75]]), 1)
    np.testing.assert_allclose(tinted, [[0.5, 0, 0]], atol=1e-6)


def test_texture_files_are_read_linear(tmp_path):
    from PIL import Image

    path = tmp_path / "t.png"
    Image.fromarray(np.full((2, 3, 3), 188, np.uint8)).save(path)
    pixels = read_linear_rgb(path)
    assert pixels.shape == (2, 3, 3)
    assert pixels[0, 0, 0] == pytest.approx(0.5, abs=0.01)  # sRGB 188 is linear 0.5
    with pytest.raises(UserError, match="no such texture"):
        read_linear_rgb(tmp_path / "missing.png")


# Mesh files ----------------------------------------------------------------------------------

@pytest.mark.parametrize("extension", ["ply", "stl", "off", "obj", "glb"])
def test_each_format_loads(tmp_path, extension):
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    path = tmp_path / f"box.{extension}"
    box.export(path)
    objects = load_mesh_file(path)
    assert len(objects) == 1
    mesh = objects[0].mesh
    points = mesh.vertices @ objects[0].transform[:3, :3].T + objects[0].transform[:3, 3]
    np.testing.assert_allclose(points.max(axis=0) - points.min(axis=0), [1, 2, 3], atol=1e-6)
    assert len(mesh.faces) == 12


def test_multi_object_obj_keeps_colours_and_normals(tmp_path):
    (tmp_path / "two.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    (tmp_path / "two.obj").write_text(
        "mtllib two.mtl\no a\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
        "o b\nusemtl blue\nv 0 0 1\nv 1 0 1\nv 0 1 1\nvn 0.6 0 0.8\nvn 0 0 1\nvn 0 0 1\nf 4//1 5//2 6//3\n")
    objects = {tuple(o.colour): o for o in load_mesh_file(tmp_path / "two.obj")}
    assert set(objects) == {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)}
    assert objects[(1.0, 0.0, 0.0)].mesh.normals is None  # face normals
    np.testing.assert_allclose(objects[(0.0, 0.0, 1.0)].mesh.normals[0], [0.6, 0, 0.8])  # smooth shading


def test_multi_object_glb_keeps_placement_and_base_colour(tmp_path):
    red = trimesh.creation.box()
    red.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(baseColorFactor=[255, 0, 0, 255]))
    scene = trimesh.Scene()
    scene.add_geometry(red, geom_name="red")
    scene.add_geometry(trimesh.creation.icosphere(), geom_name="ball",
                       transform=trimesh.transformations.translation_matrix([3, 0, 0]))
    scene.export(tmp_path / "two.glb")
    objects = load_mesh_file(tmp_path / "two.glb")
    assert len(objects) == 2
    by_name = {o.mesh.name: o for o in objects}
    assert by_name["red"].colour == (1.0, 0.0, 0.0)
    assert by_name["ball"].colour is None
    np.testing.assert_allclose(by_name["ball"].transform[:3, 3], [3, 0, 0])


def test_mesh_setup_normalises_and_stands_on_the_floor(tmp_path):
    box = trimesh.creation.box((10.0, 20.0, 5.0))
    box.apply_translation([100, 50, -7])
    box.export(tmp_path / "big.stl")
    setup = mesh_setup(load_mesh_file(tmp_path / "big.stl"))
    subject = setup.scene.instances[0]
    points = setup.scene.meshes[subject.mesh].vertices @ subject.transform[:3, :3].T + subject.transform[:3, 3]
    assert points[:, 1].min() == pytest.approx(0, abs=1e-9)
    assert np.ptp(points, axis=0).max() == pytest.approx(MESH_SIZE)
    assert setup.scene.lights and len(setup.scene.instances) == 2  # subject and floor


@pytest.mark.parametrize("name, content, message", [
    ("missing.obj", None, "no such mesh file"),
    ("empty.ply", b"", "empty"),
    ("text.ply", b"this is not a mesh\n", "not a readable PLY"),
    ("points.obj", b"v 0 0 0\nv 1 0 0\n", "no triangles"),
    ("bad.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
    ("mesh.xyz", b"1 2 3\n", "unsupported mesh format"),
])
def test_bad_mesh_files_raise_one_clear_error(tmp_path, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(UserError, match=message) as err:
        load_mesh_file(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
