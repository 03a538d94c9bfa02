"""Parsing and validation of lens prescriptions."""

import subprocess
import sys
from importlib import resources

import numpy as np
import pytest

from conftest import shared_file
from realistic import LensFileError, load_lens, parse_prescription
from realistic.optics.paraxial import paraxial_data

KOLB_RADII = [58.950, 169.660, 38.550, 81.540, 25.500, 0, -28.990, 81.540, -40.770, 874.130, -79.460]
KOLB_V = [47.1, 0, 47.1, 30.1, 0, 0, 38.0, 57.3, 0, 48.0, 0]


@pytest.mark.parametrize("name,rows,stop", [("dgauss", 11, 5), ("wide", 13, 5), ("fisheye", 12, 6),
                                            ("telephoto", 7, 3), ("dgauss100", 11, 5)])
def test_bundled_lenses_load(name, rows, stop):
    lens = load_lens(name)
    assert lens.surface_count == rows
    assert lens.stop == stop
    assert lens.radius_mm[stop] == 0


def test_dgauss100_is_the_kolb_table():
    lens = load_lens("dgauss100")
    np.testing.assert_allclose(lens.radius_mm, KOLB_RADII)
    np.testing.assert_allclose(lens.abbe_v, KOLB_V)
    assert lens.film_gap_mm == pytest.approx(72.228)
    assert lens.stop_diameter_mm == pytest.approx(34.2)


def test_dgauss50_is_the_kolb_table_halved_with_its_glasses():
    half, full = load_lens("dgauss"), load_lens("dgauss100")
    np.testing.assert_allclose(half.radius_mm, full.radius_mm / 2)
    np.testing.assert_allclose(half.thickness_mm[:-1], full.thickness_mm[:-1] / 2)
    np.testing.assert_allclose(half.index_d, full.index_d)
    np.testing.assert_allclose(half.abbe_v, full.abbe_v)


@pytest.mark.parametrize("name", ["dgauss.50mm", "wide.22mm", "fisheye.10mm", "telephoto.250mm"])
def test_bundled_copies_match_shared_files(name):
    shared = load_lens(str(shared_file(f"lenses/{name}.dat")))
    bundled = load_lens(str(resources.files("realistic.optics.formats") / "lenses" / f"{name}.dat"))
    for field in ("radius_mm", "thickness_mm", "index_d", "aperture_mm"):
        np.testing.assert_array_equal(getattr(shared, field), getattr(bundled, field))


@pytest.mark.parametrize("hundred,scaled,factor", [("dgauss", "dgauss.50mm", 0.5), ("wide", "wide.22mm", 0.22),
                                                   ("fisheye", "fisheye.10mm", 0.1),
                                                   ("telephoto", "telephoto.250mm", 2.5)])
def test_shifted_convention_is_detected_and_read_correctly(hundred, scaled, factor):
    lens100 = load_lens(str(shared_file(f"lenses/{hundred}.dat")))
    lens_scaled = load_lens(str(shared_file(f"lenses/{scaled}.dat")))
    assert "previous surface" in lens100.convention_note
    assert lens_scaled.convention_note == ""
    np.testing.assert_allclose(lens100.thickness_mm[:-1] * factor, lens_scaled.thickness_mm[:-1], rtol=2e-3)
    assert paraxial_data(lens100).efl_mm * factor == pytest.approx(paraxial_data(lens_scaled).efl_mm, rel=2e-3)


def test_crlf_and_lf_parse_alike():
    text = "# c\n0 3 0 6\n10 2 1.5 8\n-10 0 1 8\n"
    a = parse_prescription(text)
    b = parse_prescription(text.replace("\n", "\r\n"))
    np.testing.assert_array_equal(a.radius_mm, b.radius_mm)
    np.testing.assert_array_equal(a.thickness_mm, b.thickness_mm)


def test_five_columns_and_blank_cells():
    text = "r\tt\tn\tV\tap\n20\t2\t1.5\t60\t10\n-20\t1\t\t\t10\n\t3\t\t\t6\n30\t0\t1.0\t0\t10\n"
    lens = parse_prescription(text)
    assert lens.stop == 2
    np.testing.assert_allclose(lens.index_d, [1.5, 1, 1, 1])
    np.testing.assert_allclose(lens.abbe_v, [60, 0, 0, 0])


BAD_FILES = {
    "non-numeric": ("10 2 1.5 8\n0 3 abc 6\n-10 0 1 8\n", 2, "'abc'"),
    "columns": ("10 2 1.5 8\n0 3 0\n-10 0 1 8\n", 2, "found 3"),
    "mixed columns": ("10 2 1.5 60 8\n0 3 0 6\n-10 0 1 0 8\n", 2, "earlier rows have 5"),
    "no stop": ("10 2 1.5 8\n-10 0 1 8\n", None, "no aperture stop"),
    "two stops": ("0 2 0 8\n10 2 1.5 8\n-10 2 0 8\n0 3 0 6\n", 4, "second aperture stop"),
    "zero thickness": ("10 2 1.5 8\n0 0 0 6\n-10 0 1 8\n", 2, "thickness 0"),
    "negative thickness": ("10 2 1.5 8\n0 -1 0 6\n-10 0 1 8\n", 2, "thickness -1"),
    "index below one": ("10 2 0.8 8\n0 3 0 6\n-10 0 1 8\n", 1, "index 0.8"),
    "aperture beyond sphere": ("10 2 1.5 21\n0 3 0 6\n-10 0 1 8\n", 1, "semi-diameter > |R|"),
    "empty": ("# only a comment\n\n", None, "no surface rows"),
}


@pytest.mark.parametrize("kind", [k for k in BAD_FILES if BAD_FILES[k][2]])
def test_malformed_files_name_file_line_and_value(kind, tmp_path):
    text, line, fragment = BAD_FILES[kind]
    path = tmp_path / "bad.dat"
    path.write_text(text)
    with pytest.raises(LensFileError) as err:
        load_lens(str(path))
    message = str(err.value)
    assert message.startswith(f"{path}:{line}:" if line else f"{path}:")
    assert fragment in message


def test_stop_must_sit_in_air():
    # radius 0 between glass and air is a flat face; between two glasses of one index, a stop in glass
    with pytest.raises(LensFileError, match="must sit in air"):
        parse_prescription("10 2 1.5 8\n0 3 1.5 6\n-10 0 1 8\n")


@pytest.mark.parametrize("kind", [k for k in BAD_FILES if BAD_FILES[k][2]])
def test_cli_reports_bad_lens_in_one_line_with_status_2(kind, tmp_path):
    path = tmp_path / "bad.dat"
    path.write_text(BAD_FILES[kind][0])
    run = subprocess.run([sys.executable, "-m", "realistic", "lens", "info", str(path)],
                         capture_output=True, text=True)
    assert run.returncode == 2
    assert "Traceback" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1
    assert str(path) in run.stderr


def test_unknown_lens_name_is_a_clear_error():
    with pytest.raises(LensFileError, match="not a bundled lens name"):
        load_lens("no-such-lens")
