"""Shared fixtures: where the project's shared reference data lives (skips when it is absent)."""

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


def shared_file(relative: str) -> Path:
    """Path of a file in ../shared, or skip the test with the reason."""
    path = SHARED / relative
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (a clone without ../shared skips this test)")
    return path
