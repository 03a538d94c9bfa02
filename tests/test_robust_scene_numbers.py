"""Physically meaningless scene numbers are refused with the file and line, or reported with what
was used instead; input that is not honoured is reported; singular transforms are a warning, never
a traceback (issue 32). Each regression below imports or renders silently wrong on f91acd8."""

import dataclasses
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from realistic.core import validation
from realistic.errors import UserError
from realistic.renderer.output import report_image_problems
from realistic.scene.lights import DistantLight, EmissiveInstance, InfiniteLight, PointLight, SpotLight
from realistic.scene.model import AreaLight, Material
from realistic.scene.pbrt.importer import import_pbrt

LOOK = "LookAt 0 0 5  0 0 0  0 1 0\n"
FILM = 'Film "image" "integer xresolution" 8 "integer yresolution" 8\n'


def scene_file(folder, world: str, camera: str = 'Camera "perspective"\n', before: str = LOOK,
               world_begin: bool = True):
    path = folder / "scene.pbrt"
    path.write_text(before + camera + FILM + ("WorldBegin\n" if world_begin else "") + world)
    return path


def refusal(path) -> str:
    """The one-line UserError importing ``path`` raises."""
    with pytest.raises(UserError) as err:
        import_pbrt(path)
    message = str(err.value)
    assert "\n" not in message
    return message


def line_of(path, text: str) -> str:
    """``path:N`` of the first line of ``path`` that contains ``text``."""
    lines = path.read_text().splitlines()
    return f"{path}:{next(i for i, line in enumerate(lines, 1) if text in line)}"


# ---- 1. emission: finite, non-negative, within float32 after the scale ---------------------------

@pytest.mark.parametrize("light", [
    'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [-1 -1 -1]\nShape "sphere"\nAttributeEnd\n',
    'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1e308 1e308 1e308]\nShape "sphere"\nAttributeEnd\n',
    'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1e30 1 1] "float scale" 1e30\nShape "disk"\nAttributeEnd\n',
    'LightSource "infinite" "rgb L" [-1 1 1]\n',
    'LightSource "point" "rgb I" [1e308 1 1]\n',
    'LightSource "spot" "rgb I" [1 -2 1]\n',
    'LightSource "distant" "rgb L" [1 1 1] "float scale" -3\n',
])
def test_a_light_whose_emission_is_negative_or_overflows_is_refused_at_its_line(tmp_path, light):
    path = scene_file(tmp_path, light)
    message = refusal(path)
    source = next(word for word in ("AreaLightSource", "LightSource") if word in light)
    assert message.startswith(line_of(path, source) + ": ")
    assert "must be between 0 and" in message


@pytest.mark.parametrize("make", [
    lambda rgb: PointLight(rgb, np.zeros(3)),
    lambda rgb: SpotLight(rgb, np.eye(4), 0.5, 0.9),
    lambda rgb: DistantLight(rgb, np.array([0.0, 0.0, 1.0])),
    lambda rgb: InfiniteLight(rgb),
    lambda rgb: EmissiveInstance(0, rgb),
    lambda rgb: AreaLight("disk", (1.0, 1.0), rgb),
])
@pytest.mark.parametrize("rgb", [(-1.0, 1.0, 1.0), (math.nan, 1.0, 1.0), (1.0, math.inf, 1.0), (1e308, 1.0, 1.0)])
def test_the_python_api_refuses_the_same_emission(make, rgb):
    with pytest.raises(UserError, match="must be"):
        make(rgb)
    make((1.0, 2.0, validation.MAX_EMISSION))  # the limit itself is fine


# ---- 1. reflectance: matte Kd clamped to [0, 1] as pbrt-v4 does, refused when not finite -------

def test_a_matte_kd_outside_0_1_is_clamped_with_a_warning(tmp_path):
    path = scene_file(tmp_path, 'Material "matte" "rgb Kd" [-5 1e30 .5]\nShape "sphere"\n')
    imported = import_pbrt(path)
    assert {inst.material.diffuse for inst in imported.scene.instances} == {(0.0, 1.0, 0.5)}
    assert any(w.startswith(line_of(path, "Material")) and "clamped" in w for w in imported.warnings)


def test_a_matte_kd_that_is_not_finite_is_refused(tmp_path):
    path = scene_file(tmp_path, 'Material "matte" "rgb Kd" [.5 nan .5]\nShape "sphere"\n')
    assert refusal(path).startswith(line_of(path, "Material"))


@pytest.mark.parametrize("kd", [(-0.1, 0.5, 0.5), (1.5, 0.5, 0.5), (math.nan, 0.5, 0.5)])
def test_the_python_api_refuses_a_matte_albedo_outside_0_1(kd):
    with pytest.raises(UserError, match="matte Kd"):
        Material(kd)


# ---- 1. camera numbers --------------------------------------------------------------------------

def test_a_projective_camera_transform_is_refused(tmp_path):
    path = scene_file(tmp_path, "", before=LOOK + "ConcatTransform [1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 2]\n")
    message = refusal(path)
    assert message.startswith(line_of(path, 'Camera "perspective"')) and "projective" in message


def test_a_huge_film_distance_is_refused(tmp_path):
    camera = ('Camera "realistic" "string specfile" "dgauss.50mm.dat" "float filmdistance" 1e300 '
              '"float aperture_diameter" 10 "float filmdiag" 35\n')
    path = scene_file(tmp_path, "", camera=camera)
    message = refusal(path)
    assert message.startswith(line_of(path, "Camera")) and "film distance" in message


def test_an_up_vector_along_the_view_is_refused(tmp_path):
    path = scene_file(tmp_path, "", before="LookAt 0 0 5  0 0 0  0 0 1\n")
    message = refusal(path)
    assert message.startswith(line_of(path, "LookAt")) and "parallel" in message


# ---- 2. input that is not honoured is reported --------------------------------------------------

def test_screenwindow_is_reported(tmp_path):
    path = scene_file(tmp_path, "", camera='Camera "perspective" "float screenwindow" [-1 1 -1 1]\n')
    assert any(w.startswith(line_of(path, "Camera")) and "screenwindow" in w for w in import_pbrt(path).warnings)


def test_an_unknown_perspective_parameter_is_reported(tmp_path):
    path = scene_file(tmp_path, "", camera='Camera "perspective" "float fvo" 30\n')
    assert any('"fvo"' in w for w in import_pbrt(path).warnings)


def test_a_missing_world_begin_is_reported(tmp_path):
    path = scene_file(tmp_path, 'Shape "sphere"\n', world_begin=False)
    assert any("no WorldBegin" in w for w in import_pbrt(path).warnings)


def test_a_v4_file_with_world_begin_and_no_world_end_is_not_reported(tmp_path):
    path = tmp_path / "v4.pbrt"
    path.write_text(LOOK + 'Camera "perspective"\nFilm "rgb"\nWorldBegin\n'
                    'Material "diffuse" "rgb reflectance" [.5 .5 .5]\nShape "sphere"\n')
    imported = import_pbrt(path)
    assert imported.dialect.name == "v4" and imported.warnings == []


# ---- 3. singular and projective transforms on shapes: a warning, the shape skipped ---------------

@pytest.mark.parametrize("world", [
    'ObjectBegin "a"\nScale 0 0 0\nShape "sphere"\nObjectEnd\nObjectInstance "a"\n',
    'Transform [0 0 0 0  0 0 0 0  0 0 0 0  0 0 0 1]\nShape "sphere"\n',
    'ConcatTransform [1 0 0 .5  0 1 0 0  0 0 1 0  0 0 0 1]\nShape "sphere"\n',
    'Scale 1 0 1\nShape "trianglemesh" "integer indices" [0 1 2] "point P" [0 0 0 1 0 0 0 1 0]\n',
])
def test_a_shape_under_a_singular_or_projective_transform_is_skipped_with_its_line(tmp_path, world):
    path = scene_file(tmp_path, world)
    imported = import_pbrt(path)
    assert imported.scene.instances == []  # nothing the intersector would have to invert
    assert any(w.startswith(line_of(path, "Shape")) and "singular" in w for w in imported.warnings)


def test_an_instance_under_a_singular_transform_is_skipped_at_its_line(tmp_path):
    path = scene_file(tmp_path, 'ObjectBegin "a"\nShape "sphere"\nObjectEnd\nScale 0 0 0\nObjectInstance "a"\n')
    imported = import_pbrt(path)
    assert imported.scene.instances == []
    assert any(w.startswith(line_of(path, "ObjectInstance")) and "singular" in w for w in imported.warnings)


# ---- 1. a film with NaN or infinite pixels is reported ------------------------------------------

def test_nan_and_infinite_pixels_are_counted_in_one_warning(tmp_path, capsys):
    image = np.ones((4, 5, 3), np.float32)
    image[0, 0, 1], image[2, 3] = np.nan, np.inf
    assert report_image_problems(tmp_path / "x.exr", image) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 of 20 pixels are NaN or infinite" in err
    assert report_image_problems(tmp_path / "x.exr", np.ones((2, 2, 3))) == 0
    assert capsys.readouterr().err == ""


# ---- 4. property: any numbers give a finite scene or a one-line error naming file:line ----------

NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(
    [0.0, -0.0, 5e-324, -1.0, 1e-300, 1e300, -1e300, 1e38, 3.5e38, 0.5, 1.0]))


def _text(value: float) -> str:
    return repr(float(value)).replace("inf", "1e999")  # pbrt text has no inf; 1e999 reads as one


def _finite_scene(imported) -> bool:
    scene = imported.scene
    arrays = [np.asarray(scene.camera.world_from_camera, np.float64)]  # a ThinLensCamera or a LensCamera
    arrays += [np.asarray(inst.transform) for inst in scene.instances]
    arrays += [mesh.vertices for mesh in scene.meshes]
    for light in scene.lights:
        arrays += [np.asarray(getattr(light, f.name), np.float64) for f in dataclasses.fields(light)
                   if isinstance(getattr(light, f.name), (tuple, np.ndarray)) and getattr(light, f.name) is not None]
    for inst in scene.instances:
        diffuse = getattr(inst.material, "diffuse", None)
        if isinstance(diffuse, tuple):
            arrays.append(np.asarray(diffuse))
    return all(np.all(np.isfinite(a)) for a in arrays)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(light=st.lists(NUMBERS, min_size=4, max_size=4), kd=st.lists(NUMBERS, min_size=3, max_size=3),
       ks=NUMBERS, rough=NUMBERS, transform=st.lists(NUMBERS, min_size=3, max_size=3), fov=NUMBERS,
       lens=NUMBERS, kind=st.sampled_from(["area", "point", "infinite", "distant"]))
def test_any_numbers_import_finite_or_fail_in_one_line_at_their_file(tmp_path, light, kd, ks, rough, transform, fov,
                                                                       lens, kind):
    r, g, b, s = (_text(v) for v in light)
    emitter = {
        "area": f'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [{r} {g} {b}] "float scale" {s}\n'
                f'Shape "disk"\nAttributeEnd\n',
        "point": f'LightSource "point" "rgb I" [{r} {g} {b}] "float scale" {s}\n',
        "infinite": f'LightSource "infinite" "rgb L" [{r} {g} {b}]\n',
        "distant": f'LightSource "distant" "rgb L" [{r} {g} {b}] "point from" [0 0 {s}]\n',
    }[kind]
    world = (emitter + f'Material "matte" "rgb Kd" [{" ".join(_text(v) for v in kd)}]\nShape "sphere"\n'
             f'Material "plastic" "rgb Ks" [{_text(ks)} .5 .5] "float roughness" {_text(rough)}\n'
             f'AttributeBegin\nScale {" ".join(_text(v) for v in transform)}\nShape "sphere"\nAttributeEnd\n')
    camera = f'Camera "perspective" "float fov" {_text(fov)} "float lensradius" {_text(lens)}\n'
    path = scene_file(tmp_path, world, camera=camera)
    try:
        imported = import_pbrt(path)
    except UserError as err:
        message = str(err)
        assert "\n" not in message and message.startswith(f"{path}:")
        return
    assert _finite_scene(imported)


def test_rendering_an_object_flattened_by_scale_0_warns_instead_of_a_traceback(tmp_path):
    """On f91acd8 this render ended in numpy's LinAlgError when the intersector inverted the instance."""
    path = scene_file(tmp_path, 'LightSource "point" "rgb I" [10 10 10] "point from" [0 0 4]\n'
                                'ObjectBegin "a"\nScale 0 0 0\nShape "sphere"\nObjectEnd\nObjectInstance "a"\n'
                                'Shape "sphere" "float radius" .5\nWorldEnd\n')
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-m", "realistic", "render", str(path), "--spp", "1", "--backend", "numpy",
                           "--out", str(tmp_path / "out.exr")], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    assert f'{line_of(path, "Shape")}: unsupported: Shape "sphere" under a transform that is singular' in done.stderr


def test_an_all_black_image_is_reported(tmp_path, capsys):
    """A scene whose light reaches nothing rendered an all-black image with exit 0 and no word."""
    from realistic.cli import main

    path = tmp_path / "dark.pbrt"
    path.write_text('Camera "perspective"\nFilm "image" "integer xresolution" 8 "integer yresolution" 6\n'
                    'WorldBegin\nShape "sphere" "float radius" 1\nWorldEnd\n')
    assert main(["render", str(path), "--spp", "1", "--backend", "numpy", "--out", str(tmp_path / "d.exr")]) == 0
    assert "every pixel is black after 48 samples" in capsys.readouterr().err
    assert report_image_problems(tmp_path / "x.exr", np.zeros((2, 2, 3)), samples_done=0) == 0  # nothing taken yet
