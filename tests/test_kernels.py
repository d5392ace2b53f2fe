"""numba kernels compile one signature each, whatever the write flags of their inputs
(``control.kernels.read_only``): stored tables are read-only, fresh ones are not."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from control import dtw as dtw_module
from control.kernels import read_only
from control.motion import _fk, load_library


def _frozen(a: np.ndarray) -> np.ndarray:
    b = np.array(a)
    b.flags.writeable = False
    return b


def test_read_only_views_leave_the_array_alone() -> None:
    a = np.arange(6.0)
    v = read_only(a)
    assert not v.flags.writeable and a.flags.writeable and np.shares_memory(a, v)


def test_kernels_compile_once_for_writable_and_read_only_inputs(
    rng: np.random.Generator, mocap: Path
) -> None:
    shape, centre = rng.random((30, 3, 4)), rng.random((30, 3, 2))
    query = rng.random((5, 6))
    starts = np.arange(0, 25, dtype=np.int64)
    got = [
        dtw_module.dtw_best_window(query, s, c, starts, 5, 2)
        for s, c in ((shape, centre), (_frozen(shape), _frozen(centre)))
    ]
    assert got[0] == got[1]
    motion = load_library(mocap, clips=["02_01"], use_cache=False, workers=1).clips[0].motion
    sk = motion.skeleton
    writable = _fk._fk(sk, np.array(motion.root_pos), np.array(motion.quats))
    stored = _fk._fk(sk, _frozen(motion.root_pos), _frozen(motion.quats))
    for a, b in zip(writable, stored, strict=True):
        np.testing.assert_array_equal(a, b)
    assert len(dtw_module._best_window_kernel.signatures) == 1
    assert len(_fk._fk_kernel.signatures) == 1
