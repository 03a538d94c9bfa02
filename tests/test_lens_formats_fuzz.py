"""Property-based tests of the JSON (``focal_length_mm`` too), CODE V and Zemax EVENASPH and PARAXIAL
readers: whatever the text, the outcome is a lens that obeys the model's rules (and traces) or a
one-line LensFileError naming the file (and for .zmx paraxial surfaces, the line); nothing else."""

from __future__ import annotations

import json
import re

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.optics.formats import format_lens
from realistic.optics.formats.codev import parse_codev
from realistic.optics.formats.json_lens import parse_json_lens
from realistic.optics.formats.zemax import parse_zmx
from realistic.optics.tracer import trace_from_film
from test_fuzz_lens_files import check_error, check_lens, check_paraxial

VALUES = st.one_of(st.floats(-60, 60, allow_nan=False), st.floats(allow_nan=True, allow_infinity=True),
                   st.integers(-3, 3), st.sampled_from([0, 1, 1.5, -1, 1e300, -1e-300]))
TEXT_VALUES = st.one_of(VALUES.map(repr), st.sampled_from(["0", "abc", "", "nan", "inf", "1e400", "'X'", "-0"]))


def check_text(parse, text: str, path: str) -> None:
    try:
        lens = parse(text, path)
    except UserError as err:
        check_error(err, path)
        return
    check_lens(lens)
    check_paraxial(lens)
    assert np.all(np.isfinite(lens.conic)) and np.all(np.isfinite(lens.aspheric_coefficients))
    film = np.zeros((16, 3))
    targets = np.column_stack([np.linspace(-3, 3, 16), np.zeros(16), np.full(16, 30.0)])
    result = trace_from_film(lens, 30.0, film, targets)
    assert np.all(np.isfinite(result.direction[result.passed]))
    for suffix in (".json", ".seq"):  # what was read can be written (or is refused in one line)
        try:
            format_lens(lens, suffix)
        except UserError as err:
            assert "\n" not in str(err)


def glass_after(draw, i: int, count: int, stop: int) -> bool:
    """Whether surface i may have glass behind it in a plausible lens (not at or before the stop, not last)."""
    return i not in (stop, stop - 1, count - 1) and draw(st.integers(0, 3)) > 0


def odd(draw, good, bad):
    """Mostly a plausible value, one time in six a hostile one."""
    return draw(bad) if draw(st.integers(0, 5)) == 0 else draw(good)


@st.composite
def json_surfaces(draw, stop: bool, glass: bool):
    surface = {"radius": 0 if stop else odd(draw, st.floats(-80, 80), st.one_of(VALUES, st.lists(VALUES, max_size=3))),
               "thickness": odd(draw, st.floats(0.1, 20), VALUES),
               "ior": 0 if stop else odd(draw, st.just(1.5168 if glass else 0), VALUES),
               "semi_aperture": odd(draw, st.floats(0.5, 15), VALUES)}
    if not stop and draw(st.booleans()):
        surface["conic_constant"] = odd(draw, st.floats(-5, 2), st.one_of(VALUES, st.lists(VALUES, max_size=2)))
    if not stop and draw(st.booleans()):
        surface["aspheric_coefficients"] = odd(draw, st.lists(st.floats(-1e-5, 1e-5), max_size=9),
                                               st.lists(VALUES, max_size=11))
    if draw(st.integers(0, 5)) == 0:
        key = draw(st.sampled_from(["abbe_number", "transform", "bogus"]))
        surface[key] = draw(st.one_of(VALUES, st.none(), st.lists(st.lists(VALUES, max_size=3), max_size=4)))
    if draw(st.integers(0, 9)) == 0:
        del surface[draw(st.sampled_from(list(surface)))]
    return surface


FOCAL_LENGTHS = st.one_of(st.floats(20, 200), st.floats(-200, -20),
                          st.lists(st.one_of(st.floats(20, 200), st.none()), min_size=2, max_size=2))
#: Any JSON value (NaN and infinities too, which Python's json reads and writes).
JSON_VALUES = st.recursive(st.one_of(st.none(), st.booleans(), VALUES, st.text(max_size=4)),
                           lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                   st.dictionaries(st.text(max_size=3), inner, max_size=2)),
                           max_leaves=5)


@st.composite
def json_paraxial_surfaces(draw):
    """An ideal thin lens in air (``focal_length_mm``), its focal length mostly plausible, one time in
    six any JSON value; sometimes with a radius or glass it may not have."""
    surface = {"radius": 0, "thickness": odd(draw, st.floats(0.1, 200), VALUES), "ior": 0,
               "semi_aperture": odd(draw, st.floats(0.5, 15), VALUES),
               "focal_length_mm": odd(draw, FOCAL_LENGTHS, JSON_VALUES)}
    if draw(st.integers(0, 9)) == 0:
        surface[draw(st.sampled_from(["radius", "ior"]))] = draw(VALUES)
    return surface


@st.composite
def json_lenses(draw):
    count = draw(st.integers(3, 6))
    stop = draw(st.integers(0, count - 1))
    surfaces = [draw(json_paraxial_surfaces()) if i != stop and draw(st.integers(0, 3)) == 0
                else draw(json_surfaces(i == stop, glass_after(draw, i, count, stop))) for i in range(count)]
    document = {"name": draw(st.one_of(st.text(max_size=5), st.none(), VALUES)), "surfaces": surfaces}
    text = json.dumps(document, indent=draw(st.sampled_from([None, 1, 2])))
    cut = draw(st.one_of(st.none(), st.none(), st.integers(0, len(text))))
    return text if cut is None else text[:cut]


JSON_ANY = st.recursive(st.one_of(st.none(), st.booleans(), VALUES, st.text(max_size=4)),
                        lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                st.dictionaries(st.sampled_from(["surfaces", "radius", "ior", "x"]),
                                                                inner, max_size=3)), max_leaves=12).map(json.dumps)


@given(st.one_of(json_lenses(), JSON_ANY, st.text(max_size=60)))
def test_json_text_gives_a_valid_lens_or_a_lens_file_error(text):
    check_text(parse_json_lens, text, "fuzz.json")


@st.composite
def codev_lines(draw):
    command = draw(st.sampled_from(["S", "SO", "SI", "STO", "CIR", "ASP", "CON", "K", "A", "B", "J", "RDM", "DIM",
                                    "THI", "RDY", "CUY", "XDE", "REX", "GO", "WL", "TIT", "CIR EDG", "CIR OBS"]))
    values = draw(st.lists(TEXT_VALUES, max_size=3))
    if command == "S" and draw(st.booleans()):
        values = values[:2] + [draw(st.sampled_from(["516800.6417", "'N-BK7'", "REFL", "7", "0.5", "1.2.3"]))]
    return " ".join([command] + values)


@st.composite
def codev_lenses(draw):
    count = draw(st.integers(3, 6))
    stop = draw(st.integers(0, count - 1))
    lines = [draw(st.sampled_from(["RDM", "RDM; DIM M", "RDM; DIM C", "RDM; DIM I"])), "SO 0 1e20"]
    for i in range(count):
        radius = 0.0 if i == stop else draw(st.floats(-80, 80))
        glass = draw(st.sampled_from([" 516800.6417", " 805180.2541"])) if glass_after(draw, i, count, stop) else ""
        lines += [f"S {radius!r} {draw(st.floats(0.1, 20))!r}{glass}", f"  CIR {draw(st.floats(0.5, 12))!r}"]
        if i == stop:
            lines.append("  STO")
        elif draw(st.booleans()):
            lines += ["  ASP", f"  K {draw(st.floats(-5, 2))!r}", f"  A {draw(st.floats(-1e-4, 1e-4))!r}"]
    lines.append("SI 0 0")
    for _ in range(draw(st.integers(0, 3))):
        lines.insert(draw(st.integers(0, len(lines))), draw(codev_lines()))
    return draw(st.sampled_from(["\n", "\r\n", "; "])).join(lines) + "\n"


@given(st.one_of(codev_lenses(), st.lists(codev_lines(), max_size=20).map("\n".join), st.text(max_size=60)))
def test_codev_text_gives_a_valid_lens_or_a_lens_file_error(text):
    check_text(parse_codev, text, "fuzz.seq")


GLASS = "___BLANK 1 0 1.5168 64.17 0 0"


@st.composite
def evenasph_lenses(draw):
    count = draw(st.integers(3, 6))
    stop = draw(st.integers(1, count))
    lines = ["MODE SEQ", draw(st.sampled_from(["UNIT MM", "UNIT CM", "UNIT IN"])), "SURF 0", "  CURV 0",
             "  DISZ INFINITY"]
    for number in range(1, count + 1):
        lines.append(f"SURF {number}")
        kind = draw(st.sampled_from(["STANDARD", "EVENASPH", "PARAXIAL", "PARAXIAL_XY"]))
        if number == stop:
            lines += ["  STOP", "  CURV 0", "  DISZ 1"]
        elif kind.startswith("PARAXIAL"):  # an ideal thin lens in air, its PARMs any number or missing
            lines += [f"  TYPE {kind}", "  CURV 0", f"  DISZ {draw(st.floats(0.1, 100))!r}", "  GLAS AIR"]
            good = st.floats(10, 200) if kind == "PARAXIAL" else st.floats(-0.1, 0.1)
            for k in draw(st.lists(st.integers(0, 3), max_size=3)):
                lines.append(f"  PARM {k} {odd(draw, good, VALUES)!r}")
        else:
            lines += [f"  TYPE {kind}",
                      f"  CURV {draw(st.floats(-0.1, 0.1))!r}", f"  CONI {draw(st.one_of(st.floats(-5, 3), VALUES))!r}",
                      f"  DISZ {draw(st.floats(0.1, 10))!r}",
                      f"  GLAS {GLASS if glass_after(draw, number - 1, count, stop - 1) else 'AIR'}"]
            for k in draw(st.lists(st.integers(0, 10), max_size=4)):
                lines.append(f"  PARM {k} {draw(st.one_of(st.floats(-1e-3, 1e-3), VALUES))!r}")
        lines.append(f"  DIAM {draw(st.floats(0.5, 10))!r}")
    lines += [f"SURF {count + 1}", "  CURV 0", "  DIAM 10"]
    return "\n".join(lines) + "\n"


@given(evenasph_lenses())
def test_zemax_evenasph_and_paraxial_text_gives_a_valid_lens_or_a_lens_file_error(text):
    try:
        parse_zmx(text, "fuzz.zmx")
    except UserError as err:
        if "PARM" in str(err) or "PARAXIAL" in str(err):
            assert re.match(r"fuzz\.zmx:\d+: ", str(err)), str(err)  # the line at fault
    check_text(parse_zmx, text, "fuzz.zmx")
