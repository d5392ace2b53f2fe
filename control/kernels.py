"""Calling numba kernels with one compiled signature each.

numba compiles a kernel again for every new combination of argument types, and an
array's write flag is part of its type: the same kernel fed a stored (read-only) table
once and a fresh one next compiles twice, 0.5-1 s each on a first run. The kernels'
wrappers hand their input arrays over read-only, so each kernel has one signature.
"""

from __future__ import annotations

import numpy as np

__all__ = ["read_only"]


def read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (the array itself and its flags are untouched)."""
    view = array.view()
    view.flags.writeable = False
    return view
