"""The disk cache's folder: $REALISTIC_CACHE_DIR, "off", else the user cache folder (XDG on Linux)."""

import sys
from pathlib import Path

import pytest

from realistic.core import disk_cache

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the XDG layout is Linux's")


def test_the_variable_names_the_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("REALISTIC_CACHE_DIR", str(tmp_path / "mine"))
    assert disk_cache.cache_dir() == tmp_path / "mine"


def test_off_turns_the_cache_off(monkeypatch):
    monkeypatch.setenv("REALISTIC_CACHE_DIR", "off")
    assert disk_cache.cache_dir() is None


@linux_only
def test_xdg_cache_home_is_honoured(tmp_path, monkeypatch):
    monkeypatch.delenv("REALISTIC_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert disk_cache.cache_dir() == tmp_path / "realistic"


@linux_only
@pytest.mark.parametrize("xdg", [None, ""])
def test_without_xdg_it_is_dot_cache_in_home(tmp_path, monkeypatch, xdg):
    monkeypatch.delenv("REALISTIC_CACHE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    if xdg is None:
        monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    else:
        monkeypatch.setenv("XDG_CACHE_HOME", xdg)
    assert disk_cache.cache_dir() == Path(tmp_path) / ".cache" / "realistic"
