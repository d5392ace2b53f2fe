"""The one error type every motion reader raises for bad input."""

from __future__ import annotations

from pathlib import Path

__all__ = ["MotionFormatError"]


class MotionFormatError(ValueError):
    """A motion or skeleton file that cannot be read.

    The message names the file, the line (or frame) where that is known, and what is wrong:
    ``"02_01.amc:17: bone 'lfemur' expects 3 values (rx ry rz), got 2"``.

    Attributes
    ----------
    path : the file, as given.
    line : 1-based line number, or ``None`` when the problem is not tied to one line.
    problem : what is wrong, without the location.
    """

    def __init__(self, path: str | Path, problem: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = self.path if line is None else f"{self.path}:{line}"
        super().__init__(f"{where}: {problem}")

    def __reduce__(self) -> tuple[type, tuple[str, str, int | None]]:
        # Keeps the error intact when it crosses a process boundary.
        return (type(self), (self.path, self.problem, self.line))
