"""The exit-pupil table's disk cache: a stored table is the built one, a bad entry is rebuilt."""

import numpy as np

from realistic.core import disk_cache
from realistic.optics import sampling
from realistic.optics.formats import load_lens
from realistic.optics.paraxial import film_distance_for_focus


def _table(stop_divisor: float = 1.0):
    lens = load_lens("telephoto")
    lens = lens.with_stop_diameter(lens.stop_diameter_mm / stop_divisor)
    return sampling.exit_pupil_table(lens, film_distance_for_focus(lens, np.inf), 35.0)


def _forbid_building(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the table was built although it is cached")
    monkeypatch.setattr(sampling, "_build_exit_pupil_table", refuse)


def test_a_cached_table_is_read_back_exactly_without_building(cache, monkeypatch):
    built = _table()
    assert len(list(cache.glob("exit-pupil-*.npz"))) == 1
    sampling._cached_table.cache_clear()
    _forbid_building(monkeypatch)
    read = _table()
    assert read.plane_z_mm == built.plane_z_mm and read.film_radius_mm == built.film_radius_mm
    assert np.array_equal(read.bounds, built.bounds) and np.array_equal(read.padding_mm, built.padding_mm)


def test_another_stop_is_another_entry(cache):
    wide_open, stopped_down = _table(), _table(4.0)
    assert len(list(cache.glob("exit-pupil-*.npz"))) == 2
    assert stopped_down.area_mm2()[0] < wide_open.area_mm2()[0]


def test_a_corrupt_entry_is_rebuilt(cache):
    built = _table()
    for entry in cache.glob("exit-pupil-*.npz"):
        entry.write_bytes(b"not a zip file")
    sampling._cached_table.cache_clear()
    assert np.array_equal(_table().bounds, built.bounds)


def test_an_unwritable_cache_is_skipped(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(blocker / "cache"))
    sampling._cached_table.cache_clear()
    assert _table().area_mm2()[0] > 0
    sampling._cached_table.cache_clear()


def test_the_cache_can_be_turned_off(tmp_path, monkeypatch):
    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    assert disk_cache.cache_dir() is None
    disk_cache.store_arrays("x", {"a": np.zeros(2)})
    assert disk_cache.load_arrays("x") is None


def test_keys_differ_with_any_part():
    assert disk_cache.cache_key("k", 1.0, b"a") != disk_cache.cache_key("k", 1.0, b"b")
    assert disk_cache.cache_key("k", 0.1 + 0.2) != disk_cache.cache_key("k", 0.3)


def test_an_entry_carries_its_key_and_digest_and_a_mismatch_reads_as_absent(cache):
    """An entry copied under another key, altered in place (its stored digest kept), or truncated is
    never handed back; a good one is, without the cache's own fields."""
    disk_cache.store_arrays("kind-a", {"x": np.arange(5.0)})
    assert list(disk_cache.load_arrays("kind-a")) == ["x"]
    (cache / "kind-a.npz").rename(cache / "kind-b.npz")
    assert disk_cache.load_arrays("kind-b") is None  # another key's content
    disk_cache.store_arrays("kind-c", {"x": np.arange(5.0)})
    with np.load(cache / "kind-c.npz") as stored:
        fields = {name: stored[name] for name in stored.files}
    fields["x"] = fields["x"] + 1  # the content changed, the digest not
    np.savez(cache / "kind-c.npz", **fields)
    assert disk_cache.load_arrays("kind-c") is None
    disk_cache.store_arrays("kind-d", {"x": np.arange(5.0)})
    data = (cache / "kind-d.npz").read_bytes()
    (cache / "kind-d.npz").write_bytes(data[:len(data) // 2])
    assert disk_cache.load_arrays("kind-d") is None


def test_another_stops_table_under_this_key_is_rebuilt(cache):
    """A table copied under another table's key is not read back: the right one is built."""
    stopped_down = _table(4.0)
    sampling._cached_table.cache_clear()
    (stopped_entry,) = cache.glob("exit-pupil-*.npz")
    wide_open = _table()
    (wide_entry,) = set(cache.glob("exit-pupil-*.npz")) - {stopped_entry}
    wide_entry.write_bytes(stopped_entry.read_bytes())
    sampling._cached_table.cache_clear()
    again = _table()
    assert np.array_equal(again.bounds, wide_open.bounds) and not np.array_equal(again.bounds, stopped_down.bounds)


def test_a_full_disk_skips_the_entry_without_an_error(cache, monkeypatch):
    """A cache write that fails for want of space (ENOSPC; at exit, where the program binaries are
    stored, this printed a traceback) leaves no entry and raises nothing."""
    import errno
    from pathlib import Path

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", full)
    disk_cache.store_arrays("k" * 64, {"values": np.arange(3)})
    assert disk_cache.load_arrays("k" * 64) is None
    assert not [p for p in cache.iterdir() if p.suffix == ".npz"]
