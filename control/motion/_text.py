"""Shared text helpers for the motion readers: decoding, number parsing, atomic writes."""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from ._errors import MotionFormatError
from ._quat import FloatArray

__all__ = [
    "MAX_ABS",
    "atomic_write",
    "current_umask",
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


def current_umask() -> int:
    """The process's file-mode creation mask (read without changing it where Linux allows)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def atomic_write(path: str | Path, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success it replaces ``path`` in one step,
    on failure it is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(fd, 0o666 & ~current_umask())  # as open() would make it, not mkstemp's 0600
        newline = None if "b" in mode else "\n"
        with os.fdopen(fd, mode, newline=newline) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_npz(
    path: Path, keys: Sequence[str], error: Callable[[Path, str], Exception], what: str
) -> dict[str, np.ndarray]:
    """The arrays ``keys`` of an ``.npz`` file, read without pickle.

    Raises ``error(path, problem)`` when the file cannot be read (missing, truncated,
    not a zip of arrays) or lacks one of ``keys`` (``"not a {what} (missing ...)"``).
    """
    try:
        with path.open("rb") as fh, np.load(fh, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            arrays = {} if missing else {k: z[k] for k in keys}
    except Exception as exc:  # a damaged zip or header raises anything
        # (zlib.error, EOFError, tokenize.TokenError, NotImplementedError, MemoryError, ...)
        raise error(
            path, f"unreadable, truncated or damaged ({type(exc).__name__}: {exc})"
        ) from exc
    if missing:
        raise error(path, f"not a {what} (missing {', '.join(missing)})")
    return arrays
