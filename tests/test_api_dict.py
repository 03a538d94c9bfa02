"""``rl.load_dict``: a scene from one plain description. What it builds is what the description
says (sizes, placements, lights, the lens's focus and stop), its materials are those a pbrt-v4
file with the same parameters gives, and any other input is a one-line UserError naming the key."""

import copy
import math
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import realistic as rl
from realistic.optics.paraxial import focus_distance_for_film, paraxial_data
from realistic.renderer.from_dict import CAMERA_KEYS, LIGHT_KEYS, SCENE_KEYS, SHAPE_COMMON, SHAPE_KEYS
from realistic.scene.lights import DistantLight, EmissiveInstance, PointLight
from realistic.scene.metals import named_metal
from realistic.scene.model import AreaLight
from realistic.scene.pbrt.importer import import_pbrt

DESCRIPTION = {
    "shapes": [{"type": "sphere", "radius": 0.5, "center": [0, 0.5, 0],
                "material": {"type": "conductor", "eta": "metal-Au-eta", "k": "metal-Au-k", "roughness": 0.05}},
               {"type": "rectangle", "width": 10, "height": 4, "normal": [0, 1, 0], "material": "floor"},
               {"type": "disk", "radius": 0.5, "center": [0, 3, 0], "normal": [0, -1, 0], "emission": 20}],
    "materials": {"floor": {"type": "diffuse", "reflectance": [0.6, 0.5, 0.4]}},
    "lights": [{"type": "distant", "direction": [1, 2, 1], "irradiance": 2},
               {"type": "point", "position": [1, 1, 1], "intensity": [1, 2, 3]}],
    "camera": {"type": "lens", "lens": "dgauss", "eye": [0, 1, 4], "target": [0, 0.5, 0], "focus": 3,
               "fstop": 4, "film_diagonal": 30, "width": 16, "height": 12, "spp": 2},
}


def test_the_description_builds_what_it_says():
    scene = rl.load_dict(DESCRIPTION)
    ball, floor = scene.instances
    lo = ball.transform[:3, 3] - 0.5
    np.testing.assert_allclose(ball.transform[:3, 3], [0, 0.5, 0])
    np.testing.assert_allclose(np.ptp(scene.meshes[ball.mesh].vertices, axis=0), [1, 1, 1], atol=1e-12)
    assert np.all(scene.bounds()[0] <= lo + 1e-9)
    floor_points = scene.meshes[floor.mesh].vertices @ floor.transform[:3, :3].T + floor.transform[:3, 3]
    np.testing.assert_allclose(floor_points[:, 1], 0, atol=1e-12)  # the plane faces +y: it lies in y = 0
    assert sorted(np.ptp(floor_points, axis=0).round(9).tolist()) == [0, 4, 10]
    light, distant, point = scene.lights
    assert isinstance(light, AreaLight) and light.shape == "disk" and light.radiance == (20, 20, 20)
    assert light.area() == pytest.approx(math.pi * 0.25)
    np.testing.assert_allclose(light.frame()[0], [0, 3, 0], atol=1e-12)
    np.testing.assert_allclose(light.frame()[3], [0, -1, 0], atol=1e-12)
    assert isinstance(distant, DistantLight) and distant.radiance == (2, 2, 2)
    np.testing.assert_allclose(distant.direction, np.array([1, 2, 1]) / math.sqrt(6))
    assert isinstance(point, PointLight) and point.intensity == (1, 2, 3)
    camera = scene.camera
    assert (camera.width, camera.height, camera.spp, camera.film_diagonal_mm) == (16, 12, 2, 30)
    assert paraxial_data(camera.lens).f_number == pytest.approx(4)
    assert focus_distance_for_film(camera.lens, camera.film_distance_mm) / 1000 == pytest.approx(3)
    np.testing.assert_allclose(camera.world_from_camera[:3, 3], [0, 1, 4])


def test_materials_are_what_a_pbrt_v4_file_with_those_parameters_gives(tmp_path):
    (tmp_path / "s.pbrt").write_text(
        'Camera "perspective"\nWorldBegin\n'
        'Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.05\n'
        'Shape "sphere" "float radius" 0.5\n'
        'Material "diffuse" "rgb reflectance" [0.6 0.5 0.4]\nShape "sphere"\n'
        'Material "coateddiffuse" "rgb reflectance" [0.2 0.3 0.4] "float roughness" 0.1 "bool remaproughness" false\n'
        'Shape "sphere"\n')
    with pytest.warns(UserWarning):  # coateddiffuse is approximated, and says so
        pbrt = import_pbrt(tmp_path / "s.pbrt", dialect="v4").scene
        ours = rl.load_dict({"shapes": [*DESCRIPTION["shapes"][:2], {
            "type": "sphere", "material": {"type": "coateddiffuse", "reflectance": [0.2, 0.3, 0.4],
                                           "roughness": 0.1, "remaproughness": False}}],
            "materials": DESCRIPTION["materials"]})
    assert [i.material for i in ours.instances] == [i.material for i in pbrt.instances]
    assert ours.instances[0].material.eta == named_metal("Au")[0]


def test_emitting_spheres_and_rectangles_are_lights():
    scene = rl.load_dict({"shapes": [{"type": "sphere", "emission": [1, 2, 3], "two_sided": True},
                                     {"type": "quad", "width": 2, "height": 3, "emission": 5}]})
    emitter, quad = scene.lights
    assert isinstance(emitter, EmissiveInstance) and emitter.instance == 0 and emitter.two_sided
    assert isinstance(quad, AreaLight) and quad.shape == "quad" and quad.area() == pytest.approx(6)


def test_an_emitting_sphere_keeps_its_world_centre_and_radius_for_cone_sampling():
    scene = rl.load_dict({"shapes": [{"type": "sphere", "radius": 0.5, "center": [1, 2, 3], "emission": 1,
                                      "transform": [[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}]})
    (emitter,) = scene.lights
    assert isinstance(emitter, EmissiveInstance) and emitter.sphere == ((2.0, 4.0, 6.0), pytest.approx(1.0))


def test_a_mesh_file_is_placed_by_its_transform_and_may_emit(tmp_path):
    (tmp_path / "tri.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    move = [[2, 0, 0, 1], [0, 2, 0, 2], [0, 0, 2, 3], [0, 0, 0, 1]]
    scene = rl.load_dict({"shapes": [{"type": "mesh", "filename": tmp_path / "tri.ply", "transform": move,
                                      "emission": [1, 1, 1]}]})
    np.testing.assert_allclose(np.array(scene.bounds()), [[1, 2, 3], [3, 4, 3]])
    assert isinstance(scene.lights[0], EmissiveInstance) and scene.lights[0].instance == 0
    with pytest.raises(rl.UserError, match=r"^shapes\[0\]\.filename: .*missing\.ply"):
        rl.load_dict({"shapes": [{"type": "mesh", "filename": str(tmp_path / "missing.ply")}]})


def test_a_thin_lens_camera_and_the_scene_settings():
    scene = rl.load_dict({"camera": {"type": "perspective", "fov": 30, "eye": [0, 0, 5], "lens_radius": 0.1,
                                     "width": 8, "height": 4, "spp": 1},
                          "integrator": "path", "max_depth": 3, "light_samples": 2, "background": 0.5})
    camera = scene.camera
    assert isinstance(camera, rl.ThinLensCamera) and camera.fov_deg == 30 and camera.focal_distance == 5
    assert (scene.integrator, scene.max_depth, scene.light_samples, scene.background) == ("path", 3, 2,
                                                                                             (0.5, 0.5, 0.5))


def test_a_described_scene_renders(tmp_path):
    image = rl.render(rl.load_dict(DESCRIPTION), backend="numpy", threads=1, spp=1)
    assert isinstance(image, rl.Image) and image.shape == (12, 16, 3) and float(image.mean()) > 0


def _with(path: str, value: object) -> dict:
    """DESCRIPTION with the value at ``path`` (dotted, [i] for list items) replaced."""
    description = copy.deepcopy(DESCRIPTION)
    *parents, last = path.replace("[", ".").replace("]", "").split(".")
    node = description
    for key in parents:
        node = node[int(key)] if key.isdigit() else node[key]
    node[int(last) if last.isdigit() else last] = value
    return description


@pytest.mark.parametrize("path, value, message", [
    ("shapes[2].radius", -1, r"^shapes\[2\]\.radius: disk radius must be a positive finite number, got -1$"),
    ("shapes[0].center", [0, 1], r"^shapes\[0\]\.center: must be a list of three numbers"),
    ("shapes[1].normal", [0, 0, 0], r"^shapes\[1\]\.normal: a direction must not be zero"),
    ("shapes[1].radius", 1, r"^shapes\[1\]\.radius: a rectangle has no 'radius'"),
    ("shapes[0].type", "torus", r"^shapes\[0\]\.type: must be one of sphere, disk"),
    ("shapes[0].material", "gold", r"^shapes\[0\]\.material: no material named 'gold'"),
    ("shapes[0].material.roughness", "rough", r"^shapes\[0\]\.material\.roughness: must be a number"),
    ("shapes[2].emission", [1, -1, 1], r"^shapes\[2\]\.emission: colour must be between 0"),
    ("shapes[0].transform", [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]],
     r"^shapes\[0\]\.transform: must be invertible"),
    ("materials.floor.reflectance", [2, 0, 0], None),  # clamped to [0, 1] with a warning, as pbrt-v4 does
    ("lights[0].irradiance", float("nan"), r"^lights\[0\]\.irradiance: colour must be a finite number"),
    ("lights[1].direction", [0, 0, 1], r"^lights\[1\]\.direction: a point light has no 'direction'"),
    ("camera.spp", 0, r"^camera\.spp: samples per pixel must be between 1 and"),
    ("camera.fstop", 0.5, r"^camera\.fstop: f/0\.5 is faster than dgauss opens"),
    ("camera.lens", "no-such-lens", r"no-such-lens"),
    ("camera.target", [0, 1, 4], r"^camera: eye and target coincide"),
    ("camera.film_diagonal", 5000, r"^camera\.film_diagonal: film diagonal \(mm\) must be at most 1000"),
    ("integrator", "whitted", r"^integrator: must be one of directlighting, path, got 'whitted'$"),
    ("shapes", {"type": "sphere"}, r"^shapes: must be a list, got dict$"),
])
def test_a_bad_value_is_one_line_naming_its_key_path(path, value, message):
    if message is None:
        with pytest.warns(UserWarning, match=r"materials\.floor: .*clamped"):
            rl.load_dict(_with(path, value))
        return
    with pytest.raises(rl.UserError, match=message) as raised:
        rl.load_dict(_with(path, value))
    assert "\n" not in str(raised.value)


def test_unknown_keys_are_refused_not_ignored():
    with pytest.raises(rl.UserError, match=r"^camera: unknown key 'fnumber'"):
        rl.load_dict({"camera": {"type": "lens", "fnumber": 4}})
    with pytest.raises(rl.UserError, match=r"^the description: unknown key 'shape' \(known: shapes, "):
        rl.load_dict({"shape": []})
    with pytest.raises(rl.UserError, match=r"^the description: must be a dict, got list$"):
        rl.load_dict([{"type": "sphere"}])


KEYS = sorted({*SCENE_KEYS, *SHAPE_COMMON, *(k for keys in SHAPE_KEYS.values() for k in keys),
               *(k for keys in LIGHT_KEYS.values() for k in keys), *(k for keys in CAMERA_KEYS.values() for k in keys),
               "reflectance", "roughness", "eta", "Kd", "materials", "amount"})
TYPES = sorted({*SHAPE_KEYS, *LIGHT_KEYS, *CAMERA_KEYS, "diffuse", "conductor", "mix", "dielectric", "plastic"})
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True),
                    st.sampled_from(TYPES), st.text(max_size=8), st.sampled_from(["dgauss", "floor", "metal-Au-eta"]))
ANY_KEY = st.sampled_from([*KEYS, "type"])
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=5) | st.dictionaries(ANY_KEY, inner, max_size=6),
                      max_leaves=25)


@given(description=st.dictionaries(st.sampled_from(KEYS), VALUES, max_size=5)
       | st.builds(lambda shapes, camera, materials: {"shapes": shapes, "camera": camera, "materials": materials},
                   st.lists(st.dictionaries(ANY_KEY, VALUES, max_size=6), max_size=3),
                   st.dictionaries(ANY_KEY, VALUES, max_size=6),
                   st.dictionaries(st.sampled_from(["floor", "x"]), VALUES, max_size=2)))
def test_any_description_gives_a_scene_or_a_one_line_user_error(description, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a string taken for a mesh or lens file names nothing of the project's
    try:
        with warnings.catch_warnings():  # a material approximated says so: not what this test judges
            warnings.simplefilter("ignore")
            scene = rl.load_dict(description)
    except rl.UserError as err:
        assert str(err) and "\n" not in str(err)
    else:
        assert isinstance(scene, rl.Scene)
