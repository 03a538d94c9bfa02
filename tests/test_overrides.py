"""The user's options are applied in one place after import (``renderer.inputs.apply_overrides``),
the same way to a pbrt scene's camera and to a staged mesh's: the importer gives what the file says,
the options replace it."""

import numpy as np
import pytest

from conftest import shared_file
from realistic.camera.lens_camera import LensCamera
from realistic.errors import UserError
from realistic.optics.paraxial import film_distance_for_focus
from realistic.renderer.inputs import RenderOptions, build_render_inputs
from realistic.scene.pbrt.importer import import_pbrt

FILM = 'Film "image" "integer xresolution" [32] "integer yresolution" [16]\nSampler "random" "integer pixelsamples" 3\n'
V3 = ('Camera "realistic" "string lensfile" "dgauss.50mm.dat" "float aperturediameter" 6 "float focusdistance" 3\n'
      'WorldBegin\nShape "sphere"\nWorldEnd\n')


def _scene(tmp_path, camera: str = V3) -> str:
    path = tmp_path / "s.pbrt"
    path.write_text(FILM + 'PixelFilter "gaussian"\n' + camera)
    return str(path)


def test_the_importer_gives_what_the_file_says(tmp_path):
    camera = import_pbrt(_scene(tmp_path), [shared_file("lenses")]).scene.camera
    assert (camera.width, camera.height, camera.spp) == (32, 16, 3)
    assert camera.pixel_filter.name == "gaussian" and camera.lens_sampling == "pupil"
    assert camera.lens.stop_diameter_mm == 6


@pytest.mark.parametrize("scene", ["pbrt", "mesh"])
def test_film_options_replace_the_scenes_on_every_kind_of_scene(tmp_path, scene):
    path = _scene(tmp_path) if scene == "pbrt" else None
    options = dict(resolution=(12, 6), spp=2, pixel_filter="mitchell", lens_sampling="rear", light_samples=3,
                   integrator="path", max_depth=2)
    inputs = build_render_inputs(RenderOptions(scene=path, search_paths=[shared_file("lenses")] if path else [],
                                               **options))
    camera = inputs.scene.camera
    assert (camera.width, camera.height, camera.spp) == (12, 6, 2)
    assert camera.pixel_filter.name == "mitchell" and camera.lens_sampling == "rear"
    assert (inputs.scene.light_samples, inputs.scene.integrator, inputs.scene.max_depth) == (3, "path", 2)


@pytest.mark.parametrize("scene", ["pbrt", "mesh"])
def test_the_stop_changes_and_the_focus_follows_the_thick_lens_model(tmp_path, scene):
    path = _scene(tmp_path) if scene == "pbrt" else None
    search = [shared_file("lenses")] if path else []
    plain = build_render_inputs(RenderOptions(scene=path, search_paths=search)).scene.camera
    stopped = build_render_inputs(RenderOptions(scene=path, search_paths=search, aperture_mm=5.0)).scene.camera
    assert stopped.lens.stop_diameter_mm == 5.0
    assert stopped.film_distance_mm == plain.film_distance_mm  # the film stays where the scene focused it
    focused = build_render_inputs(RenderOptions(scene=path, search_paths=search, focus_distance=2.5)).scene.camera
    assert isinstance(focused, LensCamera)
    assert focused.film_distance_mm == film_distance_for_focus(focused.lens, 2.5 * focused.mm_per_unit)


def test_stop_options_on_a_perspective_camera_name_its_line_and_the_focus_is_its_focal_distance(tmp_path):
    path = _scene(tmp_path, 'Camera "perspective" "float fov" 40 "float lensradius" 0.1\n'
                            'WorldBegin\nShape "sphere"\nWorldEnd\n')
    with pytest.raises(UserError, match=r"s\.pbrt:4: the stop options .* give --lens too"):
        build_render_inputs(RenderOptions(scene=path, f_number=4.0))
    assert build_render_inputs(RenderOptions(scene=path, focus_distance=2.0)).camera.focal_distance == 2.0
    assert isinstance(build_render_inputs(RenderOptions(scene=path, lens="wide", f_number=4.0)).camera, LensCamera)
    with pytest.raises(UserError, match="--camera-pos apply to mesh scenes"):
        build_render_inputs(RenderOptions(scene=path, camera_position=np.ones(3)))
