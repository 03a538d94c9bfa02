"""Regressions for bad scene and lens inputs: each is a one-line UserError naming the file and line
at fault, or a warning where pbrt itself would carry on, never a traceback or a hang."""

import subprocess
import sys
import time

import numpy as np
import pytest

from realistic.errors import LensFileError, UserError
from realistic.optics.formats import load_lens
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.lens import MAX_SURFACES, build_lens
from realistic.optics.paraxial import paraxial_data
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.parser import MAX_INCLUDE_DEPTH, parse_pbrt

CAMERA = 'Camera "perspective"\n'
V3_LENS = 'Camera "realistic" "string lensfile" "dgauss.50mm.dat" '
HOMEWORK_LENS = 'Camera "realistic" "string specfile" "dgauss.50mm.dat" '


def write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def error_of(call, *args, kind=UserError):
    """The message of the UserError (of ``kind``) ``call(*args)`` raises: one line."""
    with pytest.raises(kind) as err:
        call(*args)
    message = str(err.value)
    assert "\n" not in message
    return message


# ---- 1. Include cycles and depth ----------------------------------------------------------------

def test_a_file_that_includes_itself_is_a_cycle_at_its_include_line(tmp_path):
    path = write(tmp_path, "a.pbrt", 'WorldBegin\nShape "sphere"\nInclude "a.pbrt"\n')
    assert error_of(parse_pbrt, path) == f'{path}:3: Include "a.pbrt" makes a cycle: {path} -> a.pbrt'


def test_two_files_that_include_each_other_name_the_closing_include(tmp_path):
    a = write(tmp_path, "a.pbrt", 'WorldBegin\n\nInclude "b.pbrt"\n')
    b = write(tmp_path, "b.pbrt", 'Shape "sphere"\nImport "a.pbrt"\n')
    assert error_of(parse_pbrt, a) == f'{b}:2: Import "a.pbrt" makes a cycle: {a} -> b.pbrt -> a.pbrt'


def test_a_cycle_reached_through_another_spelling_of_the_path_is_found(tmp_path):
    (tmp_path / "sub").mkdir()
    write(tmp_path, "sub/b.pbrt", 'Include "../a.pbrt"\n')
    a = write(tmp_path, "a.pbrt", 'Include "sub/b.pbrt"\n')
    assert "makes a cycle" in error_of(parse_pbrt, a)


def test_repeated_includes_of_one_file_are_not_a_cycle(tmp_path):
    write(tmp_path, "leaf.pbrt", 'Shape "sphere"\n')
    write(tmp_path, "mid.pbrt", 'Include "leaf.pbrt"\nInclude "leaf.pbrt"\n')
    top = write(tmp_path, "top.pbrt", 'WorldBegin\nInclude "mid.pbrt"\nInclude "mid.pbrt"\nInclude "leaf.pbrt"\n'
                                      'Shape "disk"\nWorldEnd\n')
    scene = parse_pbrt(top)
    assert [s.type for s in scene.shapes] == ["sphere"] * 5 + ["disk"]
    assert scene.shapes[-1].where == f"{top}:5"


def test_include_depth_is_bounded(tmp_path):
    for i in range(MAX_INCLUDE_DEPTH + 2):
        write(tmp_path, f"f{i}.pbrt", f'Include "f{i + 1}.pbrt"\n')
    write(tmp_path, f"f{MAX_INCLUDE_DEPTH + 2}.pbrt", 'Shape "sphere"\n')
    message = error_of(parse_pbrt, tmp_path / "f0.pbrt")
    assert message.startswith(f"{tmp_path / f'f{MAX_INCLUDE_DEPTH}.pbrt'}:1: ")
    assert f"more than {MAX_INCLUDE_DEPTH} deep" in message
    write(tmp_path, f"f{MAX_INCLUDE_DEPTH}.pbrt", 'Shape "sphere"\n')  # one less deep: fine
    assert len(parse_pbrt(tmp_path / "f0.pbrt").shapes) == 1


def test_an_include_name_too_long_for_the_system_is_a_missing_file(tmp_path):
    path = write(tmp_path, "a.pbrt", f'Include "{"x" * 5000}.pbrt"\nShape "sphere"\n')
    scene = parse_pbrt(path)
    assert len(scene.shapes) == 1 and "no such file" in scene.warnings[0]


# ---- 2. trianglemesh arrays ---------------------------------------------------------------------

MESH = 'Shape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2] '


@pytest.mark.parametrize("params,fragment", [
    ('"point P" [0 0 0 1 0 0 0 1] "integer indices" [0 1 2]', '"point P" needs 3 values per point, got 8'),
    ('"point P" [] "integer indices" [0 1 2]', '"point P" [] is an empty list'),
    ('"point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2 0]', '"integer indices" needs 3 per triangle, got 4'),
    ('"point P" [0 0 0 1 0 0 0 1 0 1 1 1] "integer indices" []', '"integer indices" [] is an empty list'),
    ('"point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 3]', "index 3 is not a point number (0 to 2"),
    ('"point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 -1 2]', "index -1 is not a point number"),
    ('"point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1.5 2]', "index 1.5 is not a point number"),
    ('"point P" [0 0 0 1 0 0 0 1 0] "integer indices" ["a" 1 2]', '"indices" expects numbers'),
])
def test_bad_trianglemesh_points_and_indices_name_the_shape_line(tmp_path, params, fragment):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\n\nShape "trianglemesh" {params}\nWorldEnd\n')
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:4: ")
    assert fragment in message


@pytest.mark.parametrize("extra,name", [('"float uv" [0 0 1 0 1]', "uv"), ('"float st" [0 0 1 0]', "st"),
                                        ('"float uv" [0 0 1 0 0 1 1 1]', "uv"), ('"normal N" [0 0 1 0 0 1 0]', "N")])
def test_uv_or_normals_that_do_not_fit_the_points_are_dropped_with_a_warning(tmp_path, extra, name):
    path = write(tmp_path, "s.pbrt", f"{CAMERA}WorldBegin\n{MESH}{extra}\nWorldEnd\n")
    imported = import_pbrt(path)
    (mesh,) = imported.scene.meshes
    assert (mesh.uv if name != "N" else mesh.normals) is None
    assert len(imported.warnings) == 1
    assert imported.warnings[0].startswith(f'{path}:3: unsupported: trianglemesh "{name}" has ')
    assert f"({name} ignored)" in imported.warnings[0]


def test_zero_length_normals_are_dropped_with_a_warning_and_others_are_normalised(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\n{MESH}"normal N" [0 0 2 0 0 1 0 0 0]\n'
                                     f'{MESH}"normal N" [0 0 2 0 3 0 1 0 0]\nWorldEnd\n')
    imported = import_pbrt(path)
    assert imported.scene.meshes[0].normals is None
    np.testing.assert_allclose(imported.scene.meshes[1].normals, [[0, 0, 1], [0, 1, 0], [1, 0, 0]])
    assert imported.warnings == [f'{path}:3: unsupported: trianglemesh "N" with a zero-length normal '
                                 f'(normals ignored)']


def test_three_points_without_indices_make_one_triangle_as_in_pbrt(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nShape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0]\n'
                                     f"WorldEnd\n")
    np.testing.assert_array_equal(import_pbrt(path).scene.meshes[0].faces, [[0, 1, 2]])


# ---- 3. unclosed blocks, missing WorldEnd -------------------------------------------------------

@pytest.mark.parametrize("block", ['AttributeBegin', 'TransformBegin', 'ObjectBegin "o"'])
def test_a_block_left_open_at_the_end_of_the_file_is_a_warning_at_its_line(tmp_path, block):
    kind = block.split()[0]
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\n{block}\nTranslate 1 0 0\nShape "sphere"\n')
    imported = import_pbrt(path)
    assert f"{path}:3: unsupported: {kind} without a matching {kind[:-5]}End by the end of the file" \
           in "\n".join(imported.warnings)
    assert imported.warnings[-1].startswith(f"{path}: unsupported: no WorldEnd after the WorldBegin at {path}:2 ")


def test_blocks_left_open_at_world_end_are_closed_there_with_a_warning(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nAttributeBegin\nTransformBegin\nTranslate 1 0 0\n'
                                     f'WorldEnd\n')
    imported = import_pbrt(path)
    assert imported.warnings == [
        f"{path}:4: unsupported: TransformBegin without a matching TransformEnd before WorldEnd (closed there)",
        f"{path}:3: unsupported: AttributeBegin without a matching AttributeEnd before WorldEnd (closed there)"]


def test_a_complete_file_has_no_warnings(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nAttributeBegin\nShape "sphere"\nAttributeEnd\n'
                                     f'WorldEnd\n')
    assert import_pbrt(path).warnings == []


def test_a_mismatched_end_names_the_block_it_would_close(tmp_path):
    path = write(tmp_path, "s.pbrt", "WorldBegin\nTransformBegin\nAttributeEnd\n")
    assert error_of(parse_pbrt, path) == f"{path}:3: AttributeEnd closes the TransformBegin at {path}:2"


# ---- 4. lenses with no refracting surface, afocal lenses -----------------------------------------

@pytest.mark.parametrize("text", ["0 5 0 10\n", "inf 2 1 10\n0 5 0 10\n-30 20 0 10\n"])
def test_a_lens_without_a_refracting_surface_is_refused_naming_the_file(tmp_path, text):
    path = write(tmp_path, "stop.dat", text)
    message = error_of(load_lens, str(path), kind=LensFileError)
    assert message.startswith(f"{path}: no refracting surface")


def test_an_afocal_lens_names_the_lens(tmp_path):
    path = write(tmp_path, "plate.dat", "inf 5 1.5 10\ninf 5 0 10\n0 5 0 8\n")  # a flat glass plate
    lens = load_lens(str(path))
    assert error_of(paraxial_data, lens).startswith(f"{path}: the lens is afocal")


# ---- 5. the surface count is capped, and a huge file is refused quickly ---------------------------

def rows(count, stop_at=0):
    return "".join("0 1 0 10\n" if i == stop_at else f"{100 + i} 1 {1.5 if i % 2 else 1} 10\n" for i in range(count))


def test_a_prescription_at_the_surface_limit_loads_and_one_past_it_is_refused(tmp_path):
    assert parse_prescription(rows(MAX_SURFACES), "x.dat").surface_count == MAX_SURFACES
    message = error_of(parse_prescription, "# lens\n" + rows(MAX_SURFACES + 1), "x.dat", kind=LensFileError)
    assert message == (f"x.dat:{MAX_SURFACES + 2}: at least {MAX_SURFACES + 1} surfaces exceed the limit of "
                       f"{MAX_SURFACES} (real lenses have well under 50)")


def test_a_huge_prescription_is_refused_quickly(tmp_path):
    path = write(tmp_path, "huge.dat", rows(400_000))
    start = time.perf_counter()
    message = error_of(load_lens, str(path), kind=LensFileError)
    assert time.perf_counter() - start < 2.0
    assert message.startswith(f"{path}:{MAX_SURFACES + 1}: at least {MAX_SURFACES + 1} surfaces exceed")


def test_build_lens_itself_refuses_too_many_surfaces():
    n = MAX_SURFACES + 5
    radius = [0.0] + [100.0 + i for i in range(1, n)]
    args = (list(range(1, n + 1)), radius, [1.0] * n, [1.5 if i % 2 else 1.0 for i in range(n)], [0.0] * n,
            [10.0] * n)
    message = error_of(build_lens, "x.dat", *args, kind=LensFileError)
    assert message == (f"x.dat:{MAX_SURFACES + 1}: {n} surfaces exceed the limit of {MAX_SURFACES} "
                       f"(real lenses have well under 50)")


@pytest.mark.parametrize("diameter,shown", [(-1.0, "-1"), (0, "0"), (float("nan"), "nan"), (float("inf"), "inf"),
                                            (None, "None"), ("4", "'4'"), (True, "True")])
def test_with_stop_diameter_refuses_what_is_not_a_positive_length(diameter, shown):
    message = error_of(load_lens("dgauss").with_stop_diameter, diameter)
    assert message == f"aperture diameter must be a positive number of mm, got {shown}"


def test_a_zmx_file_past_the_surface_limit_is_refused_at_its_surf_line():
    blocks = ["SURF 0\n  DISZ INFINITY\n"] + [
        f"SURF {i}\n  CURV {0.01 if i % 2 else -0.01}\n  DISZ 1\n  GLAS {'___BLANK 1 0 1.5 60' if i % 2 else 'AIR'}"
        f"\n  DIAM 5\n" for i in range(1, MAX_SURFACES + 3)]
    text = "".join(blocks)
    line = text.splitlines().index(f"SURF {MAX_SURFACES + 2}") + 1
    assert error_of(parse_zmx, text, "x.zmx") == (f"x.zmx:{line}: at least {MAX_SURFACES + 1} surfaces exceed the "
                                                  f"limit of {MAX_SURFACES} (real lenses have well under 50)")


# ---- 6. a directory as a lens file --------------------------------------------------------------

def test_a_directory_given_as_a_lens_file_says_so(tmp_path):
    assert error_of(load_lens, str(tmp_path), kind=LensFileError) == f"{tmp_path}: is a directory, not a lens file"
    assert error_of(load_lens, "x" * 5000).startswith("x" * 5000 + ": cannot read")


def test_a_directory_given_as_a_scene_says_so(tmp_path):
    assert error_of(parse_pbrt, tmp_path) == f"{tmp_path}: is a directory, not a scene file"


# ---- 7. camera parameters -----------------------------------------------------------------------

@pytest.mark.parametrize("camera,fragment", [
    (V3_LENS + '"float aperturediameter" -1', "aperture diameter must be a positive number of mm, got -1"),
    (HOMEWORK_LENS + '"float filmdistance" 36 "float aperture_diameter" 0',
     "aperture diameter must be a positive number of mm, got 0"),
    (HOMEWORK_LENS + '"float filmdistance" 36 "float aperture_diameter" -4', "got -4"),
    (HOMEWORK_LENS + '"float filmdistance" 36 "float aperture_diameter" []',
     '"float aperture_diameter" [] is an empty list'),
    (HOMEWORK_LENS + '"float filmdistance" []', '"float filmdistance" [] is an empty list'),
    (HOMEWORK_LENS + '"float filmdistance" 0', "film distance"),
    (HOMEWORK_LENS + '"float filmdistance" -36', "film distance"),
    (HOMEWORK_LENS + '"float filmdistance" 36 "float filmdiag" 0', "film diagonal"),
    (HOMEWORK_LENS + '"float filmdistance" 36 "float filmdiag" -35', "film diagonal"),
    (V3_LENS + '"float focusdistance" -2', "focusdistance must be a positive number of metres, got -2"),
    (V3_LENS + '"float focusdistance" 0.01', "closer than"),
    (HOMEWORK_LENS, 'needs "float filmdistance"'),
    ('Camera "realistic" "string lensfile" []',
     '"string lensfile" [] is an empty list: give it a value or leave it out'),
    ('Camera "perspective" "float fov" 0', "fov must be between 0 and 180"),
])
def test_bad_camera_parameters_name_the_camera_line(tmp_path, camera, fragment):
    path = write(tmp_path, "s.pbrt", f'Film "image" "integer xresolution" 8 "integer yresolution" 8\n{camera}\n'
                                     f"WorldBegin\nWorldEnd\n")
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:2: ")
    assert message.count(f"{path}:2:") == 1
    assert fragment in message


@pytest.mark.parametrize("film,fragment", [('"integer xresolution" 0', "resolution width"),
                                           ('"integer yresolution" 2.5', '"yresolution" must be a whole number'),
                                           ('"integer xresolution" 1e300', "resolution width")])
def test_bad_film_settings_name_the_film_line(tmp_path, film, fragment):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}Film "image" {film}\nWorldBegin\nWorldEnd\n')
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:2: ") and fragment in message


@pytest.mark.parametrize("diagonal", ["0", "-35", "1e9"])
def test_a_bad_pbrt3_film_diagonal_names_the_film_line(tmp_path, diagonal):
    path = write(tmp_path, "s.pbrt", f'{V3_LENS}\nFilm "image" "float diagonal" {diagonal}\nWorldBegin\nWorldEnd\n')
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:2: ") and "film diagonal" in message


def test_cli_reports_a_bad_camera_parameter_in_one_line_with_status_2(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{V3_LENS}"float aperturediameter" -1\nWorldBegin\nWorldEnd\n')
    result = subprocess.run([sys.executable, "-m", "realistic", "render", "--backend", "numpy", "--out",
                             str(tmp_path / "x.exr"), str(path)], capture_output=True, text=True)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert f"{path}:1: aperture diameter must be a positive number of mm, got -1" in result.stderr


# ---- found by the fuzz tests --------------------------------------------------------------------

def test_a_number_beyond_a_double_is_a_syntax_error(tmp_path):
    path = write(tmp_path, "s.pbrt", 'WorldBegin\nTranslate 1 1e999 0\n')
    assert error_of(parse_pbrt, path) == f"{path}:2: number 1e999 is too large for a double"


def test_transforms_that_overflow_or_make_the_camera_singular_are_errors(tmp_path):
    path = write(tmp_path, "s.pbrt", 'Scale 1e300 1 1\nScale 1e300 1 1\n')
    assert error_of(parse_pbrt, path).startswith(f"{path}:2: Scale: the transform overflows")
    path = write(tmp_path, "s.pbrt", 'Scale 0 1 1\nCamera "perspective"\n')
    assert error_of(parse_pbrt, path).startswith(f"{path}:2: Camera: the camera transform is singular")


def test_a_huge_rotation_axis_still_rotates(tmp_path):
    path = write(tmp_path, "s.pbrt", 'Rotate 90 0 0 1e300\nShape "sphere"\n')
    np.testing.assert_allclose(parse_pbrt(path).shapes[0].transform @ [1, 0, 0, 1], [0, 1, 0, 1], atol=1e-15)


def test_bool_parameters_must_be_true_or_false(tmp_path):
    path = write(tmp_path, "s.pbrt", 'AreaLightSource "diffuse" "bool twosided" "false"\nShape "disk"\n')
    assert parse_pbrt(path).shapes[0].area_light.params.items["twosided"].values == (False,)
    path = write(tmp_path, "s.pbrt", 'AreaLightSource "diffuse"\n"bool twosided" "yes"\n')
    assert error_of(parse_pbrt, path) == f'{path}:2: "bool twosided" expects "true" or "false", found "yes"'


def test_a_one_sided_light_given_as_bool_false_stays_one_sided(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nAreaLightSource "diffuse" "bool twosided" "false"\n'
                                     f'Shape "disk"\nWorldEnd\n')
    assert import_pbrt(path).scene.lights[0].two_sided is False


@pytest.mark.parametrize("shape,fragment", [
    ('Shape "sphere" "float radius" 0', "sphere radius 0 (only positive sizes"),
    ('Shape "disk" "float radius" -1', "disk radius -1"),
    ('Shape "cone" "float height" 0', "cone height 0"),
    ('Shape "cylinder" "float zmin" 1 "float zmax" 1', "cylinder with zmin = zmax"),
    ('Shape "sphere" "float radius" 1e300', "beyond the 1e+18"),
    ('Scale 1e10 1e10 1e10 Shape "sphere" "float radius" 1e10', "beyond the 1e+18"),
    ('AreaLightSource "diffuse" Shape "disk" "float radius" 0', "disk radius 0"),
    ('AreaLightSource "diffuse" Scale 1 0 1 Shape "disk"', "area light whose transform flattens it"),
    ('Shape "cone" "float radius" 1e300 "float height" 1', "beyond the 1e+18"),
    ('AreaLightSource "diffuse" Shape "disk" "float radius" 1e-300', "area light of area 0 (too small"),
])
def test_degenerate_or_out_of_range_shapes_are_skipped_with_a_warning(tmp_path, shape, fragment):
    path = write(tmp_path, "s.pbrt", f"{CAMERA}WorldBegin\n{shape}\nWorldEnd\n")
    imported = import_pbrt(path)
    assert imported.scene.instances == [] and imported.scene.lights == []
    assert len(imported.warnings) == 1 and imported.warnings[0].startswith(f"{path}:3: unsupported: ")
    assert fragment in imported.warnings[0]


def test_texture_parameters_that_name_nothing_or_themselves_are_errors(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nMaterial "matte" "texture Kd" []\nShape "sphere"\n')
    assert error_of(import_pbrt, path) == (f'{path}:3: "texture Kd" [] is an empty list: give it a value or leave '
                                           f"it out (pbrt-v4 refuses one)")
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nTexture "a" "color" "scale" "texture tex1" "b"\n'
                                     f'Texture "b" "color" "scale" "texture tex1" "a"\n'
                                     f'Material "matte" "texture Kd" "a"\nShape "sphere"\n')
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:") and 'texture "a" is made of itself ("a" -> "b" -> "a")' in message


def test_colours_given_as_strings_are_syntax_errors(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nMaterial "matte" "rgb Kd" "red"\nShape "sphere"\n')
    assert error_of(import_pbrt, path) == f'{path}:3: "Kd" expects numbers'


def test_object_redefinition_keeps_earlier_instances_on_the_old_definition(tmp_path):
    path = write(tmp_path, "s.pbrt", 'WorldBegin\nObjectBegin "o"\nShape "sphere"\nObjectEnd\nObjectInstance "o"\n'
                                     'ObjectBegin "o"\nShape "disk"\nObjectEnd\nObjectInstance "o"\n')
    scene = parse_pbrt(path)
    kinds = [[s.type for s in scene.objects[name]] for name, _, _ in scene.instances]
    assert kinds == [["sphere"], ["disk"]]
    assert any('ObjectBegin "o" redefines an object' in w for w in scene.warnings)


def test_huge_light_sample_counts_are_capped_with_a_warning(tmp_path):
    path = write(tmp_path, "s.pbrt", f'{CAMERA}WorldBegin\nAreaLightSource "diffuse" "integer nsamples" 1e9\n'
                                     f'Shape "disk"\nWorldEnd\n')
    imported = import_pbrt(path)
    assert imported.scene.light_samples == 1024
    assert "nsamples 1000000000 (at most 1024 are taken)" in imported.warnings[0]


def test_zmx_curvature_must_be_finite():
    text = "SURF 0\n DISZ INFINITY\nSURF 1\n CURV INFINITY\n DISZ 1\n DIAM 5\nSURF 2\n"
    assert error_of(parse_zmx, text, "x.zmx") == ("x.zmx:4: CURV INFINITY is not a finite curvature "
                                                  "(a flat surface is CURV 0)")


def test_a_missing_texture_file_is_named_once_at_the_texture_line(tmp_path):
    """The error was prefixed twice: the Material's line, then the Texture's."""
    world = ('WorldBegin\nTexture "t" "spectrum" "imagemap" "string filename" "nope.png"\n'
             'Material "matte" "texture Kd" "t"\nShape "sphere"\nWorldEnd\n')
    path = write(tmp_path, "t.pbrt", CAMERA + world)
    message = error_of(import_pbrt, path)
    assert message.count(".pbrt:") == 1 and 'texture file "nope.png" not found' in message, message


def test_a_number_too_large_for_a_double_is_shown_shortened(tmp_path):
    radius = "1" + "0" * 500
    path = write(tmp_path, "n.pbrt", CAMERA + f'WorldBegin\nShape "sphere" "float radius" {radius}\nWorldEnd\n')
    message = error_of(import_pbrt, path)
    assert "(501 characters) is too large for a double" in message and len(message) < 200, message


def test_a_second_world_begin_is_an_error_at_its_line(tmp_path):
    """Accepted silently before (pbrt-v3 and pbrt-v4 refuse a WorldBegin inside the world)."""
    path = write(tmp_path, "w.pbrt", CAMERA + 'WorldBegin\nShape "sphere"\nWorldBegin\nWorldEnd\n')
    message = error_of(import_pbrt, path)
    assert message.startswith(f"{path}:4: WorldBegin again (the world began at {path}:2)"), message
