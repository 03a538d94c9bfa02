"""pbrt dialects: which version a file is read as, and the texture orientation each version uses.

pbrt-v1/v2 look an image texture up with v = 0 at the file's first (top) row; pbrt-v3/v4 flip the
image on load (pbrt-v3 src/textures/imagemap.cpp), so v = 0 is its bottom row. A picture mapped
with uv (0, 0) at the lower left therefore appears upright in v3 and upside down in v2.
"""

import warnings

import numpy as np
import pytest

import realistic as rl
from realistic.core.image_files import write_exr
from realistic.scene.pbrt.dialect import choose_dialect
from realistic.scene.pbrt.importer import import_pbrt
from realistic.scene.pbrt.parser import parse_pbrt

RED, BLUE = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)


def scene_text(header: str = "", camera: str = 'Camera "perspective" "float fov" 60') -> str:
    return (f'{header}LookAt 0 0 -1  0 0 0  0 1 0\n{camera}\nWorldBegin\n'
            'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1]\nTranslate 0 0 -2\n'
            'Shape "disk" "float radius" 6\nAttributeEnd\n'
            'Texture "picture" "color" "imagemap" "string filename" "picture.exr"\n'
            'Material "matte" "texture Kd" "picture"\n'
            'Shape "trianglemesh" "point P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "integer indices" [0 1 2 0 2 3]\n'
            '    "float uv" [0 0  1 0  1 1  0 1]\nWorldEnd\n')


@pytest.fixture
def picture_scene(tmp_path):
    picture = np.zeros((8, 8, 3), np.float32)
    picture[:4] = RED  # the file's top rows
    picture[4:] = BLUE  # its bottom rows
    write_exr(tmp_path / "picture.exr", picture)

    def write(header: str = "", name: str = "s.pbrt"):
        path = tmp_path / name
        path.write_text(scene_text(header))
        return path

    return write


@pytest.mark.parametrize("dialect,bottom", [("v1", RED), ("v2", RED), ("v3", BLUE), ("v4", BLUE)])
def test_the_texture_lands_where_each_pbrt_puts_it(picture_scene, dialect, bottom):
    scene = rl.load_scene(picture_scene(), resolution=(16, 16), spp=4, pbrt_dialect=dialect)
    image = rl.render(scene, backend="numpy")
    lower, upper = image[12:, 4:12].mean(axis=(0, 1)), image[:4, 4:12].mean(axis=(0, 1))
    top = BLUE if bottom == RED else RED
    assert np.argmax(lower) == np.argmax(bottom) and np.argmax(upper) == np.argmax(top)
    assert lower.max() > 0 and upper.max() > 0


@pytest.mark.parametrize("header,expected,why", [
    ("", "v3", "no version-specific"),
    ('SurfaceIntegrator "directlighting"\n', "v2", "SurfaceIntegrator"),
    ('Renderer "sampler"\n', "v2", "Renderer"),
    ('Integrator "path"\n', "v3", "Integrator"),
    ('ColorSpace "srgb"\n', "v4", "ColorSpace"),
    ('Option "bool wavefront" true\n', "v4", "Option"),
    ('Film "rgb" "integer xresolution" 8\n', "v4", 'Film "rgb"'),
])
def test_auto_reads_the_files_signals(picture_scene, header, expected, why):
    dialect = choose_dialect(parse_pbrt(picture_scene(header)))
    assert dialect.name == expected and why in dialect.reason


def test_the_cameras_parameters_are_signals_and_mixed_signals_warn(tmp_path):
    homework = tmp_path / "h.pbrt"
    homework.write_text('Camera "realistic" "string specfile" "dgauss.50mm.dat" "float filmdistance" 36.77\n')
    assert choose_dialect(parse_pbrt(homework)).name == "v2"
    v3 = tmp_path / "v3.pbrt"
    v3.write_text('Camera "realistic" "string lensfile" "dgauss.50mm.dat" "float aperturediameter" 10\n')
    assert choose_dialect(parse_pbrt(v3)).name == "v3"
    mixed = tmp_path / "m.pbrt"
    mixed.write_text('SurfaceIntegrator "directlighting"\nIntegrator "path"\n')
    parsed = parse_pbrt(mixed)
    assert choose_dialect(parsed).name == "v3"
    assert any("mixes pbrt versions" in w and "v2: SurfaceIntegrator" in w for w in parsed.warnings)


def test_the_choice_and_its_reason_reach_the_exr_header(picture_scene, tmp_path, capsys):
    out = tmp_path / "o.exr"
    from realistic.cli import main

    assert main(["render", str(picture_scene('Renderer "sampler"\n')), "--res", "8x8", "--spp", "1",
                        "--backend", "numpy", "--out", str(out)]) == 0
    assert "read as pbrt-v2 (Renderer at" in capsys.readouterr().err
    assert rl.read_exr(out)[1]["pbrtDialect"].startswith("pbrt-v2 (Renderer at")


def test_pbrt_dialect_is_for_pbrt_scenes():
    with pytest.raises(rl.UserError, match="--pbrt-dialect applies to pbrt scenes"):
        rl.RenderOptions(pbrt_dialect="v2")


def test_a_scene_renders_without_dispersion_unless_asked_and_says_which_lens_stands_in(tmp_path):
    path = tmp_path / "lensed.pbrt"
    path.write_text('LookAt 0 0 -1  0 0 0  0 1 0\nCamera "realistic" "string lensfile" "dgauss.50mm.dat" '
                    '"float aperturediameter" 10 "float focusdistance" 2\nWorldBegin\nShape "sphere"\nWorldEnd\n')
    assert rl.load_lens("dgauss").has_dispersion  # the bundled stand-in carries Abbe numbers
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = rl.load_scene(path, resolution=(8, 8), spp=1)
        asked = rl.load_scene(path, resolution=(8, 8), spp=1, dispersion=True)
    assert not scene.camera.spectral and asked.camera.spectral  # pbrt would not disperse unless asked
    assert any('the bundled "dgauss" prescription stands in' in str(w.message) for w in caught)


def _camera_scene(tmp_path, camera: str, header: str = "", film: str = "") -> str:
    path = tmp_path / "camera.pbrt"
    path.write_text(f'{header}Film "image" "integer xresolution" 30 "integer yresolution" 20 {film}\n'
                    f'{camera}\nWorldBegin\nShape "sphere"\nWorldEnd\n')
    return str(path)


CLASSIC = 'Camera "realistic" "string specfile" "dgauss.50mm.dat" "float filmdistance" 36.77 "float filmdiag" 70'
PBRT3 = 'Camera "realistic" "string lensfile" "dgauss.50mm.dat" "float focusdistance" 3'


def test_the_classic_camera_is_in_mm_from_the_front_vertex_with_its_own_film_diagonal(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the bundled lens stands in for the file
        camera = rl.load_scene(_camera_scene(tmp_path, CLASSIC, film='"float diagonal" 50')).camera
    assert camera.origin == "front_vertex" and camera.mm_per_unit == pytest.approx(1.0)
    assert camera.film_diagonal_mm == 70.0 and camera.film_distance_mm == 36.77


@pytest.mark.parametrize("header", ["", 'ColorSpace "srgb"\n'])
def test_pbrt3_and_pbrt4_cameras_are_in_metres_from_the_film_with_the_films_diagonal(tmp_path, header):
    """pbrt-v3 src/core/film.cpp: Film "diagonal" (mm, default 35) sizes the film of every camera."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sized = rl.load_scene(_camera_scene(tmp_path, PBRT3, header, film='"float diagonal" 50')).camera
        default = rl.load_scene(_camera_scene(tmp_path, PBRT3, header)).camera
    assert sized.origin == "film" and sized.mm_per_unit == pytest.approx(1000.0)
    assert sized.film_diagonal_mm == 50.0 and default.film_diagonal_mm == 35.0


def test_a_parameter_of_another_versions_camera_is_reported_as_ignored(tmp_path):
    path = _camera_scene(tmp_path, PBRT3 + ' "float filmdiag" 70')
    imported = import_pbrt(path)
    assert imported.scene.camera.film_diagonal_mm == 35.0
    assert any('"filmdiag" is not a realistic-camera parameter in pbrt-v3' in w for w in imported.warnings)


def test_a_camera_read_in_the_wrong_dialect_names_what_it_lacks(tmp_path):
    path = _camera_scene(tmp_path, CLASSIC)
    with pytest.raises(rl.UserError) as error:
        rl.load_scene(path, pbrt_dialect="v3")
    message = str(error.value)
    assert message.startswith(f"{path}:2: ") and '"string lensfile"' in message and "--pbrt-dialect" in message


def test_the_python_api_takes_search_paths_as_strings(picture_scene, tmp_path):
    elsewhere = tmp_path / "scenes"
    elsewhere.mkdir()
    path = picture_scene(name="scenes/s.pbrt")  # the texture stays in tmp_path, found only by the search path
    with pytest.raises(rl.UserError, match="picture.exr"):
        rl.load_scene(path, resolution=(8, 8), spp=1)
    by_str = rl.load_scene(str(path), resolution=(8, 8), spp=1, search_paths=[str(tmp_path)])
    by_path = rl.load_scene(path, resolution=(8, 8), spp=1, search_paths=[tmp_path])
    assert np.array_equal(rl.render(by_str, backend="numpy"), rl.render(by_path, backend="numpy"))
