"""Silhouette bank speed: silhouettes per second, the whole library, peak memory.

Usage: python -m benchmarks.bench_bank [LIBRARY_DIR] [--out FILE]

- Silhouettes per second in one process, rendering plus features, for the numba capsule
  rasterizer and for headless pyrender (EGL), at 160x120 and 320x240 (exercise clip
  13_29, 18 views). Rendering alone is reported too.
- The whole library at 15 frames/s built into a fresh bank with 1 and 2 processes
  (rasterizer, 160x120), with the peak memory of the build (parent and children).
Targets (issue 5): >= 2,000 silhouettes/s per process at 160x120; the all-shared library
(about 11k frames x 18 views) in <= 60 s.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

import numba
import numpy as np

from benchmarks._report import machine, save
from control.motion import default_library_path, load_library
from silhouette_bank import (
    BankSettings,
    CameraRing,
    build_bank,
    capsule_body,
    gl_features,
    gl_silhouettes,
    motion_features,
    motion_silhouettes,
)
from silhouette_bank._gl import GLRenderer


def _rate(fn: Any, n: int) -> float:
    fn()  # warm up (numba compile, GL context)
    t = time.perf_counter()
    fn()
    return n / (time.perf_counter() - t)


def per_process(root: Path) -> dict[str, Any]:
    m = load_library(root, clips=["13_29"]).clip("13_29").motion
    body = capsule_body(m.skeleton)
    frames = np.arange(0, m.n_frames, 2)
    out: dict[str, Any] = {}
    for w, h in ((160, 120), (320, 240)):
        ring = CameraRing(width=w, height_px=h)
        n = frames.size * ring.n_views
        key = f"{w}x{h}"
        out[key] = {
            "raster_render": _rate(lambda ring=ring: motion_silhouettes(m, body, ring, frames), n),
            "raster_with_features": _rate(
                lambda ring=ring: motion_features(m, body, ring, frames), n
            ),
        }
        threads = numba.get_num_threads()
        numba.set_num_threads(1)  # one core, like one pyrender process
        out[key]["raster_render_1_thread"] = _rate(
            lambda ring=ring: motion_silhouettes(m, body, ring, frames), n
        )
        out[key]["raster_with_features_1_thread"] = _rate(
            lambda ring=ring: motion_features(m, body, ring, frames), n
        )
        numba.set_num_threads(threads)
        with GLRenderer(ring) as gl:
            few = frames[:60]
            k = few.size * ring.n_views
            out[key]["gl_render"] = _rate(
                lambda gl=gl, ring=ring, few=few: gl_silhouettes(gl, m, body, ring, few), k
            )
            out[key]["gl_with_features"] = _rate(
                lambda gl=gl, ring=ring, few=few: gl_features(gl, m, body, ring, few), k
            )
    return out


def whole_library(root: Path, workers: int) -> dict[str, Any]:
    lib = load_library(root)
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        bank = build_bank(lib.clips, BankSettings(), Path(tmp) / "bank", workers=workers)
        seconds = time.perf_counter() - t
        size = sum(p.stat().st_size for p in (Path(tmp) / "bank").iterdir())
    n = bank.n_frames * bank.features.shape[1]
    return {
        "workers": workers,
        "frames": bank.n_frames,
        "silhouettes": n,
        "seconds": seconds,
        "silhouettes_per_second": n / seconds,
        "bank_mb": size / 1e6,
        "peak_rss_mb_parent": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "peak_rss_mb_children": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--out", default="benchmarks/results/bank.json")
    args = ap.parse_args()
    root = Path(args.root)
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "per_process": per_process(root),
        "library_1_process": whole_library(root, 1),
        "library_2_processes": whole_library(root, 2),
    }
    save(result, args.out)


if __name__ == "__main__":
    main()
