"""The pbrt scene language front end: tokens, parameters, transforms, state and errors."""

import numpy as np
import pytest

from conftest import shared_file
from realistic.errors import UserError
from realistic.scene.pbrt.parser import Param, Params, parse_pbrt


def write(tmp_path, text, name="scene.pbrt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_rotate_turns_x_into_y_about_z(tmp_path):
    path = write(tmp_path, 'WorldBegin\nAttributeBegin\nRotate 90 0 0 1\nShape "sphere"\nAttributeEnd\n'
                           'Rotate 90 1 0 0\nShape "sphere"\n')
    about_z, about_x = parse_pbrt(path).shapes
    np.testing.assert_allclose(about_z.transform @ [1, 0, 0, 1], [0, 1, 0, 1], atol=1e-15)
    np.testing.assert_allclose(about_x.transform @ [0, 1, 0, 1], [0, 0, 1, 1], atol=1e-15)


def test_look_at_places_the_eye_at_the_origin_and_the_target_on_plus_z(tmp_path):
    path = write(tmp_path, 'LookAt 1 2 3  4 6 3  0 0 1\nCamera "perspective"\n')
    m = parse_pbrt(path).camera.transform  # world to camera
    np.testing.assert_allclose(m @ [1, 2, 3, 1], [0, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(m @ [4, 6, 3, 1], [0, 0, 5, 1], atol=1e-12)
    np.testing.assert_allclose(m @ [1, 2, 4, 1], [0, 1, 0, 1], atol=1e-12)  # up stays up


def test_parameters_comments_and_include(tmp_path):
    write(tmp_path, 'Shape "sphere" "float radius" 2  # a comment\n', "inc.pbrt")
    path = write(tmp_path, 'Film "image" "integer xresolution" [64] "string filename" "a.exr"\n'
                           'WorldBegin\nInclude "inc.pbrt"\nShape "disk" "float radius" [ 3 ] "bool x" "true"\n')
    scene = parse_pbrt(path)
    assert scene.film.params.get_float("xresolution") == 64
    assert scene.film.params.get_string("filename") == "a.exr"
    assert [s.type for s in scene.shapes] == ["sphere", "disk"]
    assert scene.shapes[0].params.get_float("radius") == 2
    assert scene.shapes[0].where == f"{tmp_path / 'inc.pbrt'}:1"


def test_attribute_and_transform_stacks(tmp_path):
    path = write(tmp_path, 'WorldBegin\nAttributeBegin\nTranslate 1 0 0\nMaterial "matte" "rgb Kd" [1 0 0]\n'
                           'TransformBegin\nScale 2 2 2\nShape "sphere"\nTransformEnd\nShape "sphere"\n'
                           'AttributeEnd\nShape "sphere"\n')
    a, b, c = parse_pbrt(path).shapes
    np.testing.assert_allclose(a.transform @ [1, 0, 0, 1], [3, 0, 0, 1])
    np.testing.assert_allclose(b.transform @ [1, 0, 0, 1], [2, 0, 0, 1])
    np.testing.assert_allclose(c.transform, np.eye(4))
    assert a.material.type == b.material.type == "matte" and c.material.params.items == {}


def test_object_instances_compose_transforms(tmp_path):
    path = write(tmp_path, 'WorldBegin\nObjectBegin "o"\nTranslate 0 1 0\nShape "sphere"\nObjectEnd\n'
                           'Translate 5 0 0\nObjectInstance "o"\nTranslate 1 0 0\nObjectInstance "o"\n')
    scene = parse_pbrt(path)
    (shape,) = scene.objects["o"]
    points = [inst @ shape.transform @ [0, 0, 0, 1] for _, inst, _ in scene.instances]
    np.testing.assert_allclose(points, [[5, 1, 0, 1], [6, 1, 0, 1]])


def test_named_coordinate_systems(tmp_path):
    path = write(tmp_path, 'Translate 1 2 3\nCoordinateSystem "here"\nIdentity\nCamera "perspective"\n'
                           'WorldBegin\nCoordSysTransform "here"\nShape "sphere"\nCoordSysTransform "camera"\n'
                           'Shape "sphere"\n')
    here, camera = parse_pbrt(path).shapes
    np.testing.assert_allclose(here.transform @ [0, 0, 0, 1], [1, 2, 3, 1])
    np.testing.assert_allclose(camera.transform, np.eye(4))


@pytest.mark.parametrize("text,line,fragment", [
    ('Film "image"\nTranslate 1 x 3\n', 2, "expected a number after Translate"),
    ('Shape "sphere" "float radius [2]\n', 1, "unterminated string"),
    ('WorldBegin\nAttributeEnd\n', 2, "without a matching AttributeBegin"),
    ('Shape "sphere" "floaty radius" [2]\n', 1, 'expected a parameter "type name"'),
    ('Shape "sphere" "float radius" [2\n', 1, "unexpected end of file"),
    ('WorldBegin\nObjectInstance "nope"\n', 2, 'no object of that name'),
    ('Rotate 30 0 0 0\n', 1, "zero rotation axis"),
    ('LookAt 1 2 3  1 2 3  0 1 0\n', 1, "eye and target coincide"),
    ('LookAt 0 0 0  0 5 0  0 1 0\n', 1, "parallel to the viewing direction"),
    ('Camera "perspective"\n[ 1 2 ]\n', 2, "expected a directive"),
])
def test_syntax_errors_name_file_line_and_expectation(tmp_path, text, line, fragment):
    path = write(tmp_path, text)
    with pytest.raises(UserError) as err:
        parse_pbrt(path)
    assert str(err.value).startswith(f"{path}:{line}:")
    assert fragment in str(err.value)


def test_unknown_directive_is_reported_once_and_skipped(tmp_path):
    path = write(tmp_path, 'Foo 1 2 "x"\nFoo 3\nWorldBegin\nShape "sphere"\n')
    scene = parse_pbrt(path)
    assert scene.warnings == [f"{path}:1: unsupported: directive Foo (ignored)"]
    assert len(scene.shapes) == 1


def test_homework_scene_camera_and_instances():
    scene = parse_pbrt(shared_file("scenes/pbrt/dof-dragons.dgauss.pbrt"))
    assert scene.camera.type == "realistic"
    assert scene.camera.params.get_string("specfile") == "dgauss.50mm.dat"
    assert scene.camera.params.get_float("filmdistance") == pytest.approx(36.77)
    world_from_camera = np.linalg.inv(scene.camera.transform)
    # camera position and viewing direction as given in shared/scenes/pbrt/README.md
    np.testing.assert_allclose(world_from_camera @ [0, 0, 0, 1], [2.3, 0.05, -0.5, 1], atol=1e-12)
    view = world_from_camera[:3, :3] @ [0, 0, 1]
    np.testing.assert_allclose(view / np.linalg.norm(view), [-0.78693, -0.05234, 0.61482], atol=1e-5)
    xs = [inst[1][0, 3] for inst in scene.instances]
    np.testing.assert_allclose(xs, -0.6 + 0.26 * np.arange(11), atol=1e-12)
    assert [name for name, _, _ in scene.instances][:3] == ["dragon-b", "dragon-a", "dragon-b"]
    assert scene.warnings == []


def test_typed_getters_give_the_default_only_when_a_parameter_is_missing():
    """``get_float``/``get_floats``/``get_string`` fall back to the default for a missing parameter;
    ``get_required_float`` refuses one in one line naming it. Any lookup of an empty list
    (``"float empty" []``) is an error at its file and line, as in pbrt-v4 (issue 34: it used to
    read as absent)."""
    params = Params({"empty": Param("float", "empty", (), "scene.pbrt:3"),
                     "two": Param("float", "two", (1.5, 2.5), "scene.pbrt:4"),
                     "word": Param("string", "word", ("box",), "scene.pbrt:5")})
    assert params.get_float("missing") is None
    assert params.get_float("two", 7.0) == 1.5 and params.get_floats("two", []) == [1.5, 2.5]
    assert params.get_string("word", "x") == "box" and params.get_string("missing", "x") == "x"
    assert params.get_required_float("two") == 1.5
    with pytest.raises(UserError, match='^"missing" needs a number$'):
        params.get_required_float("missing")
    for lookup in (lambda: params.get_float("empty", 7.0), lambda: params.get_floats("empty"),
                   lambda: params.get_required_float("empty"), lambda: params.has("empty")):
        with pytest.raises(UserError, match=r'^scene.pbrt:3: "float empty" \[\] is an empty list'):
            lookup()
    with pytest.raises(UserError, match='scene.pbrt:5: "word" expects numbers'):
        params.get_floats("word")


@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_an_include_that_is_a_fifo_or_a_directory_says_so(tmp_path, kind):
    """An Include naming a FIFO (opening it would block) or a directory is one line at the Include
    saying what the name is; it was reported as "no such file" and skipped."""
    import os

    from realistic.errors import UserError

    target = tmp_path / "part.pbrt"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    scene = tmp_path / "scene.pbrt"
    scene.write_text('WorldBegin\nInclude "part.pbrt"\nWorldEnd\n')
    with pytest.raises(UserError) as raised:
        parse_pbrt(scene)
    message = str(raised.value)
    assert message.startswith(f"{scene}:2:") and ("FIFO" if kind == "fifo" else "a directory") in message
    assert "\n" not in message
