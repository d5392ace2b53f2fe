"""Small real libraries for the graph tests, loaded once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from control.motion import Library, load_library


@pytest.fixture(scope="session")
def walk_lib(mocap: Path, tmp_path_factory: pytest.TempPathFactory) -> Library:
    """Subject 02's walks, run and jump (164 frames at 15 frames/s): small enough for
    brute force over all pairs."""
    cache = tmp_path_factory.mktemp("motion-cache")
    return load_library(mocap, clips=["02_0[1-4]"], cache_dir=cache)


@pytest.fixture(scope="session")
def medium_lib(mocap: Path, tmp_path_factory: pytest.TempPathFactory) -> Library:
    """Subjects 02 and 03 (about 3,000 frames): a graph worth walking in."""
    cache = tmp_path_factory.mktemp("motion-cache")
    return load_library(mocap, clips=["02_*", "03_*"], cache_dir=cache)
