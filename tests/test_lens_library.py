"""The bundled lens library: each prescription against the values its published source states."""

import json
import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.cli import main
from realistic.cli.lens_judge import parse_fields
from realistic.errors import UserError
from realistic.optics.formats import BUNDLED_LENSES, bundled_lens_files, load_lens
from realistic.optics.library import element_count, image_circle_mm, read_library_lens
from realistic.optics.paraxial import paraxial_data

#: (library name, stated EFL mm, stated f-number, stated full angle of view deg, stop, source: the patent
#: number or book as the file's header names it).
#: stop "published": the source's stop diameter; "resized": set to the stated f-number (the header
#: says by how much), so there the f-number check holds by construction and the EFL check does not.
STATED = [
    ("cooke.triplet.101mm", 101.181, 1 / (2 * 0.1443), 2 * 11.86, "published", "Modern Optical Engineering"),
    ("tessar.100mm", 100.0, 3.5, 44.0, "published", "2,084,714"),
    ("wide.28mm-f3.5", 28.0, 3.5, 75.0, "published", "2,645,974"),
    ("gauss.50mm-f0.95", 51.6, 0.95, 45.0, "published", "S39-010178"),
    ("gauss.52mm-f2", 52.0, 2.0, 45.0, "published", "4,123,144"),
    ("gauss.60mm-f1.3", 60.0, 1.3, 42.0, "published", "S29-002028"),
    ("longfocus.200mm", 200.0, 1.86, 12.3, "published", "H01-102413"),
    ("apo.180mm", 180.0, 2.3, 12.36, "published", "4,726,669"),
    ("gauss.35mm-f1.8", 35.0, 1.8, 60.0, "resized", "2,854,890"),
    ("gauss.35mm-f2", 35.0, 2.0, 63.0, "resized", "H05-164961"),
    ("retrofocus.28mm-f3.5", 28.0, 3.5, 75.0, "resized", "2,696,758"),
    ("retrofocus.28mm-f2.8", 28.0, 2.8, 76.0, "resized", "4,046,459"),
    ("telephoto.300mm-f2.8", 300.0, 2.8, 8.24, "resized", "S56-159613"),
    ("telephoto.300mm-f2.9", 293.44373, 2.9, 8.4, "resized", "6,288,845"),
    ("macro.35mm-f2", 36.08, 2.01, 42.56, "resized", "2026-008235"),
    ("zoom.70-200mm-72", 72.10, 2.923, 33.4, "resized", "5,537,259"),
    ("zoom.70-200mm-135", 135.00, 2.923, 18.2, "resized", "5,537,259"),
    ("zoom.70-200mm-194", 194.01, 2.923, 12.72, "resized", "5,537,259"),
]


def test_every_new_library_file_has_a_row_and_every_row_a_file():
    assert set(bundled_lens_files()) - set(BUNDLED_LENSES) == {row[0] for row in STATED}


@pytest.mark.parametrize("name, efl, f_number, angle, stop, source", STATED, ids=[r[0] for r in STATED])
def test_paraxial_efl_and_f_number_match_the_source(name, efl, f_number, angle, stop, source):
    lens, header = read_library_lens(name)
    para = paraxial_data(lens)
    assert para.efl_mm == pytest.approx(efl, rel=0.01)
    assert para.f_number == pytest.approx(f_number, rel=0.01)
    assert source in header
    resized = re.search(r"\(x (\d+\.\d+)\)", header)
    assert (resized is not None) == (stop == "resized")
    if resized:  # a small correction of the published stop, not a different lens
        assert abs(float(resized.group(1)) - 1) < 0.05


@pytest.mark.parametrize("name, efl, f_number, angle, stop, source", STATED, ids=[r[0] for r in STATED])
def test_image_circle_covers_the_stated_angle_of_view(name, efl, f_number, angle, stop, source):
    lens, _ = read_library_lens(name)
    coverage = 2 * efl * math.tan(math.radians(angle / 2))
    assert image_circle_mm(lens, points=25, samples=2000) >= 0.9 * coverage


def test_element_count_counts_cemented_elements_separately():
    lens, _ = read_library_lens("zoom.70-200mm-135")
    assert element_count(lens) == 18  # counted by hand in the source table (three of them cemented pairs)
    assert element_count(read_library_lens("tessar.100mm")[0]) == 4


def test_lens_list_json_reports_every_library_lens(capsys):
    assert main(["lens", "list", "--json"]) == 0
    entries = json.loads(capsys.readouterr().out)
    assert [e["name"] for e in entries] == list(bundled_lens_files())
    for e in entries:
        assert e["focal_length_mm"] > 0 and e["f_number"] > 0 and e["image_circle_mm"] > 0
        assert e["elements"] >= 1 and (e["aspheres"] > 0) == e["file"].endswith(".json") and e["source"]


@given(st.text(max_size=40))
def test_field_lists_parse_or_fail_with_one_line(text):
    try:
        values = parse_fields(text)
    except UserError as err:
        assert "\n" not in str(err)
    else:
        assert values and all(abs(v) < 90 for v in values)


def test_an_unknown_lens_name_lists_the_library():
    with pytest.raises(UserError, match="not a bundled lens name .*tessar.100mm"):
        load_lens("no-such-lens")
    assert load_lens("tessar.100mm").name == "tessar.100mm"
