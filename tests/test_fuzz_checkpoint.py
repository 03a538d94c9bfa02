"""Checkpoints are untrusted input (issue 32): every field of an edited or damaged checkpoint is
checked on load; what loads renders on to a finite, complete image, anything else is one line."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from realistic.errors import UserError
from realistic.renderer.aov import AovLayout
from realistic.renderer.checkpoint import FORMAT, RenderIdentity, load_checkpoint, save_checkpoint
from realistic.renderer.film import Film, PassFilm, Splats
from realistic.renderer.pass_plan import plan_passes

WIDTH, HEIGHT, SPP, PASS_SAMPLES = 4, 3, 4, 6
IDENTITY = RenderIdentity(f"{WIDTH}x{HEIGHT}", 0, "s" * 64, "c" * 64, SPP, PASS_SAMPLES, "numpy", 1)
PLAN = plan_passes(WIDTH * HEIGHT, SPP, PASS_SAMPLES)


def _valid_parts() -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of a checkpoint of passes 0-2 taken and 4 and 6 waiting."""
    rng = np.random.default_rng(1)
    film = PassFilm(Film(WIDTH, HEIGHT, SPP), PLAN)
    for index in (0, 1, 2, 4, 6):
        film.add(index, PLAN[index].first_pixel, rng.random((PLAN[index].pixel_count, 3)))
    arrays = {"sums": film.film.sums, "samples": film.film.samples,
              "waiting_index": np.array(sorted(film.waiting), np.int64),
              "waiting_first_pixel": np.array([film.waiting[i][0] for i in sorted(film.waiting)], np.int64),
              **{f"waiting_{i}": film.waiting[i][1] for i in film.waiting}}
    header = {"format": FORMAT, "next_pass": film.next_pass, **IDENTITY.__dict__}
    return header, arrays


def _write(path: Path, header: dict, arrays: dict[str, np.ndarray]) -> Path:
    with path.open("wb") as handle:
        np.savez(handle, header=np.array(json.dumps(header)), **arrays)
    return path


def _loads_and_renders_on_or_refuses(path: Path) -> None:
    """The property: a one-line UserError naming the file, or a film that every remaining pass
    completes, with finite values and each pixel's spp samples."""
    try:
        film = load_checkpoint(path, IDENTITY, PLAN)
    except UserError as err:
        assert "\n" not in str(err) and str(path) in str(err), str(err)
        return
    assert np.all(np.isfinite(film.image()))
    for index in range(len(PLAN)):
        if not film.has(index):
            film.add(index, PLAN[index].first_pixel, np.ones((PLAN[index].pixel_count, 3)))
    assert film.next_pass == len(PLAN) and not film.waiting
    assert np.all(film.film.samples == SPP) and np.all(np.isfinite(film.image()))


def test_a_valid_checkpoint_loads_whole(tmp_path):
    header, arrays = _valid_parts()
    film = load_checkpoint(_write(tmp_path / "x.partial", header, arrays), IDENTITY, PLAN)
    assert film.next_pass == 3 and sorted(film.waiting) == [4, 6]
    np.testing.assert_array_equal(film.film.sums, arrays["sums"])
    film_saved = tmp_path / "y.partial"
    save_checkpoint(film_saved, IDENTITY, film)
    assert load_checkpoint(film_saved, IDENTITY, PLAN).passes_taken == 5


@pytest.mark.parametrize("change, reason", [
    (lambda h, a: a["sums"].__setitem__((0, 0), np.nan), "film sums not finite"),
    (lambda h, a: a["sums"].__setitem__((1, 2), 1e308), "film sums not finite or beyond"),
    (lambda h, a: a["samples"].__setitem__(0, -4), "sample counts are not those of its 3 passes"),
    (lambda h, a: a["samples"].__setitem__(0, 10**9), "sample counts are not those"),
    (lambda h, a: h.__setitem__("next_pass", 10**6), "pass index 1000000 is not 0 to"),
    (lambda h, a: h.__setitem__("next_pass", -1), "pass index -1"),
    (lambda h, a: h.__setitem__("next_pass", 2.0), "pass index 2.0"),
    (lambda h, a: h.__setitem__("next_pass", True), "pass index True"),
    (lambda h, a: a.__setitem__("sums", a["sums"][:-1]), "film sums of the wrong shape"),
    (lambda h, a: a.__setitem__("sums", a["sums"].astype(np.float32)), "film sums of the wrong shape or type"),
    (lambda h, a: a.__setitem__("samples", a["samples"].astype(np.float64)), "sample counts of the wrong"),
    (lambda h, a: a.__setitem__("waiting_index", np.array([4, 4], np.int64)), "out of range or repeated"),
    (lambda h, a: a.__setitem__("waiting_index", np.array([4, 10**6], np.int64)), "out of range"),
    (lambda h, a: a.__setitem__("waiting_index", np.array([2, 6], np.int64)), "out of range"),
    (lambda h, a: a.__setitem__("waiting_first_pixel", np.array([0, 0], np.int64)), "does not start at its"),
    (lambda h, a: a.__setitem__("waiting_4", a["waiting_4"][:, :2]), "waiting pass 4 of the wrong shape"),
    (lambda h, a: a["waiting_6"].__setitem__((0, 0), np.inf), "waiting pass 6 not finite"),
    (lambda h, a: a.pop("samples"), "no samples"),
    (lambda h, a: h.__setitem__("seed", "0"), "another seed"),
    (lambda h, a: h.__setitem__("seed", 0.0), "another seed"),
    (lambda h, a: h.__setitem__("spp", True), "another spp"),
    (lambda h, a: h.pop("backend"), "another backend"),
    (lambda h, a: a.__setitem__("padding", np.zeros(10**6)), "larger than a checkpoint of this film"),
])
def test_each_edited_field_is_refused_in_one_line(tmp_path, change, reason):
    header, arrays = _valid_parts()
    change(header, arrays)
    path = _write(tmp_path / "x.exr.partial", header, arrays)
    with pytest.raises(UserError) as err:
        load_checkpoint(path, IDENTITY, PLAN)
    assert reason in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)


HEADER_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=6)
DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.uint8, np.bool_, np.complex128])
ARRAYS = DTYPES.flatmap(lambda dtype: hnp.arrays(dtype, hnp.array_shapes(min_dims=0, max_dims=3, max_side=14)))
NAMES = ["sums", "samples", "waiting_index", "waiting_first_pixel", "waiting_4", "waiting_6", "waiting_3"]
SPECIAL = st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1.0, 0.0, 2.0**63, -(2.0**63), 1e30, 1e31])


@given(st.sampled_from([*IDENTITY.__dict__, "format", "next_pass", "extra"]), HEADER_VALUES)
def test_any_header_field_loads_or_is_refused_in_one_line(tmp_path_factory, name, value):
    header, arrays = _valid_parts()
    header[name] = value
    _loads_and_renders_on_or_refuses(_write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays))


@given(st.sampled_from(NAMES), ARRAYS | st.none())
def test_any_array_loads_or_is_refused_in_one_line(tmp_path_factory, name, array):
    header, arrays = _valid_parts()
    if array is None:
        arrays.pop(name, None)
    else:
        arrays[name] = array
    _loads_and_renders_on_or_refuses(_write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays))


@given(st.sampled_from(NAMES[:2] + NAMES[4:6]), st.data())
def test_any_value_in_an_array_loads_or_is_refused_in_one_line(tmp_path_factory, name, data):
    header, arrays = _valid_parts()
    array = arrays[name]
    flat = array.reshape(-1)
    position = data.draw(st.integers(0, flat.size - 1))
    special = data.draw(SPECIAL)
    if array.dtype.kind == "f":
        flat[position] = special
    elif np.isfinite(special) and abs(special) < 2**62:
        flat[position] = int(special)
    _loads_and_renders_on_or_refuses(_write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays))


@given(st.data())
def test_any_damaged_byte_loads_or_is_refused_in_one_line(tmp_path_factory, data):
    header, arrays = _valid_parts()
    path = _write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays)
    content = bytearray(path.read_bytes())
    for _ in range(data.draw(st.integers(1, 4))):
        content[data.draw(st.integers(0, len(content) - 1))] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(len(content) // 2, len(content)))
    path.write_bytes(bytes(content[:cut]))
    _loads_and_renders_on_or_refuses(path)


AOVS = ("depth", "normal")
AOV_COLUMNS = AovLayout(AOVS).columns
AOV_IDENTITY = dataclasses.replace(IDENTITY, aovs=",".join(AOVS))


def _valid_aov_parts() -> tuple[dict, dict[str, np.ndarray]]:
    """``_valid_parts`` of a render with AOVs: each film row holds ``AOV_COLUMNS`` sums."""
    header, arrays = _valid_parts()
    rng = np.random.default_rng(2)
    for name in ["sums", *(name for name in arrays if name.startswith("waiting_") and name[8:].isdigit())]:
        rows = len(arrays[name])
        extra = rng.random((rows, AOV_COLUMNS - 3)) * (arrays[name][:, :1] != 0)  # none where no samples
        arrays[name] = np.column_stack([arrays[name], extra])
    return {**header, "aovs": AOV_IDENTITY.aovs}, arrays


def _aov_loads_and_renders_on_or_refuses(path: Path) -> None:
    try:
        film = load_checkpoint(path, AOV_IDENTITY, PLAN, columns=AOV_COLUMNS)
    except UserError as err:
        assert "\n" not in str(err) and str(path) in str(err), str(err)
        return
    for index in range(len(PLAN)):
        if not film.has(index):
            film.add(index, PLAN[index].first_pixel, np.ones((PLAN[index].pixel_count, AOV_COLUMNS)))
    assert film.next_pass == len(PLAN) and np.all(np.isfinite(film.film.sums))


def test_a_checkpoint_with_aovs_loads_whole_and_only_for_the_same_aovs(tmp_path):
    header, arrays = _valid_aov_parts()
    path = _write(tmp_path / "x.partial", header, arrays)
    film = load_checkpoint(path, AOV_IDENTITY, PLAN, columns=AOV_COLUMNS)
    np.testing.assert_array_equal(film.film.sums, arrays["sums"])
    with pytest.raises(UserError, match="another set of AOVs"):
        load_checkpoint(path, IDENTITY, PLAN)
    with pytest.raises(UserError, match="film sums of the wrong shape"):
        load_checkpoint(path, dataclasses.replace(IDENTITY, aovs=AOV_IDENTITY.aovs), PLAN, columns=AOV_COLUMNS - 1)
    old_header, old_arrays = _valid_parts()  # written before AOVs: no "aovs" in its header
    old_header.pop("aovs")
    assert load_checkpoint(_write(tmp_path / "old.partial", old_header, old_arrays), IDENTITY, PLAN).next_pass == 3


@given(st.sampled_from(NAMES), ARRAYS | st.none())
def test_any_array_of_a_checkpoint_with_aovs_loads_or_is_refused_in_one_line(tmp_path_factory, name, array):
    header, arrays = _valid_aov_parts()
    if array is None:
        arrays.pop(name, None)
    else:
        arrays[name] = array
    _aov_loads_and_renders_on_or_refuses(_write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays))


@given(st.sampled_from(["sums", "waiting_4"]), st.data())
def test_any_value_in_an_aov_column_loads_or_is_refused_in_one_line(tmp_path_factory, name, data):
    header, arrays = _valid_aov_parts()
    row = data.draw(st.integers(0, len(arrays[name]) - 1))
    arrays[name][row, data.draw(st.integers(3, AOV_COLUMNS - 1))] = data.draw(SPECIAL)
    _aov_loads_and_renders_on_or_refuses(_write(tmp_path_factory.mktemp("cp") / "x.partial", header, arrays))


def _pass_data(index: int) -> tuple[np.ndarray, Splats]:
    """Pass ``index``'s sums and flare splats (a few ascending pixels of the film), the same in every call."""
    rng = np.random.default_rng(100 + index)
    pixel = np.flatnonzero(rng.random(WIDTH * HEIGHT) < 0.5).astype(np.int64)
    return rng.random((PLAN[index].pixel_count, 3)), Splats(pixel, rng.random((len(pixel), 3)))


def _flare_film(taken: tuple[int, ...]) -> PassFilm:
    """A film with lens flare holding the passes ``taken`` (``_pass_data``)."""
    film = PassFilm(Film(WIDTH, HEIGHT, SPP, flare=True), PLAN)
    for index in taken:
        film.add(index, PLAN[index].first_pixel, *_pass_data(index))
    return film


FLARE_IDENTITY = dataclasses.replace(IDENTITY, flare="ghosts >= 0.0001")
FLARE_WHOLE = _flare_film(tuple(range(len(PLAN)))).image()


def _flare_parts(tmp_path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of a flare checkpoint (``save_checkpoint``) of passes 0-2 taken and 4 and 6 waiting."""
    path = tmp_path / "saved.partial"
    save_checkpoint(path, FLARE_IDENTITY, _flare_film((0, 1, 2, 4, 6)))
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    return json.loads(str(arrays.pop("header"))), arrays


FLARE_NAMES = ["flare", "waiting_flare_4", "waiting_flare_pixel_4", "waiting_flare_6", "waiting_flare_pixel_6"]


def _flare_resumes_whole_or_is_refused(path: Path, arrays: dict[str, np.ndarray], altered: bool) -> None:
    """The property: a one-line UserError naming the file, or a film holding exactly the file's flare
    that every remaining pass completes to a finite image, the uninterrupted render's bit for bit
    when the file was not altered."""
    try:
        film = load_checkpoint(path, FLARE_IDENTITY, PLAN, flare=True)
    except UserError as err:
        assert "\n" not in str(err) and str(path) in str(err), str(err)
        assert altered, str(err)
        return
    assert film.film.flare is not None
    np.testing.assert_array_equal(film.film.flare, arrays["flare"])  # what the file holds, nothing else
    for number in film.waiting:
        splats = film.waiting[number][2]
        assert splats is not None
        np.testing.assert_array_equal(splats.pixel, arrays[f"waiting_flare_pixel_{number}"])
        np.testing.assert_array_equal(splats.value, arrays[f"waiting_flare_{number}"])
    for index in range(len(PLAN)):
        if not film.has(index):
            film.add(index, PLAN[index].first_pixel, *_pass_data(index))
    image = film.image()
    assert np.all(np.isfinite(image))
    if not altered:
        np.testing.assert_array_equal(image, FLARE_WHOLE)


def test_an_unaltered_flare_checkpoint_resumes_bit_identically(tmp_path):
    header, arrays = _flare_parts(tmp_path)
    assert set(FLARE_NAMES) <= set(arrays)
    _flare_resumes_whole_or_is_refused(_write(tmp_path / "x.partial", header, arrays), arrays, altered=False)


@given(st.sampled_from(FLARE_NAMES), ARRAYS | st.none())
def test_any_flare_array_resumes_or_is_refused_in_one_line(tmp_path_factory, name, array):
    folder = tmp_path_factory.mktemp("cp")
    header, arrays = _flare_parts(folder)
    original = arrays.pop(name)
    if array is not None:
        arrays[name] = array
    altered = array is None or array.dtype != original.dtype or not np.array_equal(array, original)
    path = _write(folder / "x.partial", header, arrays)
    if name in arrays:
        _flare_resumes_whole_or_is_refused(path, arrays, altered)
    else:
        with pytest.raises(UserError) as err:
            load_checkpoint(path, FLARE_IDENTITY, PLAN, flare=True)
        assert "\n" not in str(err.value) and str(path) in str(err.value)


@given(st.sampled_from(FLARE_NAMES), st.data())
def test_any_flare_value_or_length_resumes_or_is_refused_in_one_line(tmp_path_factory, name, data):
    """NaN, inf, huge and negative values (a spectral camera's flare may be negative: ``cie_rgb`` has
    negative lobes), and arrays cut short."""
    folder = tmp_path_factory.mktemp("cp")
    header, arrays = _flare_parts(folder)
    original = arrays[name].copy()
    if data.draw(st.booleans(), label="truncate"):
        arrays[name] = arrays[name][:data.draw(st.integers(0, max(len(original) - 1, 0)), label="length")]
    else:
        flat = arrays[name].reshape(-1)
        position = data.draw(st.integers(0, flat.size - 1), label="position")
        special = data.draw(SPECIAL, label="value")
        if flat.dtype.kind == "f":
            flat[position] = special
        elif np.isfinite(special) and abs(special) < 2**62:
            flat[position] = int(special)
    altered = arrays[name].shape != original.shape or not np.array_equal(arrays[name], original, equal_nan=False)
    _flare_resumes_whole_or_is_refused(_write(folder / "x.partial", header, arrays), arrays, altered)


@given(st.data())
def test_any_damaged_byte_of_a_flare_checkpoint_resumes_or_is_refused_in_one_line(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("cp")
    path = folder / "x.partial"
    save_checkpoint(path, FLARE_IDENTITY, _flare_film((0, 1, 2, 4, 6)))
    content = bytearray(path.read_bytes())
    for _ in range(data.draw(st.integers(1, 4), label="bytes")):
        content[data.draw(st.integers(0, len(content) - 1), label="at")] = data.draw(st.integers(0, 255), label="to")
    path.write_bytes(bytes(content[:data.draw(st.integers(len(content) // 2, len(content)), label="cut")]))
    try:
        film = load_checkpoint(path, FLARE_IDENTITY, PLAN, flare=True)
    except UserError as err:
        assert "\n" not in str(err) and str(path) in str(err), str(err)
        return
    for index in range(len(PLAN)):
        if not film.has(index):
            film.add(index, PLAN[index].first_pixel, *_pass_data(index))
    assert np.all(np.isfinite(film.image()))
