"""File locks between processes that share the cache: a build lock per folder (one
process builds an entry, the others wait and load it), and a shared hold on a file for
as long as an object that uses it lives (a run's open window tables, which another
run's pruning then leaves).

POSIX ``flock``; where there is none (not POSIX, or a file system without locks) the
locks are no-ops: two processes may then build the same entry (the atomic writes leave
one good file) and files in use are told from others by age alone.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover  (not POSIX: no locks)
    fcntl = None  # type: ignore[assignment]

__all__ = ["LOCK_NAME", "build_lock", "hold_while", "is_held", "is_locked"]

#: the lock file inside a folder that a process is building (``build_lock``)
LOCK_NAME = ".building.lock"


@contextmanager
def build_lock(folder: str | Path) -> Iterator[None]:
    """Hold the build lock of ``folder`` (made if missing): another process that asks
    for it waits until this one is done, then finds what it built."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / LOCK_NAME, "a") as fh:
        if fcntl is not None:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def is_locked(folder: str | Path) -> bool:
    """Whether a process holds ``folder``'s build lock now."""
    return is_held(Path(folder) / LOCK_NAME)


def is_held(path: str | Path) -> bool:
    """Whether a process (this one too) holds a ``flock`` on the file ``path`` now."""
    if fcntl is None or not Path(path).is_file():
        return False
    try:
        with open(path, "rb") as fh:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    except BlockingIOError:
        return True
    except OSError:
        return False
    return False


def hold_while(path: str | Path, owner: object) -> bool:
    """Hold a shared ``flock`` on the file ``path`` for as long as ``owner`` lives (it
    must allow weak references, as a numpy array does), so that ``is_held(path)`` is true
    in every process meanwhile. Returns whether a hold was taken (``False``: no such
    file, or no locks here)."""
    if fcntl is None:
        return False
    try:
        fh = open(path, "rb")  # noqa: SIM115  (closed when ``owner`` goes)
    except OSError:
        return False
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        fh.close()
        return False
    weakref.finalize(owner, fh.close)
    return True
