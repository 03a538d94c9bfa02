"""Spectral light values (``blackbody``, ``spectrum``, ``xyz``) reach the scene as the RGB each pbrt
version's film records for them (``realistic.core.pbrt_spectra``), checked against values derived here:
CIE 1931 chromaticities of Planck's law integrated in this file and published illuminant white points,
pbrt-v4's luminance normalisation (a spectral light has the luminance of RGB (1, 1, 1) at the same
scale), each version's white for a flat spectrum, and one-line errors at the parameter's line."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from realistic.core.cie_data import CIE_X, CIE_Y, CIE_Z, NAMED_ILLUMINANTS
from realistic.errors import UserError
from realistic.scene.lights import DistantLight, EmissiveInstance, InfiniteLight, PointLight, SpotLight
from realistic.scene.model import AreaLight
from realistic.scene.pbrt.importer import import_pbrt

CAMERA = 'LookAt 0 0 -5  0 0 0  0 1 0\nCamera "perspective" "float fov" 40\n'
#: CIE 15:2004 (Table T.3 and T.1): illuminant A and D65 in CIE 1931 (x, y).
ILLUMINANT_A_XY = (0.44757, 0.40745)
D65_XY = (0.31271, 0.32902)
#: Linear sRGB to XYZ (IEC 61966-2-1), to read the chromaticity and luminance of an imported RGB.
XYZ_FROM_SRGB = np.array([[0.4124564, 0.3575761, 0.1804375],
                          [0.2126729, 0.7151522, 0.0721750],
                          [0.0193339, 0.1191920, 0.9503041]])
#: pbrt-v2/v3 ``XYZToRGB`` (src/core/spectrum.h), the unadapted sRGB matrix.
PBRT3_RGB_FROM_XYZ = np.array([[3.240479, -1.537150, -0.498535],
                               [-0.969256, 1.875991, 0.041556],
                               [0.055648, -0.204043, 1.057311]])


def scene_file(folder, body, version="v4", name="s.pbrt"):
    """A scene for pbrt ``version`` (a v4 Film, or v3's WorldEnd) around ``body`` (line 5 onward)."""
    film = 'Film "rgb"' if version == "v4" else 'Film "image"'
    end = "" if version == "v4" else "WorldEnd\n"
    path = folder / name
    path.write_text(f'{film} "integer xresolution" 8 "integer yresolution" 8\n{CAMERA}WorldBegin\n{body}\n{end}')
    return path


def area_rgb(folder, light, version="v4"):
    """The radiance of a disk area light written with ``light``'s parameters."""
    imported = import_pbrt(scene_file(folder, f'AreaLightSource "diffuse" {light}\nShape "disk"', version),
                           dialect=version)
    (emitter,) = imported.scene.lights
    assert isinstance(emitter, AreaLight)
    return np.array(emitter.radiance)


def xy_of_rgb(rgb):
    xyz = XYZ_FROM_SRGB @ rgb
    return xyz[:2] / xyz.sum()


def planck_xy(temperature):
    """CIE 1931 (x, y) of Planck's law (CODATA 2018 constants) summed over the 1 nm tables."""
    h, c, k = 6.62607015e-34, 299792458.0, 1.380649e-23
    nm = np.arange(360, 831, dtype=np.float64)
    metres = nm * 1e-9
    radiance = 2 * h * c * c / (metres**5 * np.expm1(h * c / (metres * k * temperature)))
    xyz = np.array([np.dot(radiance, CIE_X), np.dot(radiance, CIE_Y), np.dot(radiance, CIE_Z)])
    return xyz[:2] / xyz.sum()


@pytest.mark.parametrize("temperature", [2000.0, 3000.0, 4500.0, 6500.0, 10000.0])
def test_a_v4_blackbody_has_the_chromaticity_of_plancks_law(tmp_path, temperature):
    xy = xy_of_rgb(area_rgb(tmp_path, f'"blackbody L" [{temperature}]'))
    assert np.allclose(xy, planck_xy(temperature), atol=2e-4)


def test_a_2856_k_blackbody_and_stdillum_a_have_illuminant_as_chromaticity(tmp_path):
    assert np.allclose(xy_of_rgb(area_rgb(tmp_path, '"blackbody L" [2856]')), ILLUMINANT_A_XY, atol=3e-4)
    assert np.allclose(xy_of_rgb(area_rgb(tmp_path, '"spectrum L" "stdillum-A"')), ILLUMINANT_A_XY, atol=1e-4)


def test_stdillum_d65_is_pbrt_v4s_white(tmp_path):
    # pbrt-v4's sRGB colour space takes its white from the same D65 table: (1, 1, 1) exactly
    assert np.allclose(area_rgb(tmp_path, '"spectrum L" "stdillum-D65"'), 1.0, atol=1e-12)


# Published white points: the ACES white of SMPTE ST 2065-1, and CIE 15:2004's F2 and F11, as the white-point
# tables of the literature reproduce them (e.g. the "Standard illuminant" reference tables); values, not
# derivations of ours.
@pytest.mark.parametrize("name,xy", [("illum-acesD60", (0.32168, 0.33767)),
                                     ("stdillum-F2", (0.37208, 0.37529)),
                                     ("stdillum-F11", (0.38052, 0.37713))])
def test_named_illuminants_have_their_published_white_points(tmp_path, name, xy):
    assert np.allclose(xy_of_rgb(area_rgb(tmp_path, f'"spectrum L" "{name}"')), xy, atol=1e-4)


def test_stdillum_d50_is_pbrt_v4s_table_not_d50s_white_point(tmp_path):
    # pbrt-v4's CIE_Illum_D5000 (src/pbrt/util/spectrum.cpp) differs from CIE D50 (x, y = 0.34567, 0.35850):
    # its own table's chromaticity, summed here from the tables, is what pbrt-v4 renders
    start, values = NAMED_ILLUMINANTS["stdillum-D50"]
    nm = np.arange(360, 831)
    spectrum = np.interp(nm, start + 5.0 * np.arange(len(values)), values)
    xyz = np.array([np.dot(spectrum, CIE_X), np.dot(spectrum, CIE_Y), np.dot(spectrum, CIE_Z)])
    assert np.allclose(xy_of_rgb(area_rgb(tmp_path, '"spectrum L" "stdillum-D50"')), xyz[:2] / xyz.sum(), atol=1e-4)


@pytest.mark.parametrize("light", ['"blackbody L" [3000]', '"blackbody L" [12000]', '"spectrum L" "stdillum-F2"',
                                   '"spectrum L" "illum-acesD60"', '"spectrum L" [400 1 500 3 600 2 700 0.5]'])
def test_v4_spectral_lights_have_the_luminance_of_white_at_the_same_scale(tmp_path, light):
    white = area_rgb(tmp_path, '"rgb L" [1 1 1] "float scale" 2.5')
    spectral = area_rgb(tmp_path, f'{light} "float scale" 2.5')
    luminance = XYZ_FROM_SRGB[1]
    assert luminance @ white == pytest.approx(2.5, rel=1e-6)
    assert luminance @ spectral == pytest.approx(2.5, rel=2e-4)


def test_v4_point_spot_distant_and_infinite_lights_convert_as_area_lights_do(tmp_path):
    body = ('LightSource "point" "blackbody I" [3000] "float scale" 2\n'
            'LightSource "spot" "blackbody I" [3000] "float scale" 2\n'
            'LightSource "distant" "blackbody L" [3000] "float scale" 2\n'
            'LightSource "infinite" "blackbody L" [3000] "float scale" 2\n'
            'LightSource "point" "blackbody I" [3000] "float power" 10\n')
    lights = import_pbrt(scene_file(tmp_path, body), dialect="v4").scene.lights
    expected = area_rgb(tmp_path, '"blackbody L" [3000] "float scale" 2')
    point, spot, distant, infinite, powered = lights
    assert isinstance(point, PointLight) and isinstance(spot, SpotLight)
    assert isinstance(distant, DistantLight) and isinstance(infinite, InfiniteLight)
    for emitted in (point.intensity, spot.intensity, distant.radiance, infinite.radiance):
        assert np.allclose(emitted, expected, rtol=1e-12)
    # pbrt-v4 PointLight::Create: the luminous intensity of "power" P is P / (4 pi)
    assert XYZ_FROM_SRGB[1] @ np.array(powered.intensity) == pytest.approx(10 / (4 * math.pi), rel=2e-4)


def test_a_flat_spectrum_renders_as_each_versions_conversion(tmp_path):
    flat = '"spectrum L" [300 1 900 1]'
    # pbrt-v2/v3: XYZ of the equal-energy white E (sums of the tables over y bar's), unadapted sRGB matrix
    e_xyz = np.array([np.sum(CIE_X), np.sum(CIE_Y), np.sum(CIE_Z)]) / np.sum(CIE_Y)
    v2 = area_rgb(tmp_path, flat, "v2")
    assert np.allclose(v2, (1.205, 0.948, 0.909), atol=1e-3)  # issue 34's numbers
    assert np.allclose(v2, PBRT3_RGB_FROM_XYZ @ e_xyz, rtol=1e-6)
    # pbrt-v3 scales the sums by (830 - 360) / (CIE_Y_integral * 471) rather than dividing by their y
    v3 = area_rgb(tmp_path, flat, "v3")
    assert np.allclose(v3, v2 * np.sum(CIE_Y) * 470 / (106.856895 * 471), rtol=1e-6)
    # pbrt-v4: E's chromaticity at the luminance of white
    v4 = area_rgb(tmp_path, flat, "v4")
    assert np.allclose(xy_of_rgb(v4), e_xyz[:2] / e_xyz.sum(), atol=2e-4)
    assert XYZ_FROM_SRGB[1] @ v4 == pytest.approx(1.0, rel=2e-4)


def test_v3_blackbody_is_normalised_at_its_peak_and_scaled_by_its_second_value(tmp_path):
    one = area_rgb(tmp_path, '"blackbody L" [6500 1]', "v3")
    assert np.allclose(area_rgb(tmp_path, '"blackbody L" [6500 2.5]', "v3"), 2.5 * one, rtol=1e-12)
    assert np.allclose(xy_of_rgb(one), planck_xy(6500.0), atol=2e-4)
    # its peak is 1 (pbrt-v3 BlackbodyNormalized): at 6500 K, near 446 nm, the visible spectrum is about
    # flat-topped, so its luminance is below a flat 1's (0.998) but above half of it
    luminance = XYZ_FROM_SRGB[1] @ one
    assert 0.5 < luminance < 0.998


def test_v3_blackbody_xyz_is_plancks_law_over_its_peak_summed_as_from_sampled(tmp_path):
    h, c, k, temperature = 6.62606957e-34, 299792458.0, 1.3806488e-23, 4000.0  # pbrt-v3's constants

    def planck(metres):
        return 2 * h * c * c / (metres**5 * np.expm1(h * c / (metres * k * temperature)))

    spectrum = planck(np.arange(360, 831) * 1e-9) / planck(2.8977721e-3 / temperature)
    xyz = np.array([spectrum @ CIE_X, spectrum @ CIE_Y, spectrum @ CIE_Z]) * 470 / (106.856895 * 471)
    rgb = area_rgb(tmp_path, f'"blackbody L" [{temperature} 1]', "v3")
    assert np.allclose(np.linalg.solve(PBRT3_RGB_FROM_XYZ, rgb), xyz, rtol=1e-9)


@pytest.mark.parametrize("temperature", ["1", "1e30", "1e300"])
def test_extreme_v3_blackbodies_are_black(tmp_path, temperature):
    # with its peak far from the visible, the peak-normalised spectrum is all but 0 there (pbrt-v3's float
    # arithmetic gives zeros at 1 K and 1e30 K; beyond float's range it would give NaN)
    rgb = area_rgb(tmp_path, f'"blackbody L" [{temperature} 1]', "v3")
    assert np.all(rgb >= 0) and np.all(rgb < 1e-30)


def test_v2_blackbody_is_one_at_555_nm(tmp_path):
    # pbrt-v2 Blackbody: norm = 555^5 (exp(c2 / (555 T)) - 1), so at any T the spectrum is 1 at 555 nm,
    # and a very hot one falls as lambda^-4 (Rayleigh-Jeans): luminance near the flat spectrum's y
    hot = area_rgb(tmp_path, '"blackbody L" [1e9 1]', "v2")
    xyz = np.linalg.solve(PBRT3_RGB_FROM_XYZ, hot)
    nm = np.arange(360, 831, dtype=np.float64)
    expected_y = np.dot((555.0 / nm) ** 4, CIE_Y) / np.sum(CIE_Y)
    assert xyz[1] == pytest.approx(expected_y, rel=1e-5)


def test_v3_sorts_unsorted_samples_and_v4_refuses_them(tmp_path):
    sorted_rgb = area_rgb(tmp_path, '"spectrum L" [400 1 500 2 600 3]', "v3")
    assert np.allclose(area_rgb(tmp_path, '"spectrum L" [600 3 400 1 500 2]', "v3"), sorted_rgb)
    with pytest.raises(UserError, match=r"s\.pbrt:5: .*wavelengths must increase"):
        area_rgb(tmp_path, '"spectrum L" [600 3 400 1 500 2]', "v4")


def test_xyz_before_v4_is_converted_with_xyz_to_rgb(tmp_path):
    assert np.allclose(area_rgb(tmp_path, '"xyz L" [0.9505 1 1.089]', "v3"),
                       PBRT3_RGB_FROM_XYZ @ np.array([0.9505, 1, 1.089]), rtol=1e-12)


def test_a_spectrum_file_reads_as_its_pairs(tmp_path):
    (tmp_path / "warm.spd").write_text("# a warm light\n400 0.2\n500 0.6\n600 1.0\n700 1.2\n")
    inline = area_rgb(tmp_path, '"spectrum L" [400 0.2 500 0.6 600 1.0 700 1.2]', "v3")
    assert np.allclose(area_rgb(tmp_path, '"spectrum L" "warm.spd"', "v3"), inline)


def test_a_colour_outside_srgb_is_clipped_with_a_warning(tmp_path):
    path = scene_file(tmp_path, 'AreaLightSource "diffuse" "spectrum L" [640 1 660 1]\nShape "disk"')
    imported = import_pbrt(path, dialect="v4")
    (emitter,) = imported.scene.lights
    assert min(emitter.radiance) == 0 and emitter.radiance[0] > 1
    assert any("s.pbrt:5:" in w and "outside sRGB" in w for w in imported.warnings)


def test_spectral_area_lights_on_meshes_emit_the_converted_rgb(tmp_path):
    path = scene_file(tmp_path, 'AreaLightSource "diffuse" "blackbody L" [3000]\nShape "sphere"')
    (emitter,) = import_pbrt(path, dialect="v4").scene.lights
    assert isinstance(emitter, EmissiveInstance)
    assert np.allclose(emitter.radiance, area_rgb(tmp_path, '"blackbody L" [3000]'))


@pytest.mark.parametrize("version,light,said", [
    ("v4", '"blackbody L" [0]', "positive number of kelvin"),
    ("v4", '"blackbody L" [-300]', "positive number of kelvin"),
    ("v4", '"blackbody L" [1e999]', "too large for a double"),
    ("v4", '"blackbody L" [3000 1]', "one temperature in pbrt-v4"),
    ("v3", '"blackbody L" [3000]', "[temperature scale]"),
    ("v3", '"blackbody L" [3000 -1]', "must not be negative"),
    ("v4", '"blackbody L" [1e-3]', "no luminance"),
    ("v4", '"blackbody L" [1e300]', "no luminance"),
    ("v2", '"blackbody L" [1 1]', "too low"),
    ("v4", '"spectrum L" [400 1 500]', "pairs, got 3"),
    ("v4", '"spectrum L" [400 1 500 -2]', "negative value"),
    ("v4", '"spectrum L" [400 1 1e999 2]', "too large for a double"),
    ("v3", '"spectrum L" [400 1 400 2]', "must increase"),
    ("v4", '"spectrum L" [400 0 700 0]', "no luminance"),
    ("v4", '"spectrum L" "metal-Zz-eta"', "not found"),
    ("v4", '"xyz L" [1 1 1]', "no xyz"),
])
def test_bad_spectra_are_one_line_errors_at_their_line(tmp_path, version, light, said):
    with pytest.raises(UserError) as err:
        area_rgb(tmp_path, light, version)
    message = str(err.value)
    assert "\n" not in message and "s.pbrt:5:" in message and said in message


def test_a_parameter_on_its_own_line_is_located_there(tmp_path):
    path = scene_file(tmp_path, 'LightSource "point"\n  "blackbody I" [-1]')
    with pytest.raises(UserError, match=r"s\.pbrt:6: "):
        import_pbrt(path, dialect="v4")


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-1000, 2000).map(float),
                    st.floats(350, 850))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(version=st.sampled_from(["v2", "v3", "v4"]), kind=st.sampled_from(["blackbody", "spectrum", "xyz"]),
       values=st.lists(numbers, min_size=0, max_size=7), light=st.sampled_from(["area", "point"]))
def test_any_spectral_parameter_imports_or_fails_in_one_line(tmp_path, version, kind, values, light):
    text = " ".join(repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("1e999" if v > 0 else "-1e999"))
                    for v in values)
    if light == "area":
        body = f'AreaLightSource "diffuse" "{kind} L" [{text}]\nShape "disk"'
    else:
        body = f'LightSource "point" "{kind} I" [{text}]'
    try:
        imported = import_pbrt(scene_file(tmp_path, body, version), dialect=version)
    except UserError as err:
        assert "\n" not in str(err) and "s.pbrt:" in str(err)
        return
    (emitter,) = imported.scene.lights
    emitted = np.array(emitter.intensity if isinstance(emitter, PointLight) else emitter.radiance)
    assert np.all(np.isfinite(emitted)) and np.all(emitted >= 0)


def test_a_rendered_white_surface_under_a_blackbody_has_the_lights_colour(tmp_path):
    # a grey diffuse plane reflects every channel alike: each pixel's RGB is the light's RGB times one number
    from realistic.renderer.inputs import RenderOptions, build_render_inputs
    from realistic.renderer.job import RenderJob
    from realistic.renderer.passes import render

    path = tmp_path / "lit.pbrt"
    path.write_text('Film "rgb" "integer xresolution" 8 "integer yresolution" 8\nLookAt 0 0 -4 0 0 0 0 1 0\n'
                    'Camera "perspective" "float fov" 30\nWorldBegin\nAttributeBegin\nAreaLightSource "diffuse" '
                    '"blackbody L" [3000]\nTranslate 0 0 -6\nShape "disk" "float radius" 3\nAttributeEnd\n'
                    'Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]\n'
                    'Shape "trianglemesh" "point3 P" [-5 -5 0 5 -5 0 5 5 0 -5 5 0] "integer indices" [0 1 2 0 2 3]\n')
    imported = build_render_inputs(RenderOptions(scene=path, spp=2))
    image = render(RenderJob(imported.scene, (imported.camera,), "numpy"))[0].image
    light = area_rgb(tmp_path, '"blackbody L" [3000]')
    lit = image.reshape(-1, 3)
    lit = lit[lit[:, 1] > 0]
    assert len(lit) > 0 and np.allclose(lit / lit[:, 1:2], light / light[1], rtol=1e-4)


@pytest.mark.parametrize("dialect,scale", [("v2", '"blackbody scale" [3000 1]'), ("v3", '"blackbody scale" [3000 1]'),
                                           ("v3", '"rgb scale" [1 0.5 0.25]'), ("v4", '"float scale" 2')])
def test_an_area_lights_scale_is_read_as_its_point_lights(tmp_path, dialect, scale):
    """An area light's ``scale`` is read as the version reads a LightSource's (a spectrum in v1-v3, a
    float in v4): a blackbody scale on an area light was taken as 1."""
    path = tmp_path / "s.pbrt"
    path.write_text('Camera "perspective"\nWorldBegin\n'
                    f'LightSource "point" "rgb I" [1 1 1] {scale}\n'
                    f'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1] {scale}\nShape "disk"\nAttributeEnd\n'
                    "WorldEnd\n")
    lights = import_pbrt(path, dialect=dialect).scene.lights
    point = next(light for light in lights if isinstance(light, PointLight))
    area = next(light for light in lights if isinstance(light, AreaLight))
    np.testing.assert_allclose(area.radiance, point.intensity, rtol=1e-12)
    assert not np.allclose(area.radiance, 1.0)
