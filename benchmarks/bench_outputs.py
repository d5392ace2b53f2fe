"""What ``mimic`` does with the files it is told to write, and with numbers nobody should
give it (issue 60): the table of cases and outcomes.

Usage: python -m benchmarks.bench_outputs [--code DIR] [--library DIR] [--out FILE]

Each case runs ``mimic`` in a process of its own (``--code``: the checkout whose code
runs, to measure an older commit the same way), in a fresh folder holding a copy of the
committed recording and its ground-truth sidecar, with the tests' small library (13_30,
``--k 12``). A few cases need a fault the machine does not have (a full disk, a video
writer that drops frames, a Ctrl-C during the build): those patch the one call in the
child before ``mimic`` runs. For each: the exit status, the last line on stderr, the
seconds it took, whether the input's checksum is unchanged, and which files of the
folder were made, changed or removed. A traceback, a changed input, or exit 0 for a
case that must fail is a failure.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._report import machine, save

REPO = Path(__file__).resolve().parents[1]
RECORDING = REPO / "recordings" / "13_29_first12s_160x120.mkv"

#: name -> (argv after ``mimic``, the patch the child makes first, whether it must fail,
#: what its message must say: the option named, what happened)
PERFORM = ["perform", "--video", "in.mkv", "--clips", "13_30", "--k", "12"]
SET = ["--seconds", "3", "--out", "a.bvh", "--log", "a.jsonl"]
WALK = ["graph", "walk", "--clips", "13_30", "--out", "w.bvh", "--seconds"]
CASES: dict[str, tuple[list[str], str, bool, str]] = {
    "--out over the input video": (
        [*PERFORM, "--out", "in.mkv"],
        "",
        True,
        "--out in.mkv: the same file as --video",
    ),
    "--log over the input video": (
        [*PERFORM, "--log", "in.mkv"],
        "",
        True,
        "--log in.mkv: the same file as --video",
    ),
    "--video-out over the input video": (
        [*PERFORM, "--video-out", "in.mkv"],
        "",
        True,
        "--video-out in.mkv: the same file as --video",
    ),
    "--log over the input's sidecar": (
        [*PERFORM, "--log", "in.mkv.json"],
        "",
        True,
        "--log in.mkv.json: the same file as --video's sidecar",
    ),
    "--out and --log the same file": (
        [*PERFORM, "--out", "s.x", "--log", "s.x"],
        "",
        True,
        "--log s.x: the same file as --out s.x",
    ),
    "--log over --out's timing file": (
        [*PERFORM, "--out", "c.bvh", "--log", "c.bvh.json"],
        "",
        True,
        "the same file as --out's timing file",
    ),
    "--out in /proc": (
        [*PERFORM, "--out", "/proc/x.bvh"],
        "",
        True,
        "--out /proc/x.bvh: cannot write",
    ),
    "--out a folder": ([*PERFORM, "--out", "."], "", True, "--out .: is a folder"),
    "--video-out whose frames fail to write": (
        [*PERFORM, *SET, "--video-out", "a.mp4"],
        "drop_frames",
        True,
        "--video-out a.mp4: could not be written",
    ),
    "a full disk writing --out": (
        [*PERFORM, *SET],
        "full_disk",
        True,
        "--out a.bvh: the disk is full",
    ),
    "a PNG named .mp4, with --log": (
        [*PERFORM[:2], "p.mp4", *PERFORM[3:], "--log", "r.jsonl"],
        "",
        False,
        "0 decisions",
    ),
    "--live-port 70000": (
        [*PERFORM, "--live-port", "70000", "--realtime"],
        "",
        True,
        "argument --live-port",
    ),
    "--live-port -5": (
        [*PERFORM, "--live-port", "-5", "--realtime"],
        "",
        True,
        "argument --live-port",
    ),
    "graph walk --seconds inf": ([*WALK, "inf"], "", True, "argument --seconds"),
    "graph walk --seconds 1e12": ([*WALK, "1e12"], "", True, "argument --seconds"),
    "perform --seconds nan": ([*PERFORM, "--seconds", "nan"], "", True, "argument --seconds"),
    "perform --seconds -1": ([*PERFORM, "--seconds", "-1"], "", True, "argument --seconds"),
    "perform --window 0": ([*PERFORM, "--window", "0"], "", True, "argument --window"),
    "perform --window -1": ([*PERFORM, "--window", "-1"], "", True, "argument --window"),
    "perform --window nan": ([*PERFORM, "--window", "nan"], "", True, "argument --window"),
    "perform --lookahead -1": ([*PERFORM, "--lookahead", "-1"], "", True, "argument --lookahead"),
    "--masks of unreadable images": (
        ["perform", "--masks", "masks", "--clips", "13_30", "--k", "12"],
        "",
        True,
        "no mask image in the folder could be read",
    ),
    "Ctrl-C before the first frame": (
        [*PERFORM, "--out", "a.bvh", "--log", "a.jsonl"],
        "stop_at_once",
        True,
        "stopped by SIGINT before the first frame",
    ),
    "$MIMIC_CACHE a regular file": (
        ["graph", "build", "--clips", "13_30"],
        "cache_file",
        True,
        "is a file, not a folder",
    ),
    "--camera 7 (no such camera)": (
        ["perform", "--camera", "7", "--clips", "13_30", "--k", "12", "--live-port", "0"],
        "",
        True,
        "camera 7: no frame in 20 s",
    ),
}

#: what the child runs: the patch for its case, then ``mimic``'s main
CHILD = """
import errno, os, sys
sys.path.insert(0, CODE)
patch = PATCH
if patch == "drop_frames":
    import cv2
    real = cv2.VideoWriter
    class Dropping:
        fourcc = staticmethod(real.fourcc)
        def __init__(self, *a):
            self.w, self.n, self.drop = real(*a), 0, str(a[0]).endswith(".mp4")
        def isOpened(self):
            return self.w.isOpened()
        def write(self, img):
            self.n += 1
            if self.n % 2 or not self.drop:
                self.w.write(img)
        def release(self):
            self.w.release()
    cv2.VideoWriter = Dropping
elif patch == "full_disk":
    import mimic.perform
    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")
    mimic.perform.write_bvh = full
elif patch == "stop_at_once":
    import mimic.perform
    class AtOnce(mimic.perform.StopOnSignal):
        def __call__(self):
            return "SIGINT"
    mimic.perform.StopOnSignal = AtOnce
from mimic.cli import main
sys.exit(main(ARGV))
"""


def _sums(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()[:12]
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _prepare(folder: Path) -> None:
    shutil.copy(RECORDING, folder / "in.mkv")
    shutil.copy(f"{RECORDING}.json", folder / "in.mkv.json")
    for name in ("a.bvh", "a.bvh.json", "a.mp4", "a.jsonl"):  # a previous run's set
        (folder / name).write_text(f"the previous run's {name}\n")
    import cv2
    import numpy as np

    assert cv2.imwrite(str(folder / "p.png"), np.full((40, 40, 3), 90, np.uint8))
    (folder / "p.png").rename(folder / "p.mp4")
    (folder / "masks").mkdir()
    (folder / "masks" / "0001.png").write_bytes(b"not a picture")
    (folder / "cache").write_text("not a folder")


def run_case(name: str, code: Path, library: str, timeout: float) -> dict[str, Any]:
    argv, patch, must_fail, says = CASES[name]
    with tempfile.TemporaryDirectory(prefix="mimic-outputs-") as tmp:
        folder = Path(tmp)
        _prepare(folder)
        before = _sums(folder)
        env = dict(os.environ, MIMIC_MOCAP=library)
        if patch == "cache_file":
            env["MIMIC_CACHE"] = str(folder / "cache")
        child = CHILD.replace("CODE", repr(str(code))).replace("PATCH", repr(patch))
        child = child.replace("ARGV", repr(argv))
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(
                [sys.executable, "-c", child],
                cwd=folder,
                env=env,
                capture_output=True,
                text=True,
                timeout=timeout,
            )
            rc: int | None = proc.returncode
            err, out = proc.stderr, proc.stdout
        except subprocess.TimeoutExpired as exc:
            rc = None
            err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
            out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        seconds = time.perf_counter() - t0
        after = _sums(folder)
    lines = [x for x in err.splitlines() if x.strip()]
    said_so = says in err or says in out
    changed = sorted(k for k in before if k in after and before[k] != after[k])
    made = sorted(k for k in after if k not in before and not k.startswith("cache/"))
    removed = sorted(k for k in before if k not in after)
    wrote = [x[len("wrote ") :] for x in out.splitlines() if x.startswith("wrote ")]
    claimed = [w.split(" (")[0] for w in wrote if w.split(" (")[0] not in after]
    inputs_kept = all(before[k] == after.get(k) for k in ("in.mkv", "in.mkv.json"))
    # a run that fails must leave the previous run's files as they were: all or nothing
    partial = must_fail and bool(changed or made or removed)
    # an error must name what the user named, not a hidden temporary file
    hidden = must_fail and ".tmp" in (lines[-1] if lines else "")
    failed = (
        "Traceback" in err
        or not inputs_kept
        or bool(claimed)
        or rc is None
        or (must_fail and rc == 0)
        or partial
        or hidden
        or not said_so
    )
    return {
        "case": name,
        "argv": argv,
        "exit": rc if rc is not None else f"still running after {timeout:g} s",
        "said": lines[-1] if lines else "",
        "seconds": round(seconds, 1),
        "input_unchanged": inputs_kept,
        "changed": changed,
        "made": made,
        "removed": removed,
        "said_wrote_but_no_file": claimed,
        "failed_but_changed_files": partial,
        "names_a_temporary_file": hidden,
        "says_what_happened": said_so,
        "traceback": "Traceback" in err,
        "failure": failed,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", default=str(REPO), help="the checkout whose mimic runs")
    ap.add_argument("--library", default=str(REPO.parent / "shared" / "mocap"))
    ap.add_argument("--timeout", type=float, default=90.0, help="seconds a case may run")
    ap.add_argument("--case", action="append", help="only these cases (default: all)")
    ap.add_argument("--out", default="benchmarks/results/outputs.json")
    args = ap.parse_args()
    rows = []
    for name in args.case or list(CASES):
        row = run_case(name, Path(args.code), args.library, args.timeout)
        rows.append(row)
        print(
            f"{'FAIL' if row['failure'] else 'ok  '} {name}: exit {row['exit']}, "
            f"{row['seconds']} s; {row['said'][:150]}",
            flush=True,
        )
    commit = subprocess.run(
        ["git", "-C", args.code, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    result = {
        "machine": machine(),
        "code": commit,
        "cases": len(rows),
        "failures": sum(r["failure"] for r in rows),
        "table": rows,
    }
    save(result, args.out)
    print(json.dumps({k: result[k] for k in ("code", "cases", "failures")}))
    return 1 if result["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
