"""Cached tables are untrusted (issue 32): an exit-pupil table or image-circle diameter read from the
disk cache is used only when it is one the search could have produced for that lens and film;
anything else (zeros and NaN, which crashed the kernel, the wrong shape, which was a traceback,
arbitrary arrays or bytes) is rebuilt."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from realistic.core import disk_cache
from realistic.optics import library, sampling
from realistic.optics.formats import load_lens
from realistic.optics.paraxial import film_distance_for_focus

INTERVALS = 8  # a small table: each rebuild is one pupil search


def _table(lens_name: str = "dgauss") -> sampling.ExitPupilTable:
    lens = load_lens(lens_name)
    sampling._cached_table.cache_clear()
    return sampling.exit_pupil_table(lens, film_distance_for_focus(lens, np.inf), 43.27, INTERVALS)


def _only_entry(folder) -> tuple:
    """The key and path of the one cache entry in ``folder``."""
    (path,) = list(folder.glob("exit-pupil-*.npz"))
    return path.stem, path


def _same(a: sampling.ExitPupilTable, b: sampling.ExitPupilTable) -> bool:
    return (a.plane_z_mm == b.plane_z_mm and a.film_radius_mm == b.film_radius_mm
            and np.array_equal(a.bounds, b.bounds) and np.array_equal(a.padding_mm, b.padding_mm))


def _poisoned(reference: sampling.ExitPupilTable, how: str) -> dict[str, np.ndarray]:
    arrays = {"plane_z_mm": np.asarray(reference.plane_z_mm), "film_radius_mm": np.asarray(reference.film_radius_mm),
              "bounds": reference.bounds.copy(), "padding_mm": reference.padding_mm.copy()}
    if how == "zeros":
        arrays["bounds"][:] = 0.0
    elif how == "nan":
        arrays["bounds"][2, 1] = np.nan
    elif how == "shape":
        arrays["bounds"] = arrays["bounds"][:, :3]
    elif how == "huge":
        arrays["bounds"][0] = [-1e30, 1e30, -1e30, 1e30]
    elif how == "plane":
        arrays["plane_z_mm"] = np.asarray(0.0)
    return arrays


@pytest.mark.parametrize("how", ["zeros", "nan", "shape", "huge", "plane"])
def test_a_poisoned_exit_pupil_entry_is_rebuilt(cache, how):
    """A well-formed entry (right key, valid digest) holding zeros or NaN crashed the kernel; one of
    the wrong shape gave a traceback. Each is now rebuilt into the table the search gives."""
    reference = _table()
    key, _ = _only_entry(cache)
    disk_cache.store_arrays(key, _poisoned(reference, how))
    assert _same(_table(), reference)


@pytest.mark.parametrize("name", ["dgauss", "fisheye", "canon-ef24-f1.4"])
def test_tables_the_search_builds_are_trusted(cache, monkeypatch, name):
    """The checks accept what the search produces (no rebuild on every run)."""
    built = _table(name)
    sampling._cached_table.cache_clear()
    monkeypatch.setattr(sampling, "_build_exit_pupil_table", lambda *args: pytest.fail("rebuilt"))
    assert _same(_table(name), built)


ARRAYS = st.dictionaries(
    st.sampled_from(["plane_z_mm", "film_radius_mm", "bounds", "padding_mm", "other"]),
    hnp.arrays(st.sampled_from([np.float64, np.float32]),
               st.sampled_from([(), (INTERVALS, 4), (INTERVALS, 2), (INTERVALS, 3), (1,)]),
               elements=st.floats(-1e3, 1e3, width=32) | st.sampled_from([0.0, np.nan, np.inf])),
    min_size=0, max_size=5)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(arrays=ARRAYS, raw=st.none() | st.binary(max_size=200))
def test_any_cache_entry_is_rebuilt_or_used_never_a_crash(cache, arrays, raw):
    """Arbitrary arrays stored under the table's key (digest valid), or arbitrary bytes in its file:
    the table used is the one the search builds."""
    reference = _table()
    key, path = _only_entry(cache)
    if raw is None:
        disk_cache.store_arrays(key, arrays)
    else:
        path.write_bytes(raw)
    assert _same(_table(), reference)


@pytest.mark.parametrize("diameter", [np.nan, -1.0, 1e300, np.inf])
def test_a_poisoned_image_circle_entry_is_recomputed(cache, diameter):
    lens = load_lens("dgauss")
    reference = library.image_circle_mm(lens, points=5, samples=500)
    (path,) = list(cache.glob("image-circle-*.npz"))
    disk_cache.store_arrays(path.stem, {"diameter_mm": np.asarray(diameter)})
    assert library.image_circle_mm(lens, points=5, samples=500) == reference
