"""Motion library load time: cold (parse everything) and warm (from the cache).

Usage: python -m benchmarks.bench_motion_load [LIBRARY_DIR] [--repeat N] [--out FILE]

Prints and writes JSON (default ``benchmarks/results/motion_load.json``): the median of
``--repeat`` runs for a cold load with one process and with the default process count,
a warm load, and source frames parsed per second. Targets (issue 2): cold <= 5 s,
warm <= 0.5 s on the 2-core development machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._report import machine, save
from control.motion import default_library_path, load_library


def _timed(**kwargs: Any) -> tuple[float, Any]:
    t = time.perf_counter()
    lib = load_library(**kwargs)
    return time.perf_counter() - t, lib


def run(root: Path, repeat: int) -> dict[str, Any]:
    cold1, cold, warm = [], [], []
    lib = None
    source_frames = 0
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            cold1.append(_timed(root=root, cache_dir=Path(tmp) / "a", workers=1)[0])
            t, lib = _timed(root=root, cache_dir=Path(tmp) / "b")
            cold.append(t)
            warm.append(_timed(root=root, cache_dir=Path(tmp) / "b")[0])
            source_frames = load_library(root, fps=None, cache_dir=Path(tmp) / "b").n_frames
    assert lib is not None
    source_bytes = sum(
        p.stat().st_size for p in root.rglob("*") if p.suffix.lower() in (".amc", ".bvh", ".asf")
    )
    med = statistics.median
    return {
        "library": str(root),
        "clips": len(lib.clips),
        "source_frames": source_frames,
        "source_megabytes": round(source_bytes / 1e6, 1),
        "frames_at_15fps": lib.n_frames,
        "cold_load_s_1_process": round(med(cold1), 3),
        "cold_load_s": round(med(cold), 3),
        "cold_processes": min(os.cpu_count() or 1, 4),
        "warm_load_s": round(med(warm), 3),
        "frames_parsed_per_s_1_process": round(source_frames / med(cold1)),
        "frames_parsed_per_s": round(source_frames / med(cold)),
        "repeat": repeat,
        "machine": machine(),
        "targets": {"cold_load_s": 5.0, "warm_load_s": 0.5},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("library", nargs="?", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "motion_load.json"
    )
    args = ap.parse_args()
    result = run(args.library or default_library_path(), args.repeat)
    save(result, args.out)


if __name__ == "__main__":
    main()
