"""Parameters whose names differ between pbrt versions are read under each version's names (the
table in ``scene/pbrt/dialect.ParameterNames``, with its sources), and the version-only materials and
parameters choose the dialect (issue 34: the v4 ``scale`` texture was read only as ``tex1``/``tex2``
and pbrt-v3's area light ``samples`` was ignored, both silently)."""

import pytest

from realistic.scene.pbrt.importer import import_pbrt

CAMERA = 'Camera "perspective" "float fov" 40\n'


def _import(tmp_path, world: str, dialect: str = "auto"):
    path = tmp_path / "scene.pbrt"
    path.write_text(CAMERA + "WorldBegin\n" + world + "WorldEnd\n")
    return import_pbrt(path, dialect=dialect)


def _albedo(imported) -> tuple[float, ...]:
    return tuple(round(c, 6) for c in imported.scene.instances[-1].material.diffuse)


@pytest.mark.parametrize("version,factors,material", [
    ("v4", '"texture tex" "c" "float scale" 0.5', 'Material "diffuse" "texture reflectance" "s"'),
    ("v3", '"texture tex1" "c" "rgb tex2" [0.5 0.5 0.5]', 'Material "matte" "texture Kd" "s"')])
def test_a_scale_texture_multiplies_its_versions_two_factors(tmp_path, version, factors, material):
    world = ('Texture "c" "spectrum" "constant" "rgb value" [0.2 0.4 0.6]\n'
             f'Texture "s" "spectrum" "scale" {factors}\n{material}\nShape "sphere"\n')
    imported = _import(tmp_path, world)
    assert imported.dialect.name == version and _albedo(imported) == (0.1, 0.2, 0.3)
    assert not [w for w in imported.warnings if "not used here" in w]


def test_another_versions_scale_names_are_reported_not_read(tmp_path):
    world = ('Texture "s" "spectrum" "scale" "rgb tex" [0.2 0.4 0.6] "float scale" 0.5\n'
             'Material "matte" "texture Kd" "s"\nShape "sphere"\n')
    imported = _import(tmp_path, world, dialect="v3")
    assert _albedo(imported) == (1.0, 1.0, 1.0)  # pbrt-v3 reads tex1 and tex2, both 1 here
    assert sum('parameter not used here' in w for w in imported.warnings) == 2


@pytest.mark.parametrize("dialect,parameter,light_samples,unused", [
    ("v3", "samples", 4, False), ("v3", "nsamples", 4, False), ("v2", "nsamples", 4, False),
    ("v2", "samples", 1, True), ("v4", "nsamples", 1, True)])
def test_area_light_samples_under_each_versions_name(tmp_path, dialect, parameter, light_samples, unused):
    world = (f'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1] "integer {parameter}" 4\n'
             'Shape "disk"\nAttributeEnd\n')
    imported = _import(tmp_path, world, dialect)
    assert imported.scene.light_samples == light_samples
    assert any(f'"{parameter}": parameter not used here' in w for w in imported.warnings) == unused


@pytest.mark.parametrize("world,version", [
    ('Material "measured" "string filename" "acryl_blue.brdf"\n', "v2"),
    ('Material "measured" "string filename" "paint.bsdf"\n', "v4"),
    ('Material "shinymetal"\n', "v2"),
    ('Material "disney"\n', "v3"),
    ('Material "coateddiffuse"\n', "v4"),
    ('MakeNamedMaterial "m" "string type" "conductor"\n', "v4"),
    ('AttributeBegin\nAreaLightSource "diffuse" "integer samples" 4\nShape "disk"\nAttributeEnd\n', "v3"),
])
def test_version_only_materials_and_parameters_choose_the_dialect(tmp_path, world, version):
    """The seed scene (pbrt-v2's dof-dragons.pbrt) names no v2-only directive, but its measured
    materials are pbrt-v2's: it was read as pbrt-v3 (path integrator, v3 texture orientation)."""
    assert _import(tmp_path, world).dialect.name == version
