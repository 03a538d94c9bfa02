"""scenes/dof-dragons/seed*.pbrt: the seed scene (pbrt-v2 dof-dragons.pbrt) with the shared dragon
and measured BRDFs, through the four homework lenses. It reaches ../shared by relative paths, so
these tests skip where a checkout has no ../shared beside it."""

from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED, shared_file
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.parser import parse_pbrt, resolve_file

SCENES = Path(__file__).resolve().parents[1] / "scenes" / "dof-dragons"
#: lens: (seed file, lens file, the homework scene's filmdistance and aperture_diameter; shared/DATA.md)
LENSES = {"dgauss": ("seed.pbrt", "dgauss.50mm.dat", 36.77, 17.1),
          "wide": ("seed.wide.pbrt", "wide.22mm.dat", 14.54, 8.756),
          "fisheye": ("seed.fisheye.pbrt", "fisheye.10mm.dat", 23.192, 6.08),
          "telephoto": ("seed.telephoto.pbrt", "telephoto.250mm.dat", 123.74390, 40.5)}
DRAGON_TRIANGLES = 202_520  # shared/meshes/dragon.ply (shared/DATA.md, section 3)


@pytest.fixture(scope="module")
def shared():
    shared_file("meshes/dragon.ply")
    shared_file("scenes/pbrt/brdfs/acryl_blue.brdf")
    return SHARED


@pytest.mark.parametrize("lens", sorted(LENSES))
def test_each_seed_file_has_the_homework_camera_for_its_lens_from_the_shared_lens_file(shared, lens):
    name, lens_file, film_distance, stop = LENSES[lens]
    imported = import_pbrt(SCENES / name)
    camera = imported.scene.camera
    assert imported.dialect.name == "v2"
    assert Path(camera.lens.source.split("(")[-1].rstrip(")")).name == lens_file
    assert camera.film_distance_mm == film_distance and camera.lens.stop_diameter_mm == stop
    assert not any("stands in" in w for w in imported.warnings)  # the shared file, not the bundled copy


def test_the_seed_world_is_the_seeds_floor_and_eleven_dragons_with_their_measured_brdfs(shared):
    parsed = parse_pbrt(SCENES / "seed.pbrt")
    assert [name for name, _, _ in parsed.instances] == ["dragon-b", "dragon-a"] * 5 + ["dragon-b"]
    xs = [transform[0, 3] for _, transform, _ in parsed.instances]
    np.testing.assert_allclose(np.diff(xs), 0.26)  # the seed's Translate .26 between dragons
    assert xs[0] == pytest.approx(-0.6)
    expected = {"dragon-b": "acryl_blue.brdf", "dragon-a": "garnet_red.brdf"}
    for name, brdf in expected.items():
        (shape,) = parsed.objects[name]
        assert shape.material.type == "measured"
        declared_in = Path(shape.material.where.rsplit(":", 1)[0]).parent
        found = resolve_file(shape.material.params.get_string("filename"), declared_in, [])
        assert found is not None and found.resolve() == (shared / "scenes/pbrt/brdfs" / brdf).resolve()
        mesh = resolve_file(shape.params.get_string("filename"), shape.directory, [])
        assert mesh is not None and mesh.resolve() == (shared / "meshes/dragon.ply").resolve()


def test_the_seed_scene_imports_the_shared_dragon_once_and_instances_it(shared):
    imported = import_pbrt(SCENES / "seed.pbrt")
    scene = imported.scene
    dragons = [m for m in scene.meshes if len(m.faces) == DRAGON_TRIANGLES]
    assert len(dragons) == 1  # the file loaded and stored once for both object definitions
    assert len(scene.instances) == 12  # the floor and eleven dragons
    assert len(scene.lights) == 1


def test_the_repository_holds_no_copy_of_the_shared_data():
    for path in SCENES.iterdir():
        assert path.suffix == ".pbrt", path


def test_the_seed_scene_renders_its_dragons(shared):
    import realistic as rl

    scene = rl.load_scene(str(SCENES / "seed.pbrt"), resolution=(24, 24), spp=2)
    image = rl.render(scene, backend="numpy")
    assert np.all(np.isfinite(image)) and image.mean() > 0
