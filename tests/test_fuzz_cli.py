"""Property-based tests of the command line's value parsing: whatever the text, the outcome is a
value within the documented limits or one UserError line (exit 2), never another exception."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from realistic.camera.exposure import parse_shutter
from realistic.cli import main
from realistic.cli.values import parse_pixel, parse_resolution, parse_spp_list, parse_vector
from realistic.core import validation
from realistic.errors import UserError
from realistic.renderer.memory import parse_size

#: Text that looks like the values users type, and text that does not.
NUMBERISH = st.text(alphabet="0123456789.,x-+eE naifINF/ ", max_size=24)
ANY_TEXT = st.one_of(NUMBERISH, st.text(max_size=24))


def outcome(parse, text):
    try:
        return parse(text)
    except UserError as err:
        assert "\n" not in str(err)
        return None


@given(ANY_TEXT)
def test_resolution_parses_within_the_limits_or_refuses(text):
    value = outcome(parse_resolution, text)
    if value is not None:
        width, height = value
        assert 1 <= width <= validation.MAX_IMAGE_SIDE and 1 <= height <= validation.MAX_IMAGE_SIDE


@given(ANY_TEXT)
def test_spp_lists_parse_within_the_limits_or_refuse(text):
    value = outcome(parse_spp_list, text)
    assert value is None or all(1 <= spp <= validation.MAX_SPP for spp in value)


@given(ANY_TEXT)
def test_vectors_pixels_shutters_and_sizes_parse_or_refuse(text):
    vector = outcome(lambda t: parse_vector(t, "target"), text)
    assert vector is None or (vector.shape == (3,) and all(abs(v) < float("inf") for v in vector))
    outcome(parse_pixel, text)
    shutter = outcome(parse_shutter, text)
    assert shutter is None or shutter > 0
    size = outcome(parse_size, text)
    assert size is None or size >= 0


OPTIONS = ["--res", "--spp", "--seed", "--blades", "--blade-rotation", "--blade-curvature", "--exposure",
           "--aperture", "--fstop", "--focus", "--film-diagonal", "--light-samples", "--iso", "--shutter",
           "--max-memory", "--camera-pos", "--target", "--focus-on", "--lens-sampling", "--dispersion", "--threads"]


@given(st.lists(st.tuples(st.sampled_from(OPTIONS), ANY_TEXT), max_size=4))
def test_render_options_are_accepted_or_refused_in_one_line(tmp_path_factory, capsys, options):
    # the output is no image type a render writes, so a command line that passes every check stops there
    out = tmp_path_factory.mktemp("out") / "x.tif"
    argv = ["render", *[part for option, value in options for part in (option, value)], "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("realistic: error:") and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.parametrize("command", [["lens", "info"], ["lens", "plot"], ["bench"]])
@given(text=st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789-./", min_size=1, max_size=12))
def test_other_commands_refuse_bad_values_in_one_line(tmp_path_factory, capsys, command, text):
    folder = tmp_path_factory.mktemp("cmd")
    extra = {"lens": ["--wavelength", text], "bench": ["--spp", text, "--plot", str(folder / "p.txt"),
                                                       "--res", text]}[command[0]]
    argv = [*command, *(["nosuchlens"] if command[0] == "lens" else []), *extra]
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("realistic: error:") and err.count("\n") == 1, err
