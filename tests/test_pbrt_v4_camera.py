"""pbrt-v4's realistic camera: each parameter lands where pbrt-v4 (src/pbrt/cameras.cpp) puts it.

- ``focusdistance``: the film sits where the lens images that plane (checked with real paraxial rays
  traced from the film centre, not with the thick-lens code that placed it);
- ``aperturediameter``: the stop's diameter, clamped to the lens file's stop as pbrt does;
- ``aperture``: pbrt-v4's built-in shapes with their sizes and their orientation after pbrt's FlipY
  (areas against the closed forms of the square, the regular pentagon and the star), or an image
  whose top row lies at +y.
"""

import math

import numpy as np
import pytest

from conftest import flat_field_brightness
from realistic.core.image_files import write_exr
from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.tracer import trace_from_film
from realistic.scene.pbrt.importer import import_pbrt

FILE_STOP_MM = 17.1  # dgauss.50mm.dat's stop row


def scene(tmp_path, camera_params, header="", name="s.pbrt"):
    path = tmp_path / name
    path.write_text(f'{header}Film "rgb" "integer xresolution" 8 "integer yresolution" 8\n'
                    f'Camera "realistic" "string lensfile" "dgauss.50mm.dat" {camera_params}\nWorldBegin\n')
    return path


def camera_of(tmp_path, camera_params, **kwargs):
    imported = import_pbrt(scene(tmp_path, camera_params), **kwargs)
    return imported.scene.camera, imported.warnings


@pytest.mark.parametrize("focus_m", [0.5, 2.0, 10.0])
def test_focusdistance_puts_the_film_where_paraxial_rays_from_its_centre_meet_that_plane(tmp_path, focus_m):
    camera, _ = camera_of(tmp_path, f'"float aperturediameter" 4 "float focusdistance" {focus_m}')
    lens, film = camera.lens, camera.film_distance_mm
    heights = np.array([0.02, 0.04])  # mm on the rear-vertex plane: paraxial rays
    origins = np.zeros((2, 3))
    targets = np.column_stack([heights, np.zeros(2), np.full(2, film)])
    out = trace_from_film(lens, film, origins, targets - origins)
    assert out.passed.all()
    axis_z = out.origin[:, 2] - out.origin[:, 0] * out.direction[:, 2] / out.direction[:, 0]
    np.testing.assert_allclose(axis_z, focus_m * 1000, rtol=2e-3)


def test_the_default_focus_is_ten_metres_and_the_default_stop_one_millimetre(tmp_path):
    camera, _ = camera_of(tmp_path, "")
    assert camera.lens.stop_diameter_mm == 1.0
    far, _ = camera_of(tmp_path, '"float focusdistance" 10')
    assert camera.film_distance_mm == far.film_distance_mm


def test_aperturediameter_is_the_stops_diameter(tmp_path):
    camera, warnings = camera_of(tmp_path, '"float aperturediameter" 6.5')
    assert camera.lens.stop_diameter_mm == 6.5
    assert camera.lens.stop_shape is None and not any('aperture "' in w or "clamped" in w for w in warnings)


def test_an_aperturediameter_wider_than_the_files_stop_is_clamped_to_it_with_a_warning(tmp_path):
    camera, warnings = camera_of(tmp_path, '"float aperturediameter" 20')
    assert camera.lens.stop_diameter_mm == FILE_STOP_MM
    assert any('s.pbrt:2: unsupported: "aperturediameter" 20 mm is wider than the lens file\'s stop' in w
               for w in warnings)


def shaped(tmp_path, aperture, diameter=10.0):
    camera, warnings = camera_of(tmp_path, f'"float aperturediameter" {diameter} "string aperture" "{aperture}"')
    assert camera.lens.stop_diameter_mm == diameter
    return camera.lens.stop_shape, warnings


def test_pentagon_is_pbrts_regular_pentagon_of_0_8_the_radius_pointing_to_minus_y(tmp_path):
    shape, warnings = shaped(tmp_path, "pentagon")
    r = 5.0
    circumradius = 0.8 * r
    exact = 2.5 * circumradius**2 * math.sin(2 * math.pi / 5)
    assert shape.open_area_mm2(10.0) == pytest.approx(exact, rel=2e-3)
    apothem = circumradius * math.cos(math.pi / 5)
    x = np.array([0.0, 0.0, 0.0, 0.0])
    y = np.array([-0.98 * circumradius, 0.98 * apothem, 1.02 * apothem, -1.02 * circumradius])
    # pbrt draws the vertex at +y and flips the image: the vertex lands at -y, a flat side at +y
    assert shape.inside(x, y, 10.0).tolist() == [True, True, False, False]
    ratio = exact / (math.pi * r * r)
    assert any(f'aperture "pentagon" passes {ratio:.0%}' in w and "s.pbrt:2:" in w for w in warnings)


def test_square_spans_the_middle_half_of_the_stops_square(tmp_path):
    shape, _ = shaped(tmp_path, "square")
    assert shape.open_area_mm2(10.0) == pytest.approx(5.0 * 5.0, rel=2e-3)
    x = np.array([2.45, 2.55, 0.0, 2.45])
    y = np.array([2.45, 0.0, 2.55, -2.45])
    assert shape.inside(x, y, 10.0).tolist() == [True, False, False, True]


def test_star_is_pbrts_five_pointed_star(tmp_path):
    shape, _ = shaped(tmp_path, "star")
    outer, inner = 5.0, 5.0 * math.cos(math.radians(72)) / math.cos(math.radians(36))
    exact = 10 * 0.5 * outer * inner * math.sin(math.radians(36))
    assert shape.open_area_mm2(10.0) == pytest.approx(exact, rel=0.015)  # a 128-pixel mask
    # outer points at 36 + 72 k degrees (one at 180), inner corners between them (one at 0)
    assert shape.inside(np.array([-4.6, 0.6 * inner]), np.array([0.0, 0.0]), 10.0).tolist() == [True, True]
    assert not shape.inside(np.array([1.2 * inner]), np.array([0.0]), 10.0)[0]


def test_gaussian_opens_the_fraction_of_each_ring_that_pbrts_profile_transmits(tmp_path):
    shape, _ = shaped(tmp_path, "gaussian")
    side = 512
    g = (np.arange(side) + 0.5) / side * 2 - 1  # units of the stop radius
    x, y = np.meshgrid(g, g)
    r2 = x * x + y * y
    profile = np.maximum(0, np.exp(-r2) - math.exp(-1)) / (1 - math.exp(-1))
    open_ = shape.inside(x * 5.0, y * 5.0, 10.0)
    for lo, hi in [(0.0, 0.3), (0.3, 0.6), (0.6, 0.8), (0.8, 1.0)]:
        ring = (r2 >= lo * lo) & (r2 < hi * hi)
        assert open_[ring].mean() == pytest.approx(profile[ring].mean(), abs=0.03)
    assert not open_[r2 > 1.05].any()
    # total: the profile's integral over the unit disk, pi (1 - 2/e) / (1 - 1/e), of the square's 4
    assert open_.mean() == pytest.approx(math.pi * (1 - 2 / math.e) / (1 - 1 / math.e) / 4, rel=0.01)


def test_an_aperture_image_is_the_stops_transmission_with_its_top_row_at_plus_y(tmp_path):
    picture = np.zeros((64, 64, 3), np.float32)
    picture[:32, :16] = 1.0  # the file's top-left quarter... of the top half: open
    write_exr(tmp_path / "stop.exr", picture)
    shape, warnings = shaped(tmp_path, "stop.exr")
    inside = shape.inside(np.array([-4.0, -4.0, 4.0, -1.0]), np.array([2.0, -2.0, 2.0, 2.0]), 10.0)
    assert inside.tolist() == [True, False, False, False]
    assert shape.open_area_mm2(10.0) == pytest.approx(100 / 8, rel=0.01)
    assert any('aperture "stop.exr" passes' in w for w in warnings)


def test_a_missing_aperture_image_is_one_line_naming_the_camera(tmp_path):
    with pytest.raises(UserError, match=r's\.pbrt:2: aperture image "nope.png" not found') as err:
        shaped(tmp_path, "nope.png")
    assert "\n" not in str(err.value)


def test_an_empty_aperture_keeps_the_circle(tmp_path):
    shape, _ = shaped(tmp_path, "")
    assert shape is None


def test_aperture_is_a_v4_parameter(tmp_path):
    """It signals pbrt-v4, and a file read as pbrt-v3 (which has none) is told it is ignored."""
    path = scene(tmp_path, '"float aperturediameter" 8 "string aperture" "pentagon"', header="")
    path.write_text(path.read_text().replace('Film "rgb"', 'Film "image"'))
    assert import_pbrt(path).dialect.name == "v4"
    v3 = import_pbrt(path, dialect="v3")
    assert v3.scene.camera.lens.stop_shape is None
    assert any('"aperture" is not a realistic-camera parameter in pbrt-v3' in w for w in v3.warnings)


def test_a_pentagon_stop_passes_its_area_share_of_the_light():
    """Brightness follows the open area: the shape module's promise, which the warning quotes."""
    from realistic.scene.pbrt.dialect import v4_builtin_aperture

    lens = load_lens("dgauss").with_stop_diameter(10.0)
    circle = flat_field_brightness(lens)
    pentagon = flat_field_brightness(lens.with_stop_shape(v4_builtin_aperture("pentagon")))
    exact = 2.5 * 4.0**2 * math.sin(2 * math.pi / 5) / (math.pi * 25)
    assert pentagon / circle == pytest.approx(exact, rel=0.03)
