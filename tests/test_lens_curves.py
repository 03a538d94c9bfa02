"""Field curves against the cos^4 law, and the lens drawings' commands."""

import json
import math
import subprocess
import sys

import pytest
from PIL import Image

from realistic import load_lens
from realistic.core.image_files import read_exr
from realistic.optics.field_curves import field_curves, vignetting_map
from realistic.optics.paraxial import film_distance_for_focus, paraxial_data


@pytest.mark.parametrize("name", ["telephoto", "dgauss"])
def test_small_stop_follows_the_cos4_law(name):
    # With a small stop nothing vignettes and the exit pupil is a fixed disk Z from the film:
    # Kolb's E = L A cos^4(theta) / Z^2 predicts E(r) / E(0) = cos^4(atan(r / Z)).
    lens = load_lens(name)
    lens = lens.with_stop_diameter(lens.stop_diameter_mm / 8)
    z = film_distance_for_focus(lens, math.inf) - paraxial_data(lens).exit_pupil_mm
    for row in field_curves(lens, film_diagonal_mm=30, points=5, samples=20_000):
        expected = math.cos(math.atan(row["film_radius_mm"] / z)) ** 4
        assert row["relative_illumination"] == pytest.approx(expected, abs=0.02)
        assert row["vignetting"] == pytest.approx(1.0, abs=0.02)


def test_fisheye_has_strong_barrel_distortion_and_a_bounded_image_circle():
    rows = field_curves(load_lens("fisheye"), points=9, samples=5000)
    distortion = [r["distortion_percent"] for r in rows[1:] if r["distortion_percent"] is not None]
    assert all(b < a for a, b in zip(distortion, distortion[1:]))
    assert distortion[-1] < -30
    assert rows[-1]["relative_illumination"] == 0.0  # 21.6 mm lies outside its image circle


def test_vignetting_map_is_radial_and_one_at_the_centre():
    rows = [{"film_radius_mm": 0.0, "relative_illumination": 1.0}, {"film_radius_mm": 10.0,
                                                                      "relative_illumination": 0.5}]
    image = vignetting_map(rows, 4, 4, 20.0 * 2 ** 0.5)  # 5 mm pixels, centres at +-2.5 and +-7.5 mm
    inner = 1 - 0.5 * math.hypot(2.5, 2.5) / 10
    assert image[1, 1] == image[2, 2] == image[1, 2] == pytest.approx(inner)
    assert image[0, 0] == image[3, 3] == pytest.approx(0.5)  # beyond the last radius: held


def test_plot_and_curves_commands_write_their_files(tmp_path):
    png, curves, data = tmp_path / "lens.png", tmp_path / "curves.png", tmp_path / "curves.json"
    exr = tmp_path / "map.exr"
    for args in (["plot", "dgauss", "--out", str(png)],
                 ["curves", "wide", "--out", str(curves), "--json", str(data), "--vignetting-map", str(exr),
                  "--map-res", "48x32"]):
        run = subprocess.run([sys.executable, "-m", "realistic", "lens", *args], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
    assert Image.open(png).size[0] > 500 and Image.open(curves).size[0] > 500
    rows = json.loads(data.read_text())["curves"]
    assert rows[0]["relative_illumination"] == 1.0 and len(rows) > 10
    image, header = read_exr(exr)
    assert image.shape == (32, 48, 3) and header["lens"] == "wide"
    assert image[16, 24, 0] > 0.95 and image[0, 0, 0] < image[16, 24, 0]  # bright centre, dim corner
