"""pbrt scenes into our scene and camera: materials, textures, shapes, lights, camera conventions."""

import numpy as np
import pytest

from conftest import shared_file
from realistic.camera.base import SampleBlock
from realistic.camera.lens_camera import LensCamera
from realistic.camera.thin_lens import ThinLensCamera
from realistic.errors import UserError
from realistic.optics.paraxial import focus_distance_for_film
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.scene.model import CheckerTexture, ImageTexture
from realistic.scene.pbrt.importer import import_pbrt

HOMEWORK = ["dgauss", "fisheye", "telephoto", "wide"]


def write(tmp_path, text):
    path = tmp_path / "scene.pbrt"
    path.write_text(text)
    return path


CAMERA = 'Film "image" "integer xresolution" [32] "integer yresolution" [16]\nCamera "perspective" "float fov" 40\n'


def test_materials_textures_and_unsupported_reports(tmp_path):
    path = write(tmp_path, CAMERA + 'WorldBegin\n'
                 'Texture "c" "color" "checkerboard" "float uscale" 4 "float vscale" 4 '
                 '"rgb tex1" [1 1 1] "rgb tex2" [0 0 0]\n'
                 'Texture "s" "color" "scale" "texture tex1" "c" "color tex2" [.5 .5 .5]\n'
                 'Material "matte" "texture Kd" "s"\nShape "sphere"\n'
                 'Material "velvet"\nShape "sphere"\n'
                 'Material "plastic" "rgb Kd" [.1 .2 .3]\nShape "sphere"\n'
                 'LightSource "goniometric" "rgb I" [1 1 1]\n')
    imported = import_pbrt(path)
    a, b, c = (inst.material for inst in imported.scene.instances)
    assert isinstance(a.texture, CheckerTexture) and a.texture.cells == 4
    assert a.diffuse == pytest.approx((0.5, 0.5, 0.5))
    assert b.diffuse == (0.5, 0.5, 0.5) and b.texture is None
    assert c.diffuse == pytest.approx((0.1, 0.2, 0.3)) and c.specular == (0.25, 0.25, 0.25)  # plastic
    text = "\n".join(imported.warnings)
    assert f'{path}:8: unsupported: Material "velvet", rendered as matte grey' in text
    assert 'LightSource "goniometric" is not supported' in text


def test_shapes_instances_and_area_light(tmp_path):
    path = write(tmp_path, CAMERA + 'WorldBegin\nAttributeBegin\nAreaLightSource "area" "color L" [2 3 4] '
                 '"integer nsamples" [4]\nTranslate 0 5 0\nRotate 90 1 0 0\nShape "disk" "float radius" 2\n'
                 'AttributeEnd\nObjectBegin "o"\nShape "cone" "float radius" 1 "float height" 2\nObjectEnd\n'
                 'Translate 1 0 0\nObjectInstance "o"\nTranslate 1 0 0\nObjectInstance "o"\n'
                 'Shape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2] '
                 '"float uv" [0 0 1 0 0 1]\n')
    imported = import_pbrt(path)
    scene = imported.scene
    (light,) = scene.lights
    centre, _, _, normal = light.frame()
    np.testing.assert_allclose(centre, [0, 5, 0], atol=1e-12)
    np.testing.assert_allclose(normal, [0, -1, 0], atol=1e-12)  # pbrt's disk faces +z: rotated to face down
    assert light.radiance == (2, 3, 4) and imported.scene.light_samples == 4
    cones = [inst for inst in scene.instances if scene.meshes[inst.mesh].name == "cone"]
    assert len(cones) == 2 and cones[0].mesh == cones[1].mesh  # an instanced mesh is stored once
    assert [c.transform[0, 3] for c in cones] == [1, 2]
    tri = [inst for inst in scene.instances if scene.meshes[inst.mesh].name == "trianglemesh"]
    np.testing.assert_array_equal(scene.meshes[tri[0].mesh].uv, [[0, 0], [1, 0], [0, 1]])


def test_perspective_camera_and_film_settings(tmp_path):
    imported = import_pbrt(write(tmp_path, CAMERA + 'Sampler "random" "integer pixelsamples" 3\nWorldBegin\n'))
    assert isinstance(imported.scene.camera, ThinLensCamera)
    assert (imported.scene.camera.width, imported.scene.camera.height, imported.scene.camera.spp) == (32, 16, 3)
    overridden = build_render_inputs(RenderOptions(scene=write(tmp_path, CAMERA + 'WorldBegin\n'), resolution=(8, 4),
                                                   spp=2)).scene.camera
    assert (overridden.width, overridden.height, overridden.spp) == (8, 4, 2)


def test_missing_lens_and_texture_are_clear_errors(tmp_path):
    with pytest.raises(UserError, match='lens file "nope.dat" not found'):
        import_pbrt(write(tmp_path, 'Camera "realistic" "string specfile" "nope.dat" "float filmdistance" 30\n'))
    with pytest.raises(UserError, match="texture file \"x.exr\" not found"):
        import_pbrt(write(tmp_path, CAMERA + 'WorldBegin\nTexture "t" "color" "imagemap" "string filename" "x.exr"\n'
                          'Material "matte" "texture Kd" "t"\nShape "sphere"\n'))


@pytest.mark.parametrize("lens", HOMEWORK)
def test_homework_scene_imports_without_warnings(lens):
    # the lens files live in ../shared/lenses, not beside the scenes: found on the search path
    imported = import_pbrt(shared_file(f"scenes/pbrt/dof-dragons.{lens}.pbrt"), search_paths=[shared_file("lenses")])
    assert imported.warnings == []
    assert imported.dialect.name == "v2" and "specfile" in imported.dialect.reason
    assert imported.scene.instances[0].material.texture.v_origin == "top"  # pbrt-v2 looks the floor up so
    assert isinstance(imported.scene.camera, LensCamera)
    assert len(imported.scene.instances) == 12 and len(imported.scene.lights) == 1  # floor + 11 cones
    floor = imported.scene.instances[0].material
    assert isinstance(floor.texture, ImageTexture) and floor.diffuse == pytest.approx((0.5, 0.5, 0.5))
    # the homework camera's origin is the front lens vertex: the front of the lens sits at the eye
    camera = imported.scene.camera
    m = camera.world_from_lens
    front = m @ [0, 0, camera.film_distance_mm + camera.lens.track_length_mm, 1]
    np.testing.assert_allclose(front[:3], [2.3, 0.05, -0.5], atol=1e-12)


def test_pbrt_v3_realistic_camera_works_in_metres(tmp_path):
    path = write(tmp_path, 'Film "image" "integer xresolution" 8 "integer yresolution" 8\n'
                 'Camera "realistic" "string lensfile" "dgauss.50mm.dat" "float aperturediameter" 10 '
                 '"float focusdistance" 2\nWorldBegin\n')
    camera = import_pbrt(path).scene.camera
    assert camera.lens.stop_diameter_mm == 10
    assert focus_distance_for_film(camera.lens, camera.film_distance_mm) == pytest.approx(2000.0)
    np.testing.assert_allclose(camera.world_from_lens[:3, :3], np.eye(3) * 1e-3)
    rays = camera.generate_rays(SampleBlock(0, 64, camera.spp), 0)
    ok = rays.weight > 0
    assert ok.any() and np.all(np.abs(rays.origin[ok]) < 0.2)  # within the lens, in metres


def test_a_gzipped_scene_given_to_render_is_read_as_pbrt(tmp_path):
    """A top-level ``scene.pbrt.gz`` is a pbrt scene, as an included one is (it was called an
    unsupported mesh format): it imports to the same scene as the uncompressed file."""
    import gzip

    from realistic.core.data_files import data_file

    plain = data_file("scenes/default.pbrt")
    packed = tmp_path / "default.pbrt.gz"
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    assert RenderOptions(scene=str(packed)).is_pbrt
    a = build_render_inputs(RenderOptions(scene=str(plain), resolution=(32, 24), spp=1))
    b = build_render_inputs(RenderOptions(scene=str(packed), resolution=(32, 24), spp=1))
    assert len(a.scene.instances) == len(b.scene.instances) > 0
    assert a.camera.width == b.camera.width == 32
