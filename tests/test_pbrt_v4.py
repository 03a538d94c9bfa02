"""pbrt-v4 syntax on small scenes written here: each directive lands as pbrt-v4's parser.cpp and
scene.cpp define it (Attribute defaults, Import scoping, Option, ColorSpace, media, ActiveTransform,
unquoted bools, Film types, bilinearmesh, plymesh displacement), and what is not honoured is said
once with the file and line."""

import numpy as np
import pytest

from realistic.errors import UserError
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.lexer import PbrtSyntaxError
from realistic.scene.pbrt.parser import parse_pbrt

CAMERA = 'LookAt 0 0 -5  0 0 0  0 1 0\nCamera "perspective" "float fov" 40\n'


def write(folder, text, name="s.pbrt"):
    path = folder / name
    path.write_text(text)
    return path


def world(folder, body, header="", name="s.pbrt"):
    """A v4 scene (no WorldEnd, as pbrt-v4 writes them) around ``body``."""
    return write(folder, f'{header}Film "rgb" "integer xresolution" 8 "integer yresolution" 8\n{CAMERA}'
                         f"WorldBegin\n{body}", name)


def warnings_about(imported, text):
    return [w for w in imported.warnings if text in w]


def mesh_of(scene, name):
    (mesh,) = [m for m in scene.meshes if m.name == name]
    return mesh


def test_a_v4_file_without_worldend_reads_without_the_cut_short_warning(tmp_path):
    imported = import_pbrt(world(tmp_path, 'Shape "sphere"\n'))
    assert imported.dialect.name == "v4"
    assert not warnings_about(imported, "WorldEnd")


def test_attribute_shape_sets_defaults_that_a_shapes_own_parameter_overrides(tmp_path):
    path = world(tmp_path, 'AttributeBegin\nAttribute "shape" "float radius" 0.25\nShape "sphere"\n'
                           'Shape "sphere" "float radius" 2\nAttributeEnd\nShape "sphere"\n')
    parsed = parse_pbrt(path)
    radii = [shape.params.get_float("radius", 1.0) for shape in parsed.shapes]
    assert radii == [0.25, 2.0, 1.0]  # the attribute ends with its block; pbrt's own default after it


def test_attribute_light_material_and_texture_defaults_reach_their_directives(tmp_path):
    path = world(tmp_path, 'Attribute "light" "rgb L" [3 2 1]\nAttribute "material" "rgb reflectance" [.1 .2 .3]\n'
                           'Attribute "texture" "float uscale" 4\nAreaLightSource "diffuse"\n'
                           'Texture "t" "spectrum" "checkerboard"\nMaterial "diffuse"\nShape "disk"\n'
                           'LightSource "point"\n')
    parsed = parse_pbrt(path)
    assert parsed.shapes[0].area_light.params.get_floats("L") == [3, 2, 1]
    assert parsed.lights[0].params.get_floats("L") == [3, 2, 1]
    assert parsed.shapes[0].material.params.get_floats("reflectance") == [0.1, 0.2, 0.3]
    assert parsed.textures["t"].params.get_float("uscale") == 4
    imported = import_pbrt(path)
    assert imported.scene.lights[0].radiance == pytest.approx((3, 2, 1))


def test_a_later_attribute_of_the_same_name_replaces_the_earlier_one(tmp_path):
    parsed = parse_pbrt(world(tmp_path, 'Attribute "shape" "float radius" 3\nAttribute "shape" "float radius" 5\n'
                                        'Shape "sphere"\n'))
    assert parsed.shapes[0].params.get_float("radius") == 5


def test_an_unknown_attribute_target_is_an_error_at_its_line(tmp_path):
    path = world(tmp_path, 'Attribute "camera" "float fov" 3\n')
    with pytest.raises(PbrtSyntaxError, match=r"s\.pbrt:5: .*unknown target"):
        parse_pbrt(path)


def test_import_keeps_shapes_but_gives_back_the_graphics_state(tmp_path):
    write(tmp_path, 'Material "conductor"\nAttribute "shape" "float radius" 7\nTranslate 5 0 0\n'
                    'Shape "sphere"\nMakeNamedMaterial "gold" "string type" "conductor"\n', "part.pbrt")
    path = world(tmp_path, 'Material "diffuse"\nImport "part.pbrt"\nShape "sphere"\nNamedMaterial "gold"\n'
                           'Shape "disk"\n')
    parsed = parse_pbrt(path)
    imported_sphere, after, named = parsed.shapes
    assert imported_sphere.material.type == "conductor" and imported_sphere.transform[0, 3] == 5
    assert after.material.type == "diffuse" and after.transform[0, 3] == 0
    assert not after.params.has("radius")
    assert named.material.type == "conductor"  # named materials made in the import stay


def test_include_keeps_the_included_files_graphics_state(tmp_path):
    write(tmp_path, 'Material "conductor"\n', "part.pbrt")
    parsed = parse_pbrt(world(tmp_path, 'Include "part.pbrt"\nShape "sphere"\n'))
    assert parsed.shapes[0].material.type == "conductor"


def test_an_import_that_leaves_a_block_open_is_closed_at_its_end_with_a_warning(tmp_path):
    write(tmp_path, 'AttributeBegin\nMaterial "conductor"\n', "part.pbrt")
    parsed = parse_pbrt(world(tmp_path, 'Import "part.pbrt"\nShape "sphere"\n'))
    assert parsed.shapes[0].material.type == "matte"
    assert any("part.pbrt:1: unsupported: AttributeBegin without a matching AttributeEnd in the imported file"
               in w for w in parsed.warnings)


def test_include_names_resolve_against_the_first_files_folder_too(tmp_path):
    """pbrt-v3/v4 resolve relative names against the first scene file's folder."""
    (tmp_path / "sub").mkdir()
    write(tmp_path, 'Shape "sphere" "float radius" 3\n', "geometry.pbrt")
    write(tmp_path / "sub", 'Include "geometry.pbrt"\n', "part.pbrt")
    parsed = parse_pbrt(world(tmp_path, 'Include "sub/part.pbrt"\n'))
    assert parsed.shapes[0].params.get_float("radius") == 3


@pytest.mark.parametrize("option", ['"bool disablepixeljitter" true', '"string rendercoordsys" "world"',
                                    '"integer seed" 7', '"bool wavefront" false'])
def test_option_is_read_whole_and_reported(tmp_path, option):
    path = world(tmp_path, 'Shape "sphere"\n', header=f"Option {option}\n")
    imported = import_pbrt(path)
    assert warnings_about(imported, f"s.pbrt:1: unsupported: Option {option.split(' ', 1)[0]}")
    assert len(imported.scene.meshes) == 1  # the value did not swallow or break what follows


def test_colorspace_srgb_is_silent_and_another_is_reported(tmp_path):
    assert not warnings_about(import_pbrt(world(tmp_path, "", header='ColorSpace "srgb"\n')), "ColorSpace")
    other = import_pbrt(world(tmp_path, "", header='ColorSpace "aces2065-1"\n'))
    assert warnings_about(other, 's.pbrt:1: unsupported: ColorSpace "aces2065-1"')


def test_media_are_ignored_with_their_file_and_line(tmp_path):
    path = world(tmp_path, 'MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [1 1 1]\n'
                           'MediumInterface "fog" ""\nMediumInterface "fog"\nShape "sphere"\n')
    imported = import_pbrt(path)
    assert warnings_about(imported, 's.pbrt:5: unsupported: MakeNamedMedium "fog"')
    assert warnings_about(imported, 's.pbrt:6: unsupported: MediumInterface "fog" ""')
    assert warnings_about(imported, 's.pbrt:7: unsupported: MediumInterface "fog" (')
    assert len(imported.scene.meshes) == 1
    assert imported.dialect.name == "v4" and not warnings_about(imported, "mixes pbrt versions")


def test_active_transform_endtime_leaves_shapes_at_the_shutter_open_transform(tmp_path):
    path = world(tmp_path, 'Translate 1 0 0\nActiveTransform EndTime\nTranslate 10 0 0\nActiveTransform All\n'
                           'Translate 0 2 0\nShape "sphere"\n')
    parsed = parse_pbrt(path)
    np.testing.assert_allclose(parsed.shapes[0].transform[:3, 3], [1, 2, 0])
    assert any("s.pbrt:6: unsupported: ActiveTransform" in w for w in parsed.warnings)


def test_active_transform_is_part_of_the_attribute_state(tmp_path):
    parsed = parse_pbrt(world(tmp_path, 'AttributeBegin\nActiveTransform EndTime\nAttributeEnd\nTranslate 3 0 0\n'
                                        'Shape "sphere"\n'))
    np.testing.assert_allclose(parsed.shapes[0].transform[:3, 3], [3, 0, 0])


def test_a_bad_active_transform_and_transform_times(tmp_path):
    with pytest.raises(PbrtSyntaxError, match=r"s\.pbrt:5: expected All, StartTime or EndTime"):
        parse_pbrt(world(tmp_path, "ActiveTransform Sometimes\n"))
    parsed = parse_pbrt(world(tmp_path, "TransformTimes 0 1\nShape \"sphere\"\n", name="t.pbrt"))
    assert len(parsed.shapes) == 1 and any("t.pbrt:5: unsupported: TransformTimes" in w for w in parsed.warnings)


def test_bool_values_may_be_unquoted_as_pbrt_v4_writes_them(tmp_path):
    parsed = parse_pbrt(world(tmp_path, 'AreaLightSource "diffuse" "bool twosided" true "rgb L" [1 1 1]\n'
                                        'Shape "disk" "bool flag" [ false true ]\n'))
    assert parsed.shapes[0].area_light.params.items["twosided"].values == (True,)
    assert parsed.shapes[0].params.items["flag"].values == (False, True)


def test_an_unquoted_bool_in_a_numeric_parameter_is_an_error(tmp_path):
    with pytest.raises(UserError, match=r"s\.pbrt:5: .*expects numbers"):
        import_pbrt(world(tmp_path, 'Shape "sphere" "float radius" true\n'))


@pytest.mark.parametrize("film,said", [("rgb", None), ("image", None), ("gbuffer", "its RGB image is rendered"),
                                       ("spectral", "its RGB image is rendered"), ("foo", "rendered as an RGB")])
def test_film_types(tmp_path, film, said):
    path = write(tmp_path, f'Film "{film}" "integer xresolution" 6 "integer yresolution" 4\n{CAMERA}WorldBegin\n')
    imported = import_pbrt(path)
    camera = imported.scene.camera
    assert (camera.width, camera.height) == (6, 4)
    found = warnings_about(imported, f's.pbrt:1: unsupported: Film "{film}"')
    assert bool(found) == (said is not None) and (said is None or said in found[0])


def test_v4_sensor_settings_other_than_neutral_are_reported(tmp_path):
    neutral = write(tmp_path, f'Film "rgb" "float iso" 100 "string sensor" "cie1931"\n{CAMERA}WorldBegin\n')
    assert not warnings_about(import_pbrt(neutral), "Film")
    bright = write(tmp_path, f'Film "rgb" "float iso" 400 "float whitebalance" 5000\n{CAMERA}WorldBegin\n', "b.pbrt")
    said = warnings_about(import_pbrt(bright), "b.pbrt:1: unsupported: Film")
    assert any('"iso" 400' in w for w in said) and any('"whitebalance" 5000' in w for w in said)


def test_bilinearmesh_becomes_two_triangles_per_patch_facing_as_pbrt_does(tmp_path):
    # one patch: p00, p10, p01, p11 (the default indices 0 1 2 3), a unit square in z = 0
    path = world(tmp_path, 'Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 0] '
                           '"point2 uv" [0 0  1 0  0 1  1 1]\n')
    imported = import_pbrt(path)
    mesh = mesh_of(imported.scene, "bilinearmesh")
    assert len(mesh.faces) == 2
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    # pbrt-v4's patch normal is dp/du x dp/dv = (p10 - p00) x (p01 - p00) = +z
    assert np.all(normals[:, 2] > 0)
    area = 0.5 * np.linalg.norm(normals, axis=1).sum()
    assert area == pytest.approx(1.0)  # the two triangles tile the patch
    np.testing.assert_allclose(mesh.uv, [[0, 0], [1, 0], [0, 1], [1, 1]])
    assert warnings_about(imported, "s.pbrt:5: unsupported: bilinearmesh (each bilinear patch")


def test_bilinearmesh_with_indices_and_normals(tmp_path):
    # a 2 x 1 strip of two patches sharing an edge
    path = world(tmp_path, 'Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  2 0 0  0 0 1  1 0 1  2 0 1] '
                           '"integer indices" [0 1 3 4  1 2 4 5] "normal N" [0 2 0 0 2 0 0 2 0 0 2 0 0 2 0 0 2 0]\n')
    mesh = mesh_of(import_pbrt(path).scene, "bilinearmesh")
    assert len(mesh.faces) == 4
    np.testing.assert_allclose(mesh.normals, np.tile([0, 1, 0], (6, 1)))
    tri = mesh.vertices[mesh.faces]
    assert 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum() == \
        pytest.approx(2.0)


@pytest.mark.parametrize("params,fragment", [
    ('"point3 P" [0 0 0 1 0 0 0 1 0]', '"integer indices" needs 4 per patch, got 0'),
    ('"point3 P" [0 0 0 1 0 0 0 1 0 1 1 0] "integer indices" [0 1 2]', "needs 4 per patch, got 3"),
    ('"point3 P" [0 0 0 1 0 0 0 1 0 1 1 0] "integer indices" [0 1 2 4]', "index 4 is not a point number"),
    ('"point3 P" [0 0 0 1 0 0 0 1]', '"point P" needs 3 values per point, got 8'),
])
def test_bad_bilinearmesh_is_an_error_naming_its_line(tmp_path, params, fragment):
    with pytest.raises(UserError, match=r"s\.pbrt:5: bilinearmesh ") as err:
        import_pbrt(world(tmp_path, f'Shape "bilinearmesh" {params}\n'))
    assert fragment in str(err.value) and "\n" not in str(err.value)


def test_plymesh_displacement_is_reported_and_the_mesh_rendered_as_is(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    trimesh.creation.box().export(tmp_path / "box.ply")
    path = world(tmp_path, 'Texture "bumps" "float" "constant" "float value" 0.1\n'
                           'Shape "plymesh" "string filename" "box.ply" "texture displacement" "bumps"\n')
    imported = import_pbrt(path)
    assert len(mesh_of(imported.scene, "box.ply").faces) == 12
    assert warnings_about(imported, 's.pbrt:6: unsupported: plymesh "displacement"')


def test_nested_imports_ending_together_give_back_the_outermost_state(tmp_path):
    write(tmp_path, 'Material "dielectric"\nShape "sphere"\n', "inner.pbrt")
    write(tmp_path, 'Material "conductor"\nImport "inner.pbrt"\n', "outer.pbrt")
    parsed = parse_pbrt(world(tmp_path, 'Material "diffuse"\nImport "outer.pbrt"\nShape "disk"\n'))
    assert [(s.type, s.material.type) for s in parsed.shapes] == [("sphere", "dielectric"), ("disk", "diffuse")]


def test_loopsubdiv_is_subdivided_to_its_levels_without_a_warning(tmp_path):
    path = world(tmp_path, 'Shape "loopsubdiv" "integer levels" 3 "point3 P" [0 0 0 1 0 0 0 1 0 0 0 1] '
                           '"integer indices" [0 1 2 0 2 3 0 3 1 1 3 2]\n')
    imported = import_pbrt(path)
    mesh = mesh_of(imported.scene, "loopsubdiv")
    assert len(mesh.faces) == 4 * 4 ** 3 and mesh.normals is not None
    assert not imported.warnings


def test_strings_decode_pbrts_backslash_escapes(tmp_path):
    """pbrt-v2 (pbrtlex.ll) and pbrt-v3/v4 (parser.cpp, decodeEscaped) decode \\" \\\\ \\n \\t ... in strings."""
    (tmp_path / 'a "quoted" name.pbrt').write_text('Shape "sphere" "float radius" 4\n')
    body = 'Include "a \\"quoted\\" name.pbrt"\nShape "disk" "string label" "x\\ty\\\\z"\n'
    parsed = parse_pbrt(world(tmp_path, body))
    assert parsed.shapes[0].params.get_float("radius") == 4
    assert parsed.shapes[1].params.get_string("label") == "x\ty\\z"


def test_gzipped_scene_files_are_read_as_pbrt_v4_reads_them(tmp_path):
    import gzip

    (tmp_path / "geometry.pbrt.gz").write_bytes(gzip.compress(b'Shape "sphere" "float radius" 6\n'))
    (tmp_path / "broken.pbrt.gz").write_bytes(gzip.compress(b'Shape "sphere"\n')[:-6])
    parsed = parse_pbrt(world(tmp_path, 'Import "geometry.pbrt.gz"\n'))
    assert parsed.shapes[0].params.get_float("radius") == 6
    with pytest.raises(UserError, match=r"broken\.pbrt\.gz: cannot read scene file") as err:
        parse_pbrt(world(tmp_path, 'Include "broken.pbrt.gz"\n', name="b.pbrt"))
    assert "\n" not in str(err.value)


def test_active_transform_starttime_moves_the_shutter_open_pose_we_render(tmp_path):
    parsed = parse_pbrt(world(tmp_path, 'Translate 1 0 0\nActiveTransform StartTime\nTranslate 0 4 0\n'
                                        'ActiveTransform All\nTranslate 0 0 2\nShape "sphere"\n'))
    np.testing.assert_allclose(parsed.shapes[0].transform[:3, 3], [1, 4, 2])


def test_a_v4_scene_header_with_two_cameras_bracketed_strings_and_iso(tmp_path):
    """As pbrt-v4-scenes write them: the last Camera wins, a lens file in a subfolder (the bundled
    prescription of that name stands in here), single values in brackets, the film's ISO reported."""
    path = write(tmp_path, 'Scale -1 1 1\nLookAt 0 0 0  0 1 0  0 0 1\n'
                           'Camera "perspective" "float fov" [ 60 ]\n'
                           'Camera "realistic" "string lensfile" [ "lenses/wide.22mm.dat" ] '
                           '"float focusdistance" [ 4 ] "float aperturediameter" [ 8.7 ]\n'
                           'Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 11 ] "float iso" [ 1300 ]\n'
                           'Sampler "halton" "integer pixelsamples" [ 4 ]\nWorldBegin\nShape "sphere"\n')
    imported = import_pbrt(path)
    camera = imported.scene.camera
    assert camera.lens.name == "wide" and camera.lens.stop_diameter_mm == 8.7
    assert (camera.width, camera.height, camera.spp) == (16, 11, 4)
    assert warnings_about(imported, 's.pbrt:5: unsupported: Film "iso" 1300')


def test_named_spectra_and_blackbodies_import_and_an_unknown_metal_is_reported(tmp_path):
    path = world(tmp_path, 'AttributeBegin\nAreaLightSource "diffuse" "spectrum L" "stdillum-D65"\nShape "disk"\n'
                           'AttributeEnd\nAttributeBegin\nAreaLightSource "diffuse" "blackbody L" [ 5500 ]\n'
                           'Translate 0 0 3\nShape "disk"\nAttributeEnd\n'
                           'Material "conductor" "spectrum eta" "metal-CuZn-eta" "spectrum k" "metal-CuZn-k"\n'
                           'Shape "sphere"\n')
    imported = import_pbrt(path)
    assert len(imported.scene.lights) == 2 and len(imported.scene.meshes) == 1
    # the lights' spectra are converted as pbrt-v4 records them (tests/test_pbrt_spectra.py); brass is not known
    assert not warnings_about(imported, "s.pbrt:6:") and warnings_about(imported, "s.pbrt:14: unsupported:")


@pytest.mark.parametrize("dialect,material", [("v3", "conductor"), ("v4", "diffuse")])
def test_transform_blocks_keep_only_the_transform_before_v4_and_everything_in_v4(tmp_path, dialect, material):
    path = world(tmp_path, 'Material "diffuse"\nTransformBegin\nMaterial "conductor"\nTranslate 1 0 0\n'
                           'TransformEnd\nShape "sphere"\n')
    imported = import_pbrt(path, dialect=dialect)
    parsed = parse_pbrt(path, transform_blocks_keep_all=dialect == "v4")
    assert parsed.shapes[0].material.type == material and parsed.shapes[0].transform[0, 3] == 0
    said = warnings_about(imported, "s.pbrt:6: unsupported: TransformBegin/End (deprecated in pbrt-v4")
    assert bool(said) == (dialect == "v4")


@pytest.mark.parametrize("body,line", [('Shape "sphere" "float radius" []\n', 5),
                                       ('Attribute "shape" "float radius" [ ]\nShape "sphere"\n', 5),
                                       ('Material "conductor" "spectrum eta" []\nShape "sphere"\n', 5)])
def test_an_empty_parameter_list_is_an_error_at_its_line_as_in_pbrt_v4(tmp_path, body, line):
    """pbrt-v4 refuses an empty list where it reads a value (src/pbrt/paramdict.cpp, lookupSingle:
    "No values provided for parameter"); it used to read as if absent (a unit sphere)."""
    path = world(tmp_path, body)
    with pytest.raises(UserError) as error:
        import_pbrt(path)
    assert str(error.value).startswith(f"{path}:{line}: ") and "[] is an empty list" in str(error.value)
    assert "\n" not in str(error.value)
