"""Calling numba kernels with one compiled signature each.

numba compiles a kernel again for every new combination of argument types, and an
array's write flag is part of its type: the same kernel fed a stored (read-only) table
once and a fresh one next compiles twice, 0.5-1 s each on a first run. The kernels'
wrappers hand their input arrays over read-only (and C-contiguous, ``kernel_input``), so
each kernel has one signature, which a caller can also compile ahead of its first use.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["kernel_input", "read_only"]


def read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (the array itself and its flags are untouched)."""
    view = array.view()
    view.flags.writeable = False
    return view


def kernel_input(array: ArrayLike, dtype: DTypeLike) -> np.ndarray:
    """``array`` as a kernel's input argument: C-contiguous, of ``dtype`` and read-only,
    whatever it was (a slice, a stored table, a list), so that one signature serves."""
    return read_only(np.ascontiguousarray(array, dtype=dtype))
