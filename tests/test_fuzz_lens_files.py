"""Property-based tests of the lens file readers: whatever the bytes, reading a lens either gives a
lens that obeys the model's rules or raises a one-line UserError naming the file; nothing else."""

import math
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from realistic.errors import UserError
from realistic.optics.formats import load_lens
from realistic.optics.formats.pbrt_dat import parse_prescription
from realistic.optics.formats.zemax import decode_zmx, parse_zmx
from realistic.optics.lens import MAX_SURFACES, LensSystem
from realistic.optics.paraxial import paraxial_data


def check_lens(lens: LensSystem) -> None:
    """The rules every lens a reader returns obeys (``realistic.optics.lens.build_lens``)."""
    n = lens.surface_count
    assert 1 <= n <= MAX_SURFACES
    assert lens.radius_mm[lens.stop] == 0 and np.count_nonzero(lens.radius_mm == 0) == 1
    assert np.all(lens.thickness_mm >= 0)  # 0 between surfaces that touch at the vertex only (build_lens)
    assert np.all(np.isfinite(lens.thickness_mm)) and np.all(np.isfinite(lens.aperture_mm))
    assert np.all(lens.aperture_mm > 0) and np.all(lens.index_d >= 1)
    assert not np.any(np.isnan(lens.radius_mm))


def check_paraxial(lens: LensSystem) -> None:
    """First-order data of a valid lens is finite, or a UserError that names the lens."""
    try:
        data = paraxial_data(lens)
    except UserError as err:
        assert str(err).startswith(f"{lens.source}: ") and "\n" not in str(err)
        return
    assert all(math.isfinite(v) for v in data.as_dict().values())


def check_error(err: UserError, path: str) -> None:
    message = str(err)
    assert message.startswith(f"{path}:") or message.startswith(f"{path} ")
    assert "\n" not in message


# ---- pbrt-style .dat prescriptions ---------------------------------------------------------------

NUMBERS = st.one_of(st.integers(-300, 300).map(str),
                    st.floats(-500, 500, allow_nan=False).map(lambda x: f"{x:.6g}"),
                    st.floats(allow_nan=True, allow_infinity=True).map(repr),
                    st.sampled_from(["0", "1", "1.5", "inf", "-inf", "Infinity", "nan", "1e400", "-0", ".5", "5."]))
FIELDS = st.one_of(NUMBERS, st.sampled_from(["", "abc", "radius", "n_d", "#", "# note", "1,5", "--", "0x10"]))
SEPARATORS = st.sampled_from([" ", "\t", "  ", " \t ", "\t\t"])
ENDINGS = st.sampled_from(["\n", "\r\n", "\r"])


@st.composite
def junk_rows(draw):
    fields = draw(st.lists(FIELDS, min_size=3, max_size=6))
    row = draw(SEPARATORS).join(fields)
    if draw(st.booleans()):
        row += " # " + draw(st.text(max_size=10).map(lambda t: t.replace("\n", " ").replace("\r", " ")))
    return row


@st.composite
def lens_rows(draw):
    """Rows of a lens that is often valid: glass elements and one stop, all in air where it must be."""
    count = draw(st.integers(1, 8))
    stop = draw(st.integers(0, count))
    rows = []
    for i in range(count + 1):
        if i == stop:
            rows.append(f"0 {draw(st.floats(0.1, 10)):.4g} 0 {draw(st.floats(1, 20)):.4g}")
            continue
        radius = draw(st.sampled_from([-1, 1])) * draw(st.floats(15, 300))
        index = draw(st.sampled_from(["1", "0", "1.5168", "1.7", "1.9"]))
        rows.append(f"{radius:.5g} {draw(st.floats(0.1, 20)):.4g} {index} {draw(st.floats(1, 25)):.4g}")
    return rows


@st.composite
def prescriptions(draw):
    rows = draw(st.one_of(lens_rows(), st.lists(junk_rows(), max_size=8)))
    mixed = list(rows)
    for _ in range(draw(st.integers(0, 2))):
        mixed.insert(draw(st.integers(0, len(mixed))), draw(st.one_of(junk_rows(), st.just(""),
                                                                       st.just("# comment"))))
    ending = draw(ENDINGS)
    return ending.join(mixed) + draw(st.sampled_from(["", ending]))


@given(prescriptions())
def test_prescription_text_gives_a_valid_lens_or_a_lens_file_error(text):
    try:
        lens = parse_prescription(text, "fuzz.dat")
    except UserError as err:
        check_error(err, "fuzz.dat")
        return
    check_lens(lens)
    check_paraxial(lens)


@given(lens_rows(), ENDINGS)
def test_plausible_lenses_parse_alike_with_any_line_ending(rows, ending):
    text = "\n".join(rows) + "\n"
    try:
        reference = parse_prescription(text, "a.dat")
    except UserError:
        return
    other = parse_prescription(text.replace("\n", ending), "a.dat")
    np.testing.assert_array_equal(reference.radius_mm, other.radius_mm)
    np.testing.assert_array_equal(reference.thickness_mm, other.thickness_mm)
    check_paraxial(reference)


# ---- Zemax .zmx ----------------------------------------------------------------------------------

ZMX_VALUES = st.one_of(st.floats(-1, 1, allow_nan=False).map(lambda x: f"{x:.6g}"),
                       st.sampled_from(["0", "INFINITY", "-INFINITY", "nan", "1e400", "abc", "", "1_0"]))


@st.composite
def zmx_lines(draw):
    keyword = draw(st.sampled_from(["SURF", "TYPE", "CURV", "DISZ", "GLAS", "DIAM", "STOP", "CLAP", "CONI",
                                    "UNIT", "MODE", "SCBD", "OBSC", "COMM", "FLOA"]))
    if keyword == "SURF":
        return f"SURF {draw(st.one_of(st.integers(-1, 12).map(str), ZMX_VALUES))}"
    if keyword == "TYPE":
        return f"  TYPE {draw(st.sampled_from(['STANDARD', 'EVENASPH', 'COORDBRK', '']))}"
    if keyword == "GLAS":
        name = draw(st.sampled_from(["___BLANK", "AIR", "N-BK7", "MIRROR", ""]))
        rest = " ".join(draw(st.lists(ZMX_VALUES, max_size=6)))
        return f"  GLAS {name} {rest}"
    if keyword == "UNIT":
        return f"UNIT {draw(st.sampled_from(['MM', 'CM', 'IN', 'METER', 'FT', '']))} X W X CM MR CPMM"
    if keyword == "MODE":
        return f"MODE {draw(st.sampled_from(['SEQ', 'NSC', '']))}"
    return f"  {keyword} " + " ".join(draw(st.lists(ZMX_VALUES, max_size=3)))


@st.composite
def zmx_lenses(draw):
    """A sequential file of object, lens and image surfaces with random values (often valid)."""
    count = draw(st.integers(1, 6))
    stop = draw(st.integers(1, count + 1))
    lines = [draw(st.sampled_from(["", "MODE SEQ", "UNIT MM X W X CM MR CPMM", "UNIT IN"])),
             "SURF 0", "  TYPE STANDARD", "  CURV 0", "  DISZ INFINITY"]
    for number in range(1, count + 2):
        lines += [f"SURF {number}", "  TYPE STANDARD"]
        if number == stop:
            lines += ["  STOP", "  CURV 0"]
            glass = "AIR"
        else:
            lines.append(f"  CURV {draw(st.floats(-0.06, 0.06)):.6g}")
            glass = draw(st.sampled_from(["AIR", "___BLANK 1 0 1.5168 64.17 0 0 0", "N-SF5 0 0 1.673 32.2"]))
        lines += [f"  DISZ {draw(st.floats(0.1, 20)):.5g}", f"  GLAS {glass}",
                  f"  DIAM {draw(st.floats(0.5, 12)):.4g}"]
    lines += [f"SURF {count + 2}", "  TYPE STANDARD", "  CURV 0", "  DIAM 20"]
    for _ in range(draw(st.integers(0, 3))):
        lines.insert(draw(st.integers(0, len(lines))), draw(zmx_lines()))
    return "\n".join(lines) + "\n"


def read_zmx(data: bytes, path: str = "fuzz.zmx") -> None:
    try:
        lens = parse_zmx(decode_zmx(data, path), path)
    except UserError as err:
        check_error(err, path)
        return
    check_lens(lens)
    check_paraxial(lens)


@given(st.one_of(zmx_lenses(), st.lists(zmx_lines(), max_size=25).map("\n".join)),
       st.sampled_from(["utf-8", "utf-16", "utf-16-le", "latin-1"]))
def test_zmx_text_gives_a_valid_lens_or_a_lens_file_error(text, encoding):
    read_zmx(text.encode(encoding, errors="replace"))


@given(st.binary(max_size=400))
def test_zmx_bytes_give_a_valid_lens_or_a_lens_file_error(data):
    read_zmx(data)


# ---- load_lens on files --------------------------------------------------------------------------

@given(st.one_of(st.binary(max_size=300), prescriptions().map(str.encode), zmx_lenses().map(str.encode)),
       st.sampled_from([".dat", ".zmx", ".DAT", ".ZMX", ".txt", ""]))
def test_load_lens_on_any_file_gives_a_lens_or_a_user_error(data, suffix):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"lens{suffix}"
        path.write_bytes(data)
        try:
            lens = load_lens(str(path))
        except UserError as err:
            check_error(err, str(path))
            return
        check_lens(lens)
        assert lens.source == str(path)
