"""What every benchmark script writes: the machine it ran on, and the JSON result."""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path
from typing import Any

from control.artifacts import atomic_write

__all__ = ["machine", "save"]


def machine() -> str:
    """``"x86_64, 2 cores, Python 3.11.7"``."""
    return f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"


def save(result: dict[str, Any], out: str | Path) -> None:
    """Print ``result`` as JSON and write it to ``out`` (atomically)."""
    text = json.dumps(result, indent=2)
    print(text)
    with atomic_write(out) as fh:
        fh.write(text + "\n")
