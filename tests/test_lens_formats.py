"""JSON (isetlens / pbrt-v4 omni), Zemax EVENASPH and CODE V .seq prescriptions, and ``lens convert``."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from kernel_reference import aspherised_dgauss
from realistic import load_lens
from realistic.errors import LensFileError, UserError
from realistic.optics.formats import BUNDLED_LENSES, WRITERS, format_lens, parse_text
from realistic.optics.formats.codev import parse_codev
from realistic.optics.formats.json_lens import parse_json_lens
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.paraxial import paraxial_data


def assert_same_lens(a, b, rel=1e-12):
    """Every surface value equal to ``rel`` (1e-12 is the issue's round-trip tolerance)."""
    assert a.stop == b.stop and a.surface_count == b.surface_count
    for attr in ("radius_mm", "thickness_mm", "index_d", "abbe_v", "aperture_mm", "conic", "aspheric_coefficients"):
        x, y = getattr(a, attr), getattr(b, attr)
        assert np.array_equal(np.isinf(x), np.isinf(y)), attr
        finite = np.isfinite(x)
        np.testing.assert_allclose(x[finite], y[finite], rtol=rel, atol=0, err_msg=attr)


def aspheric_lens():
    """The aspherised double Gauss, with coefficients up to r^16 (all Zemax's EVENASPH holds)."""
    lens = aspherised_dgauss()
    coefficients = lens.aspheric_coefficients.copy()
    coefficients[0, 2:7] = (1.5e-11, -2e-14, 3e-17, -1e-20, 2e-23)
    return dataclasses.replace(lens, aspheric_coefficients=coefficients)


@pytest.mark.parametrize("suffix", list(WRITERS))
@pytest.mark.parametrize("name", list(BUNDLED_LENSES))
def test_bundled_lenses_round_trip_through_every_format(name, suffix):
    lens = load_lens(name)
    if suffix == ".dat" and lens.aspheric.any():
        pytest.skip(".dat has no columns for aspheres (the refusal is tested below)")
    if suffix == ".seq" and lens.index_d.max() >= 2:
        pytest.skip("a CODE V fictitious glass code holds indices below 2 only (the refusal is tested below)")
    back = parse_text(format_lens(lens, suffix), f"x{suffix}", suffix) if suffix != ".zmx" else \
        parse_zmx(format_lens(lens, suffix), "x.zmx")
    assert_same_lens(lens, back)


@pytest.mark.parametrize("suffix", [".json", ".zmx", ".seq"])
def test_aspheric_lens_round_trips_and_traces_alike(suffix):
    lens = aspheric_lens()
    text = format_lens(lens, suffix)
    back = parse_zmx(text, "x.zmx") if suffix == ".zmx" else parse_text(text, f"x{suffix}", suffix)
    assert_same_lens(lens, back)
    assert back.asphere_count == 2
    assert paraxial_data(back).efl_mm == pytest.approx(paraxial_data(lens).efl_mm, rel=1e-12)


def test_formats_that_cannot_hold_a_lens_refuse_it():
    with pytest.raises(UserError, match="aspheric"):
        format_lens(aspheric_lens(), ".dat")
    lens = aspheric_lens()
    lens.aspheric_coefficients[0, 8] = 1e-30  # an r^20 term
    with pytest.raises(UserError, match="EVENASPH"):
        format_lens(lens, ".zmx")
    with pytest.raises(UserError, match="use one of"):
        format_lens(lens, ".txt")
    with pytest.raises(UserError, match="CODE V glass code"):
        format_lens(load_lens("canon-rf50-f1.2"), ".seq")  # n_d 2.001


def iset_json(lens) -> str:
    """``lens`` written as isetlens writes its data/lens/*.json: ior 0 at the stop, 1 for air, the
    semi-aperture, the last thickness the film gap, and no dispersion."""
    surfaces = [{"radius": float(r), "thickness": float(t), "ior": 0 if i == lens.stop else float(n),
                 "semi_aperture": float(a) / 2}
                for i, (r, t, n, a) in enumerate(zip(lens.radius_mm, lens.thickness_mm, lens.index_d,
                                                     lens.aperture_mm))]
    return json.dumps({"name": "dgauss.22deg.50.0mm", "description": " Description: multi element lens ",
                       "type": "multi element lens", "surfaces": surfaces}, indent=1)


def test_isetlens_json_layout_reads_as_the_same_lens():
    lens = load_lens("dgauss")
    back = parse_json_lens(iset_json(lens), "d.json")
    assert back.name == "dgauss.22deg.50.0mm"
    assert paraxial_data(back).efl_mm == pytest.approx(paraxial_data(lens).efl_mm, rel=1e-12)
    np.testing.assert_array_equal(back.aperture_mm, lens.aperture_mm)
    assert not back.has_dispersion


def test_omni_pairs_and_spectral_ior_are_read_when_symmetric():
    lens = load_lens("dgauss")
    document = json.loads(iset_json(lens))
    document["surfaces"][0]["radius"] = [29.475, 29.475]
    document["surfaces"][0]["conic_constant"] = [0, 0]
    document["surfaces"][0]["ior"] = [[400, 500, 600], [1.67, 1.67, 1.67]]
    document["surfaces"][0]["transform"] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]]
    back = parse_json_lens(json.dumps(document), "d.json")
    assert back.radius_mm[0] == 29.475 and back.index_d[0] == 1.67


@pytest.mark.parametrize("edit, fragment", [
    (lambda s: s.update(radius=[29.0, 30.0]), "anamorphic"),
    (lambda s: s.update(ior=[[400, 600], [1.6, 1.7]]), "per-wavelength"),
    (lambda s: s.update(conic_constnt=-1), "unknown surface key 'conic_constnt'"),
    (lambda s: s.pop("semi_aperture"), "no 'semi_aperture'"),
    (lambda s: s.update(transform=[[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 2]]), "transform"),
    (lambda s: s.update(thickness="3"), "thickness must be a number"),
    (lambda s: s.update(aspheric_coefficients=[1e-5] * 10), "at most 9"),
])
def test_json_errors_name_the_line_of_the_surface(edit, fragment):
    document = json.loads(iset_json(load_lens("dgauss")))
    edit(document["surfaces"][3])
    text = json.dumps(document, indent=1)
    starts = [i + 1 for i, row in enumerate(text.splitlines()) if row == "  {"]  # each surface's "{"
    with pytest.raises(LensFileError) as err:
        parse_json_lens(text, "d.json")
    assert err.value.line == starts[3]
    assert fragment in str(err.value)


def test_json_syntax_errors_name_their_line():
    with pytest.raises(LensFileError) as err:
        parse_json_lens('{\n "surfaces": [\n  {"radius": 1,,}\n ]\n}', "d.json")
    assert err.value.line == 3


EVENASPH_ZMX = """MODE SEQ
UNIT CM X W X CM MR CPMM
SURF 0
  CURV 0.0
  DISZ INFINITY
SURF 1
  STOP
  CURV 0.0
  DISZ 0.2
  DIAM 0.5
SURF 2
  TYPE EVENASPH
  CURV 0.1
  CONI -2.3
  PARM 1 0
  PARM 2 -1.0E-3
  PARM 3 2.0E-5
  DISZ 0.5
  GLAS ___BLANK 1 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 0.8
SURF 3
  CURV 0.0
  DISZ 2.0
  DIAM 0.8
SURF 4
  CURV 0.0
  DIAM 1
"""


def test_zemax_evenasph_coefficients_convert_from_lens_units():
    """PARM n is the coefficient of r^(2n) in unit^(1-2n): in cm, A4 (mm) = PARM 2 x 10^-3."""
    lens = parse_zmx(EVENASPH_ZMX, "a.zmx")
    assert lens.radius_mm[1] == pytest.approx(100.0) and lens.conic[1] == -2.3
    assert lens.aspheric_coefficients[1, 0] == pytest.approx(-1.0e-3 * 10.0**-3)
    assert lens.aspheric_coefficients[1, 1] == pytest.approx(2.0e-5 * 10.0**-5)
    # the sag at the rim is the same length whichever unit the file used
    from realistic.optics.asphere import sag_mm
    sag_cm = sag_mm(np.array([0.8**2]), 0.1, -2.3, np.array([-1.0e-3, 2.0e-5] + [0.0] * 7))[0]
    sag = sag_mm(np.array([8.0**2]), 1 / lens.radius_mm[1], lens.conic[1], lens.aspheric_coefficients[1])[0]
    assert sag == pytest.approx(10 * sag_cm, rel=1e-12)


def test_zemax_r2_term_is_refused_with_its_line():
    text = EVENASPH_ZMX.replace("PARM 1 0", "PARM 1 0.01")
    with pytest.raises(LensFileError) as err:
        parse_zmx(text, "a.zmx")
    assert err.value.line == text.splitlines().index("  PARM 1 0.01") + 1 and "r^2" in str(err.value)


CODEV = """! a singlet with a hyperbolic rear face
RDM; DIM C; TIT 'test singlet'
WL 587.56; REF 1
SO 0 1e20
S 0 0.2
  STO
  CIR 0.5
S 0 0.6 516800.6417
  CIR 0.8
S -3.0 5.8
  ASP
  K -2.3
  A 1.0E-4; B -2.0E-6
  CIR 0.8
SI 0 0.1
GO
"""


def test_codev_reads_units_glass_codes_aspheres_and_defocus():
    lens = parse_codev(CODEV, "s.seq")
    assert lens.stop == 0 and math.isinf(lens.radius_mm[1]) and lens.radius_mm[2] == pytest.approx(-30.0)
    assert lens.index_d[1] == 1.5168 and lens.abbe_v[1] == 64.17
    assert lens.conic[2] == -2.3
    assert lens.aspheric_coefficients[2, 0] == pytest.approx(1.0e-4 * 10.0**-3)
    assert lens.aspheric_coefficients[2, 1] == pytest.approx(-2.0e-6 * 10.0**-5)
    assert lens.thickness_mm[-1] == pytest.approx(59.0)  # 5.8 cm to SI plus 0.1 cm defocus
    assert lens.aperture_mm[1] == pytest.approx(16.0) and lens.description == "test singlet"


@pytest.mark.parametrize("old, new, fragment", [
    ("S 0 0.6 516800.6417", "S 0 0.6 'N-BK77_SCHOTT'", "none of the catalogues"),
    ("S 0 0.6 516800.6417", "S 0 0.6 REFL", "mirror"),
    ("  A 1.0E-4; B -2.0E-6", "  XDE 0.1", "decentres"),
    ("  A 1.0E-4; B -2.0E-6", "  REX 1.0", "non-circular"),
    ("  A 1.0E-4; B -2.0E-6", "  XTO", "surface shape"),
    ("  A 1.0E-4; B -2.0E-6", "  A abc", "not a finite number"),
    ("  A 1.0E-4; B -2.0E-6", "  THI S2 PIM", "qualifiers"),
    ("  CIR 0.8\nSI", "SI", "no clear aperture"),
    ("RDM; DIM C", "DIM C", "RDM"),
])
def test_codev_refuses_what_it_cannot_model_with_file_and_line(old, new, fragment):
    text = CODEV.replace(old, new, 1)
    with pytest.raises(LensFileError) as err:
        parse_codev(text, "s.seq")
    assert fragment in str(err.value) and err.value.line is not None
    assert "\n" not in str(err.value)


def test_cli_convert_round_trips_through_every_format(tmp_path):
    source = tmp_path / "a.json"
    source.write_text(format_lens(aspheric_lens(), ".json"))
    chain = [source, tmp_path / "b.seq", tmp_path / "c.zmx", tmp_path / "d.json"]
    for src, dst in zip(chain, chain[1:]):
        run = subprocess.run([sys.executable, "-m", "realistic", "lens", "convert", str(src), str(dst)],
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
    assert_same_lens(aspheric_lens(), load_lens(str(chain[-1])))
    bad = subprocess.run([sys.executable, "-m", "realistic", "lens", "convert", str(source), str(tmp_path / "x.dat")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "aspheric" in bad.stderr
