"""Calling numba kernels with one compiled signature each.

numba compiles a kernel again for every new combination of argument types, and an
array's write flag is part of its type: the same kernel fed a stored (read-only) table
once and a fresh one next compiles twice, 0.5-1 s each on a first run. The kernels'
wrappers hand their input arrays over read-only (and C-contiguous, ``kernel_input``), so
each kernel has one signature, which a caller can also compile ahead of its first use.

``one_thread``: the numeric libraries' own thread pools (OpenBLAS, OpenMP) held to one
thread meanwhile, and numba's parallel kernels too. A decision's matrix products are
small; spread over threads they wait on one another, worst when another process shares
the cores.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numba
import numpy as np
from numpy.typing import ArrayLike, DTypeLike
from threadpoolctl import threadpool_limits

__all__ = ["kernel_input", "one_thread", "read_only"]


@contextmanager
def one_thread() -> Iterator[None]:
    """A context in which the BLAS and OpenMP libraries loaded in this process run on one
    thread each (``threadpoolctl``), and numba's parallel kernels called from this thread
    too (a mask's extents, per frame, ran on every core); on leaving, the limits are what
    they were."""
    saved = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            yield
    finally:
        numba.set_num_threads(saved)


def read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (the array itself and its flags are untouched)."""
    view = array.view()
    view.flags.writeable = False
    return view


def kernel_input(array: ArrayLike, dtype: DTypeLike) -> np.ndarray:
    """``array`` as a kernel's input argument: C-contiguous, of ``dtype`` and read-only,
    whatever it was (a slice, a stored table, a list), so that one signature serves."""
    return read_only(np.ascontiguousarray(array, dtype=dtype))
