"""The chainer the transition tests share: the exercise takes 13_29 and 13_30 and
subject 02's clips (walks, a run, a jump, the strikes of 02_05, ...)."""

from __future__ import annotations

from pathlib import Path

import pytest

from control.motion import Library, load_library
from control.transition import Chainer


@pytest.fixture(scope="session")
def chainer(mocap: Path, tmp_path_factory: pytest.TempPathFactory) -> Chainer:
    lib: Library = load_library(
        mocap, clips=["13_29", "13_30", "02_0*"], cache_dir=tmp_path_factory.mktemp("c")
    )
    return Chainer(lib.clips, seed=1)
