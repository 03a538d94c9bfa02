"""Numbers, text and files at the lens boundary (issue 32): every lens value in every format within
what float32 kernels hold and what a lens can be; JSON that overflows, is not UTF-8 or nests too
deep; names that carry escape sequences or newlines; FIFOs and directories where a file is expected.
Each named case failed on f91acd8 (a traceback, a hang, an injected row or raw escapes)."""

import dataclasses
import json
import math
import os
import unicodedata
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.cli import main
from realistic.errors import LensFileError, UserError
from realistic.optics.formats import format_lens, load_lens
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.lens import LensSystem, build_lens
from realistic.optics.paraxial import paraxial_data
from realistic.optics.ray_json import read_rays
from realistic.optics.tracer import trace_from_film

FORMATS = (".dat", ".json", ".zmx", ".seq")


def one_line(err: BaseException, path: Path | str) -> str:
    message = str(err)
    assert message.startswith(str(path)) and "\n" not in message, message
    return message


def _with(lens: LensSystem, **changes: object) -> LensSystem:
    """``lens`` with surface 0's radius, conic or A4 replaced (the writers print them exactly)."""
    radius, conic, coefficients = lens.radius_mm.copy(), lens.conic.copy(), lens.aspheric_coefficients.copy()
    radius[0] = changes.get("radius", radius[0])
    conic[0] = changes.get("conic", conic[0])
    coefficients[0, 0] = changes.get("a4", coefficients[0, 0])
    return dataclasses.replace(lens, radius_mm=radius, conic=conic, aspheric_coefficients=coefficients)


@pytest.mark.parametrize("suffix", FORMATS)
@pytest.mark.parametrize("change,words", [
    ({"radius": 1e39}, "radius 1e+39 mm is out of range"),
    ({"radius": 1e308}, "radius 1e+308 mm is out of range"),
    ({"radius": -1e39}, "radius -1e+39 mm is out of range"),
    ({"conic": -1e300}, "conic constant -1e+300 is out of range"),
    ({"a4": 1e30}, "aspheric coefficient A4 1e+30 is out of range"),
])
def test_values_beyond_float32_or_reason_are_one_line_in_every_format(tmp_path, suffix, change, words):
    """A finite value beyond float32 reached the OpenCL kernel as ``inff`` (a build traceback);
    the same check now refuses it whichever format carried it."""
    if suffix == ".dat" and ("conic" in change or "a4" in change):
        pytest.skip(".dat has no columns for aspheres")
    path = tmp_path / f"lens{suffix}"
    path.write_text(format_lens(_with(load_lens("dgauss"), **change), suffix))
    with pytest.raises(LensFileError) as err:
        load_lens(path)
    assert words in one_line(err.value, path)


ZMX_FLAT = """MODE SEQ
UNIT MM X W X CM MR CPMM
SURF 0
  CURV 0.0
  DISZ INFINITY
SURF 1
  STOP
  CURV 0.0
  DISZ 2
  DIAM 5
SURF 2
  TYPE EVENASPH
  CURV {curv}
  PARM 2 {parm}
  DISZ 5
  GLAS ___BLANK 1 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 8
SURF 3
  CURV -0.02
  DISZ 40
  DIAM 8
SURF 4
  CURV 0.0
  DIAM 10
"""


@pytest.mark.parametrize("curv,parm,words", [("1e-40", "0", "radius 1e+40 mm is out of range"),
                                             ("0.01", "1e300", "aspheric coefficient A4 1e+300 is out of range")])
def test_zemax_curvature_and_parm_extremes(curv, parm, words):
    with pytest.raises(LensFileError) as err:
        parse_zmx(ZMX_FLAT.format(curv=curv, parm=parm), "x.zmx")
    assert words in one_line(err.value, "x.zmx")


FLOAT32_MAX = float(np.finfo(np.float32).max)
EXTREME = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.sampled_from(
    [1e39, -1e39, 1e-40, 1e308, -1e300, 1e-300, 5e-324, 3.5e38, 1e12, 1e6, 1e-9, 1.0, 0.0]))


@given(column=st.integers(0, 6), value=EXTREME)
def test_every_accepted_value_fits_float32_kernels(column, value):
    """Whatever single value replaces one of a lens's quantities, ``build_lens`` refuses it in one line
    or every number the kernel is built from is a finite float32 (a radius may be inf: flat)."""
    lens = load_lens("dgauss")
    rows = [list(map(float, v)) for v in (lens.radius_mm, lens.thickness_mm, lens.index_d, lens.abbe_v,
                                          lens.aperture_mm, lens.conic)]
    coefficients = [[0.0] for _ in range(lens.surface_count)]
    if column == 6:
        coefficients[0] = [value]
    else:
        rows[column][0] = value
    try:
        built = build_lens("f.dat", list(range(1, lens.surface_count + 1)), *rows[:5], conic=rows[5],
                           coefficients=coefficients)
    except LensFileError as err:
        one_line(err, "f.dat")
        return
    with np.errstate(over="ignore"):
        semi = np.float32(built.aperture_mm / 2)
        values = [built.thickness_mm, built.index_d, built.abbe_v, built.conic, built.aspheric_coefficients,
                  semi * semi, built.radius_mm[np.isfinite(built.radius_mm)]]
        assert all(np.all(np.isfinite(np.asarray(v, np.float32))) for v in values)
    assert np.all(np.asarray(built.aperture_mm, np.float32) > 0)


# ---- JSON documents: lens files and lens trace's rays ----------------------------------------------

def _lens_json(radius_text: str) -> str:
    lens = json.loads(format_lens(load_lens("dgauss"), ".json"))
    lens["surfaces"][0]["radius"] = "RADIUS"
    return json.dumps(lens, indent=1).replace('"RADIUS"', radius_text)


RAYS = '{"rays": [{"origin": [0, 0, 0], "direction": DIRECTION}]}'
BAD_JSON = [("9" * 400, "beyond a double's range"), ("9" * 5000, "beyond a double's range"),
            ("1e400", "beyond a double's range"), ("[" * 100_000 + "]" * 100_000, "nested too deeply")]


@pytest.mark.parametrize("literal,words", BAD_JSON)
def test_lens_json_numbers_and_nesting(tmp_path, literal, words):
    """400 and 5000 digits gave OverflowError and ValueError tracebacks."""
    path = tmp_path / "l.json"
    path.write_text(_lens_json(literal))
    with pytest.raises(UserError) as err:
        load_lens(path)
    assert words in one_line(err.value, path)


@pytest.mark.parametrize("literal,words", BAD_JSON)
def test_rays_json_numbers_and_nesting(tmp_path, literal, words):
    """400 and 5000 digits and 100000-deep arrays gave OverflowError, ValueError and RecursionError."""
    path = tmp_path / "r.json"
    path.write_text(RAYS.replace("DIRECTION", f"[0, 0, {literal}]"))
    with pytest.raises(UserError) as err:
        read_rays(str(path))
    assert words in one_line(err.value, path)


@pytest.mark.parametrize("kind", ["lens", "rays"])
def test_json_that_is_not_utf8_names_the_line(tmp_path, kind):
    """Non-UTF-8 bytes in a rays file gave a UnicodeDecodeError traceback."""
    path = tmp_path / f"{kind}.json"
    text = _lens_json("1e3") if kind == "lens" else RAYS.replace("DIRECTION", "[0, 0, 1]")
    path.write_bytes(b"\n" + text.encode().replace(b"{", b'{"x\xff": 1, ', 1))
    with pytest.raises(UserError) as err:
        load_lens(path) if kind == "lens" else read_rays(str(path))
    assert "2: the " in one_line(err.value, path) and "is not UTF-8 text (byte 0xff)" in str(err.value)


@pytest.mark.parametrize("origin,direction,words", [
    ([1e300, 0, 0], [0, 0, 1], "lies beyond"), ([0, 0, 0], [0, 0, 0], "is the zero vector")])
def test_rays_beyond_reason_are_refused(tmp_path, origin, direction, words):
    """An origin of 1e300 mm traced with numpy overflow warnings into a silent miss."""
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"rays": [{"origin": origin, "direction": direction}]}))
    with pytest.raises(UserError) as err:
        read_rays(str(path))
    assert words in one_line(err.value, path)


@pytest.mark.parametrize("scale", [1e-300, 5e-324, 1e308])
def test_directions_of_any_length_are_normalised_exactly(tmp_path, scale):
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"rays": [{"origin": [0, 0, 0], "direction": [0, scale, scale]}]}))
    _, directions = read_rays(str(path))
    assert directions[0] == pytest.approx([0, math.sqrt(0.5), math.sqrt(0.5)], rel=1e-15)


JSON_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(), st.integers(), st.text(max_size=5),
              st.sampled_from([0, 1, -1, 1e-300, 1e300, 1e308, 5e-324])),
    lambda children: st.one_of(st.lists(children, max_size=4), st.dictionaries(st.text(max_size=3), children,
                                                                                max_size=3)),
    max_leaves=12)
VECTORS = st.one_of(st.lists(st.one_of(st.floats(), st.sampled_from([0.0, 1e-300, 1e300, -1e308])), min_size=3,
                             max_size=3), JSON_VALUES)
RAY_DOCUMENTS = st.one_of(
    JSON_VALUES,
    st.fixed_dictionaries({"rays": st.lists(st.one_of(
        st.fixed_dictionaries({"origin": VECTORS, "direction": VECTORS}), JSON_VALUES), max_size=4)}))


@given(document=RAY_DOCUMENTS, mangle=st.sampled_from(["", "digits", "bytes", "cut"]))
def test_fuzzed_rays_trace_or_are_one_line(tmp_path_factory, document, mangle):
    """``lens trace --input``: any document reads as rays that trace through the lens without a numpy
    warning (no overflow on the way), or is refused in one line naming the file."""
    path = tmp_path_factory.mktemp("rays") / "r.json"
    text = json.dumps(document)
    data = text.encode()
    if mangle == "digits":
        data = text.replace("0", "9" * 500, 1).encode()
    elif mangle == "bytes":
        data = b"\xfe" + data
    elif mangle == "cut":
        data = data[: len(data) // 2]
    path.write_bytes(data)
    try:
        origins, directions = read_rays(str(path))
    except UserError as err:
        one_line(err, path)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = trace_from_film(load_lens("dgauss"), 36.0, origins, directions)
    assert np.all(np.isfinite(result.origin[result.passed]))


# ---- text that reaches a terminal or another file --------------------------------------------------

EVIL_NAME = "evil\n1e-3\t10\t1.5\t40\nx\x1b[2J\x1b[31mRED\u202e"


def test_a_name_with_a_newline_does_not_add_rows_to_a_dat(tmp_path, capsys):
    """A lens name with a newline injected a surface row into the .dat ``lens convert`` wrote (EFL
    50.36 became 74.75 mm); escape sequences reached the terminal raw."""
    source = tmp_path / "evil.json"
    document = json.loads(format_lens(load_lens("dgauss"), ".json"))
    document["name"], document["description"] = EVIL_NAME, "line one\r\nline two\x1b]0;title\x07"
    source.write_text(json.dumps(document))
    out = tmp_path / "out.dat"
    assert main(["lens", "convert", str(source), str(out)]) == 0
    assert paraxial_data(load_lens(out)).efl_mm == pytest.approx(paraxial_data(load_lens("dgauss")).efl_mm)
    assert main(["lens", "info", str(source)]) == 0
    shown = capsys.readouterr().out
    assert "\x1b" not in shown and "\u202e" not in shown and "evil\\x0a1e-3" in shown
    lens = load_lens(source)
    assert lens.description == "line one\nline two\\x1b]0;title\\x07"


@given(name=st.text(max_size=20), description=st.text(max_size=20), suffix=st.sampled_from(FORMATS))
def test_any_name_survives_every_writer(tmp_path_factory, name, description, suffix):
    """Whatever a lens's name and description, its converted file reads back as the same lens."""
    lens = dataclasses.replace(load_lens("dgauss"), name=name, description=description)
    assert all(c in "\n\t" or not (unicodedata.category(c)[0] == "C" or unicodedata.category(c) in ("Zl", "Zp"))
               for c in lens.name + lens.description)
    assert "\n" not in lens.name
    path = tmp_path_factory.mktemp("names") / f"l{suffix}"
    path.write_text(format_lens(lens, suffix))
    again = load_lens(path)
    assert again.surface_count == lens.surface_count
    assert np.array_equal(again.thickness_mm, lens.thickness_mm)


# ---- files that are not regular files ---------------------------------------------------------------

@pytest.mark.parametrize("kind", ["fifo", "directory"])
@pytest.mark.parametrize("role", ["lens", "rays"])
def test_a_fifo_or_directory_says_so_and_does_not_block(tmp_path, capsys, kind, role):
    """``lens trace --input FIFO`` blocked forever; a directory was "cannot read: Is a directory"."""
    special = tmp_path / "special"
    os.mkfifo(special) if kind == "fifo" else special.mkdir()
    lens, rays = (str(special), "r.json") if role == "lens" else ("dgauss", str(special))
    assert main(["lens", "trace", lens, "--film-distance", "36", "--input", rays]) == 2
    err = capsys.readouterr().err
    words = "a named pipe (FIFO)" if kind == "fifo" else "a directory"
    assert err.count("\n") == 1 and f"{special}: is {words}, not a {role if role == 'rays' else 'lens'}" in err


def test_focus_far_away_is_the_focus_at_infinity():
    """``--focus 1e20`` was refused as "film distance ... got -14.25": the near root of the lens
    equation lost every digit to cancellation."""
    from realistic.optics.paraxial import film_distance_for_focus

    lens = load_lens("dgauss")
    far = film_distance_for_focus(lens, 1e20)
    assert far == pytest.approx(film_distance_for_focus(lens, math.inf), rel=1e-12)
    assert film_distance_for_focus(lens, 1e6) > film_distance_for_focus(lens, 1e7) > far
