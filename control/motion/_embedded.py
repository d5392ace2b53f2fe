"""The embedded default library: a handful of CMU clips shipped inside the package.

Used when neither ``$MIMIC_MOCAP`` nor ``../shared/mocap`` exists, so that
``mimic perform --camera 0`` and the demo on ``recordings/`` work on any machine. The
clips are stored as motion arrays (``_arrays``) at 30 frames/s, every 4th frame of the
120 frames/s captures (the library's default 15 frames/s is every 8th, the same frames as
from the source files), with their action labels at that rate and a README that carries
the CMU acknowledgement. Regenerate with::

    mimic library embed ../shared/mocap --out control/motion/default_library
"""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..artifacts import atomic_write, current_umask
from ._arrays import ARRAYS_SUFFIX, write_motion_arrays

__all__ = ["EMBEDDED_CLIPS", "EMBEDDED_FPS", "EMBEDDED_LIBRARY", "embed_library"]

EMBEDDED_LIBRARY = Path(__file__).resolve().parent / "default_library"
#: The labelled exercise takes, walks, a run, jumps and strikes (all on the floor).
EMBEDDED_CLIPS = ("13_29", "13_30", "13_31", "02_01", "02_02", "02_03", "02_04", "02_05", "01_01")
EMBEDDED_FPS = 30.0
#: The maximum size of the embedded library (issue 18).
EMBEDDED_MAX_BYTES = 5_000_000

ACKNOWLEDGEMENT = (
    "The data used in this project was obtained from mocap.cs.cmu.edu.\n"
    "The database was created with funding from NSF EIA-0196217."
)


def _label_rows(labels: np.ndarray, names: Sequence[str]) -> list[tuple[int, int, str]]:
    """Runs ``(first, last, action)`` of a per-frame label array, 1-based inclusive."""
    rows = []
    i = 0
    while i < labels.size:
        j = i
        while j + 1 < labels.size and labels[j + 1] == labels[i]:
            j += 1
        if labels[i] >= 0:
            rows.append((i + 1, j + 1, names[int(labels[i])]))
        i = j + 1
    return rows


def embed_library(
    source: str | Path,
    out: str | Path = EMBEDDED_LIBRARY,
    clips: Sequence[str] = EMBEDDED_CLIPS,
    fps: float = EMBEDDED_FPS,
) -> dict[str, int]:
    """Convert ``clips`` of the library at ``source`` into an embedded library at ``out``.

    The folder is written beside ``out`` and then swapped in, so a stop leaves the old
    library or the new one, never half of one. Returns the size in bytes of each file.
    """
    from ._library import load_library  # the loader imports this module

    # (the label files' own boundaries: the embedded library is cleaned when loaded)
    lib = load_library(source, fps=fps, clips=list(clips), clean_labels=False)
    missing = sorted(set(clips) - {c.name for c in lib.clips})
    if missing:
        raise FileNotFoundError(f"{source}: no clip named {', '.join(missing)}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        tmp.chmod(0o777 & ~current_umask())  # as mkdir would make it, not mkdtemp's 0700
        table = []
        for c in lib.clips:
            source = f"CMU {Path(c.path).name}, by mimic library embed"
            m = dataclasses.replace(c.motion, source=source)
            write_motion_arrays(tmp / f"{c.name}{ARRAYS_SUFFIX}", m)
            rows = _label_rows(c.labels, c.label_names)
            if rows:
                with atomic_write(tmp / "labels" / f"{c.name}.csv") as fh:
                    fh.write("first_frame,last_frame,action\n")
                    fh.writelines(f"{a},{b},{name}\n" for a, b, name in rows)
            table.append(f"| {c.name} | {m.n_frames} | {c.description} |")
        (tmp / "README.md").write_text(_readme(fps, table), encoding="utf-8")
        old = out.with_name(f".{out.name}.old")
        if old.exists():
            shutil.rmtree(old)
        if out.exists():
            out.rename(old)
        tmp.rename(out)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    files = sorted(p for p in out.rglob("*") if p.is_file())
    return {str(p.relative_to(out)): p.stat().st_size for p in files}


def _readme(fps: float, table: list[str]) -> str:
    """The embedded library's README: what it is, how to make it again, the CMU terms,
    and its clips (``table``'s rows)."""
    return "\n".join(
        [
            "# The embedded default motion library",
            "",
            "A handful of clips of the CMU Graphics Lab Motion Capture Database",
            "(mocap.cs.cmu.edu), shipped so that mimic runs where no other library is",
            f"found. Motion arrays (`*{ARRAYS_SUFFIX}`, float32) at {fps:g} frames/s, every",
            "4th frame of the 120 frames/s captures; action labels (the MoCap6 benchmark's,",
            "Fox, Hughes, Sudderth, Jordan) in `labels/`, 1-based frames at that rate.",
            "",
            "Regenerate from the full library with:",
            "",
            "```sh",
            "mimic library embed ../shared/mocap --out control/motion/default_library",
            "```",
            "",
            "## Terms",
            "",
            "The CMU database is free for all uses; it may be redistributed and included",
            "in products, but not resold as data.",
            "",
            ACKNOWLEDGEMENT,
            "",
            "## Clips",
            "",
            f"| clip | frames @{fps:g} | description |",
            "|---|---|---|",
            *table,
            "",
        ]
    )
