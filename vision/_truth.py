"""Ground truth for a performance, and what the avatar did against it.

Two sources of truth: the JSON sidecar ``mimic record`` writes beside a recording
(``<video>.json``: a label per video frame), and a labels CSV for any video
(``file,start,end,label``, times in seconds, ``file`` matched by name; the format of
``benchmarks/videos/shared_labels.csv``). A recording of a library take also has the
take's cleaned labels (``motion_truth``): where the performer's motion changes action,
which the label files' boundaries miss by up to a second either way. Label names are
the library's (case does not matter). Agreement at a lag compares the avatar's label at
each decision with the performer's label ``lag`` seconds earlier: the avatar follows, so
it may be late.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from control.motion import Clip, MotionFormatError, load_library

__all__ = [
    "LAGS",
    "LabelFileError",
    "Truth",
    "action_runs",
    "agreement",
    "avatar_labels",
    "library_actions",
    "motion_truth",
    "read_span_labels",
    "truth_for",
]

#: the lags (seconds) agreement is reported at
LAGS = tuple(float(x) for x in np.round(np.arange(0.0, 3.01, 0.25), 2))


class LabelFileError(ValueError):
    """A labels CSV or sidecar that cannot be used; the message names the file and line."""


def read_span_labels(path: str | Path) -> list[tuple[str, float, float, str]]:
    """Rows ``(file, start, end, label)`` of a labels CSV (a ``file,start,end,label``
    header line and ``#`` comments allowed)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise LabelFileError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelFileError(f"{path}: unreadable ({exc})") from None
    rows = []
    for no, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        try:
            parts = next(csv.reader([line]))
        except csv.Error as exc:  # a huge field, a stray quote
            raise LabelFileError(f"{path}:{no}: not a labels line ({exc})") from None
        if [p.strip().lower() for p in parts] == ["file", "start", "end", "label"]:
            continue
        if len(parts) != 4:
            raise LabelFileError(f"{path}:{no}: expected file,start,end,label, got {raw!r}")
        name, a, b, label = (p.strip() for p in parts)
        try:
            start, end = float(a), float(b)
        except ValueError:
            raise LabelFileError(f"{path}:{no}: start and end must be seconds") from None
        if not (math.isfinite(start) and math.isfinite(end) and 0 <= start < end):
            raise LabelFileError(f"{path}:{no}: need 0 <= start < end, got {a}, {b}")
        if not label:
            raise LabelFileError(f"{path}:{no}: empty label")
        rows.append((name, start, end, label))
    if not rows:
        raise LabelFileError(f"{path}: no labelled spans")
    return rows


@dataclass(frozen=True)
class Truth:
    """The performer's action over media time: spans ``(start, end, label)``."""

    spans: tuple[tuple[float, float, str], ...]
    source: str  # where it came from (a sidecar or a CSV)

    def label_at(self, t: float) -> str | None:
        for a, b, label in self.spans:
            if a <= t < b:
                return label
        return None


def _read_sidecar(path: Path) -> tuple[dict[str, Any], float, list[Any]]:
    """A recording sidecar: its JSON, frame rate and labels (one per video frame)."""
    try:
        side = json.loads(path.read_text(encoding="utf-8"))
        fps = float(side["fps"])
        labels = side["labels"]
        if not (math.isfinite(fps) and fps > 0) or not isinstance(labels, list):
            raise ValueError("fps must be positive and labels a list")
    except FileNotFoundError:
        raise LabelFileError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        raise LabelFileError(f"{path}: not a recording sidecar ({exc})") from None
    return side, fps, labels


def _sidecar_truth(path: Path) -> Truth:
    _, fps, labels = _read_sidecar(path)
    return _spans(labels, fps, str(path))


def _spans(labels: Sequence[Any], fps: float, source: str) -> Truth:
    """The truth of one label per frame at ``fps`` (``None`` or ``""``: unlabelled)."""
    spans = []
    i = 0
    while i < len(labels):
        j = i
        while j + 1 < len(labels) and labels[j + 1] == labels[i]:
            j += 1
        if labels[i]:
            spans.append((i / fps, (j + 1) / fps, str(labels[i]).lower()))
        i = j + 1
    return Truth(tuple(spans), source)


def motion_truth(video: str | Path, library: str | Path) -> Truth | None:
    """Where the performer of a recording of a library take changes action: each video
    frame labelled by the take's cleaned labels (``control.motion.clean_labels``) at the
    source frame its sidecar names; a frame the sidecar leaves unlabelled (a pause)
    stays so. ``None`` when the video has no sidecar, its sidecar names no take, or the
    take is not in ``library`` (or cannot be read there)."""
    path = Path(video).with_name(Path(video).name + ".json")
    if not path.is_file():
        return None
    side, fps, labels = _read_sidecar(path)
    try:
        at = np.asarray(side["source_frames"], dtype=np.float64)
        name = str(side["clip"])
    except KeyError:  # a sidecar that names no take
        return None
    except (ValueError, TypeError) as exc:
        raise LabelFileError(f"{path}: not a recording sidecar ({exc})") from None
    if at.shape != (len(labels),):
        raise LabelFileError(f"{path}: {at.size} source frames for {len(labels)} labels")
    try:
        take = load_library(library, fps=fps, clips=[name]).clip(name)
    except (MotionFormatError, KeyError):  # the take is not in this library
        return None
    cleaned = labels_at_source_frames(take, at, labels)
    return _spans(cleaned, fps, f"{path} (the cleaned labels of {take.name})")


def labels_at_source_frames(
    take: Clip, source_frames: Sequence[float] | np.ndarray, labels: Sequence[Any]
) -> list[str | None]:
    """``take``'s label (as its clip names it) at each of ``source_frames`` (frames of
    the take's source file: a recording's frames, retimed or held), from the frame of
    ``take`` nearest each; ``None`` where ``labels`` (the recording's own) has none, as
    in a pause."""
    src = np.asarray(take.source_frames, dtype=np.float64)
    at = np.asarray(source_frames, dtype=np.float64)
    j = np.clip(np.searchsorted(src, at), 0, src.size - 1)
    before = np.clip(j - 1, 0, src.size - 1)
    nearest = np.where(np.abs(src[before] - at) <= np.abs(src[j] - at), before, j)
    return [take.label_at(int(k)) if lab else None for lab, k in zip(labels, nearest, strict=True)]


def truth_for(video: str | Path, labels: str | Path | None = None) -> Truth | None:
    """The ground truth of ``video``: its rows in the ``labels`` CSV when one is given
    (an error when it has none for this video), else its recording sidecar when there is
    one, else ``None``."""
    video = Path(video)
    if labels is not None:
        rows = read_span_labels(labels)
        spans = tuple((a, b, lab.lower()) for f, a, b, lab in rows if Path(f).name == video.name)
        if not spans:
            raise LabelFileError(f"{labels}: no labelled spans for {video.name}")
        return Truth(spans, str(labels))
    side = video.with_name(video.name + ".json")
    return _sidecar_truth(side) if side.is_file() else None


def library_actions(clips: Sequence[Clip]) -> set[str]:
    """The action labels the library's clips carry, in lower case."""
    return {
        c.label_names[int(k)].lower() for c in clips for k in np.unique(c.labels[c.labels >= 0])
    }


def avatar_labels(
    decisions: Sequence[Mapping[str, Any]], clips: Sequence[Clip], lower: bool = True
) -> list[str]:
    """The avatar's action at each decision: its clip's label there (in lower case, as
    truths are compared, unless ``lower`` is False), else the clip's name (which is no
    label: ``02_05``)."""
    by_name = {c.name: c for c in clips}
    out = []
    for d in decisions:
        clip = by_name[d["clip"]]
        label = clip.label_at(int(d["clip_frame"]))
        out.append((label.lower() if lower else label) if label else clip.name)
    return out


def agreement(
    decisions: Sequence[Mapping[str, Any]],
    clips: Sequence[Clip],
    truth: Truth,
    lags: Sequence[float] = LAGS,
    known: set[str] | None = None,
) -> dict[str, Any]:
    """The share of decisions at which the avatar's label is the performer's ``lag``
    seconds earlier, per lag (decisions where the performer has no label are left out;
    with ``known``, also those whose performer action the library lacks), the best at a
    lag of at most 1 s, and the confusion at that lag (performer label -> avatar label ->
    count)."""
    mine = avatar_labels(decisions, clips)
    curve: dict[str, float | None] = {}
    counts: dict[str, int] = {}
    confusion_at: dict[float, dict[str, dict[str, int]]] = {}
    for lag in lags:
        hits = []
        conf: dict[str, dict[str, int]] = {}
        for d, got in zip(decisions, mine, strict=True):
            want = truth.label_at(float(d["t"]) - lag)
            if want is None or (known is not None and want not in known):
                continue
            hits.append(got == want)
            row = conf.setdefault(want, {})
            row[got] = row.get(got, 0) + 1
        curve[f"{lag:g}"] = round(float(np.mean(hits)), 3) if hits else None
        counts[f"{lag:g}"] = len(hits)
        confusion_at[lag] = conf
    within = [(v, float(k)) for k, v in curve.items() if float(k) <= 1.0 and v is not None]
    best, best_lag = max(within, default=(None, None), key=lambda p: (p[0], -p[1]))
    return {
        "by_lag_s": curve,
        "decisions_by_lag_s": counts,
        "best_at_lag_le_1s": best,
        "best_lag_s": best_lag,
        "confusion_at_best_lag": confusion_at.get(best_lag, {}) if best_lag is not None else {},
    }


def action_runs(
    decisions: Sequence[Mapping[str, Any]], clips: Sequence[Clip], min_seconds: float = 0.0
) -> list[tuple[float, float, str]]:
    """What the avatar did: runs ``(start, end, action)`` of the same action over the
    decisions, each ending where the next begins; a run shorter than ``min_seconds`` is
    given to the one before it (the first, to the one after)."""
    mine = avatar_labels(decisions, clips, lower=False)
    times = [float(d["t"]) for d in decisions]
    raw: list[list[Any]] = []
    for t, got in zip(times, mine, strict=True):
        if raw and raw[-1][2] == got:
            continue
        if raw:
            raw[-1][1] = t
        raw.append([t, t, got])
    if raw:
        raw[-1][1] = times[-1]
    out: list[list[Any]] = []
    for run in raw:
        if out and (run[1] - run[0] < min_seconds or out[-1][2] == run[2]):
            out[-1][1] = run[1]
        elif len(out) == 1 and out[0][1] - out[0][0] < min_seconds:
            out[0] = [out[0][0], run[1], run[2]]  # a short first run goes to the one after
        else:
            out.append(list(run))
    return [(a, b, s) for a, b, s in out]
