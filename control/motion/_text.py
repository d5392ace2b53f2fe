"""Shared text helpers for the motion readers: decoding and number parsing."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from ._errors import MotionFormatError
from ._quat import FloatArray

__all__ = [
    "MAX_ABS",
    "decode",
    "is_int",
    "parse_floats",
    "parse_floats_fast",
    "read_bytes",
]

#: Larger magnitudes are not plausible lengths or angles; rejecting them keeps later
#: arithmetic finite.
MAX_ABS = 1e9
_INT = re.compile(r"[+-]?[0-9]+")


def is_int(token: str) -> bool:
    """True for an ASCII whole number such as ``12`` or ``-3``."""
    return _INT.fullmatch(token) is not None


def read_bytes(path: str | Path) -> bytes:
    """The whole file; a missing or unreadable file is a ``MotionFormatError``."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise MotionFormatError(path, f"cannot read: {exc.strerror or exc}") from None
    if not data.strip():
        raise MotionFormatError(path, "the file is empty")
    return data


def decode(path: str | Path, data: bytes) -> str:
    """UTF-8 text of ``data`` with ``\n`` line ends (CRLF and CR-only files too, and a
    leading byte-order mark dropped); invalid bytes are an error naming line and byte."""
    try:
        text = data.decode("utf-8")
        if text.startswith("\ufeff"):
            text = text[1:]
        return text.replace("\r\n", "\n").replace("\r", "\n")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        bad = data[exc.start : exc.start + 1].hex()
        raise MotionFormatError(path, f"not UTF-8 text (byte 0x{bad})", line) from None


def parse_floats(path: str | Path, tokens: list[str], line: int, what: str) -> list[float]:
    """Parse ``tokens`` as finite floats, or raise naming ``what`` and the line."""
    out = []
    for tok in tokens:
        try:
            value = float(tok)
        except ValueError:
            raise MotionFormatError(path, f"{what}: {tok!r} is not a number", line) from None
        if value != value or value in (float("inf"), float("-inf")):
            raise MotionFormatError(path, f"{what}: {tok!r} is not a finite number", line)
        if abs(value) > MAX_ABS:
            raise MotionFormatError(path, f"{what}: {tok!r} is out of range", line)
        out.append(value)
    return out


def parse_floats_fast(text: str) -> FloatArray | None:
    """All whitespace-separated numbers of ``text`` as one array, or ``None`` when any
    token is not a number or not finite and at most ``MAX_ABS`` in magnitude (the caller
    then falls back to a line-by-line parse that can say where)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            values = np.fromstring(text, sep=" ")
        except (DeprecationWarning, ValueError):
            return None
    if values.size and not np.max(np.abs(values)) <= MAX_ABS:
        return None
    return values
