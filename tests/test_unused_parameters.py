"""Every parameter of a directive that is built but that nothing reads is reported at its file and
line (pbrt-v4 refuses such a file: ``ParameterDictionary::ReportUnused`` in src/pbrt/paramdict.cpp),
once per name; parameters of what is never built (a material no shape uses) are not judged."""

from realistic.scene.pbrt.importer import import_pbrt

CAMERA = 'Camera "perspective" "float fov" 40\n'


def _warnings(tmp_path, world: str, head: str = "") -> list[str]:
    path = tmp_path / "scene.pbrt"
    path.write_text(head + CAMERA + "WorldBegin\n" + world + "WorldEnd\n")
    return [w for w in import_pbrt(path).warnings if "not used here" in w]


def test_a_misspelt_parameter_is_reported_once_at_its_first_line(tmp_path):
    world = 'Shape "sphere" "float radiuss" 2\nShape "sphere" "float radiuss" 3\nShape "sphere" "float radius" 1\n'
    (warning,) = _warnings(tmp_path, world)
    assert warning.startswith(f"{tmp_path / 'scene.pbrt'}:3: ") and '"radiuss"' in warning


def test_parameters_every_directive_reads_are_not_reported(tmp_path):
    world = ('Material "matte" "rgb Kd" [0.5 0.5 0.5] "float sigma" 10\n'
             'LightSource "point" "rgb I" [1 1 1] "point from" [0 2 0]\n'
             'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1]\n'
             'Shape "disk" "float radius" 0.5\nAttributeEnd\n'
             'Shape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]\n')
    head = 'Film "image" "integer xresolution" 8 "integer yresolution" 8\nSampler "random" "integer pixelsamples" 4\n'
    assert _warnings(tmp_path, world, head) == []


def test_a_material_no_shape_uses_is_not_judged(tmp_path):
    world = 'MakeNamedMaterial "unused" "string type" "matte" "float nonsense" 1\nShape "sphere"\n'
    assert _warnings(tmp_path, world) == []


def test_attribute_defaults_are_not_reported_where_a_shape_does_not_read_them(tmp_path):
    world = ('AttributeBegin\nAttribute "shape" "float radius" 2\n'
             'Shape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]\nAttributeEnd\n')
    assert _warnings(tmp_path, world) == []


def test_a_camera_parameter_of_no_camera_is_reported(tmp_path):
    path = tmp_path / "c.pbrt"
    path.write_text('Camera "perspective" "float fvo" 30\nWorldBegin\nWorldEnd\n')
    assert any('"fvo": parameter not used here' in w for w in import_pbrt(path).warnings)
