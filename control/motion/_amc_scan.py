"""The AMC body scanned in one pass by a numba kernel (``_scan_kernel``): frame numbers,
bone names and numbers read straight into the motion's table.

It accepts only a strictly regular body: each frame a number on its own line, then every
bone that has dofs, in the first frame's order, one line each holding exactly its dofs'
numbers. A number of at most 18 significant digits and a power of ten within 1e±22 is one
correctly rounded division or product of two exact doubles, the value ``float()`` gives
(Clinger's fast path); the kernel hands any other number (``3.1e-018``: 1e-23) back to
``float()`` by its place in the text. Anything else stops the scan: the reader falls back
to its vectorised parse, then to the line-by-line one that says where a file is wrong,
which starts where the scan stopped (``scan_amc_prefix``). Tested against the vectorised
parse on shared AMCs (two of them holding numbers past 1e-22), against ``float()`` on
numbers written in many ways, and the line-by-line parse from where the scan stopped
against the whole one.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from ._asf import AsfSkeleton
from ._quat import FloatArray
from ._text import MAX_ABS

__all__ = ["dof_columns", "scan_amc", "scan_amc_prefix"]

_POW10 = np.array([10.0**k for k in range(23)])  # all exact in float64
_MANTISSA_MAX = 2**53


def scan_amc(body: str, asf: AsfSkeleton, moving: list[int]) -> FloatArray | None:
    """The table ``(frames, values)`` of a regular AMC body (after its header), columns
    in the skeleton's order of the ``moving`` joints' dofs; ``None`` when the body is not
    strictly regular or holds a number this scan does not read exactly."""
    table, rest = scan_amc_prefix(body, asf, moving)
    return table if rest == len(body) and table.shape[0] else None


def scan_amc_prefix(body: str, asf: AsfSkeleton, moving: list[int]) -> tuple[FloatArray, int]:
    """``(table, rest)``: the table of the body's first frames that are as ``scan_amc``
    requires, and where in ``body`` the rest begins (``len(body)``: nowhere), at the start
    of a line. A reader that must parse the rest another way need not parse these frames
    again. No frames (and ``rest`` 0) when the first frame is irregular, or a number read
    cannot be (``nan``) or is out of range: the other parses say where."""
    col, c = dof_columns(asf, moving)
    none = np.empty((0, c)), 0
    buf = np.frombuffer(body.encode("utf-8"), dtype=np.uint8)
    names = asf.skeleton.names
    order = _first_frame_order(body)
    if order is None or sorted(order) != sorted(names[j] for j in moving):
        return none
    encoded = [nm.encode("utf-8") for nm in order]
    name_bytes = np.frombuffer(b"".join(encoded), dtype=np.uint8)
    name_ends = np.cumsum([0, *map(len, encoded)]).astype(np.int64)
    widths = np.array([len(asf.dofs[asf.skeleton.index(nm)]) for nm in order], dtype=np.int64)
    cols = np.array([col[nm] for nm in order], dtype=np.int64)
    max_frames = body.count("\n") // (len(order) + 1) + 1
    out = np.empty((max_frames, c))
    hard = np.empty((buf.size // 64 + 16, 3), dtype=np.int64)
    n, n_hard, stop = _scan_kernel(buf, name_bytes, name_ends, widths, cols, _POW10, out, hard)
    if n <= 0:
        return none
    flat = out.reshape(-1)
    for a, e, at in hard[:n_hard].tolist():
        if at >= n * c:
            continue  # a number of the frame where the scan stopped
        try:
            flat[at] = float(bytes(buf[a:e]))
        except ValueError:  # "nan", say: the other parses say where
            return none
    table = out[:n]
    if table.size and not np.max(np.abs(table)) <= MAX_ABS:
        return none
    if stop == buf.size:
        return table, len(body)
    # a line's start follows a line end: a whole UTF-8 character
    return table.copy(), len(buf[:stop].tobytes().decode("utf-8"))


def dof_columns(asf: AsfSkeleton, moving: list[int]) -> tuple[dict[str, int], int]:
    """Each ``moving`` bone's first column in the motion's table (its dofs follow), and
    the table's width: the bones in the skeleton's order."""
    names = asf.skeleton.names
    col: dict[str, int] = {}
    c = 0
    for j in moving:
        col[names[j]] = c
        c += len(asf.dofs[j])
    return col, c


def _first_frame_order(body: str) -> list[str] | None:
    """The bone names of the body's first frame, in order (``None``: no first frame)."""
    lines = iter(body.split("\n", 200))
    first = next(lines, "").split()
    if len(first) != 1:
        return None
    order: list[str] = []
    for line in lines:
        tokens = line.split()
        if len(tokens) == 1 and tokens[0].isdigit():
            return order
        if not tokens:
            return None
        order.append(tokens[0])
    return order or None


@numba.njit(cache=True, inline="always")
def _space(b: np.uint8) -> bool:
    return b == 32 or b == 9 or b == 13  # space, tab, CR (not the line end)


@numba.njit(cache=True, inline="always")
def _whole(buf: NDArray[np.uint8], pos: int, most: int) -> tuple[int, int]:
    """The whole number of 1 to ``most`` digits at ``pos``, and the position after it;
    -1 for none or more digits."""
    value = 0
    digits = 0
    while pos < buf.shape[0] and 48 <= buf[pos] <= 57:
        value = value * 10 + (buf[pos] - 48)
        digits += 1
        pos += 1
    return (value if 0 < digits <= most else -1), pos


@numba.njit(cache=True)
def _scan_kernel(
    buf: NDArray[np.uint8],
    name_bytes: NDArray[np.uint8],
    name_ends: NDArray[np.int64],
    widths: NDArray[np.int64],
    cols: NDArray[np.int64],
    pow10: FloatArray,
    out: FloatArray,
    hard: NDArray[np.int64],
) -> tuple[int, int, int]:
    """Frames read into ``out``, the numbers left to ``float()`` as ``(start, end, flat
    index in out)`` rows of ``hard``, and where the scan stopped: the end of ``buf``, or
    the start of the line of the first frame that is not as ``scan_amc`` requires (the
    frames before it are read; ``hard`` may hold numbers of that frame too)."""
    n = buf.shape[0]
    pos = 0
    frame = 0
    first = 0
    n_hard = 0
    line = 0  # where the line of the frame being read starts
    while True:
        while pos < n and (_space(buf[pos]) or buf[pos] == 10):
            if buf[pos] == 10:
                line = pos + 1
            pos += 1
        if pos == n:
            return frame, n_hard, n
        # the frame number, alone on its line
        number, pos = _whole(buf, pos, 12)
        if number < 0:
            return frame, n_hard, line
        while pos < n and _space(buf[pos]):
            pos += 1
        if pos < n and buf[pos] != 10:
            return frame, n_hard, line
        if frame == 0:
            first = number
        elif number != first + frame:
            return frame, n_hard, line
        if frame >= out.shape[0]:
            return frame, n_hard, line
        for b in range(widths.shape[0]):
            while pos < n and (_space(buf[pos]) or buf[pos] == 10):
                pos += 1
            a, e = name_ends[b], name_ends[b + 1]
            if pos + (e - a) > n:
                return frame, n_hard, line
            for k in range(e - a):
                if buf[pos + k] != name_bytes[a + k]:
                    return frame, n_hard, line
            pos += e - a
            if pos < n and not (_space(buf[pos]) or buf[pos] == 10):
                return frame, n_hard, line  # a longer name that begins with this one
            for d in range(widths[b]):
                while pos < n and _space(buf[pos]):
                    pos += 1
                # [sign] digits [. digits] [(e|E) [sign] digits], read exactly or not at all
                start = pos
                neg = False
                if pos < n and (buf[pos] == 45 or buf[pos] == 43):
                    neg = buf[pos] == 45
                    pos += 1
                mant = 0
                seen = 0
                frac = 0
                big = False  # more digits than an int64 holds: float() reads it
                while pos < n and 48 <= buf[pos] <= 57:
                    big = big or mant >= 100_000_000_000_000_000
                    mant = mant if big else mant * 10 + (buf[pos] - 48)
                    seen += 1
                    pos += 1
                if pos < n and buf[pos] == 46:
                    pos += 1
                    while pos < n and 48 <= buf[pos] <= 57:
                        big = big or mant >= 100_000_000_000_000_000
                        mant = mant if big else mant * 10 + (buf[pos] - 48)
                        seen += 1
                        frac += 1
                        pos += 1
                if seen == 0:
                    return frame, n_hard, line
                exp = 0
                if pos < n and (buf[pos] == 101 or buf[pos] == 69):
                    pos += 1
                    eneg = False
                    if pos < n and (buf[pos] == 45 or buf[pos] == 43):
                        eneg = buf[pos] == 45
                        pos += 1
                    exp, pos = _whole(buf, pos, 4)
                    if exp < 0:
                        return frame, n_hard, line
                    if eneg:
                        exp = -exp
                if pos < n and not (_space(buf[pos]) or buf[pos] == 10):
                    return frame, n_hard, line
                scale = frac - exp
                at = frame * out.shape[1] + cols[b] + d
                exact = not big and mant < _MANTISSA_MAX and (mant == 0 or -22 <= scale <= 22)
                if not exact:  # float() reads it afterwards
                    if n_hard == hard.shape[0]:
                        return frame, n_hard, line
                    hard[n_hard, 0] = start
                    hard[n_hard, 1] = pos
                    hard[n_hard, 2] = at
                    n_hard += 1
                    continue
                if mant == 0:
                    value = 0.0
                elif scale >= 0:
                    value = float(mant) / pow10[scale]
                else:
                    value = float(mant) * pow10[-scale]
                out[frame, cols[b] + d] = -value if neg else value
            while pos < n and _space(buf[pos]):
                pos += 1
            if pos < n and buf[pos] != 10:
                return frame, n_hard, line  # more numbers than the bone's dofs
        frame += 1
