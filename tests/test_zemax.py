"""Zemax .zmx import: the Kolb double Gauss written as a Zemax file imports to the bundled lens."""

import math
import subprocess
import sys

import numpy as np
import pytest

from realistic import LensFileError, load_lens
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.paraxial import paraxial_data

UNITS = {"MM": 1.0, "CM": 10.0, "IN": 25.4, "METER": 1000.0}


def zmx_text(lens, unit: str = "MM") -> str:
    """``lens`` as a Zemax sequential file in ``unit``, with the clutter real files carry."""
    scale = UNITS[unit]
    lines = ["VERS 190513 80 123 L123", "MODE SEQ", 'NAME "Kolb double Gauss"', f"UNIT {unit} X W X CM MR CPMM",
             "ENPD 2.0E+1", "GCAT SCHOTT", "WAVM 1 5.8756180E-01 1",
             "SURF 0", "  TYPE STANDARD", '  CURV 0.0 0 0 0 0 ""', "  DISZ INFINITY", '  DIAM 0 0 0 0 1 ""']
    for i in range(lens.surface_count):
        radius, thickness, index, abbe = (float(x[i]) for x in (lens.radius_mm, lens.thickness_mm, lens.index_d,
                                                                lens.abbe_v))
        curvature = 0.0 if radius == 0 or math.isinf(radius) else scale / radius
        lines += [f"SURF {i + 1}"] + (["  STOP"] if i == lens.stop else [])
        lines += ["  TYPE STANDARD", "  FIMP ", f'  CURV {curvature!r} 0 0 0 0 ""', "  HIDE 0 0 0 0 0 0 0 0 0 0",
                  "  MIRR 2 0", f"  DISZ {thickness / scale!r}"]
        if index != 1:
            lines.append(f"  GLAS ___BLANK 1 0 {index!r} {abbe!r} 0 0 0 0 0 0")
        semi_diameter = float(lens.aperture_mm[i]) / 2 / scale
        lines += [f'  DIAM {semi_diameter!r} 1 0 0 1 ""', "  CONI 0", "  POPS 0 0 0 0 0 0 0 0 1 1"]
    lines += [f"SURF {lens.surface_count + 1}", "  TYPE STANDARD", '  CURV 0.0 0 0 0 0 ""', "  DISZ 0",
              '  DIAM 2.1E+1 0 0 0 1 ""', "BLNK ", "MNUM 1 1"]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def dgauss():
    return load_lens("dgauss100")


def assert_same_lens(a, b, rel=1e-12):
    assert a.stop == b.stop and a.surface_count == b.surface_count
    for attr in ("radius_mm", "thickness_mm", "index_d", "abbe_v", "aperture_mm"):
        x, y = getattr(a, attr), getattr(b, attr)
        assert np.array_equal(np.isinf(x), np.isinf(y)), attr
        finite = np.isfinite(x)
        assert x[finite] == pytest.approx(y[finite], rel=rel, abs=1e-12), attr
    assert paraxial_data(a).efl_mm == pytest.approx(paraxial_data(b).efl_mm, abs=1e-9)


@pytest.mark.parametrize("encoding", ["ascii", "utf-16", "utf-16-le-no-bom", "utf-8-sig"])
def test_dgauss100_as_zmx_imports_to_the_bundled_lens(dgauss, tmp_path, encoding):
    text = zmx_text(dgauss).replace("\n", "\r\n")
    data = (text.encode("utf-16-le") if encoding == "utf-16-le-no-bom" else
            b"\xff\xfe" + text.encode("utf-16-le") if encoding == "utf-16" else text.encode(encoding))
    path = tmp_path / "dgauss100.zmx"
    path.write_bytes(data)
    lens = load_lens(str(path))
    assert_same_lens(lens, dgauss)
    assert lens.name == "dgauss100" and lens.source == str(path)
    assert lens.film_gap_mm == pytest.approx(72.228)
    assert lens.convention_note == ""


@pytest.mark.parametrize("unit", ["CM", "IN", "METER"])
def test_lens_units_convert_to_millimetres(dgauss, unit):
    assert_same_lens(parse_zmx(zmx_text(dgauss, unit), "x.zmx"), dgauss, rel=1e-9)


def test_glass_of_a_catalogue_we_lack_with_nd_vd_on_the_line_is_read_and_noted(dgauss):
    text = zmx_text(dgauss).replace("GLAS ___BLANK 1 0 1.67 47.1", "GLAS K-LAK8 0 0 1.67 47.1", 1)
    lens = parse_zmx(text.replace("GCAT SCHOTT", "GCAT SCHOTT SUMITA"), "x.zmx")
    assert_same_lens(lens, dgauss)
    assert "K-LAK8 (line " in lens.convention_note


def test_catalogue_glass_comes_from_the_catalogue_not_the_line(dgauss):
    text = zmx_text(dgauss).replace("GLAS ___BLANK 1 0 1.67 47.1", "GLAS N-LAK8 0 0 1.67 47.1", 1)
    lens = parse_zmx(text, "x.zmx")
    assert lens.glass[0] is not None and lens.glass[0].label == "N-LAK8 (Schott)"
    assert lens.index_d[0] == pytest.approx(1.713, abs=1e-5)  # the data sheet's n_d, not the line's 1.67


def test_clear_aperture_clap_takes_precedence_over_diam(dgauss):
    text = zmx_text(dgauss).replace("  CONI 0\n", "  CLAP 0 1.0E+1 0\n", 1)
    assert parse_zmx(text, "x.zmx").aperture_mm[0] == pytest.approx(20.0)


def surface_line(text: str, surface: int, keyword: str) -> int:
    """1-based line number of ``keyword`` inside ``SURF surface``."""
    lines = text.splitlines()
    start = lines.index(f"SURF {surface}")
    return next(i for i in range(start, len(lines)) if lines[i].split()[:1] == [keyword]) + 1


def replace_line(text: str, number: int, new: str) -> str:
    lines = text.splitlines()
    lines[number - 1] = new
    return "\n".join(lines) + "\n"


# (surface whose line is changed, keyword of the line, new line, message fragment); the stop is SURF 6.
UNSUPPORTED = {
    "odd asphere": (3, "TYPE", "  TYPE ODDASPH", "surface type ODDASPH"),
    "toroid": (3, "TYPE", "  TYPE TOROIDAL", "surface type TOROIDAL"),
    "coordinate break": (4, "TYPE", "  TYPE COORDBRK", "TYPE COORDBRK: coordinate breaks"),
    "conic not a number": (3, "CONI", "  CONI abc", "CONI 'abc' is not a number"),
    "mirror": (1, "GLAS", "  GLAS MIRROR 0 0", "mirror"),
    "unknown glass": (1, "GLAS", "  GLAS N-BK77 0 0", "glass 'N-BK77' is in none of the catalogues"),
    "blank glass without values": (1, "GLAS", "  GLAS ___BLANK 1 0", "model glass ___BLANK"),
    "negative index": (1, "GLAS", "  GLAS ___BLANK 1 0 0.5 40 0 0 0 0 0 0", "must be >= 1"),
    "obscuration": (3, "CONI", "  OBSC 0 5 0", "obscuration"),
    "tilt": (3, "CONI", "  SCBD 1 0 0 0 1.5E+0 0 0 0", "tilted or decentred"),
    "annular aperture": (3, "CONI", "  CLAP 2 10 0", "annular"),
    "second stop": (8, "TYPE", "  STOP", "a second STOP"),
    "stop on image": (12, "TYPE", "  STOP", "not the object or image"),
    "curved image": (12, "CURV", "  CURV 1.0E-2", "curved image surface"),
    "glass before image": (11, "CONI", "  GLAS ___BLANK 1 0 1.5 60 0 0 0 0 0 0",
                           "before the image surface must be air"),
    "glass object space": (0, "DIAM", "  GLAS ___BLANK 1 0 1.5 60 0 0 0 0 0 0", "object space must be air"),
    "bad number": (3, "DISZ", "  DISZ abc", "DISZ 'abc' is not a number"),
    "missing diameter": (3, "DIAM", "  HIDE 0", "has no DIAM"),
    "out of order": (3, "SURF", "SURF 7", "out of order"),
}


@pytest.mark.parametrize("kind", list(UNSUPPORTED))
def test_unsupported_features_are_rejected_with_file_and_line(dgauss, tmp_path, kind):
    surface, keyword, new, fragment = UNSUPPORTED[kind]
    text = zmx_text(dgauss)
    line = surface_line(text, surface, keyword)
    text = replace_line(text, line, new)
    if kind == "missing diameter":
        line = surface_line(text, surface, "SURF")
    path = tmp_path / "bad.zmx"
    path.write_bytes(b"\xff\xfe" + text.encode("utf-16-le"))
    with pytest.raises(LensFileError) as err:
        load_lens(str(path))
    assert str(err.value).startswith(f"{path}:{line}: "), str(err.value)
    assert fragment in str(err.value)


@pytest.mark.parametrize("header, fragment", [("UNIT FT X W X CM MR CPMM", "lens unit 'FT'"),
                                              ("MODE NSC", "MODE NSC is not supported")])
def test_unsupported_file_settings_are_rejected_with_the_line(dgauss, header, fragment):
    text = zmx_text(dgauss)
    line = 4 if header.startswith("UNIT") else 2
    text = replace_line(text, line, header)
    with pytest.raises(LensFileError, match=f"^x.zmx:{line}: {fragment}"):
        parse_zmx(text, "x.zmx")


def test_shared_validation_names_the_surface_line(dgauss):
    text = zmx_text(dgauss)
    line = surface_line(text, 3, "DISZ")
    with pytest.raises(LensFileError, match=f"^x.zmx:{surface_line(text, 3, 'SURF')}: thickness 0 mm"):
        parse_zmx(replace_line(text, line, "  DISZ 0"), "x.zmx")


def test_file_without_stop_or_lens_surfaces_is_rejected(dgauss):
    with pytest.raises(LensFileError, match="^x.zmx: no STOP surface"):
        parse_zmx(zmx_text(dgauss).replace("  STOP\n", ""), "x.zmx")
    with pytest.raises(LensFileError, match="^x.zmx: 2 SURF blocks"):
        parse_zmx("SURF 0\n  DISZ INFINITY\nSURF 1\n  CURV 0\n", "x.zmx")


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "realistic", "lens", "info", *args], capture_output=True, text=True)


def test_cli_lens_info_reads_a_zmx_file(dgauss, tmp_path):
    path = tmp_path / "x.zmx"
    path.write_text(zmx_text(dgauss), encoding="utf-16")
    run = run_cli(str(path))
    assert run.returncode == 0, run.stderr
    assert "effective focal length" in run.stdout


def test_cli_reports_a_bad_zmx_in_one_line_with_status_2(dgauss, tmp_path):
    path = tmp_path / "bad.zmx"
    text = zmx_text(dgauss)
    path.write_text(replace_line(text, surface_line(text, 3, "TYPE"), "  TYPE TOROIDAL"), encoding="utf-16")
    run = run_cli(str(path))
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr
    assert f"{path}:{surface_line(text, 3, 'TYPE')}: surface type TOROIDAL" in run.stderr
