"""The side-by-side video of a performance: the performer beside the avatar.

The performer's pane is what the loop saw: for a colour source the frame itself, dimmed,
with the person mask it found tinted over it and the pose model's landmarks drawn (the
joints it could not see in grey); for a silhouette source the white mask. The panes are
streamed during the run onto a ``MaskTape`` (an MJPG file in a temporary folder,
at the pane's size), not kept in memory; at the end they are
played back beside the avatar's synthesized motion, drawn by pyrender on a floor grid by
one camera that follows the avatar's smoothed path (it never switches views). Each pane
has a caption: media time; the avatar's clip:frame, its action label, the match cost,
and a mark for a few frames after a jump or a relocation.
"""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from control.motion import Clip
from silhouette_bank import Bank, CameraRing

__all__ = ["PANE", "MaskTape", "performer_pane", "write_video"]

#: width, height of each pane (the video is two panes side by side)
PANE = (640, 480)
_BACKGROUND = (52, 44, 40)  # BGR, a dark floor
_GRID = (96, 88, 82)
_TEXT = (235, 235, 235)
_MARK = (60, 60, 230)


#: MediaPipe Pose's bones among the joints the pose descriptor reads (its landmark indices)
BONES = (
    (11, 12), (11, 13), (13, 15), (12, 14), (14, 16), (11, 23), (12, 24),
    (23, 24), (23, 25), (25, 27), (24, 26), (26, 28),
)  # fmt: skip
_MASK_TINT = (255, 190, 120)  # BGR, a light blue over the person found
_BONE = (80, 220, 255)
_HIDDEN = (150, 150, 150)


#: the tape's JPEG quality: a colour pane costs about a quarter of its lossless (FFV1)
#: size, some 10-40 kB, so that a ten-minute session's tape is a few hundred megabytes
#: at most, and a mask's black and white come back black and white
TAPE_QUALITY = 95


class MaskTape:
    """The performer's pane per avatar frame, written to a temporary MJPG video as they
    come (letterboxed into ``PANE``; nothing seen: black)."""

    def __init__(self, size: tuple[int, int] = PANE, fps: float = 15.0) -> None:
        self.size = size
        self.fps = fps
        self._dir = Path(tempfile.mkdtemp(prefix="mimic-masks-"))
        self._path = self._dir / "panes.avi"
        self._writer: Any = None
        self._n = 0
        self._open()

    def _open(self) -> None:
        if self._writer is not None:
            self._writer.release()
        fourcc = cv2.VideoWriter.fourcc(*"MJPG")
        self._writer = cv2.VideoWriter(str(self._path), fourcc, self.fps, self.size, True)
        if not self._writer.isOpened():
            raise OSError(f"{self._path}: cannot write an MJPG video here")
        self._writer.set(cv2.VIDEOWRITER_PROP_QUALITY, TAPE_QUALITY)
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def append(
        self,
        mask: NDArray[np.bool_] | None,
        image: NDArray[np.uint8] | None = None,
        landmarks: NDArray[np.float64] | None = None,
    ) -> None:
        """One frame of the pane: the ``mask`` alone (white on black), or over the colour
        ``image`` it was found in, with the pose model's ``landmarks`` ``(33, 3)`` (x, y
        as image fractions, visibility) drawn."""
        self._writer.write(performer_pane(self.size, mask, image, landmarks))
        self._n += 1

    def reset(self) -> None:
        """Drop what was written (the avatar restarted)."""
        self._open()

    def frames(self) -> Iterator[NDArray[np.uint8]]:
        """The panes written, as BGR images, in order (the tape is then closed for
        writing)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        cap = cv2.VideoCapture(str(self._path))
        try:
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                yield np.asarray(img if img.ndim == 3 else cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
        finally:
            cap.release()

    def close(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> MaskTape:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def performer_pane(
    size: tuple[int, int],
    mask: NDArray[np.bool_] | None,
    image: NDArray[np.uint8] | None = None,
    landmarks: NDArray[np.float64] | None = None,
) -> NDArray[np.uint8]:
    """The performer's pane of ``size`` (width, height): ``image`` (BGR) or, without one,
    ``mask`` in white on black, letterboxed; over an image the mask is tinted and the
    landmarks drawn (see ``MaskTape.append``)."""
    w, h = size
    pane = np.zeros((h, w, 3), dtype=np.uint8)
    src = image if image is not None else mask
    if src is None or not src.size:
        return pane
    sh, sw = src.shape[:2]
    scale = min(w / sw, h / sh)
    fit = (max(1, round(sw * scale)), max(1, round(sh * scale)))
    x0, y0 = (w - fit[0]) // 2, (h - fit[1]) // 2
    inside = pane[y0 : y0 + fit[1], x0 : x0 + fit[0]]
    small = None
    if mask is not None and mask.shape[:2] == (sh, sw):
        small = cv2.resize(mask.astype(np.uint8), fit, interpolation=cv2.INTER_NEAREST) > 0
    if image is None:
        assert small is not None  # (the mask is the source)
        inside[small] = 255
        return pane
    inside[:] = cv2.resize(image, fit, interpolation=cv2.INTER_AREA) // 2  # dimmed
    if small is not None:
        tint = np.array(_MASK_TINT, dtype=np.uint16)
        inside[small] = ((inside[small].astype(np.uint16) + tint) // 2).astype(np.uint8)
    if landmarks is not None:
        pts = np.asarray(landmarks, dtype=np.float64)
        xy = np.rint(pts[:, :2] * np.array(fit) + np.array([x0, y0])).astype(int)
        for a, b in BONES:
            seen = min(pts[a, 2], pts[b, 2]) >= 0.5
            cv2.line(pane, tuple(xy[a]), tuple(xy[b]), _BONE if seen else _HIDDEN, 2, cv2.LINE_AA)
        for k in {j for bone in BONES for j in bone}:
            colour = _BONE if pts[k, 2] >= 0.5 else _HIDDEN
            cv2.circle(pane, tuple(xy[k]), 4, colour, -1, cv2.LINE_AA)
    return pane


def _grid_lines(centre: NDArray[np.float64], extent: float = 6.0, step: float = 0.5) -> list:
    """World line segments of a floor grid around ``centre`` (x, z), each as points."""
    x0 = np.floor((centre[0] - extent) / step) * step
    z0 = np.floor((centre[2] - extent) / step) * step
    n = int(2 * extent / step) + 2
    ts = np.linspace(0.0, 2 * extent + step, 48)
    lines = []
    for k in range(n):
        x = x0 + k * step
        lines.append(np.stack((np.full_like(ts, x), np.zeros_like(ts), z0 + ts), axis=1))
        z = z0 + k * step
        lines.append(np.stack((x0 + ts, np.zeros_like(ts), np.full_like(ts, z)), axis=1))
    return lines


def _floor(ring: CameraRing, pose: NDArray[np.float64], centre: NDArray[np.float64]) -> np.ndarray:
    w, h = PANE
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = _BACKGROUND
    for line in _grid_lines(centre):
        cam = ring.to_camera(line, pose)
        keep = cam[:, 2] < -0.2  # in front of the camera
        if keep.sum() < 2:
            continue
        px = ring.project(cam[keep]).round().astype(np.int32)
        cv2.polylines(img, [px.reshape(-1, 1, 2)], False, _GRID, 1, cv2.LINE_AA)
    return img


def _caption(img: np.ndarray, lines: Sequence[str], mark: str = "") -> None:
    font = cv2.FONT_HERSHEY_SIMPLEX
    width = max((cv2.getTextSize(t, font, 0.6, 1)[0][0] for t in lines), default=0)
    if lines:  # a dark band behind the text, so that it reads on any pane
        band = img[4 : 12 + 24 * len(lines), 4 : 20 + width]
        band[:] = (band * 0.35).astype(np.uint8)
    y = 24
    for text in lines:
        cv2.putText(img, text, (12, y), font, 0.6, _TEXT, 1, cv2.LINE_AA)
        y += 24
    if mark:
        w = img.shape[1]
        cv2.rectangle(img, (w - 150, 8), (w - 10, 40), _MARK, -1)
        cv2.putText(img, mark, (w - 140, 32), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2)


def _frame_decisions(
    decisions: Sequence[dict[str, Any]], n_frames: int, fps: float, mark_s: float = 0.4
) -> tuple[float, list[dict[str, Any] | None], list[str]]:
    """The media time of avatar frame 0, the latest decision made (with a cost) at each
    avatar frame, and a mark (``JUMP``, ``RELOCATE``, ``START``) for ``mark_s`` after one."""
    t0 = 0.0
    for d in decisions:
        if "located" in d:
            t0 = float(d["t"])
    latest: list[dict[str, Any] | None] = [None] * n_frames
    marks = [""] * n_frames
    k = 0
    made: dict[str, Any] | None = None
    ds = [d for d in decisions if float(d["t"]) >= t0 - 1e-9]
    for i in range(n_frames):
        t = t0 + i / fps
        while k < len(ds) and float(ds[k]["t"]) <= t + 1e-9:
            d = ds[k]
            what = (
                "START"
                if "located" in d
                else "JUMP"
                if "jump" in d
                else "RELOCATE"
                if "relocated" in d
                else ""
            )
            if what:
                for j in range(i, min(n_frames, i + max(1, round(mark_s * fps)))):
                    marks[j] = what
            if d.get("cost") is not None:  # the latest decision that was made
                made = d
            k += 1
        latest[i] = made
    return t0, latest, marks


def write_video(
    result: Any, bank: Bank, clips: Sequence[Clip], path: str | Path, tape: MaskTape
) -> int:
    """Write the side-by-side MP4 of a performance (``result`` of ``perform`` run with
    ``tape``): performer left, avatar right, ``2 * PANE[0]`` x ``PANE[1]``. Returns the
    number of frames."""
    from silhouette_bank import capsule_body, shaded_frames, write_mp4  # GL: imported late

    synth = result.avatar.motion()
    motion = synth.motion
    graph = result.avatar.graph
    fps = motion.fps
    n = motion.n_frames
    by_name = {c.name: c for c in clips}
    history = result.avatar.history()[0]
    where = [graph.locate(int(f)) for f in history[:n]]
    t0, latest, marks = _frame_decisions(result.decisions, n, fps)
    # one camera for the whole video: the view that matched most often, following the
    # avatar's path smoothed over a second, so that it neither switches nor shakes
    views = np.asarray(result.views[:n] or [0], dtype=np.int64)
    view = int(np.bincount(views).argmax())
    ring = dataclasses.replace(bank.settings.ring, width=PANE[0], height_px=PANE[1])
    path_xz = gaussian_filter1d(motion.root_pos, sigma=max(1.0, fps), axis=0, mode="nearest")
    poses = ring.poses(path_xz)[:, view]
    body = capsule_body(motion.skeleton, bank.settings.body)
    avatar_frames = shaded_frames(motion, ring, body=body, camera_poses=poses)

    def frames() -> Iterator[np.ndarray]:
        performer = tape.frames()
        for i, shaded in enumerate(avatar_frames):
            seen = next(performer, None)
            left = np.zeros((PANE[1], PANE[0], 3), np.uint8) if seen is None else seen.copy()
            t = t0 + i / fps
            _caption(left, [f"performer  {t:6.2f} s"])
            right = _floor(ring, poses[i], path_xz[i])
            body_px = shaded.any(axis=2)
            right[body_px] = shaded[body_px]
            clip, f = where[min(i, len(where) - 1)]
            label = by_name[clip].label_at(f) if clip in by_name else None
            d = latest[i]
            cost = d.get("cost") if d else None
            _caption(
                right,
                [
                    f"avatar  {clip}:{f}  {label or '(unlabelled)'}",
                    "match cost " + (f"{cost:.3f}" if isinstance(cost, float) else "-"),
                ],
                marks[i],
            )
            yield np.ascontiguousarray(np.concatenate((left, right), axis=1))

    write_mp4(path, frames(), fps)
    return n
