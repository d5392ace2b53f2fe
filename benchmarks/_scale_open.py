"""``bench_scale``'s ``open`` step: what the vision half of a ``perform`` start-up costs on
a bank of ``N`` frames, and whether it reads the bank.

The bank: the default bank of the shared library (18 views, the default descriptor and
learned metric) tiled to ``N`` frames, every other copy mirrored, written as
``build_bank`` writes a bank (memory-mapped ``.npy`` files, a manifest with the hash of
every block, one checksum over the manifest and ``bank.npz``); rendering ``N`` frames
here would take hours (``bank`` step). Three fresh processes then each do what
``Matcher`` does before its first decision: open the bank, its shape statistics, its
window tables and its window index, and search once:

- ``first``: the bank checked in full; the statistics, tables and index made and stored;
- ``second``: all stored; the tables checked in full (the first run wrote them and did
  not check them), the bank trusted (checked by the first run, seconds after its last
  change: ``silhouette_bank.RACY_NS``);
- ``warm``: all stored and checked: nothing read but the index and what the search
  touches.

Each reports its seconds per part, its resident memory after the search (a mapped page
counts once read) and the bytes of the bank and tables it mapped.
"""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["open_run", "open_step"]


def _tiled_bank(root: Path, n: int, folder: Path) -> None:
    """Write the default bank tiled to ``n`` frames into ``folder`` (see the module)."""
    from control.artifacts import atomic_write, checksum, read_npz
    from control.motion import load_library
    from silhouette_bank import BankFileError, BankSettings, block_hashes, cached_bank, npy_file

    lib = load_library(root)
    clips = [c for c in lib.clips if c.motion.skeleton.n_joints == 31]
    bank, _, _ = cached_bank(clips, BankSettings())
    src = Path(bank.path)
    desc, nb = bank.settings.features, bank.n_frames
    reps = -(-n // nb)
    folder.mkdir(parents=True, exist_ok=True)
    rows = 4096
    blocks: dict[str, Any] = {"rows": rows}
    with (
        npy_file(folder / "features.npy", bank.features.dtype, (n, *bank.features.shape[1:])) as f,
        npy_file(folder / "root_motion.npy", np.float32, (n, *bank.root_motion.shape[1:])) as r,
    ):
        for i in range(reps):
            a, b = i * nb, min(n, (i + 1) * nb)
            feats = np.asarray(bank.features[: b - a])
            moves = np.asarray(bank.root_motion[: b - a])
            f[a:b] = desc.mirror(feats) if i % 2 else feats
            r[a:b] = moves * np.array([-1, 1], dtype=np.float32) if i % 2 else moves
        blocks["features"] = block_hashes(f, rows)
        blocks["root_motion"] = block_hashes(r, rows)
    names, starts = [], []
    for i, c in itertools.product(range(reps), range(len(bank.clip_names))):
        s = int(bank.clip_start[c]) + i * nb
        if s < n:
            names.append(f"{bank.clip_names[c]}~{i}")
            starts.append(s)
    manifest = json.loads((src / "manifest.json").read_text())
    manifest.update(clip_names=names, clip_start=[*starts, n], shards=[], blocks=blocks, built=None)
    keys = ["clip_start", "key", *(["metric_mean", "metric"] if bank.metric else [])]
    arrays = read_npz(src / "bank.npz", keys, BankFileError, "bank file")
    arrays["clip_start"] = np.asarray([*starts, n], dtype=np.int64)
    manifest["checksum"] = checksum(manifest, arrays)
    with atomic_write(folder / "bank.npz", "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]
    with atomic_write(folder / "manifest.json") as fh:
        json.dump(manifest, fh, indent=1)


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def open_run(folder: Path, recording: Path) -> dict[str, Any]:
    """One start-up on the bank in ``folder`` (see the module), in this process."""
    t0 = time.perf_counter()
    from silhouette_bank import load_bank, silhouette_features
    from vision import (
        MatchSettings,
        VideoSource,
        cached_shape_stats,
        cached_window_index,
        cached_window_tables,
        performer_queries,
    )

    took: dict[str, float] = {"imports": time.perf_counter() - t0}
    rss0 = _rss_mb()

    def lap(name: str, t: float) -> float:
        took[name] = round(time.perf_counter() - t, 3)
        return time.perf_counter()

    t = time.perf_counter()
    bank = load_bank(folder)
    t = lap("bank", t)
    mean, proj = cached_shape_stats(bank)
    t = lap("stats", t)
    st = MatchSettings()
    length = round(st.window * 15.0)
    cs = bank.clip_start
    starts = np.concatenate(
        [np.arange(a, b - length + 1) for a, b in itertools.pairwise(cs)]
    ).astype(np.int64)
    shape, centre, key = cached_window_tables(
        bank, np.arange(bank.n_frames), cs, mean, proj, st.centre_weight
    )
    t = lap("tables", t)
    index = cached_window_index(shape, centre, starts, length, folder, key=key)
    t = lap("index", t)
    src = VideoSource(recording, silhouette=True)
    feats: list[np.ndarray] = []
    while (fr := src.read()) is not None and len(feats) < length:
        if fr.index % 2 == 0:
            feats.append(
                silhouette_features(
                    np.asarray(fr.mask, np.uint8), descriptor=bank.settings.descriptor
                )
            )
    src.close()
    t = time.perf_counter()
    qs = performer_queries(np.array(feats), bank.settings.features, mean, proj, st.centre_weight)
    index.search(qs, st.band, st.landing.top_windows)
    lap("first_search", t)
    mapped = sum(a.nbytes for a in (bank.features, bank.root_motion, shape, centre))
    return {
        "seconds": {k: round(v, 3) for k, v in took.items()},
        "total_seconds": round(sum(took.values()), 2),
        "rss_added_mb": round(_rss_mb() - rss0, 1),
        "mapped_gb": round(mapped / 1e9, 2),
    }


def open_step(root: Path, n: int, recording: Path) -> dict[str, Any]:
    """The ``open`` step at ``n`` frames (see the module)."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "bank"
        t = time.perf_counter()
        _tiled_bank(root, n, folder)
        out: dict[str, Any] = {"frames": n, "write_seconds": round(time.perf_counter() - t, 1)}
        for run in ("first", "second", "warm"):
            time.sleep(2.5)  # (past silhouette_bank.RACY_NS since the last change)
            cmd = [sys.executable, "-m", "benchmarks._scale_open", str(folder), str(recording)]
            t = time.perf_counter()
            res = subprocess.run(cmd, capture_output=True, text=True, check=True)
            got = json.loads(res.stdout.strip().splitlines()[-1])
            got["wall_seconds"] = round(time.perf_counter() - t, 2)
            out[run] = got
        out["warm_seconds"] = out["warm"]["wall_seconds"]
        out["bank_gb"] = round(
            sum(p.stat().st_size for p in folder.glob("*.npy") if "windows" not in p.name) / 1e9, 2
        )
        out["tables_gb"] = round(
            sum(p.stat().st_size for p in folder.glob("windows-*.npy")) / 1e9, 2
        )
        out["index_gb"] = round(sum(p.stat().st_size for p in folder.glob("index-*.npz")) / 1e9, 2)
    return out


if __name__ == "__main__":
    print(json.dumps(open_run(Path(sys.argv[1]), Path(sys.argv[2]))))
