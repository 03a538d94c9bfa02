"""`realistic lens info` for every bundled lens and for a path."""

import json
import subprocess
import sys

import pytest

from realistic.optics.formats import BUNDLED_LENSES, load_lens
from realistic.optics.paraxial import paraxial_data

KEYS = ["efl_mm", "bfl_mm", "ffd_mm", "entrance_pupil_mm", "entrance_pupil_diameter_mm", "exit_pupil_mm",
        "exit_pupil_diameter_mm", "f_number"]


def lens_info(*args):
    run = subprocess.run([sys.executable, "-m", "realistic", "lens", "info", *args], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return run.stdout


@pytest.mark.parametrize("name", list(BUNDLED_LENSES))
def test_lens_info_json_has_the_documented_keys(name):
    info = json.loads(lens_info(name, "--json"))
    expected = paraxial_data(load_lens(name))
    for key in KEYS:
        assert info[key] == pytest.approx(getattr(expected, key))
    assert len(info["surfaces"]) == load_lens(name).surface_count


def test_lens_info_text_for_a_path(tmp_path):
    path = tmp_path / "single.dat"
    path.write_text("0 2 0 10\n40 6 1.6 30\n-60 0 1 30\n")
    text = lens_info(str(path), "--film-distance", "50")
    assert "effective focal length" in text and "in focus at film distance 50 mm" in text


def test_lens_info_reports_pass_fractions():
    info = json.loads(lens_info("telephoto", "--json", "--sampling", "35"))
    corner = info["pass_fraction"]["at"]["0.999"]
    assert corner["pupil"] >= 2 * corner["rear"]
