"""Following a performer from every side, with the defaults and a real pose model.

Usage: python -m benchmarks.bench_views [LIBRARY_DIR] [--takes 14_20,13_29]
       [--azimuths 0,45,90,135,180] [--fold person|take] [--fps 15] [--size 640x480]
       [--seconds S] [--out FILE] [--videos DIR]

Each labelled take is filmed by ``mimic record --colour`` (the shaded body of another
shape than the avatar's, a static camera at each azimuth: 0 in front, 90 at the
performer's left side, 180 behind) and replayed by ``mimic evaluate`` with its
defaults, so MediaPipe Pose itself reads the video: a side view's far limbs come with
the low visibilities real footage gives them, which simulated landmarks do not.

Folds (``--fold``): ``person`` (the default) leaves the performer's whole subject out
of the library (14_20 against subject 13's takes and the rest, 13_29 against 14_20 and
the rest); ``take`` leaves out only the take itself.

Per run: agreement at a lag of at most 1 s over the actions the library has (the
issue's figure), and the same against where the performer's motion changes action (the
take's cleaned labels: ``vision.motion_truth``), per action, the avatar's and the
performer's switches a minute, how long after the performer's changes of action the
avatar took them up (from the label file and from the motion), and
the decision points without a decision, per reason (``vision.decision_points``: a person
in view and no decision is the failure this benchmark watches). Summaries per azimuth
and per take. The JSON goes to ``benchmarks/results/views.json``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.motion import default_library_path

HERE = Path(__file__).resolve().parent


def _mimic(*args: str) -> None:
    """Run ``mimic ARGS`` in a child process (as a user would); its errors raise."""
    cmd = [sys.executable, "-m", "mimic", *args]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")


def run_one(
    library: Path,
    take: str,
    azimuth: float,
    fold: str,
    videos: Path,
    work: Path,
    a: argparse.Namespace,
) -> dict[str, Any]:
    """Record ``take`` from ``azimuth`` in colour into ``videos`` (unless it is there
    already), then ``mimic evaluate`` it, its report in ``work``."""
    video = videos / f"{take}_az{azimuth:g}.mkv"
    rec = ["record", take, str(library), "--colour", "--fps", str(a.fps), "--size", a.size]
    rec += ["--azimuth", str(azimuth), "--out", str(video)]
    if a.seconds:
        rec += ["--to", str(a.seconds)]
    t0 = time.perf_counter()
    if not video.exists():
        _mimic(*rec)
    t_rec = time.perf_counter() - t0
    leave = f"{take.split('_')[0]}_*" if fold == "person" else take
    report = work / f"{video.stem}.evaluate.json"
    t0 = time.perf_counter()
    more = shlex.split(a.perform_args)
    _mimic("evaluate", str(video), str(library), "--leave-out", leave, "--json", str(report), *more)
    t_eval = time.perf_counter() - t0
    r = json.loads(report.read_text())
    return {
        "take": take,
        "azimuth": azimuth,
        "left_out": leave,
        "agreement": r["best_at_lag_le_1s"],
        "best_lag_s": r["best_lag_s"],
        "agreement_from_motion": r.get("best_at_lag_le_1s_from_motion"),
        "best_lag_from_motion_s": r.get("best_lag_from_motion_s"),
        "switch_followed_after_s": r["switch_followed_after_s"],
        "switch_followed_after_motion_s": r.get("switch_followed_after_motion_s"),
        "per_action": r["per_action_at_best_lag"],
        "switches_per_minute": r["switches_per_minute"],
        "decision_points": r["decision_points"],
        "latency_ms": r["latency_ms"],
        "seconds": {"record": round(t_rec, 1), "evaluate": round(t_eval, 1)},
    }


def _summary(runs: list[dict[str, Any]], key: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for value in sorted({r[key] for r in runs}):
        mine = [r for r in runs if r[key] == value]
        agree = [r["agreement"] for r in mine if r["agreement"] is not None]
        moved = [r["agreement_from_motion"] for r in mine if r.get("agreement_from_motion")]
        shares = [r["decision_points"]["person_in_view_undecided_share"] for r in mine]
        out[str(value)] = {
            "agreement_mean": round(float(np.mean(agree)), 3) if agree else None,
            "agreement_min": round(float(np.min(agree)), 3) if agree else None,
            "agreement_from_motion_mean": round(float(np.mean(moved)), 3) if moved else None,
            "person_in_view_undecided_share_max": round(float(np.max(shares)), 4),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("library", nargs="?", type=Path, default=None)
    ap.add_argument("--takes", default="14_20,13_29")
    ap.add_argument("--azimuths", default="0,45,90,135,180")
    ap.add_argument("--fold", choices=("person", "take"), default="person")
    ap.add_argument("--fps", type=float, default=15.0)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--seconds", type=float, default=None, help="only the first S s of a take")
    ap.add_argument(
        "--videos",
        type=Path,
        default=None,
        help="keep the recordings here, and use those already there (recorded with the "
        "same --fps, --size and --seconds)",
    )
    ap.add_argument(
        "--perform-args",
        default="",
        help="more of mimic evaluate's flags, as one string: --perform-args '--vote-switch 0.02'",
    )
    ap.add_argument("--out", type=Path, default=HERE / "results" / "views.json")
    a = ap.parse_args()
    library = a.library or default_library_path()
    takes = [t.strip() for t in a.takes.split(",") if t.strip()]
    azimuths = [float(x) for x in a.azimuths.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        videos = a.videos or work
        videos.mkdir(parents=True, exist_ok=True)
        runs = []
        for take in takes:
            for az in azimuths:
                r = run_one(library, take, az, a.fold, videos, work, a)
                runs.append(r)
                pts = r["decision_points"]
                print(
                    f"{take} at {az:g} deg (library without {r['left_out']}): agreement "
                    f"{r['agreement']}, undecided with a person in view "
                    f"{pts['person_in_view_undecided']} of {pts['points']} "
                    f"{pts['undecided_by_reason']}; switches a minute "
                    f"{r['switches_per_minute']['avatar']} "
                    f"(performer {r['switches_per_minute']['performer']})",
                    flush=True,
                )
    result = {
        "command": "python -m benchmarks.bench_views " + shlex.join(sys.argv[1:]),
        "machine": machine(),
        "library": str(library),
        "fold": a.fold,
        "recording": {"fps": a.fps, "size": a.size, "seconds": a.seconds, "kind": "colour"},
        "by_azimuth": _summary(runs, "azimuth"),
        "by_take": _summary(runs, "take"),
        "runs": runs,
    }
    save(result, a.out)


if __name__ == "__main__":
    main()
