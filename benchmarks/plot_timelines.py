"""The performer's actions and the avatar's on one time axis, one PNG a run of a
``bench_accuracy`` result: what a viewer would see of the avatar's steadiness and lag.
The performer's row is the label files'; a result that has them adds a row for where the
performer's motion changes action (the take's cleaned labels).

Usage: python -m benchmarks.plot_timelines RESULT.json --out DIR

Each run of each fold (the held-out take, filmed one way) becomes ``DIR/TAKE_RECORDING.png``
(``vision.plot_timeline``, as ``mimic evaluate --png`` draws it below its other panels),
titled with the run's agreement, switches a minute and brief actions. A result written
before runs carried their timeline is an error naming it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from vision import plot_timeline


def _title(fold: dict[str, Any], run: dict[str, Any]) -> str:
    best = max(
        (c for c in run["curve"] if c["lag"] <= 1.0),
        key=lambda c: c["label_agreement_known_actions"] or 0.0,
    )
    sw = run["switches_per_minute"]
    return (
        f"{fold['test']} {run.get('recording', '')}: agreement "
        f"{best['label_agreement_known_actions']:.3f} at lag {best['lag']:g} s; the avatar "
        f"switches {sw['avatar']:g} times a minute ({sw['avatar_brief_actions_under_0.5s']:g} "
        f"brief), the performer {sw['performer']:g}"
    )


def plot_result(result: Path, out: Path) -> list[Path]:
    """Every run's timeline of ``result`` into ``out``; the files written."""
    data = json.loads(result.read_text())
    written = []
    for fold in data["folds"]:
        for run in fold["runs"]:
            if "timeline" not in run:
                raise ValueError(f"{result}: its runs carry no timeline (rerun bench_accuracy)")
            path = out / f"{fold['test']}_{run.get('recording', 'run')}.png"
            plot_timeline(run["timeline"], path, _title(fold, run))
            written.append(path)
    return written


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result", type=Path, help="a bench_accuracy result (JSON)")
    ap.add_argument("--out", type=Path, required=True, help="folder for the PNGs")
    a = ap.parse_args()
    try:
        written = plot_result(a.result, a.out)
    except (OSError, ValueError, KeyError) as exc:
        print(f"plot_timelines: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {len(written)} timelines to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
