"""Exposure: the meter equation, and renders whose brightness follows the exposure value."""

import math

import pytest

from conftest import flat_field_brightness
from realistic import UserError, load_lens
from realistic.camera.exposure import exposure_scale, exposure_value, parse_shutter
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data, stop_diameter_for_f_number, thick_lens


def test_a_metered_uniform_field_comes_out_middle_grey():
    # N^2 / t = L S / K meters the field: E = pi L / (4 N^2) then maps to 0.18
    n, iso, luminance = 8.0, 200.0, 1000.0
    t = n * n * 12.5 / (luminance * iso)
    irradiance = math.pi * luminance / (4 * n * n)
    assert irradiance * exposure_scale(t, iso) == pytest.approx(0.18)
    assert exposure_value(n, t) == pytest.approx(math.log2(n * n / t))


def test_shutter_parsing():
    assert parse_shutter("1/125") == pytest.approx(0.008)
    assert parse_shutter("0.5") == 0.5
    for bad in ("0", "-1", "1/0", "fast"):
        with pytest.raises(UserError):
            parse_shutter(bad)


@pytest.mark.parametrize("name", ["dgauss", "telephoto"])
def test_centre_brightness_follows_the_f_number(name):
    lens = load_lens(name)
    slow = 2 * lens_f_number(lens)
    values = []
    for n in (slow, slow * math.sqrt(2), slow * 2):
        values.append(flat_field_brightness(lens.with_stop_diameter(stop_diameter_for_f_number(lens, n))))
    # one stop per factor sqrt(2) of N: the centre irradiance halves, as pi L / (4 N^2) says
    assert values[0] / values[1] == pytest.approx(2.0, rel=0.03)
    assert values[0] / values[2] == pytest.approx(4.0, rel=0.03)
    # absolute level: pi L / (4 N_w^2) with the working f-number N_w = N (1 + m / p) for a lens focused
    # at magnification m with pupil magnification p (exit over entrance pupil diameter)
    n = slow * 2
    stopped = lens.with_stop_diameter(stop_diameter_for_f_number(lens, n))
    p = paraxial_data(stopped)
    image_distance = film_distance_for_focus(stopped, 10_000.0) + thick_lens(stopped).rear_principal_from_rear_vertex_mm
    m = image_distance / p.efl_mm - 1
    working = n * (1 + m / (p.exit_pupil_diameter_mm / p.entrance_pupil_diameter_mm))
    assert values[2] == pytest.approx(math.pi / (4 * working**2), rel=0.02)


def lens_f_number(lens):
    return paraxial_data(lens).f_number


def centre_mean(path):
    from realistic.core.image_files import read_exr

    image, header = read_exr(path)
    h, w, _ = image.shape
    return image[h // 4: 3 * h // 4, w // 4: 3 * w // 4].mean(), header


def test_render_brightness_follows_the_exposure_value(tmp_path):
    from realistic.cli import main

    common = ["render", "--backend", "numpy", "--res", "48x32", "--spp", "64", "--dispersion", "off", "--iso", "200"]
    runs = {"a": ["--fstop", "4", "--shutter", "1/60"], "b": ["--fstop", str(4 * math.sqrt(2)), "--shutter", "1/30"],
            "c": ["--fstop", "4", "--shutter", "1/30"]}
    values = {}
    for name, args in runs.items():
        assert main([*common, *args, "--out", str(tmp_path / f"{name}.exr")]) == 0
        values[name], header = centre_mean(tmp_path / f"{name}.exr")
        assert float(header["iso"]) == 200
    assert values["b"] == pytest.approx(values["a"], rel=0.04)  # same EV: same brightness
    assert values["c"] == pytest.approx(2 * values["a"], rel=1e-5)  # one EV less: twice the light


def test_fstop_faster_than_the_lens_takes_the_widest_with_a_warning(tmp_path, capsys):
    """The CLI sets the lens's widest stop, as a camera does, and says so; the API refuses."""
    from realistic.cli import main

    assert main(["render", "--backend", "numpy", "--res", "16x12", "--spp", "1", "--fstop", "1.4",
                 "--out", str(tmp_path / "x.exr")]) == 0
    assert "--fstop 1.4 is faster than dgauss opens: f/2.03 is used" in capsys.readouterr().err
    with pytest.raises(UserError, match="faster than dgauss opens"):
        stop_diameter_for_f_number(load_lens("dgauss"), 1.4)
