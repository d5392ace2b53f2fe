"""What the bank tests share: a small ring of Hu-moment views and three short clips of
subject 02 (103 frames at 15 frames/s)."""

from __future__ import annotations

from pathlib import Path

import pytest

from control.motion import Library, load_library
from silhouette_bank import BankSettings, CameraRing

SMALL = BankSettings(CameraRing(n_views=6, width=80, height_px=60), descriptor="hu")


@pytest.fixture(scope="module")
def lib(mocap: Path, tmp_path_factory: pytest.TempPathFactory) -> Library:
    return load_library(
        mocap, clips=["02_01", "02_02", "02_03"], cache_dir=tmp_path_factory.mktemp("c")
    )
