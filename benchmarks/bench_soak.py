"""A long replay (issue 19): memory and speed of ``perform`` over 30 minutes of media.

Usage: python -m benchmarks.bench_soak [LIBRARY_DIR] [--minutes M] [--tape] [--out FILE]

The committed recording (``recordings/13_29_first12s_160x120.mkv``, 12 s of silhouettes)
is played again and again, its clock running on, for ``--minutes`` of media time (default
30), through ``mimic perform``'s own preparation (the default library, graph, higher layer
and bank) and loop, with a decision log on disk and, with ``--tape``, the performer's
masks taped for the side-by-side video as perform does for ``--video-out``. The process's
resident memory (RSS, from /proc) is sampled every media minute. What a run must keep
grows with it: the decisions (a dict each) and the avatar's frames (for the BVH), so the
growth is reported per media minute, against that expectation.
"""

from __future__ import annotations

import argparse
import contextlib
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._report import machine, save
from mimic.cli import build_parser
from mimic.perform import DecisionLog
from mimic.run import prepare
from mimic.run_args import run_settings
from vision import Frame, MaskTape, VideoSource, perform

RECORDING = Path(__file__).resolve().parents[1] / "recordings" / "13_29_first12s_160x120.mkv"


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


class Looped:
    """A video played again and again, media time running on across the loops."""

    def __init__(self, path: Path, seconds: float) -> None:
        self.path, self.seconds = path, seconds
        self.inner = VideoSource(path, silhouette=True)
        self.name = f"{path.name} (looped)"
        self.offset = 0.0
        self.last = 0.0
        self.loops = 0

    def read(self) -> Frame | None:
        frame = self.inner.read()
        if frame is None:  # the end of the file: again, from the start
            self.inner.close()
            self.inner = VideoSource(self.path, silhouette=True)
            self.offset = self.last + 1.0 / 30.0
            self.loops += 1
            frame = self.inner.read()
            if frame is None:
                return None
        t = frame.t + self.offset
        if t > self.seconds:
            return None
        self.last = t
        return Frame(t, frame.index, frame.image, frame.mask, frame.problem)

    def close(self) -> None:
        self.inner.close()

    def __getattr__(self, name: str) -> Any:  # what perform asks of a video source
        return getattr(self.inner, name)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("library", nargs="?", default=None)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--tape", action="store_true", help="tape the masks as --video-out does")
    ap.add_argument("--out", default="benchmarks/results/soak.json")
    args = ap.parse_args()
    argv = ["perform", "--video", str(RECORDING)] + ([args.library] if args.library else [])
    pargs = build_parser().parse_args(argv)
    source = Looped(RECORDING, args.minutes * 60.0)
    t0 = time.perf_counter()
    ready = prepare(run_settings(pargs), source)
    prepared_s = time.perf_counter() - t0
    samples: list[dict[str, float]] = []
    next_sample = [0.0]
    wall0 = [time.perf_counter()]

    def on_decision(entry: dict[str, Any]) -> None:
        if entry["t"] >= next_sample[0]:
            samples.append(
                {
                    "media_min": round(entry["t"] / 60.0, 2),
                    "wall_s": round(time.perf_counter() - wall0[0], 1),
                    "rss_mb": round(rss_mb(), 1),
                }
            )
            print(f"  {samples[-1]}", flush=True)
            next_sample[0] += 60.0

    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        log: Any = stack.enter_context(DecisionLog(str(Path(tmp) / "decisions.jsonl")))
        tape = stack.enter_context(MaskTape(fps=ready.graph.fps)) if args.tape else None
        rss_start = rss_mb()
        wall0[0] = time.perf_counter()
        result = perform(
            source,
            ready.layer,
            ready.bank,
            ready.clips,
            ready.settings,
            start=ready.start,
            log=log,
            tape=tape,
            on_decision=on_decision,
        )
        wall = time.perf_counter() - wall0[0]
        rss_end = rss_mb()
    made = [d for d in result.decisions if d.get("decision") is not None]
    after_warm = [s for s in samples if s["media_min"] >= 1.0]
    growth = (
        (after_warm[-1]["rss_mb"] - after_warm[0]["rss_mb"])
        / max(after_warm[-1]["media_min"] - after_warm[0]["media_min"], 1e-9)
        if len(after_warm) >= 2
        else None
    )
    frames = result.avatar.n_frames
    joints = result.avatar.motion().motion.skeleton.n_joints
    result_json = {
        "machine": machine(),
        "recording": RECORDING.name,
        "minutes": args.minutes,
        "tape": args.tape,
        "loops": source.loops,
        "prepare_s": round(prepared_s, 1),
        "wall_s": round(wall, 1),
        "realtime_factor": round(result.media_seconds / wall, 1),
        "decisions": len(result.decisions),
        "decisions_made": len(made),
        "avatar_frames": frames,
        "rss_start_mb": round(rss_start, 1),
        "rss_end_mb": round(rss_end, 1),
        "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
        "rss_growth_mb_per_media_min": round(growth, 2) if growth is not None else None,
        "expected_growth_mb_per_media_min": round(
            # the avatar's frames (root + a quaternion a joint, float64) and about 1 kB a
            # decision dict, per media minute
            (frames / max(args.minutes, 1e-9)) * (3 + 4 * joints) * 8 / 1e6
            + len(result.decisions) / max(args.minutes, 1e-9) * 1e-3,
            2,
        ),
        "samples": samples,
    }
    save(result_json, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
