"""A library's metadata: clip descriptions (``descriptions.csv`` or a Markdown table in a
``README.md``) and action labels (``labels/<clip>.csv``)."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._errors import MotionFormatError
from ._parsed import library_files
from ._text import decode, read_bytes

__all__ = ["descriptions", "label_files", "read_labels"]


def _expand(cell: str, names: set[str]) -> list[str]:
    """Clip names a table cell refers to: ``02_01``, ``03_01..03_04``, ``09_01 (BVH only)``."""
    cell = re.sub(r"\(.*?\)", "", cell).strip()
    m = re.fullmatch(r"(\S+)\.\.(\S+)", cell)
    if m:
        lo, hi = m.groups()
        return sorted(n for n in names if lo <= n <= hi and len(n) == len(lo))
    return [cell] if cell in names else []


def descriptions(root: Path, names: set[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    files = library_files(root)
    for readme in [p for p in files if p.name == "README.md"]:
        text = readme.read_text(encoding="utf-8", errors="replace")
        header: list[str] | None = None
        for line in text.splitlines():
            cells = (
                [c.strip() for c in line.strip().strip("|").split("|")]
                if line.lstrip().startswith("|")
                else None
            )
            if cells is None:
                header = None
                continue
            low = [c.lower() for c in cells]
            if "clip" in low and "description" in low:
                header = low
                continue
            if header is None or len(cells) != len(header) or set(cells[0]) <= set("-: "):
                continue
            for n in _expand(cells[header.index("clip")], names):
                out.setdefault(n, cells[header.index("description")])
    for table in [p for p in files if p.name == "descriptions.csv"]:
        try:
            data = table.read_bytes()
        except OSError as exc:
            raise MotionFormatError(table, f"cannot read: {exc.strerror or exc}") from None
        if not data.strip():
            continue
        text = decode(table, data)  # not UTF-8: an error naming the file
        try:
            for row in csv.DictReader(io.StringIO(text)):
                if row.get("clip") in names and row.get("description"):
                    out[row["clip"]] = row["description"]
        except csv.Error as exc:
            raise MotionFormatError(table, f"not a descriptions CSV ({exc})") from None
    return out


def label_files(root: Path) -> dict[str, Path]:
    return {
        p.stem: p for p in library_files(root) if p.suffix == ".csv" and p.parent.name == "labels"
    }


def read_labels(path: Path, n_frames: int) -> tuple[NDArray[np.int64], tuple[str, ...]]:
    """Per source frame ``(n_frames,)`` label index (-1 unlabelled) and the label names."""
    text = decode(path, read_bytes(path))
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:  # a huge field, a stray quote
        raise MotionFormatError(path, f"not a labels CSV ({exc})") from None
    if not rows or [c.strip() for c in rows[0]] != ["first_frame", "last_frame", "action"]:
        raise MotionFormatError(path, "header must be first_frame,last_frame,action", 1)
    labels = np.full(n_frames, -1, dtype=np.int64)
    names: list[str] = []
    for n, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != 3:
            raise MotionFormatError(path, f"expected 3 fields, got {len(row)}", n)
        try:
            first, last = int(row[0]), int(row[1])
        except ValueError:
            raise MotionFormatError(
                path, f"frame numbers must be whole numbers: {row[:2]}", n
            ) from None
        action = row[2].strip()
        if not action:
            raise MotionFormatError(path, "empty action name", n)
        if first < 1 or last < first:
            raise MotionFormatError(path, f"bad frame range {first}..{last}", n)
        if first > n_frames:
            raise MotionFormatError(
                path, f"range starts at frame {first}, the clip has {n_frames}", n
            )
        if action not in names:
            names.append(action)
        k = names.index(action)
        span = labels[first - 1 : min(last, n_frames)]
        clash = (span >= 0) & (span != k)
        if clash.any():
            raise MotionFormatError(path, f"range {first}..{last} overlaps another action", n)
        span[:] = k
    return labels, tuple(names)
