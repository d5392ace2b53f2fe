"""Progress on stderr for the command line: a bar for counted work, a line per step.

On a terminal a bar redraws itself in place; into a file or a pipe (CI logs, ``2> log``)
only the finished line is written, so logs stay readable. Nothing is written for work
that ends within ``quiet_s`` seconds, so quick (cached) steps stay silent.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from typing import TextIO

__all__ = ["bar", "step"]


def bar(
    label: str, unit: str = "", stream: TextIO | None = None, quiet_s: float = 1.0
) -> Callable[[int, int], None]:
    """A callback ``(done, total)`` drawing ``label [#####.....] done/total unit``."""
    out = stream or sys.stderr
    t0 = time.perf_counter()
    tty = bool(getattr(out, "isatty", lambda: False)())
    state = {"drawn": False}

    def update(done: int, total: int) -> None:
        took = time.perf_counter() - t0
        finished = done >= total
        if not finished and (not tty or took < quiet_s):
            return
        if finished and took < quiet_s and not state["drawn"]:
            return
        width = 30
        fill = round(width * done / max(total, 1))
        text = f"{label} [{'#' * fill}{'.' * (width - fill)}] {done}/{total}"
        text += f" {unit}" if unit else ""
        if finished:
            text += f", {took:.1f} s"
        out.write(("\r" if tty else "") + text + ("\n" if finished else ""))
        out.flush()
        state["drawn"] = True

    return update


@contextlib.contextmanager
def step(label: str, stream: TextIO | None = None, quiet_s: float = 1.0) -> Iterator[None]:
    """``label ... 3.2 s`` once the step is done (on a terminal, ``label ...`` first)."""
    out = stream or sys.stderr
    tty = bool(getattr(out, "isatty", lambda: False)())
    t0 = time.perf_counter()
    if tty:
        out.write(f"{label} ...")
        out.flush()
    yield
    took = time.perf_counter() - t0
    if tty:
        out.write(f" {took:.1f} s\n")
    elif took >= quiet_s:
        out.write(f"{label} ... {took:.1f} s\n")
    out.flush()
