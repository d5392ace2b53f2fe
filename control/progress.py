"""Progress on stderr for the command line: a bar for counted work, a line per step.

On a terminal a bar redraws itself in place, with its rate and the time left; into a file
or a pipe (CI logs, ``2> log``) a line is written at most every 30 s and once finished,
so logs stay readable and a long build can still be watched. Nothing is written for work
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
    label: str,
    unit: str = "",
    stream: TextIO | None = None,
    quiet_s: float = 1.0,
    every_s: float = 30.0,
    clock: Callable[[], float] = time.perf_counter,
) -> Callable[[int, int], None]:
    """A callback ``(done, total)`` drawing ``label [#####.....] done/total unit``, with
    the rate and the time left at that rate (``ETA``); a line in a log at most every
    ``every_s`` seconds, so that a long build can be watched there too. ``done`` counts
    work finished anywhere (a cluster's workers too), so the rate is theirs together.
    The rate is taken from the first work done on, not from the start: what comes
    before it (a cluster started, a graph's features sent to its workers: half a
    minute at 500,000 frames) made a first ETA of hours for a build of minutes. The
    finished line gives the whole time and the rate over it."""
    out = stream or sys.stderr
    t0 = clock()
    tty = bool(getattr(out, "isatty", lambda: False)())
    state = {"drawn": False, "said": t0}
    first: list[tuple[float, int]] = []  # (when, done) at the first work done

    def update(done: int, total: int) -> None:
        now = clock()
        took = now - t0
        if not first and done > 0:
            first.append((now, done))
        finished = done >= total
        if not finished and took < quiet_s:
            return
        if not finished and not tty and now - state["said"] < every_s:
            return
        if finished and took < quiet_s and not state["drawn"]:
            return
        width = 30
        fill = round(width * done / max(total, 1))
        text = f"{label} [{'#' * fill}{'.' * (width - fill)}] {done}/{total}"
        text += f" {unit}" if unit else ""
        if finished:
            rate = done / took if took > 0 else 0.0
        elif first and done > first[0][1] and now > first[0][0]:
            rate = (done - first[0][1]) / (now - first[0][0])
        else:
            rate = 0.0  # (no rate yet: nothing done since the first work)
        if rate > 0:
            text += f", {_rate(rate)}{f' {unit}' if unit else ''}/s"
        if finished:
            text += f", {took:.1f} s"
        elif rate > 0:
            text += f", ETA {_clock((total - done) / rate)}"
        end = "\n" if finished or not tty else ""
        out.write(("\r" if tty else "") + text + end)
        out.flush()
        state["drawn"], state["said"] = True, now

    return update


def _rate(per_s: float) -> str:
    """A rate with two or three significant figures."""
    return f"{per_s:.3g}" if per_s < 1000 else f"{per_s:,.0f}"


def _clock(seconds: float) -> str:
    """``m:ss`` (``h:mm:ss`` past an hour)."""
    s = round(seconds)
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


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
